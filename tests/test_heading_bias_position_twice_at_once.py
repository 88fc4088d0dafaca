"""A GPS fix that arrives twice at the same instant is a step of no length in no time: the
heading-bias estimate takes it without error, and measures the same bias as from each fix
once. (GPS fixes are measured against whether the rover drives steadily or not.)"""

from __future__ import annotations

import math

import pytest

from mecanum_mav.control.headingbias import HeadingBias

BIAS = math.radians(2.0)


def drive(copies: int) -> HeadingBias:
    """Drive east at 1 m/s for 3 s, each GPS fix (every 0.1 s) given ``copies`` times."""
    estimate = HeadingBias()
    for k in range(31):
        east = 0.1 * k
        for _ in range(copies):
            estimate.on_position(0.0, east, -east * math.sin(BIAS), east * math.cos(BIAS), 0.0,
                                 0.1 * k, follows_yaw=False)
    return estimate


def test_a_gps_fix_given_twice_at_one_instant_changes_nothing() -> None:
    once, twice = drive(1), drive(2)
    assert once.measurements > 0 and once.bias_rad == pytest.approx(BIAS)
    assert twice.bias_rad == pytest.approx(once.bias_rad, rel=1e-9)
