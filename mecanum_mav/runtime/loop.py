"""The companion's loop: one pass around the rover core, and the shutdown, in one place.

Everything the rover decides is in :class:`~mecanum_mav.control.core.RoverCore`; the loop
feeds it what arrives on the two links, writes what it returns, keeps the links and tells the
core when one broke or came back. :class:`ControlLoop` is the only copy of it: the companion's
shell (:class:`~mecanum_mav.app.companion.Companion`) runs :meth:`ControlLoop.run_once` on real
links and epoll until it is stopped; the lockstep harness (:class:`~mecanum_mav.sim.lockstep.
Lockstep`) steps the same method on virtual links, a poller that never sleeps and a virtual
clock. Everything it needs is injected: the core, the two links (:class:`LoopLink`), the
clock (monotonic seconds) and the poller (:class:`LoopPoller`).

One pass, top to bottom:

1. Wait until a link is readable or something is due: the core's next timer, a link's
   reopening or pacing, the shell's slow timer (:meth:`ControlLoop.set_timer`). A wait that
   ends with nothing ready before anything is due (an interrupted wait; in the harness, a
   step between wakes) ends the pass. The poller never polls, so an idle companion uses no
   CPU.
2. Read everything waiting on a link; each message goes to ``core.handle`` and its answers
   out at once. Under overload this drains the queue and the core acts on the newest stick.
   On a datagram link from the ground station the first datagram is answered before the rest
   are read: the pilot's MANUAL_CONTROL takes the core's lane (``core.stick_lane``, compiled
   in :mod:`mecanum_mav.control.lane`: the datagram to the override's packet in one call) and
   the packet goes out before anything else is done (unsigned links only, and only when the
   flight controller's link takes it at once: on a stream link nothing may wait in it and
   the wire must be free, ``takes_packet``; else the stick takes the general way and the
   tick's override waits its turn, newest wins). Then the shell's slow timer, if due.
3. ``core.tick``: its RC_CHANNELS_OVERRIDE goes out at once; then ``core.housekeeping``:
   odometry, telemetry, heartbeats and status texts (after a stick the lane answered the
   tick has nothing to do, and housekeeping takes the odometry, after the send; the poller
   yields the CPU before it, :meth:`~mecanum_mav.io.poller.Poller.yield_cpu`, so that what
   the stick's write woke runs first: a pty's delivery). Each is
   skipped while the core is :meth:`~mecanum_mav.control.core.RoverCore.settled` (no timer
   due, nothing new) and the stream links are idle: an idle rover's refresh wake, or a
   stick the lane answered, is that alone.
4. Each stream link hands over what still waits in it (:func:`~mecanum_mav.io.links.follow`)
   and is watched on its current descriptor, for writing too while the kernel refuses more.
   Skipped with step 3 while every stream link is idle (:meth:`ControlLoop._streams_idle`):
   up, nothing waiting, watched for reading only on the descriptor it has now.

:meth:`ControlLoop.shutdown` is the way out: neutral, then the channels released, all of them
in order, the release :data:`NEUTRAL_HOLD_S` after the first neutral.

A link that breaks (serial device gone, TCP connection closed) is reported to the core once
(``core.link_down``: its failsafe fires now), leaves the poller (its dead descriptor would
wake the loop at once, forever), and is reopened on its own timer
(:meth:`~mecanum_mav.io.links.Link.reopen`); when it is back the core is told
(``core.link_up``) before anything else is sent, so the flight controller's first override is
neutral. A ``tcpin`` link waits for its next client instead (its descriptor turns readable).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol, cast

from mecanum_mav.control.core import NOTHING, LinkCounts, Outbox, RcOverride, RoverCore
from mecanum_mav.io.links import follow
from mecanum_mav.io.poller import READABLE

__all__ = ["NEUTRAL_HOLD_S", "ControlLoop", "LoopLink", "LoopPoller", "link_counts"]

NEUTRAL_HOLD_S = 0.1
"""How long the companion's last neutral overrides stand before it releases the channels.
ArduPilot reads its RC input once per main-loop pass: a neutral override followed at once by
the release never reaches the outputs, which (with no receiver) then hold the last pulse read,
the drive, until the radio failsafe takes them to trim 0.5 s later. Found with the twin
(real firmware): a Ctrl-C at 1 m/s kept all four wheels at 2000 us for 0.47 s. 0.1 s is five
passes of Rover's 50 Hz loop."""


class LoopLink(Protocol):
    """What the loop uses of a link (:class:`~mecanum_mav.io.links.Link` is one; the lockstep
    harness has virtual ones). Never raises: failures are counted by the link."""

    @property
    def name(self) -> str:
        """``"gcs"`` or ``"fc"``: what the core calls it (``core.link_down``)."""

    @property
    def steady(self) -> bool:
        """A datagram link: nothing waits in it and :func:`~mecanum_mav.io.links.follow` has
        nothing to do for it after the first call; read at the loop's start (its first
        datagram from the ground station is answered first) and after each read (one that
        is not steady is reported to the core, a stream link's break)."""

    @property
    def unchecked(self) -> bool:
        """It neither checks nor makes signatures: the stick lane may answer what it reads and
        send an override packed elsewhere (:meth:`send_packet`)."""

    @property
    def signature_check(self) -> object | None:
        """Its signature check, or None (then :meth:`take_rejections` has nothing)."""

    @property
    def mav(self) -> Any:
        """The pymavlink ``MAVLink`` that packs what it sends (``seq``, ``srcSystem``)."""

    @property
    def up(self) -> bool:
        """False from a break until it is open again."""

    @property
    def down_reason(self) -> str | None:
        """Why it is down, or None while up."""

    @property
    def next_reopen_s(self) -> float:
        """When :meth:`reopen` tries next (clock s; inf: no timer)."""

    @property
    def next_send_s(self) -> float:
        """When what waits in it can be handed over (clock s; inf: nothing waits)."""

    @property
    def wants_write(self) -> bool:
        """Watch its descriptor for writing too (:func:`~mecanum_mav.io.links.follow`)."""

    @property
    def pending(self) -> bool:
        """Whether anything waits in it to be handed over (stream links)."""

    @property
    def received(self) -> int:
        """Messages received."""

    @property
    def bad(self) -> int:
        """Malformed packets received."""

    @property
    def send_errors(self) -> int:
        """Sends that failed."""

    def reopen(self, now_s: float) -> bool:
        """Try to open it again if due; whether it is up."""

    def receive_datagram(self) -> tuple[bytes, Any] | None:
        """The next datagram and its sender, unparsed and uncounted, or None."""

    def parse_datagram(self, data: bytes, address: Any) -> list[Any]:
        """The messages of a datagram from :meth:`receive_datagram`, counted."""

    def answered(self, data: bytes, address: Any) -> None:
        """A datagram from :meth:`receive_datagram` answered unparsed (the lane): counted."""

    def read(self) -> list[Any]:
        """Every message waiting, oldest first."""

    def take_rejections(self) -> Mapping[Any, int]:
        """What the signature check dropped since the last call, per kind."""

    def takes_packet(self) -> bool:
        """Whether a packet given to :meth:`send_packet` now goes out at once, ahead of
        nothing (a stream link: up, nothing waiting, the wire free)."""

    def send_packet(self, packet: bytes) -> None:
        """Send a packet packed with ``mav.seq`` (the lane's override); ``seq`` advances."""

    def send_all(self, messages: Sequence[Any]) -> None:
        """Pack and send each message, in order."""

    def send_rc_override(self, target_system: int, target_component: int,
                         channels: list[int], *, replace: bool = True) -> None:
        """RC_CHANNELS_OVERRIDE; a stream link's waiting one is replaced (``replace``)."""

    def flush(self) -> None:
        """Hand over what waits, as pacing lets it (stream links)."""

    def wait_fd(self) -> int | None:
        """The descriptor to wait on, or None while there is none (down)."""


class LoopPoller(Protocol):
    """What the loop uses of a poller (:class:`~mecanum_mav.io.poller.Poller` is one; the
    lockstep harness has one that never sleeps). ``register`` and the rest are what
    :func:`~mecanum_mav.io.links.follow` calls; each registered link's data is the link."""

    def wait(self, timeout_s: float) -> list[tuple[Any, int]]:
        """Wait up to ``timeout_s``; the ready registrations' data and epoll events (data None:
        the shell's own wake-up)."""

    def yield_cpu(self) -> None:
        """Let whatever a write woke on this CPU run now (the loop has more to do)."""

    def register(self, fileobj: Any, events: int, data: Any = None) -> Any: ...

    def unregister(self, fileobj: Any) -> Any: ...

    def modify(self, fileobj: Any, events: int, data: Any = None) -> Any: ...

    def get_key(self, fileobj: Any) -> Any: ...


_follow = cast(Callable[[LoopPoller, LoopLink, "int | None", object], "int | None"], follow)
""":func:`~mecanum_mav.io.links.follow`, which uses only what :class:`LoopPoller` and
:class:`LoopLink` state (``register``, ``unregister``, ``modify``, ``get_key``; ``flush``,
``wait_fd``, ``wants_write``)."""


def _nothing() -> None:
    return None


def link_counts(gcs: LoopLink, fc: LoopLink) -> LinkCounts:
    """What both links counted, for the core (SYS_STATUS ``errors_comm``, the status line)."""
    return LinkCounts(gcs.received + fc.received, gcs.bad + fc.bad,
                      gcs.send_errors + fc.send_errors)


class ControlLoop:
    """The loop around a :class:`RoverCore` (see the module docstring).

    Args:
        core: the rover's decisions.
        gcs, fc: the ground station's and the flight controller's links.
        clock: monotonic time source, seconds (the core's and the links' time).
        poller: waits on the links; they are registered on it now, their data the link.
        woken: called when the poller returns a registration whose data is None (the shell's
            wake-up pipe, which it registered itself).
    """

    def __init__(self, core: RoverCore, gcs: LoopLink, fc: LoopLink, *,
                 clock: Callable[[], float], poller: LoopPoller,
                 woken: Callable[[], object] = _nothing) -> None:
        self.core, self.gcs, self.fc = core, gcs, fc
        self.clock = clock
        self.poller = poller
        self._woken = woken
        self._fc_mav = fc.mav
        self._gcs_datagrams = gcs if gcs.steady else None
        """The ground station's link when it is a datagram link (its first datagram waiting
        is answered before the rest are read)."""
        self._lane_links = gcs.unchecked and fc.unchecked
        self._fc_datagrams = fc.steady
        """A datagram link to the flight controller takes every packet at once: only a stream
        link is asked (``takes_packet``) before the lane answers."""
        """The stick lane may answer (its packets are unsigned; keys are fixed at start)."""
        self._up = {gcs: True, fc: True}
        self._timer: Callable[[float], float] | None = None
        self._timer_due_s = math.inf
        self._laned = False  # this pass answered a stick in its lane (_drain)
        self._sticks_until_s = -math.inf
        """Until when the next pass may be a stick alone (:meth:`_next_stick`); -inf: not."""
        registered = {link: _follow(poller, link, None, link) for link in (gcs, fc)}
        self._streams = {link: (fd, link.wants_write) for link, fd in registered.items()
                         if not link.steady}
        """The stream links, their registered descriptors and whether those are watched for
        writing too (followed on every pass that is not idle, :meth:`_streams_idle`)."""

    def set_timer(self, action: Callable[[float], float]) -> None:
        """Call ``action(now_s)`` on the next pass and then whenever the time it returned
        (clock s) has come: something slow-paced beside the rover (the shell's progress
        line). It runs in the loop between its steps: keep it short (no waiting)."""
        self._timer, self._timer_due_s = action, -math.inf
        self._sticks_until_s = -math.inf

    def run_once(self) -> None:
        """One pass (module docstring): wait, read and answer, tick, housekeeping, links."""
        self._laned = False
        if self._sticks_until_s > -math.inf:  # the last pass was a stick, in its lane: wait
            ready = self.poller.wait(self._sticks_until_s - self.clock())  # for the next one
            if self._next_stick(ready):
                return
            self._sticks_until_s = -math.inf  # (the rest of the pass reads what is ready)
        else:
            ready = None
        core, streams, clock = self.core, self._streams, self.clock
        gcs, fc = self.gcs, self.fc
        due = min(core.next_due_s(), gcs.next_reopen_s, fc.next_reopen_s,
                  gcs.next_send_s, fc.next_send_s, self._timer_due_s)
        if ready is None:
            ready = self.poller.wait(due - clock())
        for link, events in ready:
            if link is None:
                self._woken()
            elif events & READABLE:  # (writable: follow() flushes)
                self._drain(link)
        now = clock()
        if not ready and now < due:
            return  # woken before anything is due, with nothing to read
        if now >= self._timer_due_s and self._timer is not None:
            self._timer_due_s = self._timer(now)
        if core.settled(now) and (not streams or self._streams_idle()):
            if self._laned:  # a stick in its lane, nothing else to do: until due, the next
                self._sticks_until_s = due  # pass may be a stick alone (_next_stick)
            return  # nothing arrived and nothing is due
        for link in streams:  # (a datagram link never goes down)
            if not link.up and link.reopen(now):
                self._report(link, now)  # before anything else goes out on it
        out = core.tick(now)
        if out is not NOTHING:
            self._write(out)  # the override first,
        if core.settled(now) and (not streams or self._streams_idle()):
            return  # the pass was the output's refresh (or the lane's): nothing else is due
        if self._laned:  # (a pty delivers the stick's write from a kernel worker on this CPU:
            self.poller.yield_cpu()  # it runs now, not after housekeeping's few hundred us)
        out = core.housekeeping(now)
        if out is not NOTHING:
            self._write(out)  # then everything else
        for link, (fd, _) in streams.items():
            self._report(link, now)
            streams[link] = (_follow(self.poller, link, fd, link), link.wants_write)

    def _streams_idle(self) -> bool:
        """Whether following the stream links would change nothing: each is up, nothing
        waits in it, and the poller watches its descriptor (a ``tcpin`` link swaps it when a
        client comes) for reading only. True without stream links."""
        for link, (fd, writing) in self._streams.items():
            if writing or link.pending or not link.up or link.wait_fd() != fd:
                return False
        return True

    def shutdown(self) -> None:
        """The last words to the flight controller: neutral, then the channels released, all
        of them in order (a stream link queues them behind what waits), the neutral ones
        spread over :data:`NEUTRAL_HOLD_S` before the release (see there)."""
        core = self.core
        self._fc_mav.srcSystem = core.identity.fc_gcs_sysid
        *neutral, release = core.shutdown()
        for override in neutral:
            self.fc.send_rc_override(*override, replace=False)
            self._hold(NEUTRAL_HOLD_S / len(neutral))
        self.fc.send_rc_override(*release, replace=False)

    def _hold(self, seconds: float) -> None:
        """Let ``seconds`` of real time pass, handing over what waits in the flight
        controller's link meanwhile."""
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0.0:
            self.fc.flush()
            time.sleep(min(left, 0.005))

    def _next_stick(self, ready: list[tuple[Any, int]]) -> bool:
        """After a pass that was a stick in its lane and left nothing to do: whether the next
        wake (``ready``) was the same and nothing more, so that the pass ends here: only the
        ground station's datagram link ready, its first datagram a stick the lane answered
        (:meth:`_answer_first`), the core still settled and the stream links idle. The timers
        could only have moved later (a message would have unsettled the core): the wait ran
        until the earliest of them as that pass saw it. Else the rest of the pass takes over,
        with ``ready`` (what was read here was answered).

        What waits behind the stick is not read here: the poller is level-triggered, so the
        next wait returns at once with the link still ready and that pass reads it (a
        datagram more or another stick). Asking here would cost every stick a read that finds
        nothing (a syscall and a raised ``BlockingIOError``: 14 % of the companion's CPU per
        stick at 1 kHz, ``tools/bench_ab.py --path serial``)."""
        link = self._gcs_datagrams
        if len(ready) != 1 or ready[0][0] is not link:
            return False
        now = self.clock()
        if not self._answer_first(link, now):
            return False
        self._laned = True
        # (The ground station's link is a datagram one: the only stream link there can be is
        # the flight controller's, and this pass neither read nor followed it, so only the
        # lane's write can have changed it: a break, or a write the kernel took in part.)
        fc = self.fc
        return self.core.settled(now) and (self._fc_datagrams or (fc.up and not fc.pending))

    def _drain(self, link: LoopLink) -> None:
        """Read what waits on ``link`` and answer it: on a datagram link from the ground
        station the first datagram is answered before the rest is read
        (:meth:`_answer_first`); the rest goes to the core in order."""
        now, from_fc = self.clock(), link is self.fc
        if link is self._gcs_datagrams:  # the first datagram is answered first
            self._laned |= self._answer_first(link, now)
        messages = link.read()
        if link.signature_check is not None:
            rejected = link.take_rejections()
            if rejected:  # unsigned or badly signed: counted, said at most once a second
                self.core.refuse_unsigned(rejected, now, from_fc=from_fc)
        if not link.steady:
            self._report(link, now)  # it broke, or a tcpin client connected: the core first
        if messages:
            self._answer(messages, now, from_fc=from_fc)

    def _answer_first(self, link: LoopLink, now: float) -> bool:
        """The first datagram waiting on the ground station's datagram ``link``: a pilot's
        stick in the core's lane (its override packed in one call and sent before anything
        else is done; True), else parsed and handed to the core (False, as with none)."""
        got = link.receive_datagram()
        if got is None:
            return False
        data, address = got
        packet = (self.core.stick_lane(data, now, self._fc_mav.seq)
                  if self._lane_links and (self._fc_datagrams or self.fc.takes_packet())
                  else None)
        if packet is None:
            self._answer(link.parse_datagram(data, address), now, from_fc=False)
            return False
        self.fc.send_packet(packet)  # the pilot's stick, in its lane: sent at once
        self.core.stick_sent()
        link.answered(data, address)
        return True

    def _answer(self, messages: list[Any], now: float, *, from_fc: bool) -> None:
        """Hand ``messages`` to the core and send its answers."""
        handle = self.core.handle
        for msg in messages:
            out = handle(msg, now, from_fc=from_fc)
            if out is not NOTHING:  # a stick is answered by the tick, not here
                self._write(out)

    def _report(self, link: LoopLink, now: float) -> None:
        """Tell the core once when ``link`` went down or came back up."""
        up = link.up
        if up is self._up[link]:
            return
        self._up[link] = up
        if up:
            self._write(self.core.link_up(link.name, now))
        else:
            self._write(self.core.link_down(link.name, link.down_reason or "", now))

    def _write(self, out: Outbox) -> None:
        if out.override is not None:  # first: the latency-critical part
            self._send_override(out.override)
        if out.fc:
            self.fc.send_all(out.fc)
        if out.gcs:
            self.gcs.send_all(out.gcs)

    def _send_override(self, override: RcOverride) -> None:
        self._fc_mav.srcSystem = self.core.identity.fc_gcs_sysid  # FC_GCS_SYSID may change
        self.fc.send_rc_override(*override)
