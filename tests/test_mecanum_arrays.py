"""The vectorized math of mecanum/ keeps its docstrings' promises for arrays: a batch is
worked row by row (each row's result is what the row alone gives), integer and float32
inputs give float64 results equal to those of the same values in float64, and where a plain
float form exists the array form gives the same numbers (shaping, desaturation, the SE(2)
exponential), including the small-angle series and the non-finite rows."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mecanum_mav.mecanum.desaturation import (
    Desaturation,
    desaturate,
    desaturate_prioritized,
    desaturate_prioritized_scalar,
    normalize,
)
from mecanum_mav.mecanum.envelope import (
    ENVELOPE_ALGORITHMS,
    non_clipping_limit_2010,
    robot_speed,
    speed_grid,
    square_stick,
)
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.mecanum.geometry import Pose2d, Twist2d, pose_exp, pose_exp_array, pose_log
from mecanum_mav.mecanum.kinematics import MecanumKinematics
from mecanum_mav.mecanum.odometry import MecanumOdometry
from mecanum_mav.mecanum.shaping import deadband, expo, square_to_circle

wheel = st.floats(-3.0, 3.0, allow_nan=False)
wheel_rows = st.lists(st.lists(wheel, min_size=4, max_size=4), min_size=2, max_size=6)
stick = st.floats(-1.0, 1.0, allow_nan=False)


def as_float32_and_int(rows: np.ndarray) -> list[np.ndarray]:
    """The same values as float32 (rounded there first) and as integers."""
    return [rows.astype(np.float32), np.rint(rows).astype(np.int64)]


def same_in_float64(function, *arrays: np.ndarray) -> None:
    """``function`` of narrower arrays is the float64 result of their float64 values."""
    for narrow in zip(*(as_float32_and_int(a) for a in arrays), strict=True):
        got = function(*narrow)
        want = function(*(n.astype(np.float64) for n in narrow))
        for g, w in zip(got if isinstance(got, tuple) else (got,),
                        want if isinstance(want, tuple) else (want,), strict=True):
            assert g.dtype == np.float64
            np.testing.assert_array_equal(g, w)


# --------------------------------------------------------------------------- desaturation


@given(wheel_rows)
def test_desaturate_and_normalize_work_each_row_of_a_batch_alone_in_float64(rows):
    batch = np.array(rows)
    batch[0, 2] = math.nan  # a row with a non-finite wheel: zeros, the others untouched
    for function in (desaturate, lambda w: desaturate(w, 2.0), normalize,
                     lambda w: normalize(w, always=True)):
        together = function(batch)
        for i, row in enumerate(batch):
            np.testing.assert_array_equal(together[i], function(row))
        np.testing.assert_array_equal(together[0], np.zeros(4))
        same_in_float64(function, np.nan_to_num(batch))


@given(wheel_rows, wheel_rows)
def test_prioritized_desaturation_of_a_batch_is_its_rows_alone_and_the_plain_float_form(
        translations, rotations):
    n = min(len(translations), len(rotations))
    t, r = np.array(translations[:n]), np.array(rotations[:n])
    t[0, 1] = math.inf
    for priority in Desaturation:
        together = desaturate_prioritized(t, r, priority)
        for i in range(n):
            alone = desaturate_prioritized(t[i], r[i], priority)
            np.testing.assert_array_equal(together[i], alone)
            plain = desaturate_prioritized_scalar(tuple(map(float, t[i])),
                                                  tuple(map(float, r[i])), priority)
            np.testing.assert_allclose(alone, plain, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(together[0], np.zeros(4))
        same_in_float64(lambda a, b, p=priority: desaturate_prioritized(a, b, p),
                        np.nan_to_num(t, posinf=2.0), r)


def test_desaturate_limits_to_1_by_default_the_normalized_full_scale():
    np.testing.assert_array_equal(desaturate([2.0, -1.0, 0.5, 0.0]), [1.0, -0.5, 0.25, 0.0])
    np.testing.assert_array_equal(desaturate([0.5, -1.0, 0.5, 0.0]), [0.5, -1.0, 0.5, 0.0])


def test_the_plain_float_prioritized_desaturation_limits_to_1_by_default_and_checks_a_limit():
    assert max(map(abs, desaturate_prioritized_scalar((2.0, 2.0, 2.0, 2.0),
                                                      (0.5, -0.5, 0.5, -0.5)))) == 1.0
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="limit must be a finite number > 0"):
            desaturate_prioritized_scalar((0.1,) * 4, (0.1,) * 4, limit=bad)


# --------------------------------------------------------------------------- shaping


@given(st.lists(stick, min_size=1, max_size=8), st.floats(0.0, 0.9), st.floats(0.0, 1.0))
def test_deadband_and_expo_of_an_array_are_those_of_each_value(values, band, curve):
    a = np.array(values)
    np.testing.assert_array_equal(deadband(a, band), [deadband(v, band) for v in values])
    np.testing.assert_allclose(expo(a, curve), [expo(v, curve) for v in values], rtol=1e-15,
                               atol=1e-16)  # (v*v*v and a**3 may round apart)
    same_in_float64(lambda x: deadband(x, band), a)
    same_in_float64(lambda x: expo(x, curve), a)


def test_expo_1_is_the_pure_cubic_and_full_stick_stays_full():
    assert expo(0.5, 1.0) == 0.125
    np.testing.assert_array_equal(expo(np.array([-1.0, 0.5, 1.0]), 1.0), [-1.0, 0.125, 1.0])


@given(st.lists(st.tuples(stick, stick), min_size=1, max_size=8))
def test_square_to_circle_of_arrays_is_that_of_each_stick(sticks):
    x, y = (np.array(v) for v in zip(*sticks, strict=True))
    cx, cy = square_to_circle(x, y)
    for i, (sx, sy) in enumerate(sticks):
        assert (cx[i], cy[i]) == pytest.approx(square_to_circle(sx, sy), abs=1e-15)
    mixed = square_to_circle(x, float(y[0]))  # an array and a float broadcast
    np.testing.assert_allclose(mixed[1], square_to_circle(x, np.full_like(x, y[0]))[1])
    same_in_float64(square_to_circle, x, y)


# --------------------------------------------------------------------------- SE(2)


@pytest.mark.parametrize("dyaw", [0.0, 3e-7, -9.9e-7, 1.01e-6, 0.3, -2.0])
def test_pose_exp_array_is_pose_exp_row_by_row_across_the_small_angle_series(dyaw):
    """Below 1e-6 rad both use the same Taylor series; at yaw 0 from the origin the results
    are the same floats (a sideways twist exposes the (1 - cos t)/t term alone)."""
    twists = [(0.0, 1.0, dyaw), (1.0, 0.0, dyaw), (0.7, -0.2, dyaw)]
    got = pose_exp_array(np.zeros((3, 3)), np.array(twists))
    for row, twist in zip(got, twists, strict=True):
        want = pose_exp(Pose2d(0.0, 0.0, 0.0), Twist2d(*twist))
        assert tuple(row) == pytest.approx(tuple(want), rel=1e-15, abs=1e-300)
    start = Pose2d(2.0, -1.0, 2.5)
    moved = pose_exp_array(np.array(start), np.array(twists[2]))
    assert tuple(moved) == pytest.approx(tuple(pose_exp(start, Twist2d(*twists[2]))),
                                         rel=1e-12)


def test_pose_exp_array_keeps_non_finite_rows_to_themselves_and_returns_float64():
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, math.inf], [0.0, 0.0, 0.0],
                      [0.0, 0.0, 0.7]], dtype=np.float32)
    twists = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.1], [math.nan, 0.0, 0.0],
                       [1.7e308, 1.7e308, 0.0]])  # (the last overflows: inf)
    got = pose_exp_array(poses, twists)  # (no floating-point warning: they are errors here)
    assert got.dtype == np.float64
    assert tuple(got[0]) == (1.0, 0.0, 0.0)
    assert not np.isfinite(got[1]).all() and not np.isfinite(got[2]).all()
    assert not np.isfinite(got[3]).all()
    with pytest.raises(ValueError, match=r"^poses and twists need a last axis of length 3$"):
        pose_exp_array(np.zeros(2), np.zeros(3))
    with pytest.raises(ValueError, match=r"^poses and twists need a last axis of length 3$"):
        pose_exp_array(np.zeros(3), np.zeros(2))


@pytest.mark.parametrize("dyaw", [0.0, 5e-7, -9.9e-7, 2e-6, 1.0])
def test_pose_log_undoes_pose_exp_across_the_small_angle_series(dyaw):
    """To the last bits near the series' switch at 1e-6 rad, where its d^2 term matters."""
    start = Pose2d(0.0, 0.0, 0.0)
    for twist in (Twist2d(1.0, 0.0, dyaw), Twist2d(0.3, 1.0, dyaw)):
        back = pose_log(start, pose_exp(start, twist))
        rel = 2e-15 if abs(dyaw) < 1e-5 else 1e-14
        assert tuple(back) == pytest.approx(tuple(twist), rel=rel, abs=1e-20)


# --------------------------------------------------------------------------- envelope


@given(st.floats(0.0, 1.0), st.floats(0.0, 360.0))
def test_a_square_stick_at_velocity_v_reaches_v_of_the_way_to_the_edge_in_its_heading(
        velocity, heading):
    x, y = square_stick(velocity, heading)
    assert max(abs(x), abs(y)) == pytest.approx(velocity, abs=1e-12)
    if velocity > 1e-6:
        angle = math.degrees(math.atan2(y, x)) % 360.0
        assert math.remainder(angle - heading, 360.0) == pytest.approx(0.0, abs=1e-6)


def test_the_envelope_functions_take_integer_and_float32_arrays_as_float64():
    v, h, r = np.array([[0.0, 1.0], [1.0, 1.0]]), np.array([[0.0, 45.0], [90.0, 30.0]]), \
        np.array([[0.0, 0.0], [1.0, -1.0]])
    same_in_float64(square_stick, v, h)
    same_in_float64(non_clipping_limit_2010, h, r)
    for algorithm in ENVELOPE_ALGORITHMS:
        same_in_float64(lambda a, b, c, name=algorithm: robot_speed(name, a, b, c), v, h, r)


@pytest.mark.parametrize("algorithm", ENVELOPE_ALGORITHMS)
def test_the_speed_grid_spans_velocity_0_to_1_and_heading_0_to_360_at_the_given_rotation(
        algorithm):
    velocity, heading, speed = speed_grid(algorithm, 0.3)
    assert velocity.shape == heading.shape == speed.shape == (41, 181)
    assert (velocity[0, 0], velocity[-1, 0], heading[0, 0], heading[0, -1]) == (
        0.0, 1.0, 0.0, 360.0)
    assert np.all(velocity[:, 0] == velocity[:, -1])  # velocity down the rows
    np.testing.assert_array_equal(speed, robot_speed(algorithm, velocity, heading, 0.3))
    small = speed_grid(algorithm, 0.0, n_velocity=3, n_heading=5)
    assert small[2].shape == (3, 5)


# --------------------------------------------------------------------------- frames


def test_odometry_shift_moves_north_and_east_and_keeps_the_heading():
    odometry = MecanumOdometry(MecanumKinematics.from_half_extents(0.2, 0.2),
                               pose=Pose2d(1.0, 2.0, 0.5))
    odometry.shift(0.25, -0.5)
    assert tuple(odometry.pose) == (1.25, 1.5, 0.5)


@pytest.mark.parametrize("lon_deg", [179.9999, -179.9999, 0.0])
def test_a_global_origin_reaches_across_the_antimeridian_the_short_way(lon_deg):
    origin = GlobalOrigin(0, round(lon_deg * 1e7), 0.0)
    east_e7 = origin.lon_e7 + 2_000  # 0.0002 degrees east, about 22 m, maybe across 180
    if east_e7 >= 1_800_000_000:
        east_e7 -= 3_600_000_000
    north, east = origin.to_local(origin.lat_e7, east_e7)
    assert north == 0.0 and east == pytest.approx(22.26, abs=0.01)
    assert origin.to_global(north, east) == (origin.lat_e7, east_e7)
