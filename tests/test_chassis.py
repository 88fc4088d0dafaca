"""The simulated chassis: motor lag, encoders, slip and the true pose.

Poses are NED (x north, y east, yaw clockwise from north); velocities body FRD. Expected arcs
come from test_odometry's closed form of a constant body velocity, written independently of
geometry.pose_exp.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_odometry import assert_pose_close, exact_arc

from mecanum_mav.config.params import Params
from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.mecanum.kinematics import MecanumKinematics
from mecanum_mav.sim.chassis import SimChassis

KIN = MecanumKinematics.from_half_extents(0.2, 0.15)
FORWARD = (1.0, 1.0, 1.0, 1.0)
STRAFE_RIGHT = (1.0, -1.0, -1.0, 1.0)
CLOCKWISE = (1.0, -1.0, 1.0, -1.0)


def make(tau: float = 0.05, max_speed: float = 2.0, **kwargs: float) -> SimChassis:
    return SimChassis(KIN, max_wheel_speed_mps=max_speed, motor_tau_s=tau, **kwargs)


def drive(chassis: SimChassis, commands, seconds: float, dt: float = 0.01) -> SimChassis:
    for _ in range(round(seconds / dt)):
        chassis.step(dt, commands)
    return chassis


def test_wheels_settle_at_command_times_max_wheel_speed():
    chassis = drive(make(tau=0.05, max_speed=2.0), (0.5, 0.5, -0.25, 1.0), 2.0)
    assert chassis.wheel_speeds_mps == pytest.approx((1.0, 1.0, -0.5, 2.0), abs=1e-9)


def test_forward_command_settles_at_that_body_speed_with_no_turn():
    chassis = drive(make(max_speed=2.0), (0.5,) * 4, 2.0)
    assert chassis.velocity_body == pytest.approx((1.0, 0.0), abs=1e-9)
    assert chassis.yaw_rate == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("steps", [1, 7, 100])
def test_motor_lag_reaches_one_minus_1_over_e_after_one_time_constant(steps):
    tau = 0.08
    chassis = drive(make(tau=tau, max_speed=1.0), FORWARD, tau, dt=tau / steps)
    expected = 1.0 - math.exp(-1.0)
    assert chassis.wheel_speeds_mps == pytest.approx((expected,) * 4, rel=1e-12)


def test_encoders_integrate_the_lag_exactly_whatever_the_step_size():
    tau, t = 0.1, 0.3
    one = drive(make(tau=tau, max_speed=1.0), FORWARD, t, dt=t)
    many = drive(make(tau=tau, max_speed=1.0), FORWARD, t, dt=t / 60)
    closed_form = t - tau * (1.0 - math.exp(-t / tau))  # integral of 1 - exp(-s/tau)
    assert one.wheel_distances_m == pytest.approx((closed_form,) * 4, rel=1e-12)
    assert many.wheel_distances_m == pytest.approx(one.wheel_distances_m, rel=1e-12)
    assert one.time_s == pytest.approx(many.time_s) == pytest.approx(t)


def test_forward_moves_north_when_facing_north():
    pose = drive(make(), FORWARD, 1.0).pose
    assert pose.x_m > 1.5
    assert pose.y_m == pytest.approx(0.0, abs=1e-9)
    assert pose.yaw_rad == pytest.approx(0.0, abs=1e-9)


def test_strafe_right_moves_east_when_facing_north():
    chassis = drive(make(), STRAFE_RIGHT, 1.0)
    assert chassis.pose.y_m > 1.5
    assert chassis.pose.x_m == pytest.approx(0.0, abs=1e-9)
    assert chassis.velocity_body[1] == pytest.approx(2.0, rel=1e-6)


def test_clockwise_pattern_turns_clockwise_on_the_spot():
    chassis = drive(make(max_speed=0.2), CLOCKWISE, 0.5)
    assert chassis.yaw_rate > 0.0
    assert 0.0 < chassis.pose.yaw_rad < math.pi
    assert chassis.pose.x_m == pytest.approx(0.0, abs=1e-9)
    assert chassis.pose.y_m == pytest.approx(0.0, abs=1e-9)


def test_forward_moves_east_when_facing_east():
    pose = drive(make(pose=Pose2d(0.0, 0.0, math.pi / 2)), FORWARD, 1.0).pose
    assert pose.y_m > 1.5
    assert pose.x_m == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("steps", [1, 10, 333])
def test_constant_wheel_speeds_follow_the_exact_arc(steps):
    commands = (0.9, 0.2, 0.7, 0.1)  # forward, strafing left and turning clockwise at once
    chassis = make(tau=0.001, max_speed=1.0, pose=Pose2d(1.0, -2.0, 3.0))
    chassis.step(0.1, commands)  # the motors settle: exp(-100) is 0 in floating point
    start, speeds = chassis.pose, chassis.wheel_speeds_mps
    assert speeds == pytest.approx(commands, rel=1e-15)
    duration = 2.5
    drive(chassis, commands, duration, dt=duration / steps)
    vx, vy, w = KIN.to_chassis_speeds(list(speeds)).tolist()
    assert abs(w * duration) > 1.0
    assert_pose_close(chassis.pose, exact_arc(start, vx, vy, w, duration))


def test_slip_is_repeatable_with_the_seed_and_changes_with_it():
    runs = [drive(make(slip=0.2, seed=s), (0.8, 0.3, 0.5, 0.6), 1.0) for s in (7, 7, 8)]
    assert runs[0].pose == runs[1].pose
    assert runs[0].pose != runs[2].pose


def test_slip_moves_the_ground_not_the_encoders():
    slipping = drive(make(slip=0.2, seed=3), (0.8, 0.3, 0.5, 0.6), 1.0)
    exact = drive(make(slip=0.0), (0.8, 0.3, 0.5, 0.6), 1.0)
    assert slipping.wheel_distances_m == exact.wheel_distances_m
    assert slipping.pose != exact.pose


def test_zero_slip_body_velocity_is_exactly_the_kinematics_of_the_wheels():
    chassis = drive(make(slip=0.0), (0.8, 0.3, 0.5, 0.6), 0.3)
    vx, vy, w = KIN.to_chassis_speeds(list(chassis.wheel_speeds_mps)).tolist()
    assert chassis.velocity_body == (vx, vy)
    assert chassis.yaw_rate == w


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_wheel_command_stops_that_wheel(bad):
    chassis = drive(make(max_speed=1.0), (bad, 1.0, 1.0, 1.0), 2.0)
    assert chassis.wheel_speeds_mps == pytest.approx((0.0, 1.0, 1.0, 1.0), abs=1e-9)
    assert all(math.isfinite(v) for v in (*chassis.pose, *chassis.wheel_distances_m))


def test_commands_beyond_one_are_limited_to_full_speed():
    chassis = drive(make(max_speed=1.0), (5.0, -5.0, 1.0, -1.0), 2.0)
    assert chassis.wheel_speeds_mps == pytest.approx((1.0, -1.0, 1.0, -1.0), abs=1e-9)


@pytest.mark.parametrize("dt", [-0.01, math.nan, math.inf])
def test_a_negative_or_non_finite_time_step_is_rejected(dt):
    with pytest.raises(ValueError, match="time step"):
        make().step(dt, FORWARD)


def test_a_zero_time_step_changes_nothing():
    chassis = make()
    chassis.step(0.0, FORWARD)
    assert (chassis.time_s, chassis.wheel_speeds_mps) == (0.0, (0.0,) * 4)


def test_from_params_reads_geometry_speed_lag_and_slip():
    params = Params()
    params.update({"GEO_HALF_LEN": 0.3, "GEO_HALF_WID": 0.1, "WHL_MAX_SPD": 3.0})
    params.update({"SIM_MOTOR_TAU": 0.2, "SIM_SLIP": 0.1, "SIM_SEED": 42})
    chassis = drive(SimChassis.from_params(params), CLOCKWISE, 0.2)
    twin = drive(
        SimChassis(
            MecanumKinematics.from_half_extents(0.3, 0.1),
            max_wheel_speed_mps=3.0,
            motor_tau_s=0.2,
            slip=params["SIM_SLIP"],
            seed=42,
        ),
        CLOCKWISE,
        0.2,
    )
    assert chassis.pose == twin.pose
    expected = 3.0 * (1.0 - math.exp(-1.0))
    assert np.abs(chassis.wheel_speeds_mps) == pytest.approx([expected] * 4, rel=1e-9)
