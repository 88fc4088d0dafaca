"""Telemetry to the ground station: which messages stream how often, and how each is built.

Streams and their default rates (parameters): ODOMETRY, LOCAL_POSITION_NED, ATTITUDE and (once
a global origin is known) GLOBAL_POSITION_INT at ``TLM_POS_RATE``; SYS_STATUS,
SERVO_OUTPUT_RAW and WHEEL_DISTANCE at ``TLM_EXT_RATE``.
``MAV_CMD_SET_MESSAGE_INTERVAL`` changes one message's interval (-1 stops it, 0 returns it to
its parameter rate), ``MAV_CMD_GET_MESSAGE_INTERVAL`` reports it, ``MAV_CMD_REQUEST_MESSAGE``
sends any message below once (also AUTOPILOT_VERSION and HOME_POSITION).

Frames: positions local NED (origin where the companion started or was last reset), body
velocities FRD, yaw clockwise from north.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from mecanum_mav import __version__
from mecanum_mav.config.params import Params
from mecanum_mav.mecanum.geometry import body_to_ned
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.health import NO_SENSORS, UNKNOWN_BATTERY, Battery, SensorBits

__all__ = ["STREAMS", "StreamSchedule", "TelemetryState", "build", "ftp_nak",
           "next_on_grid"]

STREAMS: dict[str, str] = {
    "ODOMETRY": "TLM_POS_RATE",
    "LOCAL_POSITION_NED": "TLM_POS_RATE",
    "ATTITUDE": "TLM_POS_RATE",
    "GLOBAL_POSITION_INT": "TLM_POS_RATE",
    "SYS_STATUS": "TLM_EXT_RATE",
    "SERVO_OUTPUT_RAW": "TLM_EXT_RATE",
    "WHEEL_DISTANCE": "TLM_EXT_RATE",
}
"""Streamed messages and the parameter that sets each one's default rate (Hz)."""

MAX_INTERVAL_US = 2**31 - 1
"""The longest interval MESSAGE_INTERVAL can report (int32 microseconds, ~36 min): a longer
one is refused, as is one that is not a number."""

_NAME_BY_ID = {getattr(mavlink, f"MAVLINK_MSG_ID_{name}"): name for name in STREAMS}


def next_on_grid(due_s: float, interval_s: float, now_s: float) -> float:
    """The time after ``due_s`` on its grid of ``interval_s`` (s), for a periodic send done at
    ``now_s`` (early or late): the rate stays exact; after a gap it starts again from now."""
    following = due_s + interval_s
    return following if following > now_s else now_s + interval_s


class StreamSchedule:
    """When each stream is next due, on a fixed grid per message."""

    def __init__(self, params: Params) -> None:
        self.params = params
        self.overrides: dict[str, float | None] = {}  # name -> interval s, None = stopped
        self.next_s: dict[str, float] = dict.fromkeys(STREAMS, 0.0)

    def interval_s(self, name: str) -> float | None:
        """Seconds between two messages of ``name``, or None when it does not stream."""
        if name in self.overrides:
            return self.overrides[name]
        rate = float(self.params[STREAMS[name]])
        return 1.0 / rate if rate > 0.0 else None

    def set_interval(self, message_id: int, interval_us: float) -> bool:
        """MAV_CMD_SET_MESSAGE_INTERVAL (``interval_us`` in microseconds, -1 stop, 0 default);
        False if ``message_id`` is not a stream we send or the interval is not a number or
        beyond :data:`MAX_INTERVAL_US`."""
        name = _NAME_BY_ID.get(message_id)
        if name is None or not interval_us <= MAX_INTERVAL_US:  # NaN too
            return False
        if interval_us == 0:
            self.overrides.pop(name, None)
        elif interval_us < 0:
            self.overrides[name] = None
        else:
            self.overrides[name] = max(interval_us * 1e-6, 0.005)  # at most 200 Hz
        self.next_s[name] = 0.0
        return True

    def get_interval_us(self, message_id: int) -> int | None:
        """MAV_CMD_GET_MESSAGE_INTERVAL: microseconds (-1 stopped), None if unknown."""
        name = _NAME_BY_ID.get(message_id)
        if name is None:
            return None
        interval = self.interval_s(name)
        return -1 if interval is None else round(interval * 1e6)

    def due(self, now_s: float, slack_s: float) -> list[str]:
        """Streams due by ``now_s + slack_s``; their next times advance on their grid."""
        out = []
        for name, next_s in self.next_s.items():
            if now_s + slack_s < next_s:
                continue
            interval = self.interval_s(name)
            if interval is None:
                self.next_s[name] = now_s + 1.0
                continue
            out.append(name)
            self.next_s[name] = next_on_grid(next_s, interval, now_s)
        return out

    def next_due_s(self) -> float:
        """The earliest next time of any stream (for the loop's wait)."""
        return min(self.next_s.values())


@dataclass
class TelemetryState:
    """What the builders read: filled in by the companion each time it sends."""

    now_s: float
    boot_s: float
    pose: Any  # geometry.Pose2d
    velocity_body: tuple[float, float]
    yaw_rate: float
    reset_counter: int
    wheel_distances_m: tuple[float, ...]
    channels: tuple[int, ...]
    pulses_us: tuple[int, ...]
    errors_comm: int
    """Malformed packets, refused inputs and failed sends so far (SYS_STATUS ``errors_comm``)."""
    drop_rate_comm: int
    """Share of recent packets dropped as malformed or refused, c% (SYS_STATUS)."""
    origin: Any = None  # geo.GlobalOrigin, or None when the local frame has no global anchor
    sensors: SensorBits = NO_SENSORS
    battery: Battery = UNKNOWN_BATTERY

    @property
    def boot_ms(self) -> int:
        return int((self.now_s - self.boot_s) * 1000) & 0xFFFFFFFF

    @property
    def boot_us(self) -> int:
        return int((self.now_s - self.boot_s) * 1e6)


_UNKNOWN_COVARIANCE = [math.nan] + [0.0] * 20


def _odometry(mav: Any, t: TelemetryState) -> None:
    yaw = t.pose.yaw_rad
    mav.odometry_send(t.boot_us, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_BODY_FRD,
                      t.pose.x_m, t.pose.y_m, 0.0,
                      [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)],
                      t.velocity_body[0], t.velocity_body[1], 0.0, 0.0, 0.0, t.yaw_rate,
                      _UNKNOWN_COVARIANCE, _UNKNOWN_COVARIANCE, t.reset_counter % 256,
                      mavlink.MAV_ESTIMATOR_TYPE_NAIVE, 0)


def _local_position_ned(mav: Any, t: TelemetryState) -> None:
    v_north, v_east = body_to_ned(*t.velocity_body, t.pose.yaw_rad)
    mav.local_position_ned_send(t.boot_ms, t.pose.x_m, t.pose.y_m, 0.0, v_north, v_east, 0.0)


def _attitude(mav: Any, t: TelemetryState) -> None:
    mav.attitude_send(t.boot_ms, 0.0, 0.0, t.pose.yaw_rad, 0.0, 0.0, t.yaw_rate)


def _sys_status(mav: Any, t: TelemetryState) -> None:
    # Sensor bits and battery: mecanum_mav.protocol.health; the link counts: RoverCore.
    s, b = t.sensors, t.battery
    mav.sys_status_send(s.present, s.enabled, s.health, 0, b.voltage_mv, b.current_ca,
                        b.remaining_pct, t.drop_rate_comm, min(t.errors_comm, 65535), 0, 0, 0,
                        0)


def _servo_output_raw(mav: Any, t: TelemetryState) -> None:
    servos = [0] * 16
    for channel, pulse in zip(t.channels, t.pulses_us, strict=False):
        servos[channel - 1] = pulse  # (a wheel's channel is 1-16: WHL_<W>_CH's range)
    mav.servo_output_raw_send(t.boot_us & 0xFFFFFFFF, 0, *servos)


def _wheel_distance(mav: Any, t: TelemetryState) -> None:
    mav.wheel_distance_send(t.boot_us, 4, [*t.wheel_distances_m[:4], *([0.0] * 12)])


def _global_position_int(mav: Any, t: TelemetryState) -> None:
    # Only with a global origin (ORIGIN_LAT/LON or SET_GPS_GLOBAL_ORIGIN): the local position
    # placed on the earth, so a ground station's map shows the rover.
    if t.origin is None:
        return
    lat, lon = t.origin.to_global(t.pose.x_m, t.pose.y_m)
    v_north, v_east = body_to_ned(*t.velocity_body, t.pose.yaw_rad)
    heading_cdeg = round(math.degrees(t.pose.yaw_rad) * 100) % 36000
    mav.global_position_int_send(t.boot_ms, lat, lon, t.origin.alt_mm, 0, round(v_north * 100),
                                 round(v_east * 100), 0, heading_cdeg)


def _home_position(mav: Any, t: TelemetryState) -> None:
    # Home is the local origin; lat/lon are 0 until a global origin is known.
    lat, lon, alt = (0, 0, 0) if t.origin is None else (t.origin.lat_e7, t.origin.lon_e7,
                                                        t.origin.alt_mm)
    mav.home_position_send(lat, lon, alt, 0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0,
                           t.boot_us)


def _autopilot_version(mav: Any, t: TelemetryState) -> None:
    capabilities = (mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                    | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
                    | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                    | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT)
    major, minor, patch = (int(part) for part in __version__.split(".")[:3])
    version = major << 24 | minor << 16 | patch << 8 | 0xFF  # FIRMWARE_VERSION_TYPE_OFFICIAL
    mav.autopilot_version_send(capabilities, version, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8,
                               0, 0, 0, [0] * 18)


BUILDERS: dict[str, Callable[[Any, TelemetryState], None]] = {
    "ODOMETRY": _odometry,
    "LOCAL_POSITION_NED": _local_position_ned,
    "ATTITUDE": _attitude,
    "GLOBAL_POSITION_INT": _global_position_int,
    "SYS_STATUS": _sys_status,
    "SERVO_OUTPUT_RAW": _servo_output_raw,
    "WHEEL_DISTANCE": _wheel_distance,
    "HOME_POSITION": _home_position,
    "AUTOPILOT_VERSION": _autopilot_version,
}
"""Every message the companion can send on request, by name."""

REQUESTABLE: dict[int, str] = {getattr(mavlink, f"MAVLINK_MSG_ID_{n}"): n for n in BUILDERS}


def build(name: str, mav: Any, state: TelemetryState) -> None:
    """Send message ``name`` on ``mav`` from ``state``."""
    BUILDERS[name](mav, state)


# seq_number, session, opcode, size, req_opcode, burst_complete, padding, offset
_FTP_HEADER = struct.Struct("<HBBBBBBI")
FTP_NAK = 129
FTP_ERR_FILE_NOT_FOUND = 10


def ftp_nak(request_payload: bytes | list[int]) -> list[int]:
    """The FILE_TRANSFER_PROTOCOL payload refusing a request with FileNotFound.

    The companion serves no files; refusing at once lets MAVProxy skip its FTP parameter
    download (instead of waiting for it to time out) and fall back to PARAM_REQUEST_LIST.
    """
    seq, session, opcode, *_ = _FTP_HEADER.unpack_from(bytes(request_payload[:12]))
    header = _FTP_HEADER.pack((seq + 1) & 0xFFFF, session, FTP_NAK, 1, opcode, 0, 0, 0)
    payload = [*header, FTP_ERR_FILE_NOT_FOUND]
    return payload + [0] * (251 - len(payload))
