""":meth:`~mecanum_mav.mecanum.kinematics.MecanumKinematics.to_wheel_speeds` takes "floats or
array-likes" and returns float64 wheel speeds: exact numbers a caller may hold (a
``fractions.Fraction`` from a ratio, a ``decimal.Decimal`` from a config file) are their float
values, not a result of objects; and a centre of rotation of the wrong shape is refused saying
what it needs."""

from __future__ import annotations

from decimal import Decimal
from fractions import Fraction

import numpy as np
import pytest

from mecanum_mav.mecanum.kinematics import MecanumKinematics

KINEMATICS = MecanumKinematics.from_half_extents(0.2, 0.25)
VX, VY, YAW_RATE, CENTRE = 1.0, -0.5, 0.5, (0.1, 0.2)


@pytest.mark.parametrize("exact", [Fraction, lambda v: Decimal(str(v))],
                         ids=["fraction", "decimal"])
@pytest.mark.parametrize("which", ["vx", "vy", "yaw_rate", "centre"])
def test_exact_numbers_give_the_float64_wheel_speeds_of_their_float_values(exact, which):
    args = {"vx": VX, "vy": VY, "yaw_rate": YAW_RATE, "centre": np.array(CENTRE)}
    want = KINEMATICS.to_wheel_speeds(args["vx"], args["vy"], args["yaw_rate"], args["centre"])
    args[which] = (tuple(exact(v) for v in CENTRE) if which == "centre"
                   else exact(args[which]))
    got = KINEMATICS.to_wheel_speeds(args["vx"], args["vy"], args["yaw_rate"], args["centre"])
    assert got.dtype == np.float64
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("centre", [(0.1, 0.2, 0.0), [[0.1], [0.2]], 0.1])
def test_a_centre_of_rotation_that_is_not_x_y_is_refused_saying_so(centre):
    with pytest.raises(ValueError, match=r"^center_of_rotation needs a last axis of length 2: "
                                         r"\(x, y\) metres$"):
        KINEMATICS.to_wheel_speeds(np.array([1.0, 0.5]), 0.0, 0.2, centre)


@pytest.mark.parametrize("exact", [Fraction, lambda v: Decimal(str(v))],
                         ids=["fraction", "decimal"])
def test_exact_wheel_speeds_give_the_float64_chassis_speeds_of_their_float_values(exact):
    wheels = (1.25, 0.75, 1.5, -0.25)
    got = KINEMATICS.to_chassis_speeds([exact(v) for v in wheels])
    assert got.dtype == np.float64
    np.testing.assert_array_equal(got, KINEMATICS.to_chassis_speeds(np.array(wheels)))
