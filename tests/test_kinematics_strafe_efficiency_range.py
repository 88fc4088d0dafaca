"""The strafe efficiency (``WHL_STRAFE_EFF``) of :class:`MecanumKinematics` is "a finite number
in (0, 2]": 0 excluded (it divides), 2 included, anything past 2 or non-finite refused."""

from __future__ import annotations

import math

import pytest

from mecanum_mav.mecanum.kinematics import MecanumKinematics

WHEELS = ((0.2, -0.15), (0.2, 0.15), (-0.2, -0.15), (-0.2, 0.15))


@pytest.mark.parametrize("efficiency", [2.0, 1e-9, 0.8])
def test_a_strafe_efficiency_in_0_to_2_is_taken(efficiency):
    assert MecanumKinematics(*WHEELS, strafe_efficiency=efficiency).strafe_efficiency == efficiency


@pytest.mark.parametrize("efficiency", [0.0, -0.5, 2.0000001, 2.5, math.inf, math.nan])
def test_a_strafe_efficiency_outside_0_to_2_is_refused_saying_so(efficiency):
    with pytest.raises(ValueError, match=r"is not in \(0, 2\]$"):
        MecanumKinematics(*WHEELS, strafe_efficiency=efficiency)


def test_at_half_strafe_efficiency_the_wheels_are_asked_for_twice_the_sideways_speed():
    """Class docstring: the inverse kinematics ask the wheels for ``vy / strafe_efficiency``."""
    kinematics = MecanumKinematics(*WHEELS, strafe_efficiency=0.5)
    assert kinematics.wheel_speeds(0.0, 0.25, 0.0) == (0.5, -0.5, -0.5, 0.5)  # FL, FR, RL, RR
