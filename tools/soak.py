#!/usr/bin/env python3
"""Soak the companion: 50 Hz sticks with default telemetry for a long time (issue 11.4).

Method
    The real companion process (``python -m mecanum_mav run --gcs URL --fc URL``, default
    parameters, so default telemetry streams) runs between two UDP peers on 127.0.0.1 played by
    this script with tools/bench_latency.py's :class:`~bench_latency.Harness` (OS-assigned
    ports):

    - the ground station sends HEARTBEAT at 1 Hz and MANUAL_CONTROL at 50 Hz on an absolute
      schedule, after arming the rover over COMMAND_LONG. Consecutive sticks always differ and
      each one's expected front-left pulse (computed with the companion's own decoding,
      shaping, mixing and PWM code) is unique within a cycle of several hundred commands, so
      every RC_CHANNELS_OVERRIDE maps back to the command that caused it;
    - the flight controller (a stand-in, not :mod:`mecanum_mav.sim.simfc`, so that this script
      receives every override itself and stamps it in the kernel) sends what ArduPilot Rover
      sends the companion: HEARTBEAT at 1 Hz (MAV_TYPE_GROUND_ROVER, MAV_AUTOPILOT_ARDUPILOTMEGA),
      ATTITUDE at 20 Hz (a slow turn) and WHEEL_DISTANCE at 10 Hz (growing distances), so the
      estimator runs as on a real rover.

    Per reporting interval (``--interval``, default 60 s) it prints the companion's RSS
    (``VmRSS`` of /proc/PID/status at the interval's end), its CPU over the interval (% of one
    core, the kernel's clock of its process), the delay MANUAL_CONTROL sent -> matching override
    received (kernel receive stamp minus the time just before ``sendto``) as p50 / p99 / max,
    the commands with no override of their own (superseded or late, see bench_latency.py), and
    the largest gap between consecutive overrides received, also as a multiple of the refresh
    period 1 / ``OUT_RATE`` (50 ms by default; at 50 Hz input an override goes out per stick,
    so the gaps are ~20 ms), and how long the companion waited, ready to run, for a CPU
    over the interval (the kernel's ``run_delay``: a gap that long is the machine's, not the
    companion's). A one-second warm-up after arming is not counted.

Goals (issue 11.4), checked at the end:
    - RSS grows under 2 MB after the first interval (the largest RSS of the later intervals
      minus the first interval's);
    - latency does not creep: the last interval's median delay is within 1.2x the first's;
    - no gap between overrides exceeds 2 refresh periods.

The exit status is 0 when all goals are met, 1 when one is not, 2 when the companion died or
could not be started or armed.

    python tools/soak.py [--duration 1800] [--interval 60]
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from bench_latency import Harness, SutError, companion_pulse_fn, stick_cycle

from mecanum_mav.config.params import Params
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.io.links import mavlink
from mecanum_mav.protocol.heartbeat import send_gcs_heartbeat
from mecanum_mav.sim.process import CompanionProcess

INPUT_RATE_HZ = 50.0
CHUNK_S = 1.0
"""The ground station's HEARTBEAT goes out between chunks of this many seconds of sticks."""
DRAIN_S = 0.01
"""At the end of a chunk, the last command's override is waited for this long (half a period:
the next chunk keeps the schedule)."""
WARMUP_S = 1.0

FC_TICK_S = 0.05  # ATTITUDE every tick (20 Hz)
FC_WHEEL_EVERY = 2  # WHEEL_DISTANCE every 2nd tick (10 Hz)
FC_HEARTBEAT_EVERY = 20  # HEARTBEAT every 20th tick (1 Hz)
FC_YAW_RATE_RAD_S = 0.1
FC_WHEEL_SPEED_MPS = 0.5

GOAL_RSS_GROWTH_MB = 2.0
GOAL_LATENCY_RATIO = 1.2
GOAL_GAP_PERIODS = 2.0


# ---------------------------------------------------------------------------- the peers

class SoakPeers(Harness):
    """The ground station and a flight controller that also sends ATTITUDE and WHEEL_DISTANCE."""

    def _beat(self) -> None:
        mav = self.fc.mav
        tick = 0
        while not self._closed.wait(FC_TICK_S if self.fc_peer is not None else 0.02):
            if self.fc_peer is None:
                continue
            t_s = tick * FC_TICK_S
            if tick % FC_HEARTBEAT_EVERY == 0:
                self.send_fc(mav.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,
                                                  mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0,
                                                  mavlink.MAV_STATE_ACTIVE))
            yaw = math.remainder(FC_YAW_RATE_RAD_S * t_s, math.tau)
            self.send_fc(mav.attitude_encode(int(t_s * 1000) & 0xFFFFFFFF, 0.0, 0.0, yaw,
                                             0.0, 0.0, FC_YAW_RATE_RAD_S))
            if tick % FC_WHEEL_EVERY == 0:
                d = FC_WHEEL_SPEED_MPS * t_s
                self.send_fc(mav.wheel_distance_encode(int(t_s * 1e6), 4,
                                                       [d, d, d, d] + [0.0] * 12))
            tick += 1


# ---------------------------------------------------------------------------- the companion

# ---------------------------------------------------------------------------- results

@dataclass
class Interval:
    """One reporting interval."""

    end_s: float  # since the measured soak began
    rss_kb: int  # at the end
    cpu_pct: float  # % of one core over the interval
    sent: int = 0
    delays_us: list[float] = field(default_factory=list)  # matched commands only
    overrides: int = 0
    max_gap_ms: float = 0.0
    run_queue_ms: float = float("nan")  # the companion waited for a CPU this long, in all

    def pct(self, q: float) -> float:
        return float(np.percentile(self.delays_us, q)) if self.delays_us else float("nan")

    @property
    def unmatched(self) -> int:
        return self.sent - len(self.delays_us)


@dataclass
class Goal:
    name: str
    value: str
    met: bool


@dataclass
class SoakResult:
    refresh_period_ms: float
    intervals: list[Interval] = field(default_factory=list)
    error: str = ""  # the companion died, or could not be started or armed

    def goals(self) -> list[Goal]:
        ivs = self.intervals
        growth_mb = (max(i.rss_kb for i in ivs[1:]) - ivs[0].rss_kb) / 1024 if len(ivs) > 1 \
            else float("nan")
        ratio = ivs[-1].pct(50) / ivs[0].pct(50) if ivs else float("nan")
        worst_gap = max((i.max_gap_ms for i in ivs), default=float("nan"))
        periods = worst_gap / self.refresh_period_ms
        return [
            Goal(f"RSS growth after the first interval < {GOAL_RSS_GROWTH_MB:g} MB",
                 f"{growth_mb:+.2f} MB", growth_mb < GOAL_RSS_GROWTH_MB),
            Goal(f"last/first interval median delay <= {GOAL_LATENCY_RATIO:g}",
                 f"{ratio:.2f}", ratio <= GOAL_LATENCY_RATIO),
            Goal(f"largest override gap <= {GOAL_GAP_PERIODS:g} refresh periods "
                 f"({GOAL_GAP_PERIODS * self.refresh_period_ms:.0f} ms)",
                 f"{worst_gap:.1f} ms = {periods:.2f} periods", periods <= GOAL_GAP_PERIODS),
        ]

    @property
    def ok(self) -> bool:
        return not self.error and all(g.met for g in self.goals())


HEADER = (f"{'t s':>6} {'RSS MB':>7} {'dRSS MB':>8} {'CPU %':>6} {'sent':>5} {'unmatched':>9} "
          f"{'p50 us':>7} {'p99 us':>7} {'max us':>7} {'overrides':>9} {'max gap ms':>10} "
          f"{'periods':>7} {'CPU wait ms':>11}")


def interval_line(iv: Interval, first: Interval, refresh_period_ms: float) -> str:
    return (f"{iv.end_s:>6.0f} {iv.rss_kb / 1024:>7.2f} {(iv.rss_kb - first.rss_kb) / 1024:>+8.2f} "
            f"{iv.cpu_pct:>6.2f} {iv.sent:>5} {iv.unmatched:>9} {iv.pct(50):>7.0f} "
            f"{iv.pct(99):>7.0f} {max(iv.delays_us, default=float('nan')):>7.0f} "
            f"{iv.overrides:>9} {iv.max_gap_ms:>10.1f} {iv.max_gap_ms / refresh_period_ms:>7.2f}"
            f" {iv.run_queue_ms:>11.1f}")


def summary(result: SoakResult) -> list[str]:
    ivs = result.intervals
    lines = []
    if ivs:
        delays = [d for i in ivs for d in i.delays_us]
        sent = sum(i.sent for i in ivs)
        lines.append(f"all {len(ivs)} intervals: {sent} commands, {sent - len(delays)} unmatched, "
                     f"delay p50 {np.percentile(delays, 50):.0f} us, "
                     f"p99 {np.percentile(delays, 99):.0f} us, max {max(delays):.0f} us; "
                     f"RSS {ivs[0].rss_kb / 1024:.2f} -> {ivs[-1].rss_kb / 1024:.2f} MB; "
                     f"CPU {np.mean([i.cpu_pct for i in ivs]):.2f} % of a core")
        lines += [f"{g.name}: {g.value}: {'met' if g.met else 'NOT MET'}" for g in result.goals()]
    if result.error:
        lines.append(f"ERROR: {result.error}")
    return lines


# ---------------------------------------------------------------------------- the soak

def run_soak(duration_s: float, interval_s: float,
             report: Callable[[str], None] = print) -> SoakResult:
    """Run the soak; ``report`` gets each line as it is measured (the header, one line per
    interval, then the summary)."""
    params = Params()
    refresh_period_ms = 1000.0 / float(params["OUT_RATE"])
    result = SoakResult(refresh_period_ms)
    channel, encode = companion_pulse_fn(params)
    cycle = stick_cycle([encode], {PwmMap.from_params(params).neutral()[0]})
    chunk_n = round(CHUNK_S * INPUT_RATE_HZ)
    chunks_per_interval = max(1, round(interval_s / CHUNK_S))
    intervals = max(1, round(duration_s / (chunks_per_interval * CHUNK_S)))
    report(f"# soak: {intervals} x {chunks_per_interval * CHUNK_S:.0f} s, MANUAL_CONTROL at "
           f"{INPUT_RATE_HZ:.0f} Hz ({len(cycle)} distinct sticks, matched on channel {channel}), "
           f"refresh period {refresh_period_ms:.0f} ms, default telemetry; python "
           f"{platform.python_version()}, {os.cpu_count()} cores")
    peers = SoakPeers(channel, encode, cycle)
    with tempfile.TemporaryDirectory(prefix="mecanum-soak-") as tmp:
        companion = CompanionProcess(*peers.urls, Path(tmp))
        try:
            _soak(peers, companion, result, chunk_n, chunks_per_interval, intervals, report)
        except (SutError, OSError) as exc:  # (OSError: its /proc entry went)
            result.error = f"{exc}\n{companion.log()}"
        finally:
            code = companion.stop()
            peers.close()
        if not result.error and code != 0:
            result.error = f"the companion exited with {code}:\n{companion.log()}"
    for line in summary(result):
        report(line)
    return result


def _soak(peers: SoakPeers, companion: CompanionProcess, result: SoakResult, chunk_n: int,
          chunks_per_interval: int, intervals: int, report: Callable[[str], None]) -> None:
    peers.connect()
    peers.arm()
    period_s = 1.0 / INPUT_RATE_HZ

    def chunk(start: float, interval: Interval | None) -> None:
        send_gcs_heartbeat(peers.gcs.mav)
        delays, overrides = peers.run_input(INPUT_RATE_HZ, chunk_n, DRAIN_S, start)
        peers.gcs_messages.clear()  # telemetry: not needed here, and it would pile up
        if not companion.alive():
            raise SutError(f"the companion died (exit code {companion.proc.returncode})")
        if interval is not None:
            interval.sent += len(delays)
            interval.delays_us += [d for d in delays if d is not None]
            interval.overrides += overrides

    start = time.perf_counter() + 0.002
    for _ in range(round(WARMUP_S / CHUNK_S)):
        chunk(start, None)
        start += chunk_n * period_s
    report(HEADER)
    rx_ns = peers.override_rx_ns = []
    last_rx_ns = 0
    t0 = t_prev = time.perf_counter()
    cpu0, waited0 = companion.cpu_s(), companion.run_queue_s()
    for _ in range(intervals):
        iv = Interval(0.0, 0, 0.0)
        for _ in range(chunks_per_interval):
            chunk(start, iv)
            start += chunk_n * period_s
        stamps = ([last_rx_ns] if last_rx_ns else []) + rx_ns
        iv.max_gap_ms = max(np.diff(stamps), default=0) / 1e6
        last_rx_ns = stamps[-1] if stamps else last_rx_ns
        rx_ns.clear()
        now, cpu, waited = time.perf_counter(), companion.cpu_s(), companion.run_queue_s()
        iv.end_s, iv.rss_kb = now - t0, companion.rss_kb()
        iv.cpu_pct = 100.0 * (cpu - cpu0) / (now - t_prev)
        iv.run_queue_ms = 1e3 * (waited - waited0)
        cpu0, waited0, t_prev = cpu, waited, now
        result.intervals.append(iv)
        report(interval_line(iv, result.intervals[0], result.refresh_period_ms))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=1800.0, metavar="SECONDS",
                        help="measured time after a 1 s warm-up (default 1800)")
    parser.add_argument("--interval", type=float, default=60.0, metavar="SECONDS",
                        help="reporting period, whole seconds (default 60)")
    args = parser.parse_args()
    result = run_soak(args.duration, args.interval, lambda line: print(line, flush=True))
    if result.error:
        return 2
    return 0 if result.ok else 1


if __name__ == "__main__":
    sys.exit(main())
