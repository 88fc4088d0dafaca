"""The twin's physics: ArduPilot SITL's JSON backend (:mod:`mecanum_mav.sim.sitljson`) driving
the MuJoCo chassis (:mod:`mecanum_mav.sim.mujocochassis`) in lockstep.

The firmware paces the pair: it sends a servo packet per frame and waits for the answer.
:class:`BridgeCore` (no I/O) takes each packet's bytes and returns the answer:

- a packet with a new ``frame_count``: the four wheels' pulse widths (:class:`WheelMap`: per
  wheel FL, FR, RL, RR a servo channel and a sign) become wheel commands in [-1, 1] as the
  simulated board reads them (:meth:`~mecanum_mav.control.pwm.WheelOutput.command_from_pulse`
  over the wheel's ``MOT_<W>_MIN/TRIM/MAX``; a pulse of 0, no output, is 0 = stop), the
  chassis steps ``1 / frame_rate`` s, and the answer carries the chassis' new state;
- the same ``frame_count`` again (the firmware resends when an answer was late): the same
  answer again, no step (:attr:`BridgeStats.repeated`);
- a count that skips ahead: one step, the gap counted (:attr:`BridgeStats.dropped`); a count
  that goes back (the firmware restarted, e.g. ``setup-fc --reboot``): one step, counted in
  :attr:`BridgeStats.restarts`; the physics goes on (a rebooted board does not move the robot)
  but the time the firmware is told starts again from 0 (a restarted firmware's clock takes
  the first timestamp as its time since boot; setup-fc tells a reboot by that clock);
- anything else (wrong magic, wrong size): ignored, counted, never an answer.

What it tells the firmware (:class:`ChassisSensors`), all in NED/FRD: physics time, the gyro
(body rates from MuJoCo), the specific force in body FRD (the mean acceleration over the
frame minus gravity, rotated into the body: ``(0, 0, -g)`` at rest), position NED from the
start, roll/pitch/yaw, velocity NED. Every frame it records the truth (:class:`TruthSample`).

:class:`TwinBridge` serves the core on a UDP socket in a thread of its own.
"""

from __future__ import annotations

import contextlib
import math
import selectors
import socket
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from mecanum_mav.control.pwm import PwmMap, WheelOutput
from mecanum_mav.sim.sitljson import PhysicsState, ServoPacket, decode_servo_packet, encode_state

if TYPE_CHECKING:  # (mujoco is an optional extra: only the twin imports it)
    from mecanum_mav.sim.mujocochassis import MujocoChassis

__all__ = ["DEFAULT_WHEEL_MAP", "BridgeCore", "BridgeStats", "ChassisSensors", "TruthSample",
           "TwinBridge", "WheelMap"]

DEFAULT_WHEEL_MAP: tuple[tuple[int, float], ...] = ((1, 1.0), (2, 1.0), (3, 1.0), (4, 1.0))
"""Servo channel (1-based) and sign of FL, FR, RL, RR: SERVO1..4, as the companion's
pass-through board puts them (CONVENTIONS.md)."""
_NWU_TO_NED = np.diag([1.0, -1.0, -1.0])
"""MuJoCo's world is x north, y west, z up and the body x forward, y left, z up: flipping y
and z turns either into NED / FRD."""


@dataclass(frozen=True)
class TruthSample:
    """Where the chassis really was when the bridge answered a frame.

    Attributes:
        wall_s: ``time.monotonic()`` when the frame was answered.
        time_s: physics time, seconds.
        north_m, east_m: true position, local NED from the start, metres.
        yaw_rad: true heading, radians clockwise from north, [-pi, pi).
        forward_mps, right_mps: true velocity, body FRD, m/s.
    """

    wall_s: float
    time_s: float
    north_m: float
    east_m: float
    yaw_rad: float
    forward_mps: float
    right_mps: float


class WheelMap:
    """Servo outputs -> the four wheel commands FL, FR, RL, RR, through four ESCs.

    Each ESC reads its pulse as the simulated board does
    (:meth:`~mecanum_mav.control.pwm.WheelOutput.command_from_pulse`) and, as a car ESC does,
    drives only once it has seen neutral: from power-up, and again after a loss of signal
    (pulse 0, no output), it holds the wheel (command 0) until a pulse inside its dead band
    (``|command| < esc_dead_band``) arms it. (A booting ArduPilot puts out 1000 us on SERVO1
    for about 20 ms before its outputs start: without this the twin's chassis lurched at
    every boot.)

    Args:
        outputs: each wheel's pulse range (``MOT_<W>_MIN/TRIM/MAX``) and reverse
            (``MOT_<W>_REV``), from a :class:`~mecanum_mav.control.pwm.PwmMap`; its channel
            is not used (``channels`` says which servo drives the wheel).
        channels: per wheel FL, FR, RL, RR ``(servo channel 1-based, sign)``; a negative sign
            is a motor wired the other way round.
        esc_dead_band: the ESCs' dead band, a fraction of full command (``SIM_ESC_DZ``).

    Raises:
        ValueError: not four entries, a channel outside 1..32, or a sign of 0.
    """

    def __init__(self, outputs: PwmMap, channels: Sequence[tuple[int, float]] = DEFAULT_WHEEL_MAP,
                 esc_dead_band: float = 0.02) -> None:
        if len(channels) != 4:
            raise ValueError(f"need 4 (channel, sign) pairs FL, FR, RL, RR, got {len(channels)}")
        self._wheels: list[tuple[int, WheelOutput]] = []
        for (channel, sign), out in zip(channels, outputs.wheels, strict=True):
            if not 1 <= int(channel) <= 32 or not (math.isfinite(sign) and sign != 0.0):
                raise ValueError(f"bad wheel map entry ({channel}, {sign})")
            esc = WheelOutput(int(channel), out.minimum, out.trim, out.maximum,
                              out.reversed != (sign < 0.0))
            self._wheels.append((int(channel) - 1, esc))
        self._band = max(float(esc_dead_band), 1e-9)
        self._armed = [False, False, False, False]

    def pulses(self, pwm: Sequence[int]) -> tuple[int, int, int, int]:
        """The pulse widths (us) of the wheels' channels FL, FR, RL, RR (0: none)."""
        fl, fr, rl, rr = (pwm[i] if i < len(pwm) else 0 for i, _ in self._wheels)
        return (fl, fr, rl, rr)

    def commands(self, pwm: Sequence[int]) -> tuple[float, float, float, float]:
        """Wheel commands FL, FR, RL, RR in [-1, 1] from one frame's servo outputs (SERVO1
        first): 0 for a channel that outputs nothing (pulse 0, or not in the packet) and for
        an ESC that has not seen neutral since it last had no signal."""
        out = [0.0, 0.0, 0.0, 0.0]
        for wheel, (i, esc) in enumerate(self._wheels):
            pulse = pwm[i] if i < len(pwm) else 0
            if pulse <= 0:
                self._armed[wheel] = False
                continue
            command = esc.command_from_pulse(pulse)
            if not self._armed[wheel]:
                self._armed[wheel] = abs(command) < self._band
                continue
            out[wheel] = command
        return (out[0], out[1], out[2], out[3])


class ChassisSensors:
    """Reads a :class:`~mecanum_mav.sim.mujocochassis.MujocoChassis` as the firmware's JSON
    sensors (:class:`~mecanum_mav.sim.sitljson.PhysicsState`), in NED/FRD.

    The specific force is the mean acceleration since the last reading (the velocity change
    over the physics time between them, as an IMU's delta-velocity) minus gravity, in the
    body frame; gyro rates are MuJoCo's body angular velocity now.
    """

    def __init__(self, chassis: MujocoChassis) -> None:
        self._chassis = chassis
        self._gravity_ned = _NWU_TO_NED @ np.asarray(chassis.model.opt.gravity, dtype=float)
        self._z0 = float(chassis.data.qpos[2])
        self._velocity = self._velocity_ned()
        self._mujoco_time = float(chassis.data.time)
        self._accel_ned = np.zeros(3)

    def _velocity_ned(self) -> np.ndarray:
        velocity: np.ndarray = _NWU_TO_NED @ np.asarray(self._chassis.data.qvel[0:3], dtype=float)
        return velocity

    def _rotation_ned_frd(self) -> np.ndarray:
        """Body FRD -> NED rotation matrix, from MuJoCo's state quaternion (w, x, y, z)."""
        w, x, y, z = (float(v) for v in self._chassis.data.qpos[3:7])
        flu_to_nwu = np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        rotation: np.ndarray = _NWU_TO_NED @ flu_to_nwu @ _NWU_TO_NED
        return rotation

    def read(self, epoch_s: float = 0.0) -> PhysicsState:
        """The state now (call once per frame, after the step), its time counted from the
        physics time ``epoch_s`` (where the firmware last started)."""
        c = self._chassis
        data = c.data
        velocity = self._velocity_ned()
        mujoco_time = float(data.time)
        elapsed = mujoco_time - self._mujoco_time
        if elapsed > 0.0:  # (a frame shorter than MuJoCo's step may not have moved it)
            self._accel_ned = (velocity - self._velocity) / elapsed
            self._velocity, self._mujoco_time = velocity, mujoco_time
        rotation = self._rotation_ned_frd()
        accel_body = rotation.T @ (self._accel_ned - self._gravity_ned)
        gyro = _NWU_TO_NED @ np.asarray(data.qvel[3:6], dtype=float)
        pose = c.pose
        roll, pitch = c.roll_pitch
        down = -(float(data.qpos[2]) - self._z0)
        return PhysicsState(
            time_s=c.time_s - epoch_s,
            gyro=(float(gyro[0]), float(gyro[1]), float(gyro[2])),
            accel_body=(float(accel_body[0]), float(accel_body[1]), float(accel_body[2])),
            position_ned=(float(pose.x_m), float(pose.y_m), down),
            attitude=(roll, pitch, float(pose.yaw_rad)),
            velocity_ned=(float(velocity[0]), float(velocity[1]), float(velocity[2])),
        )


@dataclass(frozen=True)
class BridgeStats:
    """What the bridge has done so far.

    Attributes:
        frames: frames stepped (new frame counts answered).
        repeated: packets with the frame count just answered (answered again, no step).
        dropped: frame counts skipped (a count ahead of the next one: the gap's size).
        restarts: times the count went back (the firmware restarted).
        malformed: packets that were not servo packets (ignored).
        physics_s: physics seconds stepped.
        wall_s: wall seconds from the first frame answered to the last.
        busy_s: wall seconds spent answering (decode, step, read, encode).
        frame_rate: the firmware's last frame rate, Hz (0 before any).
        commands: the wheel commands FL, FR, RL, RR of the last frame.
        wheel_pulses: the pulse widths (us) the firmware put out for FL, FR, RL, RR in the
            last frame (0: no output).
    """

    frames: int
    repeated: int
    dropped: int
    restarts: int
    malformed: int
    physics_s: float
    wall_s: float
    busy_s: float
    frame_rate: int
    commands: tuple[float, float, float, float]
    wheel_pulses: tuple[int, int, int, int]

    @property
    def real_time_factor(self) -> float:
        """Physics seconds per wall second while stepping (NaN before two frames)."""
        return self.physics_s / self.wall_s if self.wall_s > 0.0 else math.nan

    @property
    def busy_fraction(self) -> float:
        """Mean busy time per frame over the frame period: the bridge's load at real time
        (1 / this is how much faster than real time it could go; NaN before any frame)."""
        if self.frames == 0 or self.frame_rate == 0:
            return math.nan
        return self.busy_s / self.frames * self.frame_rate


class BridgeCore:
    """The lockstep itself, bytes in, bytes out (see the module's docstring).

    Args:
        chassis: the MuJoCo chassis, at rest where the twin starts.
        wheels: servo outputs -> wheel commands.
        clock: the wall clock of :attr:`TruthSample.wall_s` (monotonic seconds).
    """

    def __init__(self, chassis: MujocoChassis, wheels: WheelMap,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.chassis = chassis
        self._wheels = wheels
        self._sensors = ChassisSensors(chassis)
        self._clock = clock
        self._last_count: int | None = None
        self._epoch_s = 0.0
        self._answer = b""
        self._frames = self._repeated = self._dropped = self._restarts = self._malformed = 0
        self._first_wall = self._last_wall = math.nan
        self._physics_s = 0.0
        self._busy_s = 0.0
        self._frame_rate = 0
        self._commands = (0.0, 0.0, 0.0, 0.0)
        self._pulses = (0, 0, 0, 0)
        self._lock = threading.Lock()
        self._truth: list[TruthSample] = [self._sample(clock())]

    def answer(self, data: bytes) -> bytes | None:
        """The answer to one datagram from the firmware, or None for one to ignore."""
        started = time.perf_counter()
        packet = decode_servo_packet(data)
        if packet is None:
            with self._lock:
                self._malformed += 1
            return None
        if packet.frame_count == self._last_count:
            with self._lock:
                self._repeated += 1
            return self._answer
        self._step(packet)
        self._answer = encode_state(self._sensors.read(self._epoch_s))
        now = self._clock()
        sample = self._sample(now)
        with self._lock:
            self._truth.append(sample)
            if math.isnan(self._first_wall):
                self._first_wall = now
            self._last_wall = now
            self._busy_s += time.perf_counter() - started
        return self._answer

    def _step(self, packet: ServoPacket) -> None:
        last = self._last_count
        with self._lock:
            if last is not None and packet.frame_count < last:
                self._restarts += 1
                self._epoch_s = self.chassis.time_s
            elif last is not None and packet.frame_count > last + 1:
                self._dropped += packet.frame_count - last - 1
            self._frames += 1
            self._frame_rate = packet.frame_rate
        self._last_count = packet.frame_count
        commands = self._wheels.commands(packet.pwm)
        dt = 1.0 / packet.frame_rate
        self.chassis.step(dt, commands)
        with self._lock:
            self._commands = commands
            self._pulses = self._wheels.pulses(packet.pwm)
            if not math.isnan(self._first_wall):
                self._physics_s += dt

    def _sample(self, wall_s: float) -> TruthSample:
        c = self.chassis
        pose = c.pose
        forward, right = c.velocity_body
        return TruthSample(wall_s, c.time_s, float(pose.x_m), float(pose.y_m),
                           float(pose.yaw_rad), forward, right)

    def truth(self) -> list[TruthSample]:
        """Every frame's truth so far, oldest first (a copy; the first is the start)."""
        with self._lock:
            return list(self._truth)

    def truth_now(self) -> TruthSample:
        """The latest truth."""
        with self._lock:
            return self._truth[-1]

    def stats(self) -> BridgeStats:
        with self._lock:
            wall = 0.0 if math.isnan(self._first_wall) else self._last_wall - self._first_wall
            return BridgeStats(self._frames, self._repeated, self._dropped, self._restarts,
                               self._malformed, self._physics_s, wall, self._busy_s,
                               self._frame_rate, self._commands, self._pulses)


class TwinBridge:
    """:class:`BridgeCore` on a UDP socket of its own (127.0.0.1, a port from the OS: give
    :attr:`port` to the firmware's ``--sim-port-out``), served by a thread until
    :meth:`close`. Answers go to wherever each packet came from (a restarted firmware comes
    from a new port)."""

    def __init__(self, core: BridgeCore, host: str = "127.0.0.1") -> None:
        self.core = core
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.bind((host, 0))
        self._sock.setblocking(False)
        self.port: int = self._sock.getsockname()[1]
        self._stop_r, self._stop_w = socket.socketpair()
        self._thread = threading.Thread(target=self._serve, name="twin-bridge", daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        sel = selectors.DefaultSelector()
        sel.register(self._sock, selectors.EVENT_READ)
        sel.register(self._stop_r, selectors.EVENT_READ)
        with sel:
            while True:
                events = sel.select()
                if any(key.fileobj is self._stop_r for key, _ in events):
                    return
                self._drain()

    def _drain(self) -> None:
        """Answer every datagram waiting, in order."""
        while True:
            try:
                data, peer = self._sock.recvfrom(512)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return
            reply = self.core.answer(data)
            if reply is not None:
                with contextlib.suppress(OSError):
                    self._sock.sendto(reply, peer)

    def close(self) -> None:
        """Stop the thread and close the socket; idempotent."""
        if self._thread.is_alive():
            with contextlib.suppress(OSError):
                self._stop_w.send(b"x")
            self._thread.join(timeout=5)
        for s in (self._sock, self._stop_r, self._stop_w):
            s.close()
