"""The lockstep harness: the companion's loop, the board and a ground station in virtual time.

:class:`Lockstep` steps three parties with a fixed ``dt_s`` and no clock and no sockets:

- the companion: its :class:`~mecanum_mav.control.core.RoverCore` in the shipped loop
  (:class:`~mecanum_mav.runtime.loop.ControlLoop`, the one the companion runs), on virtual
  links and a poller that never sleeps (:mod:`mecanum_mav.sim.wires`), its clock the
  harness's virtual time;
- the :class:`~mecanum_mav.sim.board.SimBoard` (an ArduPilot Rover board and the chassis);
- a :class:`~mecanum_mav.sim.groundstation.ScriptedGroundStation` (:attr:`Lockstep.gcs`).

Every message crosses a virtual wire as bytes: packed by the sender with its own ids and
sequence numbers (the loop's sends with the links' fast codec, as the companion sends them)
and parsed by the receiver as the companion's links parse them, so what a test sees is what a
socket would carry. One step to ``t``:

1. the :attr:`Lockstep.on_step` callbacks and the ground station's HEARTBEAT if due; what
   they sent reaches the companion at ``t``, as does what the board sent in the previous step;
2. one pass of the companion's loop (:meth:`~mecanum_mav.runtime.loop.ControlLoop.run_once`)
   at ``t``: it runs as the companion's does when it wakes then (something to read, or a
   timer due), and does nothing in a step where the companion would still be asleep; what
   it sends reaches the ground station and the board at ``t``. A pass that left something
   to read (a pass that was a stick alone reads only the stick) is followed by another at
   ``t``, as the companion's level-triggered epoll wakes it again at once;
3. the board steps its physics and sends its telemetry (delivered in the next step).

So a command's answer and an override's effect are exact in virtual time, and a run of
minutes takes a fraction of a second. Every override the board receives is logged with its
time (:attr:`Lockstep.overrides`). With ``tlog`` every packet put on the four wires is recorded
as ``--tlog`` records a companion's links (8-byte big-endian Unix microseconds, the raw
packet), stamped with virtual time from :data:`TLOG_EPOCH_S`, so ``mecanum-mav log`` can be
tried and tested on a run of the harness.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, BinaryIO, NamedTuple, TypeVar

from mecanum_mav.config.params import Params
from mecanum_mav.control.core import COMPANION_COMPID, FC_LINK_COMPID, RoverCore, Storage
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.outbox import MessageOutbox
from mecanum_mav.runtime.loop import ControlLoop, link_counts
from mecanum_mav.sim.board import SimBoard, SimState
from mecanum_mav.sim.groundstation import (
    CLOCK_EPSILON_S,
    GCS_COMPID,
    GCS_SYSID,
    ScriptedGroundStation,
)
from mecanum_mav.sim.physics import DEFAULT_PHYSICS
from mecanum_mav.sim.wires import (
    SIGNING_START_TICKS,
    TLOG_EPOCH_S,
    VirtualLink,
    VirtualPoller,
    Wire,
)

__all__ = ["SIGNING_START_TICKS", "TLOG_EPOCH_S", "Lockstep", "OverrideSeen"]

T = TypeVar("T")

MAX_PASSES_PER_STEP = 16
"""Passes of the loop in one step at most (a pass reads at least one datagram, and a step
delivers far fewer than this behind a stick): a bound, not a rate."""


class OverrideSeen(NamedTuple):
    """An RC_CHANNELS_OVERRIDE as the board received it."""

    time_s: float
    channels: list[int]
    """The 18 ``chanN_raw`` fields, channel 1 first."""
    source_system: int


class _GcsPort:
    """The ground station's end of the virtual link (virtual time)."""

    def __init__(self, harness: Lockstep) -> None:
        self._harness = harness

    @property
    def mav(self) -> Any:
        return self._harness._gcs_to_core.sender

    def now(self) -> float:
        return self._harness.now_s

    def pump(self, timeout_s: float) -> list[Any]:
        """Step until something reaches the ground station or ``timeout_s`` has passed (the
        harness delivers into ``gcs.messages`` itself, so nothing is returned here)."""
        h = self._harness
        end = h.now_s + timeout_s
        count = len(h.gcs.messages)
        while len(h.gcs.messages) == count and h.now_s < end - CLOCK_EPSILON_S:
            h.step()
        return []


class Lockstep:
    """The companion's loop (its core on virtual links), the board and a scripted ground
    station, stepped together in virtual time.

    Args:
        params: parameters for the core and the board (defaults if None).
        dt_s: the virtual time step, seconds.
        mission: the mission the core starts with.
        storage: where the core keeps accepted parameters and missions.
        signing_key: sign the ground-station link with this 32-byte key, as ``--signing-key``
            does: the scripted ground station and the core sign what they send, the core keeps
            only correctly signed packets (:meth:`inject` puts others on the wire).
        tlog: record every packet the parties send to this open binary file (see the module
            docstring; what :meth:`inject` puts on the wire is not recorded).
        physics: the board's chassis model (:data:`~mecanum_mav.sim.physics.PHYSICS`).
    """

    def __init__(self, params: Params | None = None, *, dt_s: float = 0.002,
                 mission: Sequence[MissionItem] = (), storage: Storage | None = None,
                 signing_key: bytes | None = None, tlog: BinaryIO | None = None,
                 physics: str = DEFAULT_PHYSICS) -> None:
        self.params = params if params is not None else Params()
        self.dt_s = dt_s
        self.now_s = 0.0
        p = self.params
        self._gcs_to_core = Wire(GCS_SYSID, GCS_COMPID, name="gcs->core",
                                 signing_key=signing_key)
        self._core_to_gcs = Wire(int(p["SYSID_THISMAV"]), COMPANION_COMPID, name="core->gcs",
                                 signing_key=signing_key)
        self._core_to_fc = Wire(int(p["FC_GCS_SYSID"]), FC_LINK_COMPID, name="core->fc")
        self._fc_to_core = Wire(int(p["FC_SYSID"]), int(p["FC_COMPID"]), name="fc->core")
        self._wires = (self._gcs_to_core, self._core_to_gcs, self._core_to_fc, self._fc_to_core)
        for wire in self._wires:
            wire.tlog = tlog
        self._links = {"gcs": VirtualLink("gcs", self._gcs_to_core, self._core_to_gcs),
                       "fc": VirtualLink("fc", self._fc_to_core, self._core_to_fc)}
        gcs_link, fc_link = self._links["gcs"], self._links["fc"]
        self.core = RoverCore(p, now_s=0.0, mission=mission, storage=storage,
                              link_counts=lambda: link_counts(gcs_link, fc_link))
        self.loop = ControlLoop(self.core, gcs_link, fc_link, clock=self._now,
                                poller=VirtualPoller())
        """The companion's loop (the shipped one), on the virtual links."""
        self.board = SimBoard(p, 0.0, physics=physics)
        self._board_out = MessageOutbox()
        self.gcs = ScriptedGroundStation(_GcsPort(self))
        self.overrides: list[OverrideSeen] = []
        """Every RC_CHANNELS_OVERRIDE the board received, with its virtual time."""
        self.fc_received: list[Any] = []
        """Everything else the board received from the core (its HEARTBEATs)."""
        self.fc_link_up = True
        """Clear it to cut the flight-controller link: nothing crosses it either way."""
        self.on_step: list[Callable[[float], None]] = []
        """Called with the time at the start of every step (a test's periodic sender)."""

    @property
    def lane_answers(self) -> int:
        """The ground station's datagrams the loop answered in the stick lane (unparsed)."""
        return self._links["gcs"].lane_answers

    def _now(self) -> float:
        return self.now_s

    # ------------------------------------------------------------------ time

    def step(self) -> None:
        """Advance virtual time by ``dt_s`` (see the module docstring for the order)."""
        now = self.now_s = self.now_s + self.dt_s
        for wire in self._wires:
            wire.now_s = now
        for callback in self.on_step:
            callback(now)
        self.gcs.on_time(now)
        self._gcs_to_core.follow_clock(now)
        self._core_to_gcs.follow_clock(now)
        if not self.fc_link_up:
            self._fc_to_core.drop()
        loop, links = self.loop, self._links.values()
        loop.run_once()  # the companion's loop, one pass,
        for _ in range(MAX_PASSES_PER_STEP - 1):  # and more at once while a link is readable
            if not any(link.readable() for link in links):
                break
            loop.run_once()
        self.gcs.receive(self._core_to_gcs.deliver(), now)
        received = self._core_to_fc.deliver() if self.fc_link_up else self._core_to_fc.drop()
        if received:
            self._log_fc(received, now)
            self.board.receive(received, now)
        self.board.on_time(now, self._board_out)
        for msg in self._board_out.take():
            self._fc_to_core.sender.send(msg)

    def run_for(self, seconds: float) -> None:
        """Step for ``seconds`` of virtual time."""
        end = self.now_s + seconds
        while self.now_s < end - CLOCK_EPSILON_S:
            self.step()

    def run_until(self, predicate: Callable[[], T], timeout_s: float) -> T | None:
        """Step until ``predicate()`` returns something truthy (returned), or None once
        ``timeout_s`` of virtual time has passed."""
        end = self.now_s + timeout_s
        while True:
            result = predicate()
            if result:
                return result
            if self.now_s >= end - CLOCK_EPSILON_S:
                return None
            self.step()

    def every(self, period_s: float, action: Callable[[float], object]) -> Callable[[], None]:
        """Call ``action(now_s)`` now and then every ``period_s`` of virtual time (a ground
        station streaming sticks or setpoints); returns a function that stops it."""
        next_s = [self.now_s]

        def tick(now_s: float) -> None:
            if now_s >= next_s[0] - CLOCK_EPSILON_S:
                action(now_s)
                next_s[0] += period_s

        action(self.now_s)
        next_s[0] += period_s
        self.on_step.append(tick)
        return lambda: self.on_step.remove(tick) if tick in self.on_step else None

    def link_down(self, link: str, reason: str = "device gone") -> None:
        """Break ``link`` (``"fc"`` or ``"gcs"``) as the companion finds a link broken (USB
        unplugged, connection closed): the loop finds it down in the next step and tells the
        core once, as it does in the companion (:meth:`RoverCore.link_down`). The flight
        controller's wire is cut too; the ground station's is not (a test stops sending
        instead)."""
        if link == "fc":
            self.fc_link_up = False
        self._links[link].break_off(reason)

    def link_up(self, link: str) -> None:
        """``link`` is open again: the loop finds it up in the next step and tells the core
        before anything else goes out on it (:meth:`RoverCore.link_up`)."""
        if link == "fc":
            self.fc_link_up = True
        self._links[link].come_back()

    def inject(self, data: bytes, *, from_fc: bool = False) -> None:
        """Put raw bytes on the wire to the core, as the ground station (or the flight
        controller) would send them: garbage, truncated or hand-made packets."""
        (self._fc_to_core if from_fc else self._gcs_to_core).queue.append(bytes(data))

    # ------------------------------------------------------------------ views

    def truth(self) -> SimState:
        """The simulated chassis's true state now."""
        return self.board.state()

    def overrides_since(self, time_s: float) -> list[OverrideSeen]:
        """The overrides the board received at or after ``time_s``."""
        return [o for o in self.overrides if o.time_s >= time_s]

    # ------------------------------------------------------------------ plumbing

    def _log_fc(self, messages: list[Any], now: float) -> None:
        for msg in messages:
            if msg.get_type() == "RC_CHANNELS_OVERRIDE":
                channels = [getattr(msg, f"chan{i}_raw") for i in range(1, 19)]
                self.overrides.append(OverrideSeen(now, channels, msg.get_srcSystem()))
            else:
                self.fc_received.append(msg)
