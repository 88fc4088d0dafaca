"""The odometry takes its four cumulative wheel distances as any sequence of numbers (a numpy
array of any float or integer type, integers), checked the same way as plain floats: four
finite values or ValueError, the state unchanged (mecanum_mav.mecanum.odometry)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest

from mecanum_mav.mecanum.kinematics import MecanumKinematics
from mecanum_mav.mecanum.odometry import MecanumOdometry

KIN = MecanumKinematics.from_half_extents(0.2, 0.15)
STEPS = ([0.05, 0.07, 0.03, 0.05], [1.0, 2.0, 1.0, 3.0], [2.0, 1.0, 3.0, 3.0])
"""Cumulative distances (m) of three updates (the last two whole metres: integers too)."""


def driven(steps: Sequence[Sequence[float]] | Sequence[np.ndarray]) -> MecanumOdometry:
    odom = MecanumOdometry(KIN, yaw_rad=0.0)
    for distances in steps:
        odom.update(distances)
    return odom


@pytest.mark.parametrize("form", [np.float64, np.float32], ids=["float64", "float32"])
def test_distances_in_a_numpy_array_move_the_pose_as_plain_floats_do(form: type) -> None:
    as_floats = driven(STEPS)
    as_array = driven([np.array(d, dtype=form) for d in STEPS])
    assert as_array.pose == pytest.approx(as_floats.pose, abs=1e-7)
    assert all(type(v) is float for v in as_array.pose)


def test_integer_distances_move_the_pose_as_the_same_floats_do() -> None:
    floats = [[float(v) for v in d] for d in STEPS[1:]]
    integers = [[int(v) for v in d] for d in STEPS[1:]]
    assert driven(integers).pose == driven(floats).pose
    assert driven([np.array(d, dtype=np.int64) for d in integers]).pose == driven(floats).pose


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_numpy_array_with_a_non_finite_distance_is_rejected_and_changes_nothing(
        bad: float) -> None:
    odom, twin = driven(STEPS[:1]), driven(STEPS[:1])
    with pytest.raises(ValueError, match="non-finite wheel distances"):
        odom.update(np.array([0.1, bad, 0.1, 0.1]))
    assert odom.pose == twin.pose
    assert odom.update(STEPS[1]) == twin.update(STEPS[1])  # measured from the same distances


def test_an_array_of_four_that_is_not_one_dimensional_is_rejected() -> None:
    odom = driven(STEPS[:1])
    with pytest.raises(ValueError, match="exactly 4 values"):
        odom.update(np.array([[0.1, 0.1], [0.1, 0.1]]))
