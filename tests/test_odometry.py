"""Odometry from cumulative wheel distances, and the SE(2) helpers it stands on.

Poses are NED (x north, y east, yaw clockwise from north); twists and velocities are body
FRD (x forward, y right, yaw rate clockwise). Expected poses come from the closed form of
a constant-velocity arc, written independently of geometry.pose_exp: a body velocity
(vx, vy) turning at w for a time T from heading h0 moves the robot along the chord
``chord(T) * R(h0 + w*T/2) @ (vx, vy)`` with ``chord(T) = 2*sin(w*T/2)/w`` (T when w = 0).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mecanum_mav.mecanum.geometry import (
    Pose2d,
    Twist2d,
    pose_exp,
    pose_exp_array,
    pose_log,
    wrap_pi,
)
from mecanum_mav.mecanum.kinematics import MecanumKinematics
from mecanum_mav.mecanum.odometry import MecanumOdometry

KIN = MecanumKinematics.from_half_extents(0.2, 0.15)


def exact_arc(start: Pose2d, vx: float, vy: float, w: float, t: float) -> Pose2d:
    """Pose after driving body velocity (vx, vy) m/s at yaw rate w rad/s for t s."""
    turn = w * t
    chord = t if w == 0.0 else 2.0 * math.sin(0.5 * turn) / w
    mid = start.yaw_rad + 0.5 * turn
    c, s = math.cos(mid), math.sin(mid)
    return Pose2d(
        start.x_m + chord * (c * vx - s * vy),
        start.y_m + chord * (s * vx + c * vy),
        start.yaw_rad + turn,
    )


def assert_pose_close(actual: Pose2d, expected: Pose2d, tol: float = 1e-9) -> None:
    """Positions within tol metres, headings within tol radians (modulo a full turn)."""
    assert actual.x_m == pytest.approx(expected.x_m, abs=tol)
    assert actual.y_m == pytest.approx(expected.y_m, abs=tol)
    assert wrap_pi(actual.yaw_rad - expected.yaw_rad) == pytest.approx(0.0, abs=tol)


def distances_at(vx: float, vy: float, w: float, t: float) -> list[float]:
    """Cumulative wheel distances (m) after t s at a constant body velocity."""
    return (KIN.to_wheel_speeds(vx, vy, w) * t).tolist()


def drive(
    odom: MecanumOdometry,
    vx: float,
    vy: float,
    w: float,
    duration: float,
    steps: int,
    yaw_at: Callable[[float], float | None] | None = None,
) -> list[Pose2d]:
    """Feed ``steps`` updates of a constant body velocity; ``yaw_at(t)`` gives the external
    yaw at time t (or None for none). Returns the pose after every step."""
    poses = []
    for i in range(1, steps + 1):
        t = duration * i / steps
        yaw = None if yaw_at is None else yaw_at(t)
        poses.append(odom.update(distances_at(vx, vy, w, t), yaw))
    return poses


# --- Wheel-only dead reckoning -------------------------------------------------------


@pytest.mark.parametrize(
    ("vx", "vy", "w"),
    [
        (1.0, 0.0, 0.0),  # straight ahead
        (0.0, -0.7, 0.0),  # strafe left
        (0.8, 0.3, 0.0),  # diagonal
        (1.0, 0.0, 1e-9),  # barely turning: every step is on the series branch
        (0.5, 0.2, -2e-7),
        (1.0, 0.0, 0.5),  # clockwise arc
        (0.3, -0.4, -1.3),  # counter-clockwise arc while crabbing
    ],
)
def test_constant_body_velocity_from_wheel_distances_lands_on_the_exact_arc(vx, vy, w):
    start = Pose2d(3.0, -2.0, 0.4)
    odom = MecanumOdometry(KIN, pose=start)
    final = drive(odom, vx, vy, w, duration=4.0, steps=400)[-1]
    assert_pose_close(final, exact_arc(start, vx, vy, w, 4.0))


@settings(max_examples=40, deadline=None)
@given(
    vx=st.floats(-2.0, 2.0),
    vy=st.floats(-2.0, 2.0),
    w=st.one_of(st.just(0.0), st.floats(-1e-6, 1e-6), st.floats(-3.0, 3.0)),
    start=st.tuples(st.floats(-100, 100), st.floats(-100, 100), st.floats(-math.pi, math.pi)),
    steps=st.integers(1, 200),
)
def test_any_constant_twist_integrates_to_the_exact_arc(vx, vy, w, start, steps):
    start_pose = Pose2d(*start)
    odom = MecanumOdometry(KIN, pose=start_pose)
    final = drive(odom, vx, vy, w, duration=2.0, steps=steps)[-1]
    assert_pose_close(final, exact_arc(start_pose, vx, vy, w, 2.0), tol=1e-8)


def test_a_full_circle_returns_to_the_start():
    start = Pose2d(1.0, 2.0, -0.5)
    odom = MecanumOdometry(KIN, pose=start)
    period = 8.0
    final = drive(odom, 1.0, 0.2, 2.0 * math.pi / period, duration=period, steps=500)[-1]
    assert_pose_close(final, start)


def test_driving_forward_while_turning_clockwise_from_north_curves_east():
    odom = MecanumOdometry(KIN)
    # A quarter circle of radius 1 m, clockwise: from facing north to facing east.
    final = drive(odom, math.pi / 2.0, 0.0, math.pi / 2.0, duration=1.0, steps=50)[-1]
    assert_pose_close(final, Pose2d(1.0, 1.0, math.pi / 2.0))


def test_wheel_distances_are_measured_from_the_ones_given_at_construction():
    odom = MecanumOdometry(KIN, wheel_distances_m=(10.0, 10.0, 10.0, 10.0))
    assert odom.update([10.5, 10.5, 10.5, 10.5]) == pytest.approx((0.5, 0.0, 0.0))


# --- External yaw --------------------------------------------------------------------


def test_heading_follows_the_external_yaw_plus_the_offset_fixed_at_construction():
    odom = MecanumOdometry(KIN, pose=Pose2d(0.0, 0.0, 0.5), yaw_rad=2.0)
    pose = odom.update([0.0, 0.0, 0.0, 0.0], yaw_rad=2.1)
    assert pose.yaw_rad == pytest.approx(0.6)


def test_external_yaw_replaces_the_wheel_heading_change():
    # The wheels claim a straight line; the gyro says the robot turns at 0.8 rad/s.
    start = Pose2d(0.0, 0.0, 0.3)
    gyro0, rate = 1.0, 0.8
    odom = MecanumOdometry(KIN, pose=start, yaw_rad=gyro0)
    poses = drive(odom, 1.0, 0.0, 0.0, 3.0, 300, yaw_at=lambda t: wrap_pi(gyro0 + rate * t))
    for i, pose in enumerate(poses, start=1):
        assert pose.yaw_rad == pytest.approx(wrap_pi(start.yaw_rad + rate * 3.0 * i / 300))
    assert_pose_close(poses[-1], exact_arc(start, 1.0, 0.0, rate, 3.0))


def test_external_yaw_crossing_plus_minus_pi_does_not_spin_the_pose():
    odom = MecanumOdometry(KIN, yaw_rad=math.pi - 0.01)
    pose = odom.update([0.0] * 4, yaw_rad=-math.pi + 0.01)
    assert pose.yaw_rad == pytest.approx(0.02)


def test_gyro_dropping_out_mid_run_keeps_the_pose_continuous():
    # Wheels and gyro agree; the gyro is missing for the middle third of the run.
    start = Pose2d(5.0, 5.0, 1.0)
    bias = -2.5  # gyro reading = heading + bias
    vx, vy, w, duration, steps = 0.9, 0.2, 0.6, 6.0, 600

    def gyro(t: float) -> float | None:
        if duration / 3.0 < t <= 2.0 * duration / 3.0:
            return None
        return wrap_pi(start.yaw_rad + w * t + bias)

    odom = MecanumOdometry(KIN, pose=start, yaw_rad=wrap_pi(start.yaw_rad + bias))
    poses = drive(odom, vx, vy, w, duration, steps, yaw_at=gyro)
    step_length = math.hypot(vx, vy) * duration / steps
    for before, after in zip([start, *poses], poses, strict=False):
        assert math.hypot(after.x_m - before.x_m, after.y_m - before.y_m) <= step_length * 1.001
        assert wrap_pi(after.yaw_rad - before.yaw_rad) == pytest.approx(w * duration / steps)
    assert_pose_close(poses[-1], exact_arc(start, vx, vy, w, duration))


def test_heading_returns_to_the_external_yaw_when_it_comes_back():
    # The gyro holds still; the wheels (slipping) claim a clockwise turn while it is gone.
    odom = MecanumOdometry(KIN, pose=Pose2d(0.0, 0.0, 0.2), yaw_rad=1.0)
    odom.update(distances_at(0.0, 0.0, 0.5, 1.0))
    assert odom.pose.yaw_rad == pytest.approx(0.7)
    pose = odom.update(distances_at(0.0, 0.0, 0.5, 2.0), yaw_rad=1.0)
    assert pose.yaw_rad == pytest.approx(0.2)


def test_first_external_yaw_after_a_reset_without_one_keeps_the_heading_continuous():
    odom = MecanumOdometry(KIN, pose=Pose2d(0.0, 0.0, -0.3))
    odom.update(distances_at(0.0, 0.0, 0.1, 1.0), yaw_rad=2.0)  # wheels turned 0.1 rad
    assert odom.pose.yaw_rad == pytest.approx(-0.2)
    pose = odom.update(distances_at(0.0, 0.0, 0.1, 1.0), yaw_rad=2.25)
    assert pose.yaw_rad == pytest.approx(0.05)


# --- Reset and rejected input --------------------------------------------------------


def test_reset_moves_the_pose_and_increments_reset_counter():
    odom = MecanumOdometry(KIN)
    assert odom.reset_counter == 0
    odom.update([1.0, 1.0, 1.0, 1.0])
    odom.reset(Pose2d(7.0, -1.0, 0.25))
    assert odom.reset_counter == 1
    assert odom.pose == Pose2d(7.0, -1.0, 0.25)
    # Without new distances the reset keeps the last ones: no motion until the wheels move.
    assert odom.update([1.0, 1.0, 1.0, 1.0]) == Pose2d(7.0, -1.0, 0.25)
    odom.reset(wheel_distances_m=[0.0, 0.0, 0.0, 0.0], yaw_rad=3.0)
    assert odom.reset_counter == 2
    assert odom.pose == Pose2d(0.0, 0.0, 0.0)
    assert odom.update([0.0] * 4, yaw_rad=3.1).yaw_rad == pytest.approx(0.1)


def test_reset_wraps_the_pose_heading():
    odom = MecanumOdometry(KIN)
    odom.reset(Pose2d(0.0, 0.0, 3.0 * math.pi / 2.0))
    assert odom.pose.yaw_rad == pytest.approx(-math.pi / 2.0)


BAD_UPDATES = [
    ([0.1, math.nan, 0.1, 0.1], None),
    ([0.1, 0.1, math.inf, 0.1], 0.0),
    ([0.1, 0.1, 0.1, 0.1], math.nan),
    ([0.1, 0.1, 0.1, 0.1], -math.inf),
    ([0.1, 0.1, 0.1], None),
]


@pytest.mark.parametrize(("distances", "yaw"), BAD_UPDATES)
def test_a_non_finite_or_malformed_update_is_rejected_and_changes_nothing(distances, yaw):
    odom = MecanumOdometry(KIN, yaw_rad=0.0)
    twin = MecanumOdometry(KIN, yaw_rad=0.0)
    for o in (odom, twin):
        o.update([0.05, 0.06, 0.04, 0.05], 0.01)
    with pytest.raises(ValueError):
        odom.update(distances, yaw)
    assert odom.pose == twin.pose
    assert odom.update([0.2, 0.1, 0.2, 0.3], 0.05) == twin.update([0.2, 0.1, 0.2, 0.3], 0.05)


def test_a_non_finite_reset_is_rejected_and_does_not_count():
    odom = MecanumOdometry(KIN)
    with pytest.raises(ValueError):
        odom.reset(Pose2d(math.nan, 0.0, 0.0))
    with pytest.raises(ValueError):
        odom.reset(wheel_distances_m=[0.0, 0.0, math.inf, 0.0])
    assert odom.reset_counter == 0
    assert odom.pose == Pose2d(0.0, 0.0, 0.0)


# --- SE(2) helpers -------------------------------------------------------------------

finite_xy = st.floats(-1e3, 1e3)
angle = st.floats(-math.pi, math.pi, exclude_max=True)
poses = st.builds(Pose2d, finite_xy, finite_xy, angle)
small_or_any_angle = st.one_of(st.floats(-2e-6, 2e-6), st.floats(-3.1, 3.1))
twists = st.builds(Twist2d, st.floats(-50, 50), st.floats(-50, 50), small_or_any_angle)


@given(poses, twists)
def test_pose_log_undoes_pose_exp(start, twist):
    back = pose_log(start, pose_exp(start, twist))
    np.testing.assert_allclose(back, twist, atol=1e-9)


@given(poses, poses)
def test_pose_exp_reaches_the_pose_given_by_pose_log(start, end):
    assert_pose_close(pose_exp(start, pose_log(start, end)), end, tol=1e-8)


@given(poses, twists)
def test_pose_exp_array_matches_pose_exp(start, twist):
    expected = pose_exp(start, twist)
    np.testing.assert_allclose(pose_exp_array(start, twist), expected, rtol=1e-12, atol=1e-12)


def test_pose_exp_array_broadcasts_poses_against_twists():
    starts = np.zeros((3, 1, 3))
    steps = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    result = pose_exp_array(starts, steps)
    assert result.shape == (3, 2, 3)
    np.testing.assert_allclose(result[2], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def test_facing_east_forward_goes_east_and_right_goes_south():
    facing_east = Pose2d(0.0, 0.0, math.pi / 2.0)
    assert pose_exp(facing_east, Twist2d(1.0, 0.0, 0.0))[:2] == pytest.approx((0.0, 1.0))
    assert pose_exp(facing_east, Twist2d(0.0, 1.0, 0.0))[:2] == pytest.approx((-1.0, 0.0))


def test_pose_exp_is_continuous_across_the_small_angle_series_threshold():
    start = Pose2d(0.0, 0.0, 0.0)
    below = pose_exp(start, Twist2d(100.0, 0.0, 0.999999e-6))
    above = pose_exp(start, Twist2d(100.0, 0.0, 1.000001e-6))
    # The lateral offset 100 * t / 2 changes by the 2e-12 rad difference only.
    assert above.y_m - below.y_m == pytest.approx(100.0 * 1e-12, rel=1e-3)
    assert above.x_m == pytest.approx(below.x_m, abs=1e-15)


@pytest.mark.parametrize(
    ("angle_in", "expected"),
    [
        (0.0, 0.0),
        (1e-20, 1e-20),
        (math.pi, -math.pi),
        (-math.pi, -math.pi),
        (3.0 * math.pi / 2.0, -math.pi / 2.0),
        (-3.0 * math.pi / 2.0, math.pi / 2.0),
        (7.0 * math.pi, -math.pi),
        (1e6, math.remainder(1e6, 2.0 * math.pi)),
        # Just below -pi: the modulo rounds to +pi, which must fold back to -pi.
        (math.nextafter(-math.pi, -math.inf), -math.pi),
    ],
)
def test_wrap_pi_folds_angles_into_minus_pi_to_pi(angle_in, expected):
    assert -math.pi <= wrap_pi(angle_in) < math.pi
    assert -math.pi <= wrap_pi(np.array([angle_in]))[0] < math.pi
    assert wrap_pi(angle_in) == pytest.approx(expected, abs=1e-9)
    assert wrap_pi(np.array([angle_in])) == pytest.approx([expected], abs=1e-9)


@given(st.floats(-1e9, 1e9))
def test_wrap_pi_always_lands_in_the_half_open_interval(angle_in):
    wrapped = wrap_pi(angle_in)
    assert -math.pi <= wrapped < math.pi
    assert math.sin(wrapped) == pytest.approx(math.sin(angle_in), abs=1e-6)
    array = wrap_pi(np.array([angle_in, -angle_in]))
    assert ((array >= -math.pi) & (array < math.pi)).all()


def test_wrap_pi_turns_non_finite_angles_into_nan():
    assert math.isnan(wrap_pi(math.inf))
    assert np.isnan(wrap_pi(np.array([math.nan, -math.inf]))).all()


def test_body_to_ned_and_back_are_inverse_rotations_clockwise_from_north():
    from mecanum_mav.mecanum.geometry import body_to_ned, ned_to_body

    assert body_to_ned(1.0, 0.0, math.pi / 2) == pytest.approx((0.0, 1.0))  # facing east
    assert body_to_ned(0.0, 1.0, math.pi / 2) == pytest.approx((-1.0, 0.0))  # right = south
    for yaw in (-2.0, 0.3, 3.0):
        assert ned_to_body(*body_to_ned(0.7, -0.2, yaw), yaw) == pytest.approx((0.7, -0.2))
