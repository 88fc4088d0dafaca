"""Ground-station side of the mission protocol for tests, hand-rolled on a
:class:`~mecanum_mav.sim.groundstation.ScriptedGroundStation` (the lockstep harness's, virtual
time, or one on a real UDP socket) so that packets can be lost or duplicated on purpose.

The helpers use only the ground station's ``mark``, ``messages``, ``pump``, ``wait`` and
``mav``; their deadlines are in the ground station's own time (``gcs.port.now()``)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import replace

from mecanum_mav.io.links import mavlink
from mecanum_mav.protocol.mission import MissionItem

WP, LOITER, RTL = (mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_LOITER_TIME,
                   mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH)
YAW, SPEED, JUMP = (mavlink.MAV_CMD_CONDITION_YAW, mavlink.MAV_CMD_DO_CHANGE_SPEED,
                    mavlink.MAV_CMD_DO_JUMP)
LOCAL, MISSION_FRAME = mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_MISSION
GLOBAL_REL = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT


def local_wp(seq: int, north: float, east: float, **fields) -> MissionItem:
    """A NAV_WAYPOINT in MAV_FRAME_LOCAL_NED (x/y metres * 1e4); param4 (yaw) NaN = none, as
    QGroundControl and MAVSDK send it, unless given."""
    fields.setdefault("param4", math.nan)
    return MissionItem(seq, LOCAL, fields.pop("command", WP), x=round(north * 1e4),
                       y=round(east * 1e4), **fields)


def do(seq: int, command: int, *params: float) -> MissionItem:
    """A DO / CONDITION item in MAV_FRAME_MISSION."""
    p = [*params, 0.0, 0.0, 0.0, 0.0][:4]
    return MissionItem(seq, MISSION_FRAME, command, param1=p[0], param2=p[1], param3=p[2],
                       param4=p[3])


def renumber(items: Iterable[MissionItem]) -> list[MissionItem]:
    """The items with seq 0, 1, 2 ... in order."""
    return [replace(item, seq=i) for i, item in enumerate(items)]


def same(a: MissionItem, b: MissionItem) -> bool:
    """Equal field by field, NaN equal to NaN."""
    for name in MissionItem.__dataclass_fields__:
        x, y = getattr(a, name), getattr(b, name)
        if x != y and not (isinstance(x, float) and math.isnan(x) and math.isnan(y)):
            return False
    return True
