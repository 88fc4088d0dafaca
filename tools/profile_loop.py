#!/usr/bin/env python3
"""Where the companion's loop spends its CPU: per section, per message, at 50 Hz, 1 kHz and idle.

The real :class:`~mecanum_mav.app.companion.Companion` runs in a thread of this process
between the ground station and flight controller of ``tools/bench_latency.py`` (UDP
loopback); its sections are wrapped with timers of the loop thread's own CPU
(``time.thread_time_ns``), so the harness's work is not counted:

- ``wait``: the poller's ``wait`` (the wake-up: epoll),
- ``read``: reading and parsing what arrived (``ControlLoop._drain`` less the core's ``handle``
  and ``stick_lane``, and less any sends from inside it),
- ``handle``, ``lane``: the core's message handling, and the stick's lane (``stick_lane``
  and, after the send, ``stick_sent``),
- ``tick``, ``housekeeping``: the core's output (a refresh-only wake's too), and the rest,
- ``send override``, ``send other``: packing and writing what goes out,
- ``loop``: everything else in the loop (timers, ``next_due_s``, link upkeep).

Each section's time is given per input message and per loop pass; ``loop`` is the thread's
CPU (``pthread_getcpuclockid``) less the sections. The wrappers cost about 0.3 us each, which
the report does not subtract; caches are colder at 50 Hz and idle than at 1 kHz, which is
why the same code costs several times more there. The harness shares the process (and its
GIL) with the companion, which inflates the loop's share, idle most of all: for absolute
figures use ``tools/bench_latency.py`` (the companion in its own process); this tool is for
where the time goes.

    python tools/profile_loop.py [--seconds 3] [--path udpout|udpin|serial]
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_ends import PATHS
from bench_latency import (
    COMPANION,
    Harness,
    companion_pulse_fn,
    open_harness,
    relay_pulse,
    stick_cycle,
)

from mecanum_mav.app import companion as companion_module
from mecanum_mav.config.params import Params
from mecanum_mav.runtime.loop import ControlLoop

SECTIONS = ("wait", "read", "handle", "lane", "tick", "housekeeping",
            "send override", "send other", "loop")


class Clock:
    """Thread CPU per section; a section's time excludes the sections called inside it."""

    def __init__(self) -> None:
        self.ns = dict.fromkeys(SECTIONS, 0)
        self.passes = 0
        self._stack: list[list[int]] = []  # [start, time spent in inner sections]

    def wrap(self, name: str, function: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*args: Any, **kwargs: Any) -> Any:
            frame = [time.thread_time_ns(), 0]
            self._stack.append(frame)
            try:
                return function(*args, **kwargs)
            finally:
                self._stack.pop()
                spent = time.thread_time_ns() - frame[0]
                self.ns[name] += spent - frame[1]
                if self._stack:
                    self._stack[-1][1] += spent
        return timed

    def reset(self) -> None:
        self.ns = dict.fromkeys(SECTIONS, 0)
        self.passes = 0


def instrumented(clock: Clock, params: Params, gcs_url: str, fc_url: str
                 ) -> companion_module.Companion:
    """A companion whose sections report to ``clock``."""

    class TimedPoller(companion_module.Poller):
        def wait(self, timeout_s: float) -> Any:
            clock.passes += 1
            return clock.wrap("wait", super().wait)(timeout_s)

    companion_module.Poller = TimedPoller  # type: ignore[misc]
    comp = companion_module.Companion(params, gcs_url, fc_url)
    core = comp.core
    for name, attr in (("handle", "handle"), ("lane", "stick_lane"), ("lane", "stick_sent"),
                       ("tick", "tick"), ("housekeeping", "housekeeping")):
        setattr(core, attr, clock.wrap(name, getattr(core, attr)))
    ControlLoop._drain = clock.wrap("read", ControlLoop._drain)  # type: ignore[method-assign]
    for link in (comp.gcs, comp.fc):
        link.send_rc_override = clock.wrap("send override",  # type: ignore[method-assign]
                                           link.send_rc_override)
        link.send_packet = clock.wrap("send override",  # type: ignore[method-assign]
                                      link.send_packet)
        link.send = clock.wrap("send other", link.send)  # type: ignore[method-assign]
    return comp


def measure(clock: Clock, harness: Harness, comp_thread_cpu: Callable[[], int],
            phase: Callable[[], int]) -> tuple[dict[str, int], int, int]:
    clock.reset()
    cpu0 = comp_thread_cpu()
    messages = phase()
    total = comp_thread_cpu() - cpu0
    ns = dict(clock.ns)
    ns["loop"] = max(0, total - sum(v for k, v in ns.items() if k != "loop"))
    return ns, messages, clock.passes


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="length of each phase")
    parser.add_argument("--path", choices=PATHS, default="udpout",
                        help="the companion's transports, as bench_latency's --paths")
    args = parser.parse_args()
    params = Params()
    _, encode = companion_pulse_fn(params)
    cycle = stick_cycle([encode, relay_pulse], {1500, relay_pulse(0)})
    harness = open_harness(args.path, COMPANION, cycle)
    clock = Clock()
    comp = instrumented(clock, params, *harness.urls)
    harness.listening_on(comp.gcs.local_port)
    thread = threading.Thread(target=comp.run, name="companion", daemon=True)
    thread.start()
    assert thread.ident is not None
    loop_clock = time.pthread_getcpuclockid(thread.ident)

    def comp_thread_cpu() -> int:  # the loop thread's CPU time, ns
        return time.clock_gettime_ns(loop_clock)

    try:
        harness.connect()
        harness.arm()
        harness.run_input(50.0, 50, 0.05)
        print(f"# profile_loop: the companion's loop thread, path {args.path}, "
              f"{args.seconds:g} s per phase; "
              f"us of its CPU per input message (and per loop pass)")
        phases: list[tuple[str, Callable[[], int]]] = [
            ("50 Hz", lambda: harness.run_input(50.0, int(50 * args.seconds), 0.05)[0].__len__()),
            ("1 kHz", lambda: len(harness.run_input(1000.0, int(1000 * args.seconds), 0.05)[0])),
        ]

        def idle() -> int:
            harness.pump_until(time.perf_counter() + float(params["FS_INPUT_TMO"]) + 0.2)
            clock.reset()
            harness.pump_until(time.perf_counter() + args.seconds)
            return 0

        rows = []
        for name, phase in phases:
            ns, messages, passes = measure(clock, harness, comp_thread_cpu, phase)
            rows.append((name, ns, messages, passes))
        ns, _, passes = measure(clock, harness, comp_thread_cpu, idle)
        rows.append(("idle", ns, 0, passes))
    finally:
        comp.stop()
        comp.close()
        harness.close()
    print(f"{'section':<14}" + "".join(f"{name:>22}" for name, *_ in rows))
    for section in SECTIONS:
        cells = []
        for _name, ns, messages, passes in rows:
            per_msg = ns[section] / messages / 1000 if messages else float("nan")
            cells.append(f"{per_msg:9.1f} ({ns[section] / max(1, passes) / 1000:7.1f})")
        print(f"{section:<14}" + "".join(f"{c:>22}" for c in cells))
    cells = []
    for _name, ns, messages, passes in rows:
        total = sum(ns.values())
        per_msg = total / messages / 1000 if messages else float("nan")
        cells.append(f"{per_msg:9.1f} ({total / max(1, passes) / 1000:7.1f})")
    print(f"{'total':<14}" + "".join(f"{c:>22}" for c in cells))
    for name, ns, messages, passes in rows:
        seconds = args.seconds
        print(f"{name}: {passes} loop passes, {messages} messages, loop thread "
              f"{100 * sum(ns.values()) / 1e9 / seconds:.2f} % of a core")
    return 0


if __name__ == "__main__":
    sys.exit(main())
