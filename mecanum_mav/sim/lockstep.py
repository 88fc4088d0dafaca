"""The lockstep harness: the rover core, the simulated board and a ground station in virtual time.

:class:`Lockstep` steps three parties with a fixed ``dt_s`` and no clock and no sockets:

- the :class:`~mecanum_mav.control.core.RoverCore` (the companion's decisions),
- the :class:`~mecanum_mav.sim.board.SimBoard` (an ArduPilot Rover board and the chassis),
- a :class:`~mecanum_mav.sim.groundstation.ScriptedGroundStation` (:attr:`Lockstep.gcs`).

Every message crosses a virtual wire as bytes: packed by the sender with its own ids and
sequence numbers (the core's overrides with the fast codec, as the companion sends them) and
parsed by the receiver as the companion's links parse them, so what a test sees is what a
socket would carry. One step to ``t``:

1. the ground station's HEARTBEAT if due; what it sent reaches the core at ``t``;
2. what the board sent in the previous step reaches the core at ``t``;
3. ``core.tick(t)`` and ``core.housekeeping(t)`` if anything arrived or a timer of the core
   is due (as the companion's loop wakes; a lone pilot's stick goes to ``core.stick_lane``
   first, as the companion's loop does); the core's overrides and heartbeats reach the
   board at ``t``, its messages for the ground station reach the ground station at ``t``;
4. the board steps its physics and sends its telemetry (delivered in the next step).

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
from mecanum_mav.control.core import (
    COMPANION_COMPID,
    FC_LINK_COMPID,
    LinkCounts,
    Outbox,
    RoverCore,
    Storage,
)
from mecanum_mav.io.tlog import tlog_record
from mecanum_mav.protocol.codec import encode_rc_override, send_message
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.framing import MessageParser
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.outbox import MessageOutbox
from mecanum_mav.protocol.signing import TICKS_PER_S, SignatureCheck, ticks_from_unix
from mecanum_mav.sim.board import SimBoard, SimState
from mecanum_mav.sim.groundstation import GCS_COMPID, GCS_SYSID, ScriptedGroundStation

__all__ = ["TLOG_EPOCH_S", "Lockstep", "OverrideSeen"]

T = TypeVar("T")


class OverrideSeen(NamedTuple):
    """An RC_CHANNELS_OVERRIDE as the board received it."""

    time_s: float
    channels: list[int]
    """The 18 ``chanN_raw`` fields, channel 1 first."""
    source_system: int


TLOG_EPOCH_S = 1_790_000_000.0
"""The Unix time a recorded tlog gives virtual time 0 (a date in 2026)."""
SIGNING_START_TICKS = ticks_from_unix(TLOG_EPOCH_S)
"""The signing timestamp at virtual time 0 (a date in 2026); it counts on with virtual time."""


class _Wire:
    """One direction of a virtual link: bytes queued by a sender, parsed by the receiver.

    With ``signing_key`` the sender signs (as a link with that key does) and the receiver keeps
    only correctly signed, fresh packets (:class:`~mecanum_mav.protocol.signing.SignatureCheck`).
    """

    def __init__(self, sysid: int, compid: int, *, name: str,
                 signing_key: bytes | None = None) -> None:
        self.sender = mavlink.MAVLink(self, srcSystem=sysid, srcComponent=compid)
        self.check = None
        if signing_key is not None:
            signing = self.sender.signing
            signing.secret_key, signing.sign_outgoing = signing_key, True
            signing.link_id, signing.timestamp = 0, SIGNING_START_TICKS
            self.check = SignatureCheck(signing_key, SIGNING_START_TICKS)
        self.parser = MessageParser(mavlink.MAVLink(None), datagrams=True, name=name,
                                    check=self.check)
        self.queue: list[bytes] = []
        self.received = 0
        self.tlog: BinaryIO | None = None
        self.now_s = 0.0

    def follow_clock(self, now_s: float) -> None:
        """Signing timestamps follow virtual time, as a link's follow the wall clock."""
        if self.check is not None:
            now = SIGNING_START_TICKS + int(now_s * TICKS_PER_S)
            self.check.advance(now)
            self.sender.signing.timestamp = max(self.sender.signing.timestamp, now)

    def write(self, data: bytes) -> None:
        """The sender's ``file.write``: one datagram on the wire (recorded with a tlog)."""
        self.queue.append(bytes(data))
        if self.tlog is not None:
            self.tlog.write(tlog_record(round((TLOG_EPOCH_S + self.now_s) * 1e6), data))

    def drop(self) -> list[Any]:
        """Lose everything on the wire (a cut link); returns nothing."""
        self.queue = []
        return []

    def deliver(self) -> list[Any]:
        """Everything on the wire, parsed; the wire is empty after."""
        if not self.queue:
            return []
        datagrams, self.queue = self.queue, []
        messages: list[Any] = []
        for data in datagrams:
            messages += self.parser.parse(data)
        self.received += len(messages)
        return messages


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
        while len(h.gcs.messages) == count and h.now_s < end - 1e-12:
            h.step()
        return []


class Lockstep:
    """The core, the board and a scripted ground station, stepped together in virtual time.

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
    """

    def __init__(self, params: Params | None = None, *, dt_s: float = 0.002,
                 mission: Sequence[MissionItem] = (), storage: Storage | None = None,
                 signing_key: bytes | None = None, tlog: BinaryIO | None = None) -> None:
        self.params = params if params is not None else Params()
        self.dt_s = dt_s
        self.now_s = 0.0
        p = self.params
        self._gcs_to_core = _Wire(GCS_SYSID, GCS_COMPID, name="gcs->core",
                                  signing_key=signing_key)
        self._core_to_gcs = _Wire(int(p["SYSID_THISMAV"]), COMPANION_COMPID, name="core->gcs",
                                  signing_key=signing_key)
        self._core_to_fc = _Wire(int(p["FC_GCS_SYSID"]), FC_LINK_COMPID, name="core->fc")
        self._fc_to_core = _Wire(int(p["FC_SYSID"]), int(p["FC_COMPID"]), name="fc->core")
        self._wires = (self._gcs_to_core, self._core_to_gcs, self._core_to_fc, self._fc_to_core)
        for wire in self._wires:
            wire.tlog = tlog
        self.core = RoverCore(p, now_s=0.0, mission=mission, storage=storage,
                              link_counts=self._link_counts)
        self.board = SimBoard(p, 0.0)
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

    # ------------------------------------------------------------------ time

    def step(self) -> None:
        """Advance virtual time by ``dt_s`` (see the module docstring for the order)."""
        now = self.now_s = self.now_s + self.dt_s
        for wire in self._wires:
            wire.now_s = now
        for callback in self.on_step:
            callback(now)
        self.gcs.on_time(now)
        core = self.core
        woke = False
        gcs_wire = self._gcs_to_core
        gcs_wire.follow_clock(now)
        self._core_to_gcs.follow_clock(now)
        due = core.next_due_s()  # (as the companion's loop computed it before its wait)
        if self._stick_lane(now):  # the pilot's stick in its lane, as the companion answers it
            woke = True
        else:
            delivered = gcs_wire.deliver()
            if gcs_wire.check is not None and gcs_wire.check.new_rejections:
                core.refuse_unsigned(gcs_wire.check.take_rejections(), now)
            for msg in delivered:
                self._write(core.handle(msg, now))
                woke = True
        for msg in self._fc_to_core.deliver() if self.fc_link_up else self._fc_to_core.drop():
            self._write(core.handle(msg, now, from_fc=True))
            woke = True
        # As the companion's loop: tick and housekeeping, each skipped while the core is
        # settled (a wake with nothing new; a refresh-only wake's housekeeping).
        if (woke or now >= due) and not core.settled(now):
            self._write(core.tick(now))
            if not core.settled(now):
                self._write(core.housekeeping(now))
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
        while self.now_s < end - 1e-12:
            self.step()

    def run_until(self, predicate: Callable[[], T], timeout_s: float) -> T | None:
        """Step until ``predicate()`` returns something truthy (returned), or None once
        ``timeout_s`` of virtual time has passed."""
        end = self.now_s + timeout_s
        while True:
            result = predicate()
            if result:
                return result
            if self.now_s >= end - 1e-12:
                return None
            self.step()

    def every(self, period_s: float, action: Callable[[float], object]) -> Callable[[], None]:
        """Call ``action(now_s)`` now and then every ``period_s`` of virtual time (a ground
        station streaming sticks or setpoints); returns a function that stops it."""
        next_s = [self.now_s]

        def tick(now_s: float) -> None:
            if now_s >= next_s[0] - 1e-12:
                action(now_s)
                next_s[0] += period_s

        action(self.now_s)
        next_s[0] += period_s
        self.on_step.append(tick)
        return lambda: self.on_step.remove(tick) if tick in self.on_step else None

    def link_down(self, link: str, reason: str = "device gone") -> None:
        """Break ``link`` (``"fc"`` or ``"gcs"``) as the companion finds a link broken (USB
        unplugged, connection closed) and tell the core once, as its shell does
        (:meth:`RoverCore.link_down`). The flight controller's wire is cut too; the ground
        station's is not (a test stops sending instead)."""
        if link == "fc":
            self.fc_link_up = False
        self._write(self.core.link_down(link, reason, self.now_s))

    def link_up(self, link: str) -> None:
        """``link`` is open again: the core is told first, as the shell does when it has
        reopened it (:meth:`RoverCore.link_up`)."""
        if link == "fc":
            self.fc_link_up = True
        self._write(self.core.link_up(link, self.now_s))

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

    def _stick_lane(self, now: float) -> bool:
        """A lone datagram from the ground station answered in the core's stick lane, its
        packet on the wire to the board, as the companion's loop does (on unsigned wires)."""
        wire, out = self._gcs_to_core, self._core_to_fc
        if len(wire.queue) != 1 or wire.check is not None or out.check is not None:
            return False
        sender = out.sender
        packet = self.core.stick_lane(wire.queue[0], now, sender.seq)
        if packet is None:
            return False
        sender.seq = (sender.seq + 1) & 0xFF
        out.write(packet)
        self.core.stick_sent()
        wire.queue = []
        wire.received += 1
        return True

    def _write(self, out: Outbox) -> None:
        """Put the core's output on the wires, as the companion's shell does."""
        if out.override is not None:
            sender = self._core_to_fc.sender
            sender.srcSystem = self.core.identity.fc_gcs_sysid
            packet = encode_rc_override(sender, *out.override)  # the companion's fast codec
            self._core_to_fc.write(packet)
        for msg in out.fc:
            send_message(self._core_to_fc.sender, msg)  # the companion's fast codec
        for msg in out.gcs:
            send_message(self._core_to_gcs.sender, msg)
        if out.gcs:  # the ground station has it at once (gcs.messages, gcs.arrived_s)
            self.gcs.receive(self._core_to_gcs.deliver(), self.now_s)

    def _log_fc(self, messages: list[Any], now: float) -> None:
        for msg in messages:
            if msg.get_type() == "RC_CHANNELS_OVERRIDE":
                channels = [getattr(msg, f"chan{i}_raw") for i in range(1, 19)]
                self.overrides.append(OverrideSeen(now, channels, msg.get_srcSystem()))
            else:
                self.fc_received.append(msg)

    def _link_counts(self) -> LinkCounts:
        gcs, fc = self._gcs_to_core, self._fc_to_core
        return LinkCounts(gcs.received + fc.received, gcs.parser.bad + fc.parser.bad)
