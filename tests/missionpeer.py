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
from mecanum_mav.protocol.mission import MissionItem, float_xy, item_from_fields
from mecanum_mav.sim.groundstation import ScriptedGroundStation

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


def send_item(gcs: ScriptedGroundStation, item: MissionItem, *, legacy: bool = False) -> None:
    fields = (item.seq, item.frame, item.command, item.current, item.autocontinue,
              item.param1, item.param2, item.param3, item.param4)
    if legacy:
        x, y = float_xy(item)
        gcs.mav.mission_item_send(1, 1, *fields, x, y, item.z, 0)
    else:
        gcs.mav.mission_item_int_send(1, 1, *fields, item.x, item.y, item.z, 0)


def upload(gcs: ScriptedGroundStation, items: list[MissionItem], *, legacy: bool = False,
           ignore_first: frozenset[int] = frozenset(), duplicate: bool = False,
           timeout_s: float = 5.0):
    """Upload ``items``; returns the vehicle's MISSION_ACK (or None).

    ``ignore_first``: seqs whose first request is "lost" (not answered); ``duplicate``: every
    item is sent twice.
    """
    since = gcs.mark()
    gcs.mav.mission_count_send(1, 1, len(items), 0)
    ignored: set[int] = set()
    index = since
    deadline = gcs.port.now() + timeout_s
    while gcs.port.now() < deadline:
        while index < len(gcs.messages):
            msg = gcs.messages[index]
            index += 1
            kind = msg.get_type()
            if kind == "MISSION_ACK":
                return msg
            if kind not in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
                continue
            if msg.seq in ignore_first and msg.seq not in ignored:
                ignored.add(msg.seq)
                continue
            for _ in range(2 if duplicate else 1):
                send_item(gcs, items[msg.seq], legacy=legacy)
        gcs.pump(0.02)
    return None


def download(gcs: ScriptedGroundStation, *, legacy: bool = False,
             timeout_s: float = 3.0) -> list[MissionItem] | None:
    """Download the mission item by item; None if the vehicle stops answering."""
    since = gcs.mark()
    gcs.mav.mission_request_list_send(1, 1, 0)
    count = gcs.wait("MISSION_COUNT", timeout_s=timeout_s, since=since)
    if count is None:
        return None
    items = []
    reply = "MISSION_ITEM" if legacy else "MISSION_ITEM_INT"
    for seq in range(count.count):
        since = gcs.mark()
        if legacy:
            gcs.mav.mission_request_send(1, 1, seq, 0)
        else:
            gcs.mav.mission_request_int_send(1, 1, seq, 0)
        msg = gcs.wait(reply, lambda m, s=seq: m.seq == s, timeout_s, since)
        if msg is None:
            return None
        items.append(item_from_fields(msg.seq, msg.frame, msg.command, msg.current,
                                      msg.autocontinue,
                                      (msg.param1, msg.param2, msg.param3, msg.param4),
                                      msg.x, msg.y, msg.z, encoded=not legacy))
    gcs.mav.mission_ack_send(1, 1, mavlink.MAV_MISSION_ACCEPTED, 0)
    return items
