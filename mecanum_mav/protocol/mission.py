"""Mission items: the value type, its checks, its positions and the mission file.

A :class:`MissionItem` holds exactly what MISSION_ITEM_INT carries: ``x``/``y`` are integers,
degrees * 1e7 in the global frames and metres * 1e4 in MAV_FRAME_LOCAL_NED (the mission
protocol's scaling), ``z`` a float (ignored by a rover). The legacy float MISSION_ITEM is
converted at the edge (:func:`item_from_fields` with ``encoded=False``), so one form is stored,
checked, persisted and executed.

Item 0 is home (ArduPilot's convention): it is stored and returned as uploaded and never
executed; the mission runs from item 1. Commands the executor does not support are accepted
at upload and skipped at run time with a STATUSTEXT naming them.

What :func:`check_item` refuses, with the MAV_MISSION_RESULT a ground station shows:

- a position command (NAV_WAYPOINT, NAV_LOITER_TIME) in a frame that is neither global
  (GLOBAL, GLOBAL_RELATIVE_ALT, their _INT and TERRAIN variants) nor LOCAL_NED:
  UNSUPPORTED_FRAME;
- a non-finite or off-earth coordinate: INVALID_PARAM5_X / INVALID_PARAM6_Y / INVALID_PARAM7
  (a rover ignores altitude, but a non-finite one is still a broken item);
- a non-finite, negative or absurd parameter the executor would read: INVALID_PARAM1..4.
  NaN in a parameter that has a default means "use the default" (hold time 0, acceptance
  radius ``WP_RADIUS``, yaw unchanged), as MAVSDK and QGroundControl send it;
- a DO_JUMP to itself, to item 0 or past the end: INVALID_PARAM1; a repeat count that is
  not a whole number >= -1 (-1 = for ever): INVALID_PARAM2.

The mission file is the plain-text "QGC WPL 110" format (MAVProxy's ``wp load``/``wp save``
and Mission Planner read and write it): one tab-separated line per item, ``seq current frame
command p1 p2 p3 p4 x y z autocontinue``, with ``x``/``y`` in degrees (global frames) or metres
(local), written so that they convert back to the same integers.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.limits import (
    MAX_MISSION_HOLD_S,
    MAX_MISSION_LOCAL_M,
    MAX_MISSION_RADIUS_M,
    MAX_MISSION_YAW_RATE_DPS,
    MAX_SPEED_MPS,
)

__all__ = [
    "GLOBAL_FRAMES",
    "LOCAL_FRAMES",
    "MAX_ITEMS",
    "NAV_COMMANDS",
    "POSITION_COMMANDS",
    "MissionItem",
    "MissionItemError",
    "check_item",
    "command_name",
    "float_xy",
    "item_from_fields",
    "position_ned",
]

MAX_ITEMS = 5000
"""The most items a mission may hold (more is refused with MAV_MISSION_NO_SPACE)."""

GLOBAL_FRAMES = frozenset({
    mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mavlink.MAV_FRAME_GLOBAL_INT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT, mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
})
"""Frames whose x/y are latitude/longitude (degrees * 1e7 in MISSION_ITEM_INT)."""

LOCAL_FRAMES = frozenset({mavlink.MAV_FRAME_LOCAL_NED})
"""Frames whose x/y are metres north/east of the local origin (* 1e4 in MISSION_ITEM_INT)."""

POSITION_COMMANDS = frozenset({mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_LOITER_TIME})
"""Commands whose x/y/z are a position."""

NAV_COMMANDS = POSITION_COMMANDS | {mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH}
"""Navigation commands the executor drives (the rest it runs on the way, or skips)."""

LOCAL_XY_SCALE = 1e4  # MISSION_ITEM_INT local x/y: metres * 1e4
GLOBAL_XY_SCALE = 1e7  # MISSION_ITEM_INT global x/y: degrees * 1e7
_INT32 = 2**31 - 1


class MissionItemError(ValueError):
    """An item the mission refuses; ``result`` is the MAV_MISSION_RESULT to send."""

    def __init__(self, result: int, text: str) -> None:
        super().__init__(text)
        self.result = result



@dataclass(frozen=True)
class MissionItem:
    """One mission item, as MISSION_ITEM_INT carries it (see the module docstring)."""

    seq: int
    frame: int
    command: int
    current: int = 0
    autocontinue: int = 1
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0
    y: int = 0
    z: float = 0.0

    @property
    def params(self) -> tuple[float, float, float, float]:
        """(param1, param2, param3, param4)."""
        return self.param1, self.param2, self.param3, self.param4


def command_name(command: int) -> str:
    """``NAV_WAYPOINT`` for 16: the MAV_CMD name without its prefix, or the number."""
    entry = mavlink.enums["MAV_CMD"].get(command)
    if entry is None or entry.name.endswith("ENUM_END"):
        return f"command {command}"
    return str(entry.name).removeprefix("MAV_CMD_")


def xy_scale(frame: int) -> float:
    """How MISSION_ITEM_INT scales x/y in ``frame``: 1e7 global, 1e4 local, else 1."""
    if frame in GLOBAL_FRAMES:
        return GLOBAL_XY_SCALE
    if frame in LOCAL_FRAMES:
        return LOCAL_XY_SCALE
    return 1.0  # MAV_FRAME_MISSION and the rest: x/y are plain numbers


def item_from_fields(seq: int, frame: int, command: int, current: int, autocontinue: int,
                     params: Sequence[float], x: float, y: float, z: float, *,
                     encoded: bool) -> MissionItem:
    """A :class:`MissionItem` from a message's fields.

    Args:
        encoded: True for MISSION_ITEM_INT (x/y already integers as the spec scales them),
            False for the legacy MISSION_ITEM (x/y floats in degrees or metres, scaled here).

    Raises:
        MissionItemError: a legacy x/y that is not finite or does not fit the integer form.
    """
    if not encoded:
        scale = xy_scale(frame)
        for value, result, name in ((x, mavlink.MAV_MISSION_INVALID_PARAM5_X, "x"),
                                    (y, mavlink.MAV_MISSION_INVALID_PARAM6_Y, "y")):
            if not (math.isfinite(value) and abs(value * scale) <= _INT32):
                raise MissionItemError(result, f"item {seq}: {name} not finite or too large")
        x, y = round(x * scale), round(y * scale)
    p1, p2, p3, p4 = (float(v) for v in params)
    return MissionItem(int(seq), int(frame), int(command), int(current), int(autocontinue),
                       p1, p2, p3, p4, int(x), int(y), float(z))


def float_xy(item: MissionItem) -> tuple[float, float]:
    """The item's x/y as the legacy MISSION_ITEM sends them (degrees, metres or as-is)."""
    scale = xy_scale(item.frame)
    return item.x / scale, item.y / scale


def _need(ok: bool, result: int, text: str) -> None:
    if not ok:
        raise MissionItemError(result, text)


def _param_ok(value: float, low: float, high: float, *, nan_ok: bool) -> bool:
    if math.isnan(value):
        return nan_ok
    return low <= value <= high


def check_item(item: MissionItem, count: int) -> None:
    """Refuse an item the executor must not run (see the module docstring).

    Args:
        item: the item, at position ``item.seq`` of a mission of ``count`` items.
        count: the number of items in the mission being uploaded.

    Raises:
        MissionItemError: with the MAV_MISSION_RESULT and a STATUSTEXT-sized reason.
    """
    seq, cmd = item.seq, item.command
    where = f"item {seq}"
    if cmd in POSITION_COMMANDS:
        _need(item.frame in GLOBAL_FRAMES or item.frame in LOCAL_FRAMES,
              mavlink.MAV_MISSION_UNSUPPORTED_FRAME, f"{where}: frame {item.frame} unsupported")
        _need(math.isfinite(item.z), mavlink.MAV_MISSION_INVALID_PARAM7,
              f"{where}: altitude not finite")
        if item.frame in GLOBAL_FRAMES:
            _need(abs(item.x) <= 900_000_000, mavlink.MAV_MISSION_INVALID_PARAM5_X,
                  f"{where}: latitude off the earth")
            _need(abs(item.y) <= 1_800_000_000, mavlink.MAV_MISSION_INVALID_PARAM6_Y,
                  f"{where}: longitude off the earth")
        else:
            limit = MAX_MISSION_LOCAL_M * LOCAL_XY_SCALE
            km = f"{MAX_MISSION_LOCAL_M / 1000.0:g} km"
            _need(abs(item.x) <= limit, mavlink.MAV_MISSION_INVALID_PARAM5_X,
                  f"{where}: x beyond {km}")
            _need(abs(item.y) <= limit, mavlink.MAV_MISSION_INVALID_PARAM6_Y,
                  f"{where}: y beyond {km}")
        _need(_param_ok(item.param1, 0.0, MAX_MISSION_HOLD_S, nan_ok=True),
              mavlink.MAV_MISSION_INVALID_PARAM1,
              f"{where}: time must be 0 .. {MAX_MISSION_HOLD_S:g} s")
        if cmd == mavlink.MAV_CMD_NAV_WAYPOINT:
            _need(_param_ok(item.param2, 0.0, MAX_MISSION_RADIUS_M, nan_ok=True),
                  mavlink.MAV_MISSION_INVALID_PARAM2,
                  f"{where}: radius must be 0 .. {MAX_MISSION_RADIUS_M:g} m")
        _need(not math.isinf(item.param4), mavlink.MAV_MISSION_INVALID_PARAM4,
              f"{where}: yaw infinite")
    elif cmd == mavlink.MAV_CMD_CONDITION_YAW:
        _need(math.isfinite(item.param1), mavlink.MAV_MISSION_INVALID_PARAM1,
              f"{where}: yaw angle not finite")
        _need(_param_ok(item.param2, 0.0, MAX_MISSION_YAW_RATE_DPS, nan_ok=True),
              mavlink.MAV_MISSION_INVALID_PARAM2, f"{where}: yaw rate must be >= 0 deg/s")
        _need(math.isnan(item.param3) or item.param3 in (-1.0, 0.0, 1.0),
              mavlink.MAV_MISSION_INVALID_PARAM3, f"{where}: direction must be -1, 0 or 1")
        _need(item.param4 in (0.0, 1.0), mavlink.MAV_MISSION_INVALID_PARAM4,
              f"{where}: relative must be 0 or 1")
    elif cmd == mavlink.MAV_CMD_DO_CHANGE_SPEED:
        _need(item.param2 in (-1.0, -2.0) or _param_ok(item.param2, 0.0, MAX_SPEED_MPS,
                                                        nan_ok=False),
              mavlink.MAV_MISSION_INVALID_PARAM2,
              f"{where}: speed must be 0 .. {MAX_SPEED_MPS:g} m/s")
    elif cmd == mavlink.MAV_CMD_DO_JUMP:
        target = item.param1
        _need(math.isfinite(target) and target.is_integer() and 1 <= target < count
              and target != seq, mavlink.MAV_MISSION_INVALID_PARAM1,
              f"{where}: jump target must be 1 .. {count - 1}, not itself")
        _need(math.isfinite(item.param2) and item.param2.is_integer() and item.param2 >= -1,
              mavlink.MAV_MISSION_INVALID_PARAM2, f"{where}: repeat must be >= -1")


def position_ned(item: MissionItem, origin: GlobalOrigin | None) -> tuple[float, float]:
    """The item's (north m, east m) in the local NED frame.

    Raises:
        ValueError: a global item and no origin, or a frame without a position.
    """
    if item.frame in LOCAL_FRAMES:
        return item.x / LOCAL_XY_SCALE, item.y / LOCAL_XY_SCALE
    if item.frame in GLOBAL_FRAMES:
        if origin is None:
            raise ValueError("global item and no origin (ORIGIN_LAT/LON or SET_GPS_GLOBAL_ORIGIN)")
        return origin.to_local(item.x, item.y)
    raise ValueError(f"frame {item.frame} has no position")
