"""Where a tlog's drive went against its plan: the global origin its global positions are placed
about (:func:`log_origin`), the planned mission (:func:`mission_items`,
:func:`planned_positions`) and each leg as driven (:func:`legs_driven`). Positions are metres
north and east of the local origin.

- origin: GPS_GLOBAL_ORIGIN or SET_GPS_GLOBAL_ORIGIN; else the one that puts the vehicle's
  GLOBAL_POSITION_INT on its local position; else latitude and longitude 0, 0 if the positions
  are within a degree of it (a simulator without an origin); else the first one.
- planned mission: the last MISSION_COUNT's MISSION_ITEM_INT / MISSION_ITEM (uploads and
  downloads alike); items with a position from seq 1 on (item 0 is home).
- legs: a leg is the line from the previous mission position (or, for the first, from where
  the vehicle was when it became current) to an item; its cross-track is the largest distance
  of the path from that segment while the item was current in AUTO (in any mode if the log has
  no HEARTBEAT). A reached item makes the next one current at once.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

from mecanum_mav.app.logresult import LegStat, LogAnalysis, ModeSpan, Vec
from mecanum_mav.app.logsenders import sent_by
from mecanum_mav.control.pathfollow import Leg
from mecanum_mav.io.tlog import TlogEntry
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import MissionItem, item_from_fields, position_ned
from mecanum_mav.protocol.modes import Mode

__all__ = ["finite", "legs_driven", "log_origin", "mission_items", "planned_positions",
           "sim_latlon"]

_NAV_COMMANDS = frozenset({
    mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_LOITER_UNLIM,
    mavlink.MAV_CMD_NAV_LOITER_TURNS, mavlink.MAV_CMD_NAV_LOITER_TIME,
    mavlink.MAV_CMD_NAV_SPLINE_WAYPOINT, mavlink.MAV_CMD_NAV_LAND,
    mavlink.MAV_CMD_NAV_LOITER_TO_ALT})
_RTL = mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH
_NEAR_NULL_ISLAND_E7 = 10_000_000
"""Positions within a degree (degE7) of latitude and longitude 0, 0: a simulator without an
origin."""


def log_origin(entries: Sequence[TlogEntry], vehicle: tuple[int, int] | None
               ) -> GlobalOrigin | None:
    """The log's global origin (see the module docstring), None if it has no global
    position."""
    local: Vec | None = None
    first_global: tuple[int, int] | None = None
    for e in entries:
        msg, kind = e.msg, e.msg.get_type()
        try:
            if kind in ("GPS_GLOBAL_ORIGIN", "SET_GPS_GLOBAL_ORIGIN"):
                return GlobalOrigin(msg.latitude, msg.longitude)
            if kind in ("LOCAL_POSITION_NED", "ODOMETRY") and sent_by(msg, vehicle):
                local = (msg.x, msg.y)
            elif kind == "GLOBAL_POSITION_INT" and sent_by(msg, vehicle):
                if local is not None and (msg.lat, msg.lon) != (0, 0):
                    return _origin_under(msg.lat, msg.lon, local)
                first_global = first_global or (msg.lat, msg.lon)
            elif kind in ("SIM_STATE", "SIMSTATE") and first_global is None:
                first_global = sim_latlon(msg)
        except ValueError:
            continue
    if first_global is None:
        return None
    if max(abs(first_global[0]), abs(first_global[1])) < _NEAR_NULL_ISLAND_E7:
        return GlobalOrigin(0, 0)
    return GlobalOrigin(*first_global)


def _origin_under(lat_e7: int, lon_e7: int, local: Vec) -> GlobalOrigin:
    """The origin from which (lat_e7, lon_e7) is at ``local`` (north m, east m)."""
    guess = GlobalOrigin(lat_e7, lon_e7)
    for _ in range(2):  # the east scale depends on the origin's latitude: refine once
        n, e = guess.to_local(lat_e7, lon_e7)
        back_lat, back_lon = guess.to_global(n - local[0], e - local[1])
        guess = GlobalOrigin(back_lat, back_lon)
    return guess


def sim_latlon(msg: Any) -> tuple[int, int]:
    """A simulator state's (SIM_STATE or ArduPilot's SIMSTATE) latitude and longitude, degE7."""
    if msg.get_type() == "SIMSTATE":
        return int(msg.lat), int(msg.lng)
    lat_int, lon_int = getattr(msg, "lat_int", 0), getattr(msg, "lon_int", 0)
    if lat_int or lon_int:
        return int(lat_int), int(lon_int)
    return round(msg.lat * 1e7), round(msg.lon * 1e7)


def finite(*values: float) -> bool:
    """Whether every value is finite."""
    return all(math.isfinite(v) for v in values)


def mission_items(entries: Sequence[TlogEntry]) -> list[MissionItem]:
    """The last mission in the log (see the module docstring)."""
    count: int | None = None
    items: dict[int, MissionItem] = {}
    for e in entries:
        msg, kind = e.msg, e.msg.get_type()
        if kind == "MISSION_COUNT" and msg.mission_type == mavlink.MAV_MISSION_TYPE_MISSION:
            count, items = msg.count, {}
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM") and (
                msg.mission_type == mavlink.MAV_MISSION_TYPE_MISSION):
            try:
                items[msg.seq] = item_from_fields(
                    msg.seq, msg.frame, msg.command, msg.current, msg.autocontinue,
                    (msg.param1, msg.param2, msg.param3, msg.param4), msg.x, msg.y, msg.z,
                    encoded=kind == "MISSION_ITEM_INT")
            except (ValueError, OverflowError):
                continue
    return [items[s] for s in sorted(items) if count is None or s < count]


def planned_positions(items: Iterable[MissionItem], origin: GlobalOrigin | None
                      ) -> list[tuple[int, float, float]]:
    """(seq, north m, east m) of the items with a position, seq 1 on (RTL: the origin)."""
    out = []
    for item in items:
        if item.seq < 1:
            continue
        if item.command == _RTL:
            out.append((item.seq, 0.0, 0.0))
        elif item.command in _NAV_COMMANDS:
            try:  # (integer positions: always finite)
                n, e = position_ned(item, origin)
            except ValueError:
                continue
            out.append((item.seq, n, e))
    return out


def _mode_at(spans: Sequence[ModeSpan], t: float) -> str | None:
    for span in spans:
        if span.start_s <= t < span.end_s or (span is spans[-1] and t >= span.start_s):
            return span.mode
    return None


def legs_driven(result: LogAnalysis) -> list[LegStat]:
    """Per leg: time current in AUTO and the largest distance of the path from it."""
    positions = {seq: (n, e) for seq, n, e in result.planned}
    order = [seq for seq, _, _ in result.planned]
    changes = sorted([(t, seq, 0) for t, seq in result.mission_current]
                     + [(t, seq, 1) for t, seq in result.reached])
    stats: dict[int, dict[str, Any]] = {}
    current: int | None = None
    k = 0
    has_modes = bool(result.modes)
    previous_t: float | None = None
    for t, n, e in result.path:
        while k < len(changes) and changes[k][0] <= t:
            _, seq, reached = changes[k]
            current = seq + 1 if reached and (current is None or current <= seq) else (
                current if reached else seq)
            k += 1
        in_auto = not has_modes or _mode_at(result.modes, t) == Mode.AUTO.name
        if current is None or current not in positions or not in_auto:
            previous_t = None
            continue
        stat = stats.get(current)
        if stat is None:
            earlier = [s for s in order if s < current]
            start = positions[earlier[-1]] if earlier else (n, e)
            stat = stats[current] = {"leg": Leg(start, positions[current]), "time": 0.0,
                                     "max": 0.0, "samples": 0, "order": len(stats)}
        if previous_t is not None:
            stat["time"] += t - previous_t
        stat["max"] = max(stat["max"], stat["leg"].distance_m((n, e)))
        stat["samples"] += 1
        previous_t = t
    return [LegStat(seq, s["leg"].start_ned, s["leg"].end_ned, s["time"], s["max"],
                    s["samples"])
            for seq, s in sorted(stats.items(), key=lambda kv: kv[1]["order"])]
