"""The link failsafes fire at their deadlines exactly, in virtual time (issue 23.4).

The scenario of test_failsafe_timing.py (the real process, which keeps only the causal
checks), in the lockstep harness: a ground station and a flight controller that beat, then
fall silent one after the other (the flight controller's wire cut without a word: a UDP
link), 30 times at different phases of the companion's timers. Each failsafe's STATUSTEXT
("GCS link lost", "Flight controller link lost") must reach the ground station in the first
step after the timeout since the last HEARTBEAT the core heard: later than the timeout, by at
most one step. Nothing else arrives meanwhile, so that holds only if the loop wakes for the
failsafe deadlines themselves (:meth:`RoverCore.next_due_s` includes
:meth:`Vehicle.next_due_s`), not for the next output refresh (50 ms).
"""

from __future__ import annotations

from conftest import lockstep

from mecanum_mav.sim.lockstep import Lockstep

TRIALS = 30
TIMEOUT_S = 1.5
"""FS_GCS_TMO and FS_FC_TMO (both parties beat at 1 Hz)."""
FC_LAG_S = 0.25
"""The flight controller falls silent this long after the ground station."""
EPS = 1e-9
GCS_LOST, FC_LOST = "GCS link lost", "Flight controller link lost"
GCS_BACK, FC_BACK = "GCS link regained", "Flight controller link up"


def said_at(h: Lockstep, text: str, since: int) -> float | None:
    """When the ground station received a STATUSTEXT containing ``text`` (from message index
    ``since`` on), or None."""
    for msg, at_s in zip(h.gcs.messages[since:], h.gcs.arrived_s[since:], strict=True):
        if msg.get_type() == "STATUSTEXT" and text in msg.text:
            return at_s
    return None


def test_gcs_and_fc_failsafes_fire_in_the_first_step_after_their_timeouts_in_30_of_30_trials():
    h = lockstep({"FS_GCS_TMO": TIMEOUT_S, "FS_FC_TMO": TIMEOUT_S})
    vehicle = h.core.vehicle
    gcs_delays, fc_delays = [], []
    for trial in range(TRIALS):
        h.run_for(0.3 + trial * 0.037)  # both beating; a new phase of the timers each trial
        since = len(h.gcs.messages)
        h.gcs.beating = False
        gcs_last = vehicle.gcs_seen_s
        h.run_for(FC_LAG_S)
        h.fc_link_up = False  # the board falls silent too
        fc_last = vehicle.fc_seen_s
        assert h.run_until(lambda s=since: (said_at(h, GCS_LOST, s) is not None
                                            and said_at(h, FC_LOST, s) is not None),
                           2 * TIMEOUT_S)
        gcs_fired, fc_fired = said_at(h, GCS_LOST, since), said_at(h, FC_LOST, since)
        assert gcs_fired is not None and fc_fired is not None
        assert gcs_last is not None and fc_last is not None
        gcs_delays.append(gcs_fired - gcs_last)
        fc_delays.append(fc_fired - fc_last)
        since = len(h.gcs.messages)
        h.gcs.beating, h.fc_link_up = True, True
        assert h.run_until(lambda s=since: (said_at(h, GCS_BACK, s) is not None
                                            and said_at(h, FC_BACK, s) is not None), 3.0)
    for delays in (gcs_delays, fc_delays):
        assert len(delays) == TRIALS
        assert all(TIMEOUT_S < d <= TIMEOUT_S + h.dt_s + EPS for d in delays), delays
