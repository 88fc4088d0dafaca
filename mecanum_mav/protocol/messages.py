"""The fields of received messages that the rover reads, as types.

pymavlink publishes no type information, so its message objects are ``Any`` to a type checker.
These protocols name exactly the fields each handler of the rover core reads (pymavlink's
message classes and the fast codec's :class:`~mecanum_mav.protocol.codec.ManualControl`
satisfy them structurally), so a handler's signature says what it uses and a misspelt field is
a type error. Units are MAVLink's.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import IntEnum
from typing import Protocol

from mecanum_mav.protocol.dialect import mavlink

__all__ = [
    "Addressed",
    "AttitudeMsg",
    "CommandMsg",
    "FcGpsMsg",
    "FcParamValueMsg",
    "FcPositionMsg",
    "FcSysStatusMsg",
    "FtpMsg",
    "ManualControlMsg",
    "MissionSetCurrentMsg",
    "OriginMsg",
    "ParamReadMsg",
    "ParamSetMsg",
    "PingMsg",
    "RcChannelsMsg",
    "Received",
    "Result",
    "SetModeMsg",
    "SetpointMsg",
    "WheelDistanceMsg",
]


class Result(IntEnum):
    """MAV_RESULT of a COMMAND_ACK."""

    ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
    DENIED = mavlink.MAV_RESULT_DENIED
    UNSUPPORTED = mavlink.MAV_RESULT_UNSUPPORTED
    FAILED = mavlink.MAV_RESULT_FAILED


class Received(Protocol):
    """Any received message: its type name and its sender."""

    def get_type(self) -> str:
        """The message name, e.g. ``"MANUAL_CONTROL"``."""

    def get_srcSystem(self) -> int:
        """The sender's system id."""

    def get_srcComponent(self) -> int:
        """The sender's component id."""


class Addressed(Received, Protocol):
    """A message addressed to a system and component (0 = broadcast)."""

    target_system: int
    target_component: int


class ManualControlMsg(Received, Protocol):
    """MANUAL_CONTROL: x forward, y right, r clockwise (-1000..1000, 0x7FFF invalid), z."""

    target: int
    x: int
    y: int
    z: int
    r: int


class CommandMsg(Addressed, Protocol):
    """COMMAND_LONG or COMMAND_INT (params 1-4 are what the rover's commands read)."""

    command: int
    param1: float
    param2: float
    param3: float
    param4: float


class SetModeMsg(Received, Protocol):
    """SET_MODE."""

    target_system: int
    base_mode: int
    custom_mode: int


class SetpointMsg(Addressed, Protocol):
    """SET_POSITION_TARGET_LOCAL_NED (m, m/s, rad, rad/s)."""

    coordinate_frame: int
    type_mask: int
    x: float
    y: float
    vx: float
    vy: float
    yaw: float
    yaw_rate: float


class ParamSetMsg(Addressed, Protocol):
    """PARAM_SET."""

    param_id: str
    param_value: float


class ParamReadMsg(Addressed, Protocol):
    """PARAM_REQUEST_READ."""

    param_id: str
    param_index: int


class PingMsg(Addressed, Protocol):
    """PING."""

    time_usec: int
    seq: int


class FtpMsg(Addressed, Protocol):
    """FILE_TRANSFER_PROTOCOL (the request payload)."""

    payload: list[int]


class MissionSetCurrentMsg(Addressed, Protocol):
    """MISSION_SET_CURRENT."""

    seq: int


class OriginMsg(Received, Protocol):
    """SET_GPS_GLOBAL_ORIGIN (degE7, degE7, mm)."""

    target_system: int
    latitude: int
    longitude: int
    altitude: int


class AttitudeMsg(Received, Protocol):
    """ATTITUDE from the flight controller (rad, rad/s; yaw clockwise from north)."""

    yaw: float
    yawspeed: float


class FcParamValueMsg(Received, Protocol):
    """PARAM_VALUE from the flight controller."""

    param_id: str
    param_value: float


class FcGpsMsg(Received, Protocol):
    """GPS_RAW_INT from the flight controller (fix type, degE7; ``time_usec`` of the fix)."""

    time_usec: int
    fix_type: int
    lat: int
    lon: int


class FcPositionMsg(Received, Protocol):
    """LOCAL_POSITION_NED from the flight controller (m, NED from its EKF's origin)."""

    x: float
    y: float


class FcSysStatusMsg(Received, Protocol):
    """SYS_STATUS from the flight controller: its battery (mV, cA, %; unknown: UINT16_MAX,
    -1, -1; 0 mV: no battery monitor)."""

    voltage_battery: int
    current_battery: int
    battery_remaining: int


class RcChannelsMsg(Received, Protocol):
    """RC_CHANNELS from the flight controller: its receiver's channel count, pulse widths
    (``chan1_raw`` .. ``chan18_raw``, us; 0 or UINT16_MAX: none) and RSSI (0..254, 255
    unknown)."""

    chancount: int
    rssi: int


class WheelDistanceMsg(Received, Protocol):
    """WHEEL_DISTANCE from the flight controller (cumulative metres per wheel)."""

    count: int
    distance: Sequence[float]
