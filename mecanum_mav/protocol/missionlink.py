"""The mission protocol on the ground-station link: MAVLink messages in and out of
:class:`~mecanum_mav.protocol.missionservice.MissionService`.

It decodes the mission messages, hands them to the pure protocol machine and puts what it
answers into a pymavlink ``MAVLink`` (the core's message outbox). The rover's
:class:`~mecanum_mav.control.missions.MissionControl` routes the messages here and calls
:meth:`MissionLink.tick` for the protocol's timeouts.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from mecanum_mav.protocol.missionservice import MissionService, Outgoing

__all__ = ["MISSION_MESSAGES", "MissionLink"]

MISSION_MESSAGES = ("MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_REQUEST_LIST",
                    "MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK", "MISSION_CLEAR_ALL")
"""The messages :meth:`MissionLink.handle` takes."""

_ITEM_FIELDS = ("seq", "frame", "command", "current", "autocontinue", "param1", "param2",
                "param3", "param4", "x", "y", "z")


class MissionLink:
    """Mission messages for one vehicle.

    Args:
        service: the protocol state machine (holds the mission).
        mav: pymavlink ``MAVLink`` object of the ground-station link (for sending).
        for_us: ``(target_system, target_component) -> bool``, the companion's addressing rule.
    """

    def __init__(self, service: MissionService, mav: Any,
                 for_us: Callable[[int, int], bool]) -> None:
        self.service = service
        self.mav = mav
        self.for_us = for_us

    def handle(self, msg: Any, now: float) -> None:
        """Feed one received mission message to the protocol and send its answers."""
        if not self.for_us(msg.target_system, msg.target_component):
            return
        kind = msg.get_type()
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        mission_type = getattr(msg, "mission_type", 0)
        s = self.service
        out: list[Outgoing]
        if kind == "MISSION_COUNT":
            out = s.on_count(src, msg.count, mission_type, now)
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            fields = {name: getattr(msg, name) for name in _ITEM_FIELDS}
            out = s.on_item(src, fields, encoded=kind == "MISSION_ITEM_INT",
                            mission_type=mission_type, now=now)
        elif kind == "MISSION_REQUEST_LIST":
            out = s.on_request_list(src, mission_type, now)
        elif kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            out = s.on_request(src, msg.seq, legacy=kind == "MISSION_REQUEST",
                               mission_type=mission_type, now=now)
        elif kind == "MISSION_ACK":
            s.on_ack(src, msg.type, mission_type, now)
            out = []
        else:  # MISSION_CLEAR_ALL
            out = s.on_clear_all(src, mission_type, now)
        self.send(out)

    def tick(self, now: float) -> None:
        """Re-send requests whose answers are overdue (the protocol's retries)."""
        self.send(self.service.tick(now))

    def send(self, messages: list[Outgoing]) -> None:
        """Put the protocol's answers on the link."""
        mav = self.mav
        for m in messages:
            system, component = m.target
            if m.kind == "MISSION_REQUEST_INT":
                mav.mission_request_int_send(system, component, m.seq, m.mission_type)
            elif m.kind == "MISSION_REQUEST":
                mav.mission_request_send(system, component, m.seq, m.mission_type)
            elif m.kind == "MISSION_ACK":
                mav.mission_ack_send(system, component, m.result, m.mission_type)
            elif m.kind == "MISSION_COUNT":
                mav.mission_count_send(system, component, m.count, m.mission_type)
            elif m.kind in ("MISSION_ITEM_INT", "MISSION_ITEM") and m.item is not None:
                it = m.item
                x, y = m.xy
                send = (mav.mission_item_int_send if m.kind == "MISSION_ITEM_INT"
                        else mav.mission_item_send)
                send(system, component, it.seq, it.frame, it.command, it.current,
                     it.autocontinue, it.param1, it.param2, it.param3, it.param4, x, y, it.z,
                     m.mission_type)
            else:
                raise ValueError(f"cannot send {m.kind}")

    def current_send(self, seq: int, total: int, state: int, in_auto: bool) -> None:
        """MISSION_CURRENT: ``total`` excludes home (UINT16_MAX when there is no mission)."""
        self.mav.mission_current_send(seq, total, state, 1 if in_auto else 0)

    def reached_send(self, seq: int) -> None:
        """MISSION_ITEM_REACHED."""
        self.mav.mission_item_reached_send(seq)

