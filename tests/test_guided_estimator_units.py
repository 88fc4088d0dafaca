"""Pure tests of the GUIDED controller and the odometry estimator (time passed in)."""

from __future__ import annotations

import math

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.control.guided import GuidedController, Setpoint
from mecanum_mav.mecanum.geometry import Pose2d

ORIGIN = Pose2d(0.0, 0.0, 0.0)


def controller(**values: float) -> GuidedController:
    params = Params()
    params.update(values)
    c = GuidedController(params)
    c.start(ORIGIN, 0.0)
    return c


def test_a_yaw_rate_setpoint_lapses_and_the_heading_is_then_held():
    c = controller(GUID_TIMEOUT=1.0)
    c.accept(Setpoint(None, None, None, 0.5, 0.0), ORIGIN)
    assert c.update(ORIGIN, 0.5)[2] == pytest.approx(0.5)
    turned = Pose2d(0.0, 0.0, 0.3)
    c.update(turned, 0.9)  # still live: the held heading follows
    assert c.update(turned, 1.5)[2] == pytest.approx(0.0)  # lapsed: hold where it stopped


def test_position_with_velocity_feed_forward_adds_the_velocity():
    c = controller(GUID_ACC_MAX=10.0, GUID_SPD_MAX=5.0)
    far = Setpoint((10.0, 0.0), None, None, None, 0.0)
    c.accept(far, ORIGIN)
    for t in (0.1, 0.2, 0.3, 0.4, 0.5):
        plain = c.update(ORIGIN, t)
    c = controller(GUID_ACC_MAX=10.0, GUID_SPD_MAX=5.0)
    c.accept(Setpoint((0.5, 0.0), (0.0, 1.0), None, None, 0.0), ORIGIN)
    for t in (0.1, 0.2, 0.3, 0.4, 0.5):
        fed = c.update(ORIGIN, t)
    assert plain[1] == pytest.approx(0.0)
    assert fed[1] == pytest.approx(1.0, abs=0.05)  # the east feed-forward comes through
    assert fed[0] == pytest.approx(0.75, abs=0.05)  # P term: 1.5 1/s x 0.5 m


def test_odometry_falls_back_to_commanded_speeds_and_back_without_a_jump():
    est = WheelOdometryEstimator(Params())  # ODOM_SRC auto, WHL_MAX_SPD 1 m/s
    est.on_wheel_distance([0.0] * 4, 0.0)
    est.on_wheel_distance([0.5] * 4, 1.0)  # not fresh after 1 s: re-anchor, no motion
    for i in range(1, 11):  # fresh measurements: 0.1 m per 0.1 s, all wheels forward
        est.on_wheel_distance([0.5 + 0.1 * i] * 4, 1.0 + 0.1 * i)
    assert est.pose.x_m == pytest.approx(1.0)
    t = 2.0
    while t < 3.0:  # encoders silent: commanded full forward (1 m/s) stands in
        t += 0.02
        est.on_commanded([1.0] * 4, 0.02, t)
    assert est.pose.x_m == pytest.approx(1.0 + (t - 2.0 - 0.5), abs=0.05)  # after FRESH_S
    x_before = est.pose.x_m
    est.on_wheel_distance([7.0] * 4, t + 0.01)  # encoders back, counters far ahead
    assert est.pose.x_m == pytest.approx(x_before)  # re-anchored: no jump
    est.on_wheel_distance([7.1] * 4, t + 0.11)
    assert est.pose.x_m == pytest.approx(x_before + 0.1)


def test_odometry_heading_follows_the_gyro_when_fresh_and_the_wheels_otherwise():
    est = WheelOdometryEstimator(Params())
    est.on_attitude(0.0, 0.0, 0.0)
    est.on_wheel_distance([0.0] * 4, 0.0)
    est.on_attitude(0.4, 0.0, 0.05)
    est.on_wheel_distance([0.0] * 4, 0.1)  # wheels did not turn; the gyro says 0.4 rad
    assert est.pose.yaw_rad == pytest.approx(0.4)
    params = Params()
    params.update({"ODOM_YAW_SRC": 1})
    wheels_only = WheelOdometryEstimator(params)
    wheels_only.on_attitude(0.4, 0.0, 0.05)
    wheels_only.on_wheel_distance([0.0] * 4, 0.0)
    wheels_only.on_wheel_distance([0.0] * 4, 0.1)
    assert wheels_only.pose.yaw_rad == pytest.approx(0.0)
    assert math.isfinite(est.yaw_rate)


def test_wheel_distances_not_finite_beyond_1e7_m_or_a_step_no_wheel_can_roll_move_nothing():
    # Found by tools/fuzz.py: WHEEL_DISTANCE of 1e308 m moved the pose out of float32's range,
    # and ODOMETRY could no longer be packed.
    est = WheelOdometryEstimator(Params())  # WHL_MAX_SPD 1 m/s
    assert est.on_wheel_distance([0.0] * 4, 0.0) is None
    for bad in ([1e308, 0.0, 0.0, 0.0], [math.nan] * 4, [0.0, -math.inf, 0.0, 0.0],
                [1.1e7] * 4):
        assert est.on_wheel_distance(bad, 0.05) is not None
    assert est.pose == (0.0, 0.0, 0.0)
    # 0.5 m in 0.1 s on one wheel: beyond 2 x 1 m/s x 0.1 s + 0.2 m: re-anchored, not driven
    assert "jumped" in est.on_wheel_distance([0.5, 0.0, 0.0, 0.0], 0.1)
    assert est.pose == (0.0, 0.0, 0.0)
    assert est.on_wheel_distance([0.6, 0.1, 0.1, 0.1], 0.2) is None  # from the new anchor
    assert est.pose.x_m == pytest.approx(0.1)


def test_attitude_with_a_yaw_beyond_2_pi_or_a_rate_beyond_50_rad_s_is_not_used():
    est = WheelOdometryEstimator(Params())
    est.on_attitude(0.0, 0.0, 0.0)
    est.on_wheel_distance([0.0] * 4, 0.0)
    for yaw, rate in ((1e38, 0.0), (0.4, 3.4e38), (math.nan, 0.0), (0.4, -math.inf)):
        assert est.on_attitude(yaw, rate, 0.05) is not None
    est.on_wheel_distance([0.0] * 4, 0.1)
    assert est.pose.yaw_rad == 0.0 and est.yaw_rate == 0.0
    assert est.on_attitude(0.4, 1.0, 0.15) is None
    est.on_wheel_distance([0.0] * 4, 0.2)
    assert est.pose.yaw_rad == pytest.approx(0.45)  # 0.4 rad carried 0.05 s at 1 rad/s
