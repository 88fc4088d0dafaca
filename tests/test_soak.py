"""60 s of the soak tool (tools/soak.py, issue 11.4) against the real companion process.

The companion runs as ``python -m mecanum_mav run`` between a ground station sending
MANUAL_CONTROL at 50 Hz (and HEARTBEAT at 1 Hz) and a flight controller sending HEARTBEAT,
ATTITUDE and WHEEL_DISTANCE, default telemetry on. Three reporting intervals of 20 s, the first
standing for the first minute: RSS grows under 2 MB after it, and no gap between overrides
exceeds two refresh periods, as the issue's goals say.

Latency creep is asserted more loosely here than the tool's goal (last/first median within
1.2x, met in the 30-minute run quoted in docs/benchmarks.md): a minute is too short for a
raw ratio of medians to be free of the machine's own drift (measured 1.20 and 1.43 on a
machine where other work came and went), while the failure it guards against, a standing
queue or a leak, grows the delay many times over. ``CI_CREEP_LIMIT`` catches that.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))

import soak

DURATION_S = 60.0
INTERVAL_S = 20.0
CI_CREEP_LIMIT = 2.0


def test_a_minute_of_50_hz_sticks_keeps_memory_flat_latency_steady_and_overrides_flowing():
    lines: list[str] = []
    result = soak.run_soak(DURATION_S, INTERVAL_S, lines.append)
    report = "\n".join(lines)
    print(report)
    assert not result.error, report
    assert len(result.intervals) == round(DURATION_S / INTERVAL_S), report
    assert all(iv.sent == INTERVAL_S * soak.INPUT_RATE_HZ for iv in result.intervals), report
    rss, _creep, gaps = result.goals()  # creep: the tool's 1.2x, for the 30-minute run
    assert rss.met and gaps.met, report
    first, last = result.intervals[0].pct(50), result.intervals[-1].pct(50)
    assert last <= CI_CREEP_LIMIT * first, report
