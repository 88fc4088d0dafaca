"""The companion process: two MAVLink links around the rover core.

Everything the rover decides is in :class:`~mecanum_mav.control.core.RoverCore`; this shell
opens the links, feeds the core what arrives, writes what it returns, and shuts down in order.
One thread, one loop (:meth:`Companion.run`), top to bottom:

1. Wait until a link is readable or the core's next timer is due (epoll,
   :class:`~mecanum_mav.io.poller.Poller`; it never polls, so an idle companion uses no CPU);
   then the shell's own slow timer (:meth:`Companion.set_timer`, once a second), if due.
2. Read everything waiting on a link; each message goes to ``core.handle`` and its answers
   out at once. Under overload this drains the queue and the core acts on the newest stick.
   On a datagram link the first datagram is answered before the rest are read: the pilot's
   MANUAL_CONTROL takes the core's lane (``core.stick_lane``, compiled in
   :mod:`mecanum_mav.control.lane`: the datagram to the override's packet in one call) and
   the packet goes out before anything else is done (unsigned links only).
3. ``core.tick``: its RC_CHANNELS_OVERRIDE goes out at once; then ``core.housekeeping``:
   odometry, telemetry, heartbeats and status texts (after a stick the lane answered the
   tick has nothing to do, and housekeeping takes the odometry, after the send). Each is
   skipped while the core is :meth:`~mecanum_mav.control.core.RoverCore.settled` (no timer
   due, nothing new): an idle rover's refresh wake is the refresh alone. (Not with a
   stream link, whose pacing needs step 4 every pass.)
4. Each link hands over what still waits in it (:func:`~mecanum_mav.io.links.follow`).
5. On stop (SIGINT, SIGTERM, :meth:`Companion.stop`): neutral, then the channels released.

A write never blocks the loop. On a stream link (a serial flight controller, TCP) what is sent
waits in the link and goes to the kernel paced to what the wire carries (the baud rate),
with the override *newest wins*: at 57600 baud one override takes ~5 ms on the wire, so with
1 kHz input the board gets the newest command each time the wire is free, never a queue of old
ones, and the ground-station link never waits for the flight controller's (see
:mod:`mecanum_mav.io.links`). The loop wakes for the pacing too
(:attr:`~mecanum_mav.io.links.Link.next_send_s`).

A link that breaks (serial device gone, TCP connection closed) is reported to the core once
(``core.link_down``: its failsafe fires now), leaves the selector (its dead descriptor would
wake the loop at once, forever), and is reopened on its own timer
(:meth:`~mecanum_mav.io.links.Link.reopen`, every 0.5 s, never blocking); when it is back the
core is told (``core.link_up``) before anything else is sent, so the flight controller's first
override is neutral. A ``tcpin`` link waits for its next client instead.

A send that fails is counted per link, logged at WARNING at most once a second per link, and
reported in SYS_STATUS ``errors_comm`` and the status line; it never stops the loop.
"""

from __future__ import annotations

import contextlib
import math
import os
import selectors
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, BinaryIO

from mecanum_mav.config.params import Params
from mecanum_mav.control.core import (
    COMPANION_COMPID,
    FC_LINK_COMPID,
    NOTHING,
    LinkCounts,
    Outbox,
    RcOverride,
    RoverCore,
)
from mecanum_mav.io.links import Link, follow, open_link
from mecanum_mav.io.poller import READABLE, Poller
from mecanum_mav.io.storage import FileStorage
from mecanum_mav.protocol.statustext import Severity

__all__ = ["Companion"]

FC_CLOSE_LINGER_S = 0.3
"""On a stream link (TCP, serial) the shell waits up to this long for its last overrides to
reach the flight controller before closing (see :meth:`~mecanum_mav.io.links.Link.close`)."""


class Companion:
    """The companion process's links and loop around a :class:`RoverCore`.

    Args:
        params: the parameter store (the core changes it on PARAM_SET).
        gcs_url: pymavlink URL of the ground-station link.
        fc_url: pymavlink URL of the flight-controller link.
        param_path: the parameter file the companion was started with; accepted PARAM_SETs
            are saved to it and the mission beside it.
        tlog: an open binary file to record both links' traffic to, or None.
        clock: monotonic time source in seconds.
        gcs_signing_key, fc_signing_key: each link's 32-byte MAVLink 2 signing key, or None
            (see :class:`~mecanum_mav.io.links.Link`): with a key the link signs what it
            sends and reads only correctly signed, fresh packets; the ones it drops are
            counted and reported as :attr:`~mecanum_mav.control.refusals.Refusal.SIGNATURE`.
    """

    def __init__(self, params: Params, gcs_url: str, fc_url: str, *,
                 param_path: Path | None = None, tlog: BinaryIO | None = None,
                 clock: Callable[[], float] = time.monotonic,
                 gcs_signing_key: bytes | None = None,
                 fc_signing_key: bytes | None = None) -> None:
        self.clock = clock
        storage = None if param_path is None else FileStorage(param_path)
        mission, problem = ([], "") if storage is None else storage.load_mission()
        self.core = RoverCore(params, now_s=clock(), mission=mission, storage=storage,
                              link_counts=self._link_counts)
        if problem:
            self.core.say(Severity.ERROR, problem)
        self.gcs: Link = open_link(gcs_url, source_system=self.core.identity.sysid,
                                   source_component=COMPANION_COMPID, name="gcs",
                                   signing_key=gcs_signing_key, tell_refused=True)
        self.fc: Link = open_link(fc_url, source_system=self.core.identity.fc_gcs_sysid,
                                  source_component=FC_LINK_COMPID, name="fc",
                                  signing_key=fc_signing_key)
        self._fc_mav = self.fc.mav
        self._gcs_datagrams = self.gcs if self.gcs.steady else None
        """The ground station's link when it is a datagram link (its first datagram waiting
        is answered before the rest are read)."""
        self._lane_links = self.gcs.unchecked and self.fc.unchecked
        """The stick lane may answer (its packets are unsigned; keys are fixed at start)."""
        if tlog is not None:
            self.gcs.record_to(tlog)
            self.fc.record_to(tlog)
        self._up = {self.gcs: True, self.fc: True}
        self._stopping = False  # (a plain flag: the loop reads it every pass)
        self._wake_r, self._wake_w = os.pipe()
        self._thread: threading.Thread | None = None
        self._loop_ident: int | None = None  # the thread running run(), while it runs
        self._ended = threading.Event()  # run() has sent its last overrides
        self._ended.set()
        self._timer: Callable[[float], float] | None = None
        self._timer_due_s = math.inf

    def set_timer(self, action: Callable[[float], float]) -> None:
        """Call ``action(now_s)`` from the loop on the first pass and then whenever the time
        it returned (monotonic s) has come: for something slow-paced beside the rover (the
        progress a person sees, :class:`~mecanum_mav.app.progress.Progress`). It runs in the
        loop's thread between passes: keep it short (no waiting)."""
        self._timer, self._timer_due_s = action, -math.inf

    def run(self) -> None:
        """Run until :meth:`stop`; always ends with neutral wheels and released channels."""
        core = self.core
        self._ended.clear()
        self._loop_ident = threading.get_ident()
        selector = Poller()
        selector.register(self._wake_r, selectors.EVENT_READ, None)
        gcs, fc = self.gcs, self.fc
        registered = {link: follow(selector, link, None, link) for link in (gcs, fc)}
        streams = {link: fd for link, fd in registered.items() if not link.steady}
        try:
            while not self._stopping:
                due = min(core.next_due_s(), gcs.next_reopen_s, fc.next_reopen_s,
                          gcs.next_send_s, fc.next_send_s, self._timer_due_s)
                for link, events in selector.wait(due - self.clock()):
                    if link is None:
                        os.read(self._wake_r, 64)
                    elif events & READABLE:  # (writable: follow() flushes)
                        self._drain(link)
                now = self.clock()
                if now >= self._timer_due_s and self._timer is not None:
                    self._timer_due_s = self._timer(now)
                if not streams and core.settled(now):
                    continue  # nothing arrived and nothing is due
                for link in streams:  # (a datagram link never goes down)
                    if not link.up and link.reopen(now):
                        self._report(link, now)  # before anything else goes out on it
                out = core.tick(now)
                if out is not NOTHING:
                    self._write(out)  # the override first,
                if not streams and core.settled(now):
                    continue  # the pass was the output's refresh: nothing else is due
                out = core.housekeeping(now)
                if out is not NOTHING:
                    self._write(out)  # then everything else
                for link, fd in streams.items():
                    self._report(link, now)
                    streams[link] = follow(selector, link, fd, link)
        finally:
            selector.close()
            self.fc.mav.srcSystem = core.identity.fc_gcs_sysid
            for override in core.shutdown():  # all of them, in order (close() lingers)
                self.fc.send_rc_override(*override, replace=False)
            self._loop_ident = None
            self._ended.set()

    def _drain(self, link: Link) -> None:
        """Read what waits on ``link`` and answer it: on a datagram link from the ground
        station the first datagram is answered before the rest is read (a pilot's stick in
        the core's lane, its override packed in one call and sent before anything else is
        done; else parsed and handed to the core); the rest goes to the core in order."""
        now, from_fc = self.clock(), link is self.fc
        if link is self._gcs_datagrams:  # the first datagram is answered first:
            got = link.receive_datagram()
            if got is not None:
                data, address = got
                packet = (self.core.stick_lane(data, now, self._fc_mav.seq)
                          if self._lane_links else None)
                if packet is not None:  # the pilot's stick, in its lane: sent at once
                    self.fc.send_packet(packet)
                    self.core.stick_sent()
                    link.answered(data, address)
                else:
                    self._answer(link.parse_datagram(data, address), now, from_fc=False)
        messages = link.read()
        if link.signature_check is not None:
            rejected = link.take_rejections()
            if rejected:  # unsigned or badly signed: counted, said at most once a second
                self.core.refuse_unsigned(rejected, now, from_fc=from_fc)
        if not link.steady:
            self._report(link, now)  # it broke, or a tcpin client connected: the core first
        if messages:
            self._answer(messages, now, from_fc=from_fc)

    def _answer(self, messages: list[Any], now: float, *, from_fc: bool) -> None:
        """Hand ``messages`` to the core and send its answers."""
        handle = self.core.handle
        for msg in messages:
            out = handle(msg, now, from_fc=from_fc)
            if out is not NOTHING:  # a stick is answered by the tick, not here
                self._write(out)

    def _report(self, link: Link, now: float) -> None:
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
        if out is NOTHING:
            return
        if out.override is not None:  # first: the latency-critical part
            self._send_override(out.override)
        if out.fc:
            self.fc.send_all(out.fc)
        if out.gcs:
            self.gcs.send_all(out.gcs)

    def _send_override(self, override: RcOverride) -> None:
        self._fc_mav.srcSystem = self.core.identity.fc_gcs_sysid  # FC_GCS_SYSID may change
        self.fc.send_rc_override(*override)

    def _link_counts(self) -> LinkCounts:
        gcs, fc = self.gcs, self.fc
        return LinkCounts(gcs.received + fc.received, gcs.bad + fc.bad,
                          gcs.send_errors + fc.send_errors)

    # ================================================================== lifecycle

    def start(self) -> None:
        """Run the loop in a background thread (tests, tools)."""
        self._thread = threading.Thread(target=self.run, name="companion", daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 5.0) -> None:
        """Ask the loop to end (neutral, then release) and wait for it, in whichever thread
        it runs (:meth:`start`'s or the caller's own), unless called from that thread (a
        signal handler): then it ends when the handler returns. Idempotent."""
        self._stopping = True
        with contextlib.suppress(OSError):
            os.write(self._wake_w, b"x")
        if self._loop_ident is not None and self._loop_ident != threading.get_ident():
            self._ended.wait(timeout_s)
        if self._thread is not None:
            self._thread.join(timeout_s)
            self._thread = None

    def close(self) -> None:
        """Stop and close both links."""
        self.stop()
        self.gcs.close()
        self.fc.close(linger_s=FC_CLOSE_LINGER_S)  # the release must reach the board
        for fd in (self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)
