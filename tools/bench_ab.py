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
    controller sending HEARTBEAT at 2 Hz and receiving the overrides; with ``--path serial``
    the flight controller is the master end of a pty, as in ``bench_latency``'s serial
    path):

    - ``floor``: :func:`bench_latency.run_floor`, the least a correct Python relay does;
    - ``base``: the companion at revision ``--base`` (default ``HEAD``: the last commit),
      its ``mecanum_mav`` taken with ``git archive`` into a temporary folder;
    - ``head``: the companion in this working tree (uncommitted changes included), or at
      ``--head`` when given.

    Each companion is ``python -m mecanum_mav run --gcs udpout:... --fc udpout:...`` (``--fc
    PTY,BAUD`` on the serial path) on the
    default parameters (:class:`mecanum_mav.sim.process.CompanionProcess`, its tree's package
    imported), armed over COMMAND_LONG. Its CPU is read from the kernel's clock of the
    process (:func:`mecanum_mav.sim.process.process_cpu_s`), before and after each round.
    Rounds alternate the order of the three (forward, then reversed) so drift lands on all
    alike; each round sends ``--per-round`` sticks at ``--rate``.

Report
    Per system: CPU per message (us), p50 and p99 of the stick-to-override delay (as
    ``bench_latency`` measures it), and the ratio to the floor. Then head against base per
    round: the median ratio of their CPU per message and of their p50, and in how many rounds
    head was the cheaper: a change that holds in most rounds is real; one that does not is
    noise, whatever the totals say.

    python tools/bench_ab.py [--base REV] [--head REV] [--path udpout|serial] [--rate 1000]
                             [--rounds 10] [--per-round 300]
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
from pathlib import Path

import bench_latency as bl

from mecanum_mav.config.params import Params
from mecanum_mav.sim.process import CompanionProcess

ROOT = Path(__file__).resolve().parent.parent
FLOOR, BASE, HEAD = "floor", "base", "head"
SYSTEMS = (FLOOR, BASE, HEAD)


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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", default="HEAD", help="the revision to compare against")
    parser.add_argument("--head", default=None,
                        help="a revision instead of this working tree")
    parser.add_argument("--path", choices=("udpout", "serial"), default="udpout",
                        help="the flight controller's link: UDP, or a serial line (a pty at "
                             f"{bl.SERIAL_BAUD} baud)")
    parser.add_argument("--rate", type=float, default=1000.0, help="sticks per second")
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--per-round", type=int, default=300, help="sticks per round")
    args = parser.parse_args()
    if args.rounds < 2 or args.per_round < 10 or not 1.0 <= args.rate <= 5000.0:
        parser.error("need --rounds >= 2, --per-round >= 10 and 1 <= --rate <= 5000")
    _, encode = bl.companion_pulse_fn(Params())
    cycle = bl.stick_cycle([encode, bl.relay_pulse], {1500, bl.relay_pulse(0)})
    harnesses: dict[str, bl.Harness] = {}
    suts: dict[str, bl.SutProcess | CompanionProcess] = {}
    with tempfile.TemporaryDirectory(prefix="bench_ab-") as tmp:
        trees = {BASE: export_tree(args.base, Path(tmp) / "base"),
                 HEAD: ROOT if args.head is None else export_tree(args.head, Path(tmp) / "head")}
        try:
            for kind in SYSTEMS:
                relay = kind == FLOOR
                harness = harnesses[kind] = bl.open_harness(args.path, kind, cycle)
                suts[kind] = (bl.SutProcess(kind, *harness.urls, profile=False) if relay
                              else CompanionProcess(*harness.urls, Path(tmp) / f"run-{kind}",
                                                    package_root=trees[kind]))
                harness.connect()
                if not relay:
                    harness.arm()
                harness.run_input(200.0, 20, drain_s=0.05)
            print(f"# bench_ab: base {args.base}, head {args.head or 'the working tree'}; "
                  f"path {args.path}, {args.rounds} rounds of {args.per_round} sticks at "
                  f"{args.rate:g} Hz, "
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


Round = dict[str, bl.PhaseResult]
"""One round: each system's sticks, delays and CPU."""


def measure(harnesses: dict[str, bl.Harness],
            suts: dict[str, bl.SutProcess | CompanionProcess],
            rounds: int, per_round: int, rate: float) -> list[Round]:
    """``rounds`` rounds of ``per_round`` sticks at ``rate`` to each system in turn."""
    out: list[Round] = []
    for index in range(rounds):
        this: Round = {}
        for kind in (SYSTEMS if index % 2 == 0 else SYSTEMS[::-1]):
            sut = suts[kind]
            if isinstance(sut, CompanionProcess) and not sut.alive():
                raise SystemExit(f"bench_ab: the {kind} companion exited:\n{sut.log()}")
            cpu0 = sut.cpu_s()
            delays, overrides = harnesses[kind].run_input(rate, per_round, drain_s=0.05)
            this[kind] = bl.PhaseResult(rate, per_round, delays, sut.cpu_s() - cpu0, overrides)
        out.append(this)
    return out


def report(rounds: list[Round]) -> None:
    """Totals per system, then head against base round by round."""
    pooled = {kind: bl.PhaseResult(rounds[0][kind].rate_hz,
                                   sum(r[kind].sent for r in rounds),
                                   [d for r in rounds for d in r[kind].delays_us],
                                   sum(r[kind].cpu_s for r in rounds),
                                   sum(r[kind].overrides for r in rounds))
              for kind in SYSTEMS}
    floor_cpu = pooled[FLOOR].cpu_per_msg_us
    print(f"{'system':<7} {'CPU/msg us':>10} {'p50 us':>7} {'p99 us':>7} {'x floor':>8}")
    for kind, result in pooled.items():
        print(f"{kind:<7} {result.cpu_per_msg_us:>10.1f} {result.pct(50):>7.0f} "
              f"{result.pct(99):>7.0f} {result.cpu_per_msg_us / floor_cpu:>8.2f}")
    for what, better, ratios in (
            ("CPU per message", "cheaper",
             [r[HEAD].cpu_per_msg_us / r[BASE].cpu_per_msg_us for r in rounds]),
            ("p50 delay", "faster", [r[HEAD].pct(50) / r[BASE].pct(50) for r in rounds])):
        won = sum(ratio < 1.0 for ratio in ratios)
        print(f"head/base {what}, median of {len(rounds)} rounds: "
              f"{statistics.median(ratios):.3f} (head {better} in {won} of {len(rounds)})")


if __name__ == "__main__":
    sys.exit(main())
