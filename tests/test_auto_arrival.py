"""AUTO to the issue 25 standard: where waypoints count as reached, and the pose the
controllers act on between odometry updates. The rover is the pure chain of test_auto (true
pose, first-order motor lag) unless a test says otherwise."""

from __future__ import annotations

import math

import pytest
from missionitems import local_wp
from test_auto import HOME, Run

from mecanum_mav.config.params import Params
from mecanum_mav.control.autopilot import MAX_POSE_LEAD_S, Autopilot
from mecanum_mav.control.estimator import WheelOdometryEstimator


def test_a_waypoint_passed_at_speed_is_reached_where_the_rover_crosses_it_not_at_the_radius():
    run = Run([HOME, local_wp(0, 1.5, 0.0), local_wp(0, 3.0, 0.3)], WP_RADIUS=0.2,
              WP_OVERSHOOT=0.05)
    while run.ex.current == 1 and run.t < 20:
        run.step()
    assert run.speeds[-1] > 0.3  # passed at speed
    assert run.pose.x_m >= 1.5 - 0.001  # not 20 cm before, where the radius begins
    assert run.ex.arrival_errors[1] < 0.02


def test_a_stop_waypoint_is_reached_once_the_rover_has_settled_onto_it_inside_the_radius():
    run = Run([HOME, local_wp(0, 1.5, 0.0), local_wp(0, 1.5, 1.5)], WP_RADIUS=0.2)
    while run.ex.current == 1 and run.t < 20:
        run.step()
    assert math.hypot(run.pose.x_m - 1.5, run.pose.y_m) < 0.01
    assert run.ex.arrival_errors[1] < 0.01  # converged, not reported at the radius


def _autopilot() -> Autopilot:
    params = Params()
    return Autopilot(params, WheelOdometryEstimator(params), lambda: None)


def test_between_odometry_steps_the_pose_is_carried_forward_by_the_commanded_velocity():
    pilot = _autopilot()
    pilot.guided.velocity_ned = (1.0, -0.5)
    assert pilot.pose_now(10.0).x_m == pytest.approx(0.0)  # the step just arrived
    ahead = pilot.pose_now(10.06)
    assert (ahead.x_m, ahead.y_m) == pytest.approx((0.06, -0.03))
    capped = pilot.pose_now(12.0)  # odometry stopped coming: never more than the cap
    assert capped.x_m == pytest.approx(MAX_POSE_LEAD_S)
    pilot.guided.velocity_ned = (0.0, 0.0)
    assert pilot.pose_now(12.0).x_m == 0.0
