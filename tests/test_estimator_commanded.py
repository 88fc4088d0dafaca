"""The commanded-speed odometry's lag (ODOM_CMD_TAU) and the gyro yaw carried to the moment of
the update, in virtual time (time passed in)."""

from __future__ import annotations

import math

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.sim.chassis import SimChassis


def commanded(**values: float) -> WheelOdometryEstimator:
    params = Params()
    params.update({"ODOM_SRC": 2, **values})
    return WheelOdometryEstimator(params)


def test_without_a_lag_a_commanded_step_counts_at_once():
    est = commanded(ODOM_CMD_TAU=0.0)  # WHL_MAX_SPD 1 m/s
    est.on_commanded([1.0] * 4, 0.1, 0.1)
    assert est.pose.x_m == pytest.approx(0.1)


def test_a_lagged_commanded_step_rolls_as_a_first_order_motor_does():
    tau = 0.08
    est = commanded(ODOM_CMD_TAU=tau)
    t = 0.0
    while t < 0.3 - 1e-9:
        t += 0.02
        est.on_commanded([1.0] * 4, 0.02, t)
    # integral of 1 - exp(-t / tau) from 0 to t: t - tau (1 - exp(-t / tau))
    assert est.pose.x_m == pytest.approx(t - tau * (1 - math.exp(-t / tau)), rel=1e-9)


def test_the_lagged_odometry_follows_the_simulated_chassis_wheel_for_wheel():
    """Same first-order lag, same exact discretization: the commanded distances are the
    chassis's encoder distances, whatever the commands and step sizes."""
    params = Params()
    params.update({"ODOM_SRC": 2, "ODOM_CMD_TAU": params["SIM_MOTOR_TAU"]})
    est = WheelOdometryEstimator(params)
    chassis = SimChassis.from_params(params)
    commands = [(0.8, -0.3, 0.5, 0.1), (0.0, 0.0, 0.0, 0.0), (-1.0, 1.0, 0.2, -0.4)]
    t = 0.0
    for wheels in commands:
        for _ in range(60):
            chassis.step(0.01, wheels)
            t += 0.01
            est.on_commanded(wheels, 0.01, t)
    assert est.wheel_distances_m == pytest.approx(chassis.wheel_distances_m, abs=1e-9)


def test_after_the_command_stops_the_lagged_wheels_coast_to_the_commanded_distance():
    tau = 0.08
    est = commanded(ODOM_CMD_TAU=tau)
    est.on_commanded([1.0] * 4, 1.0, 1.0)  # 1 s at full: 1 - tau (1 - e^-12.5) m so far
    t = 1.0
    for _ in range(200):  # 2 s of stop: the wheels catch up to the full metre
        t += 0.01
        est.on_commanded([0.0] * 4, 0.01, t)
    assert est.pose.x_m == pytest.approx(1.0, abs=1e-5)
    assert est.velocity_body == (0.0, 0.0)  # settled: standing still again


def test_the_gyro_yaw_is_carried_forward_at_its_rate_to_the_update():
    est = commanded(ODOM_CMD_TAU=0.0)
    est.on_attitude(0.0, 0.0, 0.0)
    est.on_commanded([1.0] * 4, 0.02, 0.02)  # anchors the gyro's offset at heading 0
    est.on_attitude(0.1, 1.0, 0.03)  # 0.1 rad, turning clockwise at 1 rad/s
    est.on_commanded([1.0] * 4, 0.02, 0.05)  # 0.02 s later: 0.12 rad
    assert est.pose.yaw_rad == pytest.approx(0.12, abs=1e-12)


def test_an_attitude_before_the_first_update_sets_the_starting_heading_itself():
    """The flight controller's north is the local frame's north, whatever heading the rover
    starts at (an EKF's heading: GLOBAL_POSITION_INT and the missions are in its frame)."""
    est = commanded(ODOM_CMD_TAU=0.0)
    est.on_attitude(0.5, 0.0, 0.0)
    assert est.pose.yaw_rad == pytest.approx(0.5)
    est.on_commanded([1.0] * 4, 0.1, 0.1)  # forward along 0.5 rad
    assert (est.pose.x_m, est.pose.y_m) == pytest.approx((0.1 * math.cos(0.5),
                                                          0.1 * math.sin(0.5)))
    assert est.reset_counter == 0


def test_an_attitude_after_the_odometry_moved_does_not_turn_its_heading():
    est = commanded(ODOM_CMD_TAU=0.0, ODOM_YAW_SRC=0)
    est.on_commanded([1.0] * 4, 0.1, 0.1)  # moved on the wheels' heading (0)
    est.on_attitude(0.5, 0.0, 0.2)
    est.on_commanded([1.0] * 4, 0.1, 0.3)
    assert est.pose.yaw_rad == pytest.approx(0.0)  # the offset is anchored, not the yaw


def test_standing_still_before_the_first_attitude_does_not_stop_it_setting_the_heading():
    est = commanded(ODOM_CMD_TAU=0.0)
    est.on_commanded([0.0] * 4, 0.02, 0.02)  # the companion's neutral outputs, standing
    est.on_attitude(-0.04, 0.0, 0.03)
    assert est.pose.yaw_rad == pytest.approx(-0.04)


@pytest.mark.parametrize("tau", [0.0, 0.08])
@pytest.mark.parametrize("dt_s", [0.0, -0.02])
def test_a_command_held_for_no_time_or_a_negative_time_rolls_no_wheel(tau, dt_s):
    est = commanded(ODOM_CMD_TAU=tau)
    est.on_commanded([1.0] * 4, dt_s, 0.5)
    assert est.wheel_distances_m == (0.0, 0.0, 0.0, 0.0)
    assert est.pose.x_m == 0.0
