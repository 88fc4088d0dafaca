"""The mission as the rover keeps it: the MAVLink mission protocol, the executor's reports and
the stored copy. Messages and time in, messages (into the core's outbox) out.

- Upload, download, clear and MISSION_SET_CURRENT go through the protocol state machine
  (:class:`~mecanum_mav.protocol.missionservice.MissionService`); an accepted mission replaces
  the executor's (a running one goes on from its current item; cleared in AUTO: HOLD) and is
  kept by the storage.
- The executor's events become MISSION_CURRENT (on change and at 1 Hz, as ArduPilot),
  MISSION_ITEM_REACHED, status texts, and HOLD at the end.
- MAV_CMD_DO_SET_MISSION_CURRENT and MAV_CMD_MISSION_START are answered here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from mecanum_mav.control.context import Handler
from mecanum_mav.control.executor import MissionExecutor
from mecanum_mav.control.refusals import Refusal
from mecanum_mav.control.vehicle import Vehicle
from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.protocol.messages import MissionSetCurrentMsg, Result
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.missionlink import MISSION_MESSAGES, MissionLink
from mecanum_mav.protocol.missionservice import MissionService
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.statustext import Severity

__all__ = ["MissionControl", "MissionStore"]

NO_MISSION_TOTAL = 0xFFFF
"""MISSION_CURRENT.total when there is no mission (UINT16_MAX)."""


class MissionStore(Protocol):
    """Where an accepted mission is kept (the companion's mission file)."""

    def save_mission(self, items: Sequence[MissionItem]) -> None:
        """Keep the mission; raises ``OSError`` when that fails."""


class MissionControl:
    """The mission protocol and the executor's reports for one rover.

    Args:
        items: the mission to start with (item 0 is home).
        to_gcs: the ground station's outbox (a pymavlink ``MAVLink`` that collects).
        for_us: the core's addressing rule, ``(target_system, target_component) -> bool``.
        from_pilot: the core's rule for who commands, ``(message) -> bool``: only the
            pilot's ground station's mission messages count.
        vehicle: the mode state machine (AUTO, HOLD).
        executor: the mission executor that drives the mission.
        pose: returns the rover's pose now (local NED).
        say: the core's STATUSTEXT.
        refuse: the core's report of a refused input (counted, said sparingly).
        store: keeps accepted missions, or None.
    """

    def __init__(self, items: Sequence[MissionItem], to_gcs: Any,
                 for_us: Callable[[int, int], bool], from_pilot: Callable[[Any], bool],
                 vehicle: Vehicle,
                 executor: MissionExecutor, pose: Callable[[], Pose2d],
                 say: Callable[[Severity, str], None],
                 refuse: Callable[[Refusal, str], None], store: MissionStore | None) -> None:
        self.service = MissionService(items)
        self.link = MissionLink(self.service, to_gcs, for_us)
        self._for_us = for_us
        self._from_pilot = from_pilot
        self.vehicle = vehicle
        self.executor = executor
        self.pose = pose
        self.say = say
        self.refuse = refuse
        self.store = store
        executor.load(items)

    @property
    def items(self) -> tuple[MissionItem, ...]:
        """The accepted mission (item 0 is home)."""
        return self.service.items

    def next_due_s(self) -> float:
        """When the protocol's next retry or timeout is due (monotonic s)."""
        return self.service.next_due_s()

    # ------------------------------------------------------------------ messages

    def routes(self) -> dict[str, Handler]:
        """The ground station's messages handled here, by type."""
        return {"MISSION_SET_CURRENT": self.on_set_current,
                **dict.fromkeys(MISSION_MESSAGES, self.on_message)}

    def on_message(self, msg: Any, now_s: float) -> None:
        """A mission protocol message (only the pilot's ground station's count)."""
        if self._from_pilot(msg):
            self.link.handle(msg, now_s)
            self._take_protocol_events(now_s)

    def on_set_current(self, msg: MissionSetCurrentMsg, now_s: float) -> None:
        """MISSION_SET_CURRENT for us from the pilot (answered by MISSION_CURRENT)."""
        if self._for_us(msg.target_system, msg.target_component) and self._from_pilot(msg):
            self.set_current(msg.seq, now_s)

    def cmd_set_current(self, p: tuple[float, ...], now_s: float) -> Result:
        """MAV_CMD_DO_SET_MISSION_CURRENT: param1 the item (-1 the current one), param2 = 1
        also resets the mission (DO_JUMP counters, start over). -1 with the reset keeps the
        current item (MAVLink: "reset mission without changing current mission item"). An item
        out of range, or no mission, is FAILED (MAVLink) with a STATUSTEXT, and changes
        nothing."""
        if math.isfinite(p[0]) and p[0] >= -1:
            seq = self.executor.current if p[0] == -1 else int(p[0])
            return self.set_current(seq, now_s, reset=p[1] == 1.0)
        self.refuse(Refusal.MISSION, f"Set current item refused: no item {p[0]:g}")
        return Result.FAILED

    def cmd_start(self, p: tuple[float, ...], now_s: float) -> Result:
        """MAV_CMD_MISSION_START: param1 the first item (0: resume), then AUTO."""
        if math.isfinite(p[0]) and p[0] >= 1 and self.set_current(
                int(p[0]), now_s) != Result.ACCEPTED:
            return Result.DENIED
        accepted = self.vehicle.request_mode(Mode.AUTO, now_s).accepted
        return Result.ACCEPTED if accepted else Result.DENIED

    def set_current(self, seq: int, now_s: float, *, reset: bool = False) -> Result:
        """Make item ``seq`` current (a running mission drives there from where it is);
        ``reset`` starts the mission over first. Refused (FAILED, a STATUSTEXT, nothing
        changed) without a mission or with ``seq`` out of range."""
        reason = self.executor.set_current(seq, self.pose(), reset=reset)
        if reason is not None:
            self.refuse(Refusal.MISSION, f"Set current item refused: {reason}")
            return Result.FAILED
        self.take_executor_events(now_s)
        return Result.ACCEPTED

    # ------------------------------------------------------------------ time

    def tick(self, now_s: float) -> None:
        """The protocol's retries and timeouts (when due) and the executor's reports."""
        if now_s >= self.service.next_due_s():
            self.link.tick(now_s)
            self._take_protocol_events(now_s)
        if self.executor.events:
            self.take_executor_events(now_s)

    def send_current(self) -> None:
        """MISSION_CURRENT: the current item, the item count without home, the state."""
        ex = self.executor
        total = len(ex.items) - 1 if ex.has_mission else NO_MISSION_TOTAL
        self.link.current_send(ex.current, total, ex.state, self.vehicle.mode is Mode.AUTO)

    def take_executor_events(self, now_s: float) -> None:
        """Report what the executor did: current item, item reached, texts, the end."""
        for event in self.executor.take_events():
            if event.kind == "current":
                self.send_current()
            elif event.kind == "reached":
                self.link.reached_send(event.seq)
            elif event.kind == "say":
                self.say(event.severity, event.text)
            else:  # "finished" (the executor's fourth and last kind)
                self.vehicle.request_mode(Mode.HOLD, now_s)

    def _take_protocol_events(self, now_s: float) -> None:
        for kind, text in self.service.take_events():
            if kind == "error":
                self.refuse(Refusal.MISSION, text)
            else:
                self._replaced(now_s)

    def _replaced(self, now_s: float) -> None:
        """A new mission was accepted (or the mission was cleared): run it, keep it."""
        items = self.service.items
        executor = self.executor
        was_running = executor.running
        executor.pause()
        executor.load(items)
        self.send_current()
        if self.vehicle.mode is Mode.AUTO and not executor.has_mission:
            self.say(Severity.WARNING, "Mission cleared: HOLD")
            self.vehicle.request_mode(Mode.HOLD, now_s)
        elif was_running:
            self.say(Severity.NOTICE, f"New mission: continuing at item {executor.current}")
        if self.store is not None:
            try:
                self.store.save_mission(items)
            except OSError as exc:
                self.say(Severity.ERROR, f"Mission save failed: {exc.strerror}")
