"""bench_latency's verdicts against the floor: the p50 and CPU ratios are paired round by
round and the median taken, so a round that the machine's own noise hit counts once."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))

import pytest
from bench_latency import PhaseResult, paired_ratio


def phase(cpu_per_msg_us: list[float], sent: int = 100) -> PhaseResult:
    """A 1 kHz phase of rounds of ``sent`` commands each, costing these CPU per message."""
    rounds = [PhaseResult(1000.0, sent, [100.0] * sent, us * sent * 1e-6, sent)
              for us in cpu_per_msg_us]
    return PhaseResult(1000.0, sent * len(rounds), [100.0] * sent * len(rounds),
                       sum(r.cpu_s for r in rounds), sent * len(rounds), rounds)


def cpu(ph: PhaseResult) -> float:
    return ph.cpu_per_msg_us


def test_a_round_hit_by_noise_moves_the_cpu_ratio_by_one_vote_not_by_its_size():
    floor = phase([60.0] * 5)
    companion = phase([90.0, 90.0, 90.0, 300.0, 90.0])
    assert companion.cpu_per_msg_us / floor.cpu_per_msg_us == pytest.approx(2.2)  # pooled
    assert paired_ratio(companion, floor, cpu) == pytest.approx(1.5)


def test_rounds_are_compared_with_the_floors_round_of_the_same_turn():
    floor = phase([50.0, 100.0, 50.0])  # the machine slowed down in the second turn
    companion = phase([70.0, 140.0, 70.0])
    assert paired_ratio(companion, floor, cpu) == pytest.approx(1.4)


def test_without_rounds_the_ratio_is_of_the_pooled_figures():
    companion = PhaseResult(1000.0, 10, [100.0] * 10, 900e-6, 10)
    floor = PhaseResult(1000.0, 10, [100.0] * 10, 600e-6, 10)
    assert paired_ratio(companion, floor, cpu) == pytest.approx(1.5)
