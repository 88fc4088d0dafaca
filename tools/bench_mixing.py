#!/usr/bin/env python3
"""Benchmark the mixing algorithms: scalar calls (the control loop's path) and batches.

Scalar: microseconds per call of each public algorithm, as percentiles over many timed blocks,
against a baseline measured in the same run: the bare arithmetic of Cartesian mixing with
desaturation written inline in plain Python, returning a tuple (what no API can beat).

Batch: wheel-sets per second for one vectorized call on 1e6 commands, against a plain-Python
loop calling the scalar path on the same commands (timed on a slice and scaled).

Goals (issue 2): scalar path in single-digit microseconds; batch > 5 million wheel-sets/s.

    python tools/bench_mixing.py [--batch 1000000] [--blocks 300] [--calls 200]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import sys
import time
from collections.abc import Callable

import numpy as np

from mecanum_mav.mecanum.mixing import (
    cartesian,
    holonomic_2010,
    max_speed_scaled,
    mix_stick,
    polar_2011,
)


def bare_cartesian(x: float, y: float, r: float) -> tuple[float, float, float, float]:
    """Baseline: Cartesian mixing and proportional desaturation, inline, no checks."""
    fl, fr, rl, rr = x + y + r, x - y - r, x - y + r, x + y - r
    peak = max(abs(fl), abs(fr), abs(rl), abs(rr))
    if peak > 1.0:
        return fl / peak, fr / peak, rl / peak, rr / peak
    return fl, fr, rl, rr


def per_call_us(fn: Callable[..., object], args: tuple[float, ...], blocks: int, calls: int
                ) -> list[float]:
    """Microseconds per call, one sample per block of ``calls`` calls."""
    samples = []
    for _ in range(blocks):
        start = time.perf_counter_ns()
        for _ in range(calls):
            fn(*args)
        samples.append((time.perf_counter_ns() - start) / calls / 1000.0)
    return samples


def pct(samples: list[float], q: float) -> float:
    return float(np.percentile(samples, q))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=1_000_000, help="commands per batch")
    parser.add_argument("--blocks", type=int, default=300, help="timed blocks per scalar case")
    parser.add_argument("--calls", type=int, default=200, help="calls per timed block")
    parser.add_argument("--loop", type=int, default=50_000,
                        help="commands the plain-Python loop baseline runs (scaled up)")
    args = parser.parse_args()
    print(f"# bench_mixing  python {platform.python_version()}  numpy {np.__version__}  "
          f"{platform.machine()}")

    scalar_cases: list[tuple[str, Callable[..., object], tuple[float, ...]]] = [
        ("baseline bare arithmetic", bare_cartesian, (0.5, 0.3, 0.4)),
        ("cartesian", cartesian, (0.5, 0.3, 0.4)),
        ("cartesian field-oriented", cartesian, (0.5, 0.3, 0.4, 30.0)),
        ("polar_2011", polar_2011, (0.6, 30.0, 0.4)),
        ("max_speed_scaled", max_speed_scaled, (0.6, 30.0, 0.4)),
        ("holonomic_2010", holonomic_2010, (0.6, 30.0, 0.4)),
        ("mix_stick polar_2011", lambda x, y, r: mix_stick(x, y, r, "polar_2011"),
         (0.5, 0.3, 0.4)),
    ]
    print("\n## scalar path: microseconds per call "
          f"({args.blocks} blocks x {args.calls} calls)")
    print(f"{'case':<28}{'p50':>8}{'p90':>8}{'p99':>8}{'max':>8}{'x base':>9}")
    base_p50 = None
    worst_p99 = 0.0
    for name, fn, fargs in scalar_cases:
        per_call_us(fn, fargs, 5, args.calls)  # warm up
        s = per_call_us(fn, fargs, args.blocks, args.calls)
        p50 = pct(s, 50)
        base_p50 = base_p50 or p50
        if fn is not bare_cartesian:
            worst_p99 = max(worst_p99, pct(s, 99))
        print(f"{name:<28}{p50:8.2f}{pct(s, 90):8.2f}{pct(s, 99):8.2f}{max(s):8.2f}"
              f"{p50 / base_p50:9.2f}")

    n = args.batch
    rng = np.random.default_rng(1)
    x, y, r = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
    m, d = rng.uniform(0, 1, n), rng.uniform(-180, 180, n)
    batch_cases: list[tuple[str, Callable[..., np.ndarray], tuple[np.ndarray, ...]]] = [
        ("cartesian", cartesian, (x, y, r)),
        ("cartesian field-oriented", cartesian, (x, y, r, d)),
        ("polar_2011", polar_2011, (m, d, r)),
        ("max_speed_scaled", max_speed_scaled, (m, d, r)),
        ("holonomic_2010", holonomic_2010, (m, d, r)),
    ]
    k = min(args.loop, n)
    print(f"\n## batch path: wheel-sets per second ({n:,} commands; plain-Python loop over "
          f"{k:,} commands, scaled)")
    print(f"{'case':<28}{'vector /s':>14}{'loop /s':>12}{'speed-up':>10}{'ms/batch':>10}")
    worst_rate = float("inf")
    for name, fn, vargs in batch_cases:
        fn(*(a[:1000] for a in vargs))  # warm up
        times = []
        for _ in range(3):
            start = time.perf_counter()
            out = fn(*vargs)
            times.append(time.perf_counter() - start)
        assert out.shape == (n, 4)
        best = min(times)
        lists = [a[:k].tolist() for a in vargs]
        start = time.perf_counter()
        for row in zip(*lists, strict=True):
            fn(*row)
        loop_rate = k / (time.perf_counter() - start)
        rate = n / best
        worst_rate = min(worst_rate, rate)
        print(f"{name:<28}{rate:14,.0f}{loop_rate:12,.0f}{rate / loop_rate:10.1f}"
              f"{statistics.median(times) * 1e3:10.1f}")

    ok_scalar = worst_p99 < 10.0
    ok_batch = worst_rate > 5e6
    print(f"\ngoal scalar p99 < 10 us: {'met' if ok_scalar else 'MISSED'} "
          f"(worst p99 {worst_p99:.2f} us)")
    print(f"goal batch > 5,000,000 wheel-sets/s: {'met' if ok_batch else 'MISSED'} "
          f"(slowest {worst_rate:,.0f}/s)")
    return 0 if ok_scalar and ok_batch else 1


if __name__ == "__main__":
    sys.exit(main())
