"""The companion process: two MAVLink links around the rover core, and the loop that runs them.

Everything the rover decides is in :class:`~mecanum_mav.control.core.RoverCore`; the loop that
feeds it what arrives and writes what it returns is :class:`~mecanum_mav.runtime.loop.
ControlLoop` (its one copy: the lockstep harness steps the same loop). This shell opens the
links, builds the loop on an epoll :class:`~mecanum_mav.io.poller.Poller` and the monotonic
clock, runs it pass after pass in one thread (:meth:`Companion.run`, or a thread of its own,
:meth:`Companion.start`) and, on stop (SIGINT, SIGTERM, :meth:`Companion.stop`), ends it with
the loop's shutdown: neutral, then the channels released. Its wake-up pipe (registered on the
poller) lets :meth:`Companion.stop` end a wait at once.

A write never blocks the loop. On a stream link (a serial flight controller, TCP) what is sent
waits in the link and goes to the kernel paced to what the wire carries (the baud rate),
with the override *newest wins*: at 57600 baud one override takes ~5 ms on the wire, so with
1 kHz input the board gets the newest command each time the wire is free, never a queue of old
ones, and the ground-station link never waits for the flight controller's (see
:mod:`mecanum_mav.io.links`). The loop wakes for the pacing too
(:attr:`~mecanum_mav.io.links.Link.next_send_s`).

A link that breaks (serial device gone, TCP connection closed) is reported to the core once
and reopened on its own timer (every 0.5 s, never blocking); when it is back the core is told
before anything else is sent, so the flight controller's first override is neutral (see
:mod:`mecanum_mav.runtime.loop`).

A send that fails is counted per link, logged at WARNING at most once a second per link, and
reported in SYS_STATUS ``errors_comm`` and the status line; it never stops the loop.
"""

from __future__ import annotations

import contextlib
import os
import selectors
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from mecanum_mav.config.params import Params
from mecanum_mav.control.core import COMPANION_COMPID, FC_LINK_COMPID, LinkCounts, RoverCore
from mecanum_mav.io.links import Link, open_link
from mecanum_mav.io.poller import Poller
from mecanum_mav.io.storage import FileStorage
from mecanum_mav.protocol.statustext import Severity
from mecanum_mav.runtime.loop import ControlLoop, link_counts

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
                                   signing_key=gcs_signing_key, tell_refused=True,
                                   clock=clock)
        self.fc: Link = open_link(fc_url, source_system=self.core.identity.fc_gcs_sysid,
                                  source_component=FC_LINK_COMPID, name="fc",
                                  signing_key=fc_signing_key, clock=clock)
        if tlog is not None:
            self.gcs.record_to(tlog)
            self.fc.record_to(tlog)
        self.loop: ControlLoop | None = None
        """The loop, while :meth:`run` runs it (and after)."""
        self._stopping = False  # (a plain flag: the loop reads it every pass)
        self._wake_r, self._wake_w = os.pipe()
        self._thread: threading.Thread | None = None
        self._loop_ident: int | None = None  # the thread running run(), while it runs
        self._ended = threading.Event()  # run() has sent its last overrides
        self._ended.set()
        self._timer: Callable[[float], float] | None = None

    def set_timer(self, action: Callable[[float], float]) -> None:
        """Call ``action(now_s)`` from the loop on the first pass and then whenever the time
        it returned (monotonic s) has come: for something slow-paced beside the rover (the
        progress a person sees, :class:`~mecanum_mav.app.progress.Progress`). It runs in the
        loop's thread between passes: keep it short (no waiting)."""
        self._timer = action
        if self.loop is not None:
            self.loop.set_timer(action)

    def run(self) -> None:
        """Run the loop (:class:`~mecanum_mav.runtime.loop.ControlLoop`) until :meth:`stop`;
        always ends with neutral wheels and released channels."""
        self._ended.clear()
        self._loop_ident = threading.get_ident()
        poller = Poller()
        poller.register(self._wake_r, selectors.EVENT_READ, None)
        loop = self.loop = ControlLoop(self.core, self.gcs, self.fc, clock=self.clock,
                                       poller=poller, woken=self._woken)
        if self._timer is not None:
            loop.set_timer(self._timer)
        run_once = loop.run_once
        try:
            while not self._stopping:
                run_once()
        finally:
            poller.close()
            loop.shutdown()  # all of them, in order (close() lingers)
            self._loop_ident = None
            self._ended.set()

    def _woken(self) -> None:
        """:meth:`stop` wrote to the wake-up pipe: empty it (the loop then looks at the flag)."""
        os.read(self._wake_r, 64)

    def _link_counts(self) -> LinkCounts:
        return link_counts(self.gcs, self.fc)

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
