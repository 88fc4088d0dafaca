"""AUTO to the issue 25 standard: where waypoints count as reached, and the pose the
controllers act on between odometry updates. The rover is the pure chain of test_auto (true
pose, first-order motor lag) unless a test says otherwise."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from missionitems import YAW, do, local_wp, renumber
from test_auto import DT, HOME, Run

from mecanum_mav.config.params import Params
from mecanum_mav.control.autopilot import MAX_POSE_LEAD_S, Autopilot
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.control.executor import SETTLE_TIMEOUT_S, MissionExecutor
from mecanum_mav.control.guided import GuidedController, Setpoint
from mecanum_mav.control.pathfollow import Leg, corner_lead, heading_schedule
from mecanum_mav.mecanum.geometry import Pose2d, wrap_pi


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


def test_between_gyro_steps_the_heading_is_carried_forward_by_the_commanded_yaw_rate():
    pilot = _autopilot()
    pilot.guided.yaw_rate = 1.0
    assert pilot.pose_now(5.0).yaw_rad == pytest.approx(0.0)
    assert pilot.pose_now(5.04).yaw_rad == pytest.approx(0.04)


def _strafe_rotate(speed: float) -> Run:
    """3 m north in six 0.5 m legs, each waypoint 30 degrees further clockwise (to 180)."""
    items = [HOME, do(0, YAW, 0.0, 0.0, 0.0, 0.0)]
    items += [replace(local_wp(0, 0.5 * k, 0.0), param4=30.0 * k) for k in range(1, 7)]
    return Run(items, WP_SPEED=speed, GUID_SPD_MAX=speed + 0.2, WHL_MAX_SPD=3.0)


def test_a_waypoint_heading_is_turned_along_its_leg_and_held_as_the_rover_passes_it():
    run = _strafe_rotate(1.0)
    headings = {}
    while run.ex.running and run.t < 20:
        before, pose = run.ex.current, run.pose  # the pose this tick decides on
        run.step()
        if run.ex.current != before and before >= 2:  # items 2..6: 30..150 degrees
            headings[before] = math.degrees(wrap_pi(pose.yaw_rad - math.radians(
                30.0 * (before - 1))))
    assert not run.ex.running
    headings[7] = math.degrees(wrap_pi(run.pose.yaw_rad - math.pi))
    assert len(headings) == 6 and max(abs(h) for h in headings.values()) < 1.0, headings


def test_a_waypoint_passed_at_speed_is_reached_within_half_a_tick_of_its_line():
    run = _strafe_rotate(1.0)
    along = {}  # how far past the waypoint's line the rover was when it counted as reached
    while run.ex.running and run.t < 20:
        before, pose = run.ex.current, run.pose
        run.step()
        if run.ex.current != before and 2 <= before <= 6:  # items 2..6 pass through
            along[before] = pose.x_m - 0.5 * (before - 1)
    assert max(abs(a) for a in along.values()) <= 1.0 * DT / 2 + 0.001, along


def test_heading_schedule_turns_in_proportion_to_the_distance_and_feeds_its_rate_forward():
    leg = Leg((0.0, 0.0), (0.5, 0.0))
    yaw, rate = heading_schedule(leg, (0.25, 0.0), 0.0, math.radians(30.0), 1.0)
    assert yaw == pytest.approx(math.radians(15.0))
    assert rate == pytest.approx(math.radians(30.0) / 0.5)
    assert heading_schedule(leg, (0.6, 0.0), 0.0, 1.0, 1.0) == (1.0, 0.0)  # past the end
    yaw, rate = heading_schedule(leg, (0.25, 0.0), math.radians(170.0), math.radians(-170.0),
                                 1.0)  # the shorter way, through 180
    assert abs(math.degrees(yaw)) == pytest.approx(180.0) and rate > 0.0


def test_a_leg_of_no_length_turns_to_its_heading_at_once_with_no_rate_fed_forward():
    # (two waypoints on the same spot, as a ground station's "turn here" item makes)
    here = Leg((1.0, 2.0), (1.0, 2.0))
    assert heading_schedule(here, (1.0, 2.0), 0.0, 1.2, 1.0) == (1.2, 0.0)


def test_a_yaw_rate_feed_forward_is_added_to_the_heading_controller():
    controller = GuidedController(Params())
    here = Pose2d(0.0, 0.0, 0.3)
    controller.start(here, 0.0)
    controller.accept(Setpoint(None, None, 0.3, None, 0.0, None, 0.5), here)
    assert controller.update(here, 0.02).yaw_rate == pytest.approx(0.5)


def _polygon_run(corner_lead: bool) -> float:
    """Worst distance (m) from the path of a 16-gon of 1.5 m (the bench's eight's circle)
    driven at 1 m/s, with or without the early turn at each corner."""
    turn = 2 * math.pi / 16
    points = [(0.75 * math.sin(turn * k), 0.75 * (1 - math.cos(turn * k))) for k in range(1, 17)]
    run = Run([HOME, *(local_wp(0, n, e) for n, e in points)], WP_SPEED=1.0,
              GUID_SPD_MAX=1.2, WHL_MAX_SPD=3.0)
    if not corner_lead:
        run.ex.corner_lead_s = 0.0
    run.until_done()
    legs = [Leg(a, b) for a, b in zip([(0.0, 0.0), *points], points, strict=False)]
    return max(min(leg.distance_m((p.x_m, p.y_m)) for leg in legs) for _, p, _ in run.track)


def test_the_turn_onto_the_next_leg_begins_early_so_the_path_stays_closer_to_the_polygon():
    assert _polygon_run(True) < 0.75 * _polygon_run(False)


def test_corner_lead_moves_the_speed_onto_the_next_leg_as_the_waypoint_nears():
    leg, north, east = Leg((0.0, 0.0), (1.0, 0.0)), (0.5, 0.0), (0.0, 1.0)
    assert corner_lead(leg, east, (0.5, 0.0), north, 0.5, 0.2) == north  # 0.1 m lead: not yet
    half = corner_lead(leg, east, (0.95, 0.0), north, 0.5, 0.2)
    assert half == pytest.approx((0.25, 0.25))
    assert corner_lead(leg, east, (1.0, 0.0), north, 0.5, 0.2) == pytest.approx((0.0, 0.5))
    assert corner_lead(leg, (0.0, 0.0), (0.95, 0.0), north, 0.5, 0.2) == north  # no next leg


def test_corner_lead_of_no_length_changes_nothing_and_past_the_end_the_turn_is_whole():
    leg, north, east = Leg((0.0, 0.0), (1.0, 0.0)), (0.5, 0.0), (0.0, 1.0)
    assert corner_lead(leg, east, (0.95, 0.0), north, 0.5, 0.0) == north  # (lead time 0)
    assert corner_lead(leg, east, (1.2, 0.0), north, 0.5, 0.0) == north  # (and past the end)
    assert corner_lead(leg, east, (0.95, 0.0), north, 0.0, 0.2) == north  # (a stop)
    assert corner_lead(leg, east, (1.2, 0.0), north, 0.5, 0.2) == pytest.approx((0.0, 0.5))


def test_a_rover_stalled_inside_the_radius_of_a_stop_goes_on_after_the_settle_timeout():
    params = Params()
    executor = MissionExecutor(params)
    executor.load(renumber([HOME, local_wp(0, 1.0, 0.0), local_wp(0, 1.0, 1.0)]))
    stalled = Pose2d(0.98, 0.0, 0.0)  # 2 cm short, inside WP_RADIUS 3 cm, not moving
    assert executor.start(stalled, 0.0, None) is None
    t = 0.0
    while executor.current == 1 and t < 5.0:
        t += DT
        executor.update(stalled, (0.06, 0.0), t)  # the controller still asks for 6 cm/s
    assert executor.current == 2
    assert SETTLE_TIMEOUT_S <= t <= SETTLE_TIMEOUT_S + 2 * DT


def test_a_control_pass_that_comes_late_starts_the_grid_again_instead_of_a_burst_of_ticks():
    from mecanum_mav.config.views import InputConfig, OutputConfig
    from mecanum_mav.control.pwm import PwmMap
    from mecanum_mav.protocol.modes import Mode

    params = Params()
    pilot = _autopilot()
    config, pwm = OutputConfig.from_params(params), PwmMap.from_params(params)
    priority = InputConfig.from_params(params).desaturation
    period = config.control_period_s
    pilot.on_mode_change(Mode.MANUAL, Mode.GUIDED, 0.0)

    def tick(now_s: float) -> object:
        return pilot.output(False, now_s, config, priority, pwm)

    tick(0.0)
    late = tick(10 * period)  # the loop was held up for ten periods: one tick now,
    assert tick(10.5 * period) is late  # the next a whole period after it, not at once
    assert tick(11 * period) is not late


@pytest.mark.parametrize(("ticks_short", "reached"), [(0.4, True), (0.6, False)])
def test_a_waypoint_passed_at_speed_counts_at_the_tick_nearest_the_line_through_it(
        ticks_short: float, reached: bool):
    """The docstring's rule: passed at speed, a waypoint is reached at the tick nearest to
    where the rover crosses the line through it square to the leg, i.e. when it is within
    half a tick's travel short of that line (the next tick would be further past it)."""
    params = Params()
    params.update({"WP_SPEED": 1.0})
    ex = MissionExecutor(params)
    ex.load(renumber([HOME, local_wp(0, 2.0, 0.0), local_wp(0, 4.0, 0.0)]))
    assert ex.start(Pose2d(0.0, 0.0, 0.0), 0.0, None) is None
    north, t, velocity = 0.0, 0.0, (0.0, 0.0)
    while north < 1.5:  # an ideal rover: it moves exactly as commanded, at 1 m/s by now
        t += DT
        north += velocity[0] * DT
        velocity = ex.update(Pose2d(north, 0.0, 0.0), velocity, t).velocity_ned
    assert velocity == pytest.approx((1.0, 0.0))
    t += DT  # one tick's travel: 2 cm
    ex.update(Pose2d(2.0 - ticks_short * 1.0 * DT, 0.0, 0.0), velocity, t)
    assert (ex.current == 2) is reached


@pytest.mark.parametrize(("north", "east"), [(2.0, 0.0), (0.0, 2.0), (-2.0, 0.0), (0.0, -2.0)])
def test_a_waypoint_headings_rate_is_fed_forward_at_the_speed_along_its_leg_whichever_way(
        north: float, east: float):
    """heading_schedule: the heading turns in proportion to the distance driven and its rate,
    turn / length x the speed along the leg, is fed forward, on a leg pointing any way."""
    params = Params()
    params.update({"WP_SPEED": 0.5})
    ex = MissionExecutor(params)
    ex.load(renumber([HOME, local_wp(0, north, east, param4=90.0)]))
    assert ex.start(Pose2d(0.0, 0.0, 0.0), 0.0, None) is None
    here, t, velocity = (0.0, 0.0), 0.0, (0.0, 0.0)
    while math.hypot(*here) < 1.0:  # an ideal rover, to the middle of the 2 m leg
        t += DT
        here = (here[0] + velocity[0] * DT, here[1] + velocity[1] * DT)
        setpoint = ex.update(Pose2d(*here, 0.0), velocity, t)
        velocity = setpoint.velocity_ned
    along = math.hypot(*velocity)
    assert along == pytest.approx(0.5)
    assert setpoint.yaw_rate_ff == pytest.approx(math.radians(90.0) / 2.0 * along, rel=0.05)
