"""The link failsafes fire in the real process, measured from outside.

The companion runs as its own process (``mecanum-mav run``) between two UDP peers played by the
test: a ground station and a flight controller, each sending HEARTBEAT at 10 Hz. In each trial
both stop (the flight controller 0.25 s after the ground station), each failsafe's STATUSTEXT
("GCS link lost", "Flight controller link lost") reaches the ground station, and not before
the timeout since the last HEARTBEAT sent (a lower bound a loaded machine cannot break: it
only delays); then both beat again until the companion reports both links back. Causal
checks with generous deadlines: when the failsafes fire is asserted exactly, within one step
of the timeout, in virtual time (test_failsafe_deadlines.py, the same scenario in the
lockstep harness); the delays measured here are printed, not judged: the wall-clock figure,
against a floor process of the same run, is tools/bench_failsafe.py's, whose peers and trials
this test runs.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))

import bench_failsafe
from bench_failsafe import TIMEOUT_S, Peers, run_trials
from sitl import CompanionProcess

TRIALS = 5


def test_gcs_and_fc_failsafes_fire_after_their_timeouts_and_both_links_come_back_in_5_trials(
        tmp_path: Path) -> None:
    peers = Peers()
    try:
        with CompanionProcess(peers.url(peers.gcs), peers.url(peers.fc), tmp_path,
                              *bench_failsafe.companion_settings()) as companion:
            trials = run_trials(peers, TRIALS)
            log = companion.log()
            alive = companion.proc.poll() is None
    finally:
        peers.close()
    assert not trials.error, f"{trials.error}\n{log}"
    assert alive, log
    report = (f"GCS worst {max(trials.gcs):.3f} s, FC worst {max(trials.fc):.3f} s, "
              f"best {min(trials.gcs + trials.fc):.3f} s")
    print(report)
    for delays in (trials.gcs, trials.fc):
        assert len(delays) == TRIALS
        assert all(d > TIMEOUT_S for d in delays), (delays, report)  # never early
