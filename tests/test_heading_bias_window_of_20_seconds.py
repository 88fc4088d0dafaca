"""The heading-bias estimator measures over a window of at most WINDOW_S (20 s) of positions
(mecanum_mav.control.headingbias: "Samples older than this are dropped: a baseline needs at
least" BASELINE_M in that time): a rover creeping too slowly to cover 0.5 m in 20 s is never
measured, however far it creeps; a little faster, it is. The estimator on its own, fed a
straight track whose odometry runs a few degrees off the flight controller's positions."""

from __future__ import annotations

import math

import pytest

from mecanum_mav.control.headingbias import BASELINE_M, WINDOW_S, HeadingBias

BIAS = math.radians(3.0)
"""The odometry's track runs this far clockwise of the flight controller's (true) one."""
PERIOD_S = 0.1


def creep(speed_mps: float, duration_s: float) -> HeadingBias:
    """Drive north at ``speed_mps`` for ``duration_s`` with a position every 0.1 s."""
    bias = HeadingBias()
    for k in range(round(duration_s / PERIOD_S) + 1):
        t = k * PERIOD_S
        travelled = speed_mps * t
        bias.on_position(travelled, 0.0, travelled * math.cos(BIAS),
                         travelled * math.sin(BIAS), 0.0, t, follows_yaw=False)
    return bias


def test_a_rover_too_slow_to_cover_the_baseline_within_the_window_is_never_measured():
    speed = 0.8 * BASELINE_M / WINDOW_S  # 2 cm/s: 0.4 m in a window
    bias = creep(speed, 3 * WINDOW_S)  # 1.2 m in all, more than twice the baseline
    assert bias.measurements == 0 and bias.bias_rad == 0.0


def test_a_rover_that_covers_the_baseline_within_the_window_is_measured():
    speed = 1.5 * BASELINE_M / WINDOW_S
    bias = creep(speed, 3 * WINDOW_S)
    assert bias.measurements > 0
    assert bias.bias_rad == pytest.approx(BIAS, abs=math.radians(0.01))
