#!/usr/bin/env python3
"""A/B: the companion at two revisions against the floor relay, paired, in one run.

Why
    On this 2-core VM one run of ``tools/bench_latency.py`` moves by 10-20 % from the next
    (the companion's CPU per message at 1 kHz measured 1.38-1.72x the floor's in runs of the
    same code), so a change worth a few microseconds cannot be judged from two runs made
    before and after it. This tool runs both versions side by side and compares them round by
    round.

Method
    Three systems under test on 127.0.0.1, each in its own process and driven by its own
    :class:`bench_latency.Harness` (a ground station sending MANUAL_CONTROL, a flight
    controller sending HEARTBEAT at 2 Hz and receiving the overrides):

    - ``floor``: :func:`bench_latency.run_floor`, the least a correct Python relay does;
    - ``base``: the companion at revision ``--base`` (default ``HEAD``: the last commit),
      its ``mecanum_mav`` taken with ``git archive`` into a temporary folder;
    - ``head``: the companion in this working tree (uncommitted changes included), or at
      ``--head`` when given.

    Each companion is ``python -m mecanum_mav run --gcs udpout:... --fc udpout:...`` on the
    default parameters, started in its tree's folder (so that tree's package is the one
    imported), armed over COMMAND_LONG. Its CPU is read from the kernel's precise clock of
    the process (``clock_gettime`` on the process's CPU clock id), before and after each
    round. Rounds alternate the order of the three (forward, then reversed) so drift lands on
    all alike; each round sends ``--per-round`` sticks at ``--rate``.

Report
    Per system: CPU per message (us), p50 and p99 of the stick-to-override delay (as
    ``bench_latency`` measures it), and the ratio to the floor. Then head against base per
    round: the median ratio of their CPU per message and of their p50, and in how many rounds
    head was the cheaper: a change that holds in most rounds is real; one that does not is
    noise, whatever the totals say.

    python tools/bench_ab.py [--base REV] [--head REV] [--rate 1000] [--rounds 10]
                             [--per-round 300]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import bench_latency as bl

from mecanum_mav.config.params import Params

ROOT = Path(__file__).resolve().parent.parent
FLOOR, BASE, HEAD = "floor", "base", "head"
_CPUCLOCK_SCHED = 2  # Linux: a process's CPU clock id is (~pid << 3) | CPUCLOCK_SCHED


def export_tree(revision: str, into: Path) -> Path:
    """``mecanum_mav`` at ``revision`` (a git revision) extracted under ``into``."""
    archive = subprocess.Popen(["git", "-C", str(ROOT), "archive", "--format=tar", revision,
                                "mecanum_mav"], stdout=subprocess.PIPE)
    assert archive.stdout is not None
    with tarfile.open(fileobj=archive.stdout, mode="r|") as tar:
        if hasattr(tarfile, "data_filter"):  # (Python 3.10.12, 3.11.4 and later)
            tar.extractall(into, filter="data")
        else:  # pragma: no cover
            tar.extractall(into)
    if archive.wait() != 0:
        raise SystemExit(f"bench_ab: git archive {revision} failed")
    return into


class CompanionProcess:
    """``python -m mecanum_mav run`` from ``tree``; its CPU from the kernel's process clock."""

    def __init__(self, tree: Path, gcs_url: str, fc_url: str) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "mecanum_mav", "run", "--gcs", gcs_url, "--fc", fc_url],
            cwd=tree, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL)
        self._clock = (~self.process.pid << 3) | _CPUCLOCK_SCHED

    def cpu_s(self) -> float:
        """CPU seconds (user + system, all threads) the process has used so far."""
        if self.process.poll() is not None:
            raise bl.SutError(f"companion exited with status {self.process.returncode}")
        return time.clock_gettime(self._clock)

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(5.0)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(2.0)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", default="HEAD", help="the revision to compare against")
    parser.add_argument("--head", default=None,
                        help="a revision instead of this working tree")
    parser.add_argument("--rate", type=float, default=1000.0, help="sticks per second")
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--per-round", type=int, default=300, help="sticks per round")
    args = parser.parse_args()
    if args.rounds < 2 or args.per_round < 10 or not 1.0 <= args.rate <= 5000.0:
        parser.error("need --rounds >= 2, --per-round >= 10 and 1 <= --rate <= 5000")
    params = Params()
    channel, encode = bl.companion_pulse_fn(params)
    cycle = bl.stick_cycle([encode, bl.relay_pulse], {1500, bl.relay_pulse(0)})
    harnesses: dict[str, bl.Harness] = {}
    suts: dict[str, bl.SutProcess | CompanionProcess] = {}
    with tempfile.TemporaryDirectory(prefix="bench_ab-") as tmp:
        trees = {BASE: export_tree(args.base, Path(tmp) / "base"),
                 HEAD: ROOT if args.head is None else export_tree(args.head, Path(tmp) / "head")}
        try:
            for kind in (FLOOR, BASE, HEAD):
                relay = kind == FLOOR
                harness = harnesses[kind] = bl.Harness(1 if relay else channel,
                                                       bl.relay_pulse if relay else encode,
                                                       cycle)
                suts[kind] = (bl.SutProcess(kind, *harness.urls, profile=False) if relay
                              else CompanionProcess(trees[kind], *harness.urls))
                harness.connect()
                if not relay:
                    harness.arm()
                harness.run_input(200.0, 20, drain_s=0.05)
            print(f"# bench_ab: base {args.base}, head {args.head or 'the working tree'}; "
                  f"{args.rounds} rounds of {args.per_round} sticks at {args.rate:g} Hz, "
                  f"python {sys.version.split()[0]}, {os.cpu_count()} cores")
            rounds = measure(harnesses, suts, args.rounds, args.per_round, args.rate)
        finally:
            for sut in suts.values():
                with contextlib.suppress(Exception):
                    sut.kill()
            for harness in harnesses.values():
                harness.close()
    report(rounds)
    return 0


Round = dict[str, tuple[float, list[float]]]
"""One round: per system, (CPU per message in us, the matched delays in us)."""


def measure(harnesses: dict[str, bl.Harness],
            suts: dict[str, bl.SutProcess | CompanionProcess],
            rounds: int, per_round: int, rate: float) -> list[Round]:
    """``rounds`` rounds of ``per_round`` sticks at ``rate`` to each system in turn."""
    order = [FLOOR, BASE, HEAD]
    out: list[Round] = []
    for index in range(rounds):
        this: Round = {}
        for kind in (order if index % 2 == 0 else order[::-1]):
            cpu0 = suts[kind].cpu_s()
            delays, _ = harnesses[kind].run_input(rate, per_round, drain_s=0.05)
            cpu_us = 1e6 * (suts[kind].cpu_s() - cpu0) / per_round
            this[kind] = (cpu_us, [d for d in delays if d is not None])
        out.append(this)
    return out


def _pct(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q / 100.0 * len(ordered)))] if ordered else (
        float("nan"))


def report(rounds: list[Round]) -> None:
    """Totals per system, then head against base round by round."""
    cpu = {k: statistics.fmean(r[k][0] for r in rounds) for k in (FLOOR, BASE, HEAD)}
    print(f"{'system':<7} {'CPU/msg us':>10} {'p50 us':>7} {'p99 us':>7} {'x floor':>8}")
    for kind in (FLOOR, BASE, HEAD):
        delays = [d for r in rounds for d in r[kind][1]]
        print(f"{kind:<7} {cpu[kind]:>10.1f} {_pct(delays, 50):>7.0f} {_pct(delays, 99):>7.0f} "
              f"{cpu[kind] / cpu[FLOOR]:>8.2f}")
    cpu_ratios = [r[HEAD][0] / r[BASE][0] for r in rounds]
    p50_ratios = [_pct(r[HEAD][1], 50) / _pct(r[BASE][1], 50) for r in rounds]
    cheaper = sum(ratio < 1.0 for ratio in cpu_ratios)
    print(f"head/base CPU per message, median of {len(rounds)} rounds: "
          f"{statistics.median(cpu_ratios):.3f} (head cheaper in {cheaper} of {len(rounds)})")
    print(f"head/base p50 delay, median of {len(rounds)} rounds: "
          f"{statistics.median(p50_ratios):.3f} "
          f"(head faster in {sum(ratio < 1.0 for ratio in p50_ratios)} of {len(rounds)})")


if __name__ == "__main__":
    sys.exit(main())
