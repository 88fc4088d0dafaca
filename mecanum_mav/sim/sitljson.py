"""ArduPilot SITL's JSON physics backend (``ardurover --model JSON:HOST``), as bytes: pure,
no I/O.

The firmware sends, once per physics frame, a little-endian binary *servo packet* to the
physics' UDP port (``--sim-port-out``, default 9002)::

    uint16 magic        18458 (16 channels) or 29569 (32 channels, SERVO_32_ENABLE 1)
    uint16 frame_rate   Hz: the physics should step 1 / frame_rate seconds
    uint32 frame_count  +1 per frame; the same count again = a resend (no answer came)
    uint16 pwm[16|32]   servo outputs, microseconds (0 = no output on that channel)

and the physics answers, to the address the packet came from, one line of JSON text that
must be *preceded and terminated* by a newline (the firmware turns newlines into string ends
and parses what lies between the last two)::

    {"timestamp":T,"imu":{"gyro":[p,q,r],"accel_body":[ax,ay,az]},
     "position":[n,e,d],"attitude":[roll,pitch,yaw],"velocity":[vn,ve,vd]}

- ``timestamp``: physics time, seconds (absolute, not a step; going back = a physics reset).
- ``imu.gyro``: body angular rate, FRD, rad/s (roll, pitch, yaw rate; yaw clockwise +).
- ``imu.accel_body``: specific force, body FRD, m/s^2 (what an accelerometer reads: at rest
  and level ``(0, 0, -9.81)``).
- ``position``: NED metres from the firmware's home; ``velocity``: NED m/s.
- ``attitude``: Euler roll, pitch, yaw (radians, ArduPilot's 3-2-1 order, yaw clockwise from
  north), or ``quaternion`` ``[w, x, y, z]`` instead.

ArduPilot's parser is not a JSON parser: it finds ``"key":`` by substring and reads the
value right after the colon with ``sscanf("[%f, %f, %f]")``, so the text must be compact
(no space after a colon or a bracket): :func:`encode_state` writes it so. Our chassis is in
NED/FRD already (CONVENTIONS.md): no sign changes at this edge.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["MAGIC_16", "MAGIC_32", "PhysicsState", "ServoPacket", "decode_servo_packet",
           "encode_servo_packet", "encode_state"]

MAGIC_16 = 18458
"""Servo packet with 16 channels."""
MAGIC_32 = 29569
"""Servo packet with 32 channels (``SERVO_32_ENABLE 1``)."""
_HEADER = struct.Struct("<HHI")
_CHANNELS = {MAGIC_16: 16, MAGIC_32: 32}

Vector3 = tuple[float, float, float]


@dataclass(frozen=True)
class ServoPacket:
    """One frame of the firmware's outputs.

    Attributes:
        frame_rate: the firmware's physics rate, Hz (step ``1 / frame_rate`` s).
        frame_count: the frame's number (a resend repeats it).
        pwm: servo outputs SERVO1.., microseconds (16 or 32 of them; 0 = no output).
    """

    frame_rate: int
    frame_count: int
    pwm: tuple[int, ...]


def decode_servo_packet(data: bytes) -> ServoPacket | None:
    """The servo packet in ``data``, or None when it is not one (unknown magic, wrong size,
    a frame rate of 0): never raises."""
    if len(data) < _HEADER.size:
        return None
    magic, frame_rate, frame_count = _HEADER.unpack_from(data)
    channels = _CHANNELS.get(magic)
    if channels is None or len(data) != _HEADER.size + 2 * channels or frame_rate == 0:
        return None
    pwm = struct.unpack_from(f"<{channels}H", data, _HEADER.size)
    return ServoPacket(frame_rate, frame_count, pwm)


def encode_servo_packet(frame_rate: int, frame_count: int, pwm: Sequence[int]) -> bytes:
    """The bytes the firmware sends for these outputs (16 channels, or 32 when more are
    given; fewer are padded with 0): for tests and fake firmware.

    Raises:
        ValueError: more than 32 channels.
    """
    if len(pwm) > 32:
        raise ValueError(f"at most 32 channels, got {len(pwm)}")
    channels = 16 if len(pwm) <= 16 else 32
    values = [*pwm, *[0] * (channels - len(pwm))]
    magic = MAGIC_16 if channels == 16 else MAGIC_32
    return _HEADER.pack(magic, frame_rate, frame_count) + struct.pack(f"<{channels}H", *values)


@dataclass(frozen=True)
class PhysicsState:
    """What the physics tells the firmware for one frame (frames and units as the module
    says: body FRD, local NED from home, radians, SI).

    Attributes:
        time_s: physics time, seconds.
        gyro: body rates (roll, pitch, yaw), rad/s, FRD.
        accel_body: specific force, body FRD, m/s^2 (level at rest: (0, 0, -g)).
        position_ned: metres north, east, down from the start.
        attitude: roll, pitch, yaw, radians (yaw clockwise from north).
        velocity_ned: m/s north, east, down.
    """

    time_s: float
    gyro: Vector3
    accel_body: Vector3
    position_ned: Vector3
    attitude: Vector3
    velocity_ned: Vector3


def _number(value: float) -> str:
    """A finite float as ArduPilot's ``atof``/``sscanf`` read it (non-finite reads 0)."""
    v = float(value)
    return repr(v) if math.isfinite(v) else "0.0"


def _vector(values: Sequence[float]) -> str:
    return "[" + ",".join(_number(v) for v in values) + "]"


def encode_state(state: PhysicsState) -> bytes:
    """The firmware's JSON line for ``state``: compact, with a newline before and after."""
    text = (f'{{"timestamp":{_number(state.time_s)},'
            f'"imu":{{"gyro":{_vector(state.gyro)},"accel_body":{_vector(state.accel_body)}}},'
            f'"position":{_vector(state.position_ned)},"attitude":{_vector(state.attitude)},'
            f'"velocity":{_vector(state.velocity_ned)}}}')
    return ("\n" + text + "\n").encode("ascii")
