"""The odometry's four cumulative wheel distances (:meth:`MecanumOdometry.update`): "four finite
cumulative wheel distances (m) as floats; ValueError otherwise", whatever the sequence (a list
of three or five is refused saying what it needs) and whatever mix of plain floats and numpy
scalars (a log's columns) it holds."""

from __future__ import annotations

import numpy as np
import pytest

from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.mecanum.kinematics import MecanumKinematics
from mecanum_mav.mecanum.odometry import MecanumOdometry

KIN = MecanumKinematics.from_half_extents(0.2, 0.15)


@pytest.mark.parametrize("distances", [[0.1, 0.2, 0.3], (0.1, 0.2, 0.3, 0.4, 0.5), [], (1.0,)])
def test_a_list_or_tuple_of_other_than_four_distances_is_refused_saying_so(distances):
    odom = MecanumOdometry(KIN, yaw_rad=0.0)
    with pytest.raises(ValueError, match=r"^wheel distances need exactly 4 values "
                                         r"\(FL, FR, RL, RR\), metres$"):
        odom.update(distances)


@pytest.mark.parametrize("mixed", [
    [np.float32(0.05), np.float32(0.07), np.float32(0.03), 0.05],
    [np.float32(0.05), np.float32(0.07), 0.03, 0.05],
    [0.05, np.float32(0.07), np.float32(0.03), np.float32(0.05)],
    [np.float32(0.05), 0.07, 0.03, 0.05], [0.05, np.float32(0.07), 0.03, 0.05],
    [0.05, 0.07, np.float32(0.03), 0.05], [0.05, 0.07, 0.03, np.float32(0.05)],
])
def test_numpy_scalars_mixed_with_floats_move_the_pose_as_their_float_values(mixed):
    odom, plain = MecanumOdometry(KIN, yaw_rad=0.0), MecanumOdometry(KIN, yaw_rad=0.0)
    for scale in (1, 3, 7):
        odom.update([v * np.float32(scale) if isinstance(v, np.float32) else v * scale
                     for v in mixed])
        plain.update([float(v * np.float32(scale)) if isinstance(v, np.float32)
                      else v * scale for v in mixed])
    assert odom.pose == plain.pose
    assert all(type(v) is float for v in odom.pose)


def test_a_non_finite_distance_is_refused_naming_the_four_and_the_pose_stays():
    odom = MecanumOdometry(KIN, yaw_rad=0.0)
    odom.update([0.1, 0.1, 0.1, 0.1])
    before = odom.pose
    want = r"^non-finite wheel distances: \(0\.2, nan, 0\.2, 0\.2\)$"
    with pytest.raises(ValueError, match=want):
        odom.update([0.2, float("nan"), 0.2, 0.2])
    assert odom.pose == before


def test_a_complex_distance_is_refused_not_taken_for_its_real_part():
    odom = MecanumOdometry(KIN, yaw_rad=0.0)
    with pytest.raises((TypeError, ValueError)):
        odom.update([0.1 + 0j, 0.1, 0.1, 0.1])
    assert odom.pose == (0.0, 0.0, 0.0)


def test_a_non_finite_external_yaw_is_refused_naming_it():
    odom = MecanumOdometry(KIN, yaw_rad=0.0)
    with pytest.raises(ValueError, match=r"^non-finite yaw: inf$"):
        odom.update([0.1, 0.1, 0.1, 0.1], yaw_rad=float("inf"))


def test_a_non_finite_starting_pose_is_refused_naming_it():
    want = r"^non-finite pose: Pose2d\(x_m=1\.0, y_m=nan, yaw_rad=0\.0\)$"
    with pytest.raises(ValueError, match=want):
        MecanumOdometry(KIN, pose=Pose2d(1.0, float("nan"), 0.0))
