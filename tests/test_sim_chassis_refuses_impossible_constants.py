"""The simulated chassis is built only with constants a motor can have (mecanum_mav.sim.chassis
.SimChassis: a wheel speed at full command above 0 m/s, a motor time constant above 0 s, a
slip of 0 or more, all finite): anything else is a ValueError naming the quantity, not a
chassis that divides by zero or runs backwards later."""

from __future__ import annotations

import math

import pytest

from mecanum_mav.mecanum.kinematics import MecanumKinematics
from mecanum_mav.sim.chassis import SimChassis

KIN = MecanumKinematics.from_half_extents(0.2, 0.15)
GOOD = {"max_wheel_speed_mps": 1.0, "motor_tau_s": 0.08, "slip": 0.0}


@pytest.mark.parametrize("value", [0.0, -1.0, math.nan, math.inf])
@pytest.mark.parametrize(("name", "words"), [("max_wheel_speed_mps", "max wheel speed"),
                                             ("motor_tau_s", "motor time constant")])
def test_a_wheel_speed_or_motor_time_constant_not_above_zero_or_not_finite_is_refused(
        name: str, words: str, value: float) -> None:
    with pytest.raises(ValueError, match=f"^{words} must be > 0"):
        SimChassis(KIN, **{**GOOD, name: value})


@pytest.mark.parametrize("slip", [-0.01, math.nan, math.inf])
def test_a_negative_or_non_finite_slip_is_refused(slip: float) -> None:
    with pytest.raises(ValueError, match=r"^slip must be >= 0"):
        SimChassis(KIN, **{**GOOD, "slip": slip})


def test_zero_slip_and_the_smallest_positive_constants_are_accepted() -> None:
    chassis = SimChassis(KIN, max_wheel_speed_mps=1e-3, motor_tau_s=1e-3, slip=0.0)
    chassis.step(0.01, (1.0, 1.0, 1.0, 1.0))
    assert 0.0 < chassis.velocity_body[0] <= 1e-3
