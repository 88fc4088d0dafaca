"""A fused position's pull on the odometry (``HeadingBias.shifted``) is not a step the rover
drove: the heading bias measured over a track with such a pull is the one measured over the
same track without it."""

from __future__ import annotations

import math

import pytest

from mecanum_mav.control.headingbias import HeadingBias

BIAS = math.radians(2.0)


def drive(pull: tuple[float, float] | None) -> HeadingBias:
    """Drive east at 1 m/s for 3 s, a position every 0.1 s, the odometry's track turned by
    BIAS clockwise (a yaw BIAS too far clockwise); with ``pull``, its position is pulled by
    that much (north, east m) just before the position at 1.1 s."""
    estimate = HeadingBias()
    offset = (0.0, 0.0)
    for k in range(31):
        t = 0.1 * k
        if pull is not None and k == 11:
            estimate.shifted(*pull)
            offset = pull
        east = 1.0 * t  # the true track (the flight controller's)
        odom = (-east * math.sin(BIAS) + offset[0], east * math.cos(BIAS) + offset[1])
        estimate.on_position(0.0, east, odom[0], odom[1], 0.0, t)
    return estimate


@pytest.mark.parametrize("pull", [(0.05, 0.0), (0.0, 0.05), (-0.03, -0.02)])
def test_a_pull_of_the_odometry_is_not_counted_as_a_step_driven(
        pull: tuple[float, float]) -> None:
    plain, pulled = drive(None), drive(pull)
    assert plain.measurements > 0
    assert plain.bias_rad == pytest.approx(BIAS)
    assert pulled.measurements == plain.measurements
    assert pulled.bias_rad == pytest.approx(plain.bias_rad, rel=1e-9)
