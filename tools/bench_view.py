"""How long the Rerun view of a 30-minute tlog takes to open (goal: under 5 s).

    python tools/bench_view.py [--minutes 30] [--keep DIR] [--runs 3]

Makes a tlog of ``--minutes`` of driving from the lockstep sample drive
(:mod:`mecanum_mav.sim.sampledrive`: both of the companion's links at their real rates,
about 125 messages a second: MANUAL sticks, failsafes, an AUTO square), repeated end to end
with its stamps shifted, then times:

- ``read``: reading the tlog (:func:`mecanum_mav.io.tlog.read_tlog`);
- ``view``: the mapping and writing the ``.rrd`` (:func:`mecanum_mav.app.view.write_rrd`);
- ``load``: Rerun reading the ``.rrd`` back whole (``rerun.chunk.RrdReader``), as a viewer
  loads it;
- ``log --view``: what a user types, in a fresh process, until it prints the served web
  viewer's address (the view is up; its summary follows), ``--runs`` times: the wall time and
  the process's own CPU time (user + sys, from ``/proc``; the viewer's process is not in it),
  which other processes on the machine skew less than the wall time; and ``log --rerun --png``
  to its end.

"open" = read + view + load: from the tlog to a recording a viewer has in memory. Prints each
time in seconds, the message and row counts, the sizes, and the machine's load average (1
minute) before and after: a load near the core count means the times were taken under load.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mecanum_mav.app.view import gc_paused, write_rrd
from mecanum_mav.config.params import Params
from mecanum_mav.io.tlog import STAMP_LEN, parse_tlog, read_tlog, tlog_record
from mecanum_mav.sim.sampledrive import sample_drive

GOAL_S = 5.0
"""A 30-minute tlog's view opens in under this (s)."""


def long_tlog(path: Path, minutes: float) -> int:
    """Write ``minutes`` of driving to ``path`` (the sample drive repeated); returns the
    messages written."""
    sample = path.with_suffix(".one.tlog")
    with sample.open("wb") as f:
        sample_drive(f)
    data = sample.read_bytes()
    sample.unlink()
    read = parse_tlog(data)
    records = [(round(e.time_s * 1e6), data[e.offset + STAMP_LEN:
                                            e.offset + STAMP_LEN + len(e.msg.get_msgbuf())])
               for e in read.entries]
    span_us = records[-1][0] - records[0][0] + 100_000
    count = 0
    with path.open("wb") as out:
        shift = 0
        while shift < minutes * 60e6:
            out.write(b"".join(tlog_record(stamp + shift, packet) for stamp, packet in records))
            count += len(records)
            shift += span_us
    return count


def timed_run(command: list[str]) -> float:
    """Wall time of ``command`` run to its end (s); it must succeed."""
    started = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started


def _cpu_s(pid: int) -> float:
    """CPU time (user + sys, s) process ``pid`` has used so far; NaN where ``/proc`` is not."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return math.nan
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def time_to_view(tlog: Path) -> tuple[float, float]:
    """Wall and CPU time from starting ``mecanum-mav log TLOG --view`` (no display: the web
    viewer on a free port) to its printing the viewer's address (s); then Ctrl-C ends it."""
    started = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "mecanum_mav", "log", str(tlog), "--view",
                             "--web-port", "0"], stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "DISPLAY": "", "WAYLAND_DISPLAY": ""})
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            if "the view: http" in line:
                return time.perf_counter() - started, _cpu_s(proc.pid)
        raise RuntimeError("log --view ended without serving its view")
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(20)
        except subprocess.TimeoutExpired:
            proc.kill()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0)
    parser.add_argument("--keep", type=Path, help="keep the tlog and .rrd in this folder")
    parser.add_argument("--runs", type=int, default=3, help="log --view runs (default 3)")
    args = parser.parse_args()
    from rerun.chunk import RrdReader

    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as scratch:
        folder = args.keep or Path(scratch)
        folder.mkdir(parents=True, exist_ok=True)
        tlog, rrd = folder / "long.tlog", folder / "long.rrd"
        messages = long_tlog(tlog, args.minutes)
        started = time.perf_counter()
        with gc_paused(keep=True):  # as 'log' reads
            entries = read_tlog(tlog).entries
        read_s = time.perf_counter() - started
        started = time.perf_counter()
        rows = write_rrd(entries, Params(), rrd)
        view_s = time.perf_counter() - started
        started = time.perf_counter()
        chunks = RrdReader(rrd).stream().to_chunks()
        load_s = time.perf_counter() - started
        shown = [time_to_view(tlog) for _ in range(max(args.runs, 1))]
        cli_s = timed_run([sys.executable, "-m", "mecanum_mav", "log", str(tlog), "--rerun",
                           str(folder / "cli.rrd"), "--png", str(folder / "cli.png")])
        open_s = read_s + view_s + load_s
        print(f"{args.minutes:g} min tlog: {messages} messages, {tlog.stat().st_size / 1e6:.1f} "
              f"MB -> {rows} rows, {len(chunks)} chunks, {rrd.stat().st_size / 1e6:.1f} MB .rrd")
        verdict = "met" if open_s < GOAL_S else "NOT met"
        print(f"read {read_s:.2f} s, view {view_s:.2f} s, load {load_s:.2f} s: "
              f"open {open_s:.2f} s (goal < {GOAL_S:g} s: {verdict})")
        worst = max(wall for wall, _ in shown)
        print(f"log --view (a process of its own, until its viewer is served): "
              f"{', '.join(f'{wall:.2f}' for wall, _ in shown)} s wall, CPU "
              f"{', '.join(f'{cpu:.2f}' for _, cpu in shown)} s "
              f"(goal < {GOAL_S:g} s: {'met' if worst < GOAL_S else 'NOT met'} in the slowest); "
              f"log --rerun --png (the summary and the PNG too, to the end): {cli_s:.2f} s")
        print(f"load average (1 min, {os.cpu_count()} cores): {load_before:.2f} before, "
              f"{os.getloadavg()[0]:.2f} after")
    return 0


if __name__ == "__main__":
    sys.exit(main())
