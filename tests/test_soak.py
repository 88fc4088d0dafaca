"""60 s of the soak tool (tools/soak.py, issue 11.4) against the real companion process.

The companion runs as ``python -m mecanum_mav run`` between a ground station sending
MANUAL_CONTROL at 50 Hz (and HEARTBEAT at 1 Hz) and a flight controller sending HEARTBEAT,
ATTITUDE and WHEEL_DISTANCE, default telemetry on. Three reporting intervals of 20 s, the first
standing for the first minute: RSS grows under 2 MB after it, as the issue's goal says, and the
overrides keep flowing: no gap between two of them reaches the override timeout setup-fc gives
the board (RC_OVERRIDE_TIME 0.5 s; a longer gap would make it lapse) by more than the time
the companion waited, ready to run, for a CPU in that interval (a starved machine's share of a
gap: the kernel's run_delay, on each interval's line). The tool's
own goal for the gaps, at most two refresh periods (100 ms) of wall-clock time, is its figure
(printed, in refresh periods); the refresh itself is asserted exactly in virtual time
(test_companion.py, ``test_overrides_are_refreshed_*``).

The tool's third goal, the last interval's median delay within 1.2x the first's, is a speed
figure for its 30-minute run (quoted in docs/benchmarks.md) and is printed here but not
asserted: over one minute a ratio of two medians of ~60-300 us follows the machine, not the
companion (measured 1.20, 1.43 and 2.24 on runs whose CPU, RSS and gaps were all flat). What
this test asserts instead is the failure that goal exists to catch, in a form the machine's
drift cannot fake or hide: no queue builds up. If the companion fell behind by even one stick,
every later stick would wait a whole input period (20 ms) behind it, so each interval's median
delay stays under half an input period: clear of both the healthy medians (tens to hundreds of
microseconds) and a companion one stick behind (measured: medians 20,058-20,126 us, ratio 1.00,
which the ratio of medians passes).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))

import soak

from mecanum_mav.protocol.fcsetup import SAFE_OVERRIDE_TIME_S

DURATION_S = 60.0
INTERVAL_S = 20.0
NO_QUEUE_MEDIAN_US = 0.5e6 / soak.INPUT_RATE_HZ  # half an input period


def _waited_ms(interval: soak.Interval) -> float:
    """How long the companion waited, ready to run, for a CPU in ``interval`` (0 where the
    kernel does not say)."""
    return interval.run_queue_ms if math.isfinite(interval.run_queue_ms) else 0.0


@pytest.mark.slow
# The suite's other minute of real time (the twin's mission, tests/test_twin_mission.py) runs
# before or after, not beside.
@pytest.mark.xdist_group("a minute of real time")
def test_a_minute_of_50_hz_sticks_keeps_memory_flat_builds_no_queue_and_overrides_never_lapse():
    lines: list[str] = []
    result = soak.run_soak(DURATION_S, INTERVAL_S, lines.append)
    report = "\n".join(lines)
    print(report)
    assert not result.error, report
    assert len(result.intervals) == round(DURATION_S / INTERVAL_S), report
    assert all(iv.sent == INTERVAL_S * soak.INPUT_RATE_HZ for iv in result.intervals), report
    rss, _creep, _gaps = result.goals()  # creep: the tool's 1.2x, for the 30-minute run
    assert rss.met, report
    # a gap the companion's own wait for a CPU in that interval accounts for is the machine's
    # (the full suite shares two cores: measured once, 803 ms with 2101 ms of run-queue wait)
    assert all(iv.max_gap_ms < SAFE_OVERRIDE_TIME_S * 1e3 + _waited_ms(iv)
               for iv in result.intervals), report
    assert all(iv.pct(50) < NO_QUEUE_MEDIAN_US for iv in result.intervals), report
