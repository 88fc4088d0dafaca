"""The twin's one-line figures (sim/twin.py, ``describe``), as ``mecanum-mav twin`` prints
them: real-time factor, frames at the firmware's rate, dropped and repeated frames, and the
bridge's load per frame."""

from __future__ import annotations

from mecanum_mav.sim.twin import describe
from mecanum_mav.sim.twinrecord import BridgeStats


def stats(frames: int, frame_rate: int, busy_s: float) -> BridgeStats:
    return BridgeStats(frames=frames, repeated=3, dropped=2, restarts=0, malformed=0,
                       physics_s=9.0, wall_s=10.0, busy_s=busy_s, frame_rate=frame_rate,
                       commands=(0.0, 0.0, 0.0, 0.0), wheel_pulses=(0, 0, 0, 0))


def test_the_figures_of_a_running_bridge_in_one_line():
    # 12000 frames at 1200 Hz, 2.4 s busy: 0.2 ms of each 0.83 ms frame
    assert describe(stats(12000, 1200, 2.4)) == (
        "real-time factor 0.900, 12000 frames at 1200 Hz, dropped 2, repeated 3, "
        "bridge busy 24 % of each frame")


def test_before_any_frame_it_says_so():
    assert describe(stats(0, 0, 0.0)) == "no frame yet"
    assert describe(stats(0, 1200, 0.0)) == "no frame yet"
