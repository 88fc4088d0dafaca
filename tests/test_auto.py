"""The mission executor and the leg follower, pure: a kinematic rover with motor lag driven
through the same GUIDED velocity and heading layer the companion uses."""

from __future__ import annotations

import itertools
import math
from itertools import pairwise

import pytest
from conftest import lockstep
from missionitems import JUMP, LOITER, RTL, SPEED, YAW, do, local_wp, renumber

from mecanum_mav.app.demo import demo_mission
from mecanum_mav.config.params import Params
from mecanum_mav.control.chain import autonomous_output
from mecanum_mav.control.executor import MissionExecutor
from mecanum_mav.control.guided import GuidedController
from mecanum_mav.control.pathfollow import (
    Leg,
    LegFollower,
    corner_speed,
    exit_speed_ahead,
    sqrt_controller,
)
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.io.links import mavlink
from mecanum_mav.mecanum.geometry import Pose2d, wrap_pi
from mecanum_mav.mecanum.kinematics import MecanumKinematics
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.statustext import Severity
from mecanum_mav.sim.chassis import SimChassis

HOME = local_wp(0, 0.0, 0.0)
DT = 0.02


class Run:
    """The companion's autonomous chain (executor -> GUIDED -> kinematics -> desaturation ->
    PWM, :func:`~mecanum_mav.control.chain.autonomous_output`) driving the simulated chassis
    (first-order motor lag), stepped at 50 Hz with the true pose as odometry."""

    def __init__(self, items, pose=None, **values):
        pose = pose or Pose2d(0.0, 0.0, 0.0)
        self.params = Params()
        self.params.update(values)
        self.ex = MissionExecutor(self.params)
        self.guided = GuidedController(self.params)
        self.ex.load(renumber(items))
        self.chassis = SimChassis.from_params(self.params, pose)
        self.kinematics = MecanumKinematics.from_half_extents(
            float(self.params["GEO_HALF_LEN"]), float(self.params["GEO_HALF_WID"]))
        self.pwm = PwmMap.from_params(self.params)
        self.pose, self.t = pose, 0.0
        self.events, self.track, self.speeds = [], [], []
        self.guided.start(pose, 0.0)
        assert self.ex.start(pose, 0.0, None) is None

    def step(self):
        wheels, _ = autonomous_output(self.guided, self.ex, self.pose, self.t, self.kinematics,
                                      float(self.params["WHL_MAX_SPD"]),
                                      int(self.params["MIX_DESAT"]), self.pwm)
        self.chassis.step(DT, wheels)
        self.pose = self.chassis.pose
        self.t += DT
        self.track.append((self.t, self.pose, self.ex.current))
        self.speeds.append(math.hypot(*self.chassis.velocity_body))
        self.events += self.ex.take_events()

    def until_done(self, limit_s=60.0):
        while self.ex.running and self.t < limit_s:
            self.step()
        assert not self.ex.running, "mission did not finish"
        return self

    def reached(self):
        return [e.seq for e in self.events if e.kind == "reached"]

    def texts(self):
        return [e.text for e in self.events if e.kind == "say"]


def test_sqrt_controller_is_linear_near_the_target_and_brakes_at_accel_beyond():
    assert sqrt_controller(0.01, 2.0, 1.0) == pytest.approx(0.02)
    far = sqrt_controller(-2.0, 2.0, 1.0)
    assert far == pytest.approx(-math.sqrt(2.0 * (2.0 - 0.125)))


def test_corner_speed_stops_for_right_angles_and_carries_speed_through_straight_ones():
    a = Leg((0.0, 0.0), (1.0, 0.0))
    assert corner_speed(a, Leg((1.0, 0.0), (1.0, 1.0)), 1.0, 1.0, 0.02) == 0.0
    assert corner_speed(a, Leg((1.0, 0.0), (2.0, 0.0)), 0.7, 1.0, 0.02) == 0.7
    shallow = corner_speed(a, Leg((1.0, 0.0), (2.0, 0.2)), 2.0, 1.0, 0.02)
    assert shallow == pytest.approx(math.sqrt(0.04) / math.sin(math.atan(0.2)))


@pytest.mark.parametrize("heading_deg", [0.0, 30.0, 135.0, -100.0])
@pytest.mark.parametrize("turn_deg", [20.0, -20.0])
def test_the_corner_speed_is_its_formula_for_the_same_turn_from_any_heading(
        heading_deg: float, turn_deg: float) -> None:
    """v = sqrt(2 * accel * overshoot) / sin(turn), for a turn of 20 degrees either way,
    whatever the heading it starts from (WP_ACCEL 0.5, WP_OVERSHOOT 0.05)."""
    h, t = math.radians(heading_deg), math.radians(heading_deg + turn_deg)
    a = Leg((0.0, 0.0), (math.cos(h), math.sin(h)))
    b = Leg(a.end_ned, (a.end_ned[0] + math.cos(t), a.end_ned[1] + math.sin(t)))
    assert corner_speed(a, b, 5.0, 0.5, 0.05) == pytest.approx(
        math.sqrt(2.0 * 0.5 * 0.05) / math.sin(math.radians(20.0)))


def test_leg_follower_brakes_to_its_exit_speed_at_accel_over_the_distance_left():
    """v^2 = exit^2 + 2 a d: 2 m before the end, exit 0.5 m/s, accel 0.5: 1.5 m/s along."""
    follower = LegFollower()
    follower.reset(5.0)
    vn, ve = follower.velocity_ned(Leg((0.0, 0.0), (10.0, 0.0)), (8.0, 0.0), 0.02, cruise=5.0,
                                   accel=0.5, exit_speed=0.5, gain=1.0)
    assert (vn, ve) == pytest.approx((1.5, 0.0))


def test_leg_follower_ramps_up_from_rest_at_accel_even_to_a_slow_cruise():
    follower = LegFollower()
    speeds = [follower.velocity_ned(Leg((0.0, 0.0), (0.0, 10.0)), (0.0, 0.0), 0.02, cruise=0.8,
                                    accel=0.5, exit_speed=0.0, gain=1.0)[1] for _ in range(3)]
    assert speeds == pytest.approx([0.01, 0.02, 0.03])


def test_leg_follower_holds_a_leg_of_no_length_as_a_point():
    follower = LegFollower()
    here, point = (0.3, -0.2), (1.0, 2.0)
    got = follower.velocity_ned(Leg(point, point), here, 0.02, cruise=1.0, accel=0.5,
                                exit_speed=0.0, gain=1.5)
    assert got == pytest.approx((sqrt_controller(0.7, 1.5, 0.5), sqrt_controller(2.2, 1.5, 0.5)))


def test_leg_follower_pulls_back_to_the_line_and_never_exceeds_cruise_along_it():
    leg, follower = Leg((0.0, 0.0), (5.0, 0.0)), LegFollower()
    for _ in range(100):
        vn, ve = follower.velocity_ned(leg, (1.0, 0.3), 0.02, cruise=0.5, accel=0.5,
                                       exit_speed=0.0, gain=1.5)
    assert vn == pytest.approx(0.5) and ve < -0.2  # full speed along, back west to the line


def test_waypoints_are_reached_in_order_within_the_radius_and_near_the_line():
    points = [(1.5, 0.0), (1.5, 1.5), (0.0, 0.0)]
    run = Run([HOME, *(local_wp(0, n, e) for n, e in points)]).until_done()
    assert run.reached() == [1, 2, 3]
    assert max(run.ex.arrival_errors.values()) <= 0.03
    legs = [Leg((0.0, 0.0), points[0]), Leg(points[0], points[1]), Leg(points[1], points[2])]
    for k, leg in enumerate(legs, start=1):
        assert max(leg.distance_m((p.x_m, p.y_m)) for _, p, c in run.track if c == k) < 0.05
    assert run.ex.state == mavlink.MISSION_STATE_COMPLETE
    assert "Mission complete" in run.texts()


def test_a_shallow_corner_is_passed_without_stopping():
    run = Run([HOME, local_wp(0, 1.5, 0.0), local_wp(0, 3.0, 0.3)], WP_OVERSHOOT=0.05)
    while run.ex.current == 1 and run.t < 20:
        run.step()
    assert run.speeds[-1] > 0.3  # still moving when it switched to the next leg
    run.until_done()
    leg = Leg((1.5, 0.0), (3.0, 0.3))
    assert max(leg.distance_m((p.x_m, p.y_m)) for _, p, c in run.track if c == 2) < 0.06


def test_do_change_speed_sets_the_leg_speed_and_is_limited_by_guid_spd_max():
    run = Run([HOME, do(0, SPEED, 1, 0.25), local_wp(0, 2.0, 0.0)]).until_done()
    assert max(run.speeds) == pytest.approx(0.25, abs=0.01)
    run = Run([HOME, do(0, SPEED, 1, 5.0), local_wp(0, 3.0, 0.0)], GUID_SPD_MAX=0.6)
    run.until_done()
    assert max(run.speeds) == pytest.approx(0.6, abs=0.01)
    said = [e for e in run.events if e.kind == "say" and "limited to GUID_SPD_MAX" in e.text]
    assert [(e.severity, e.text) for e in said] == [
        (Severity.WARNING, "Speed 5 limited to GUID_SPD_MAX 0.6")]


def test_do_change_speed_to_exactly_guid_spd_max_is_not_limited_and_says_nothing():
    run = Run([HOME, do(0, SPEED, 1, 0.6), local_wp(0, 3.0, 0.0)], GUID_SPD_MAX=0.6)
    run.until_done()
    assert max(run.speeds) == pytest.approx(0.6, abs=0.01)
    assert not any("limited" in t for t in run.texts())


def test_condition_yaw_at_the_end_turns_in_place_before_the_mission_completes():
    run = Run([HOME, local_wp(0, 0.5, 0.0), do(0, YAW, 90.0, 45.0, 0.0, 0.0)]).until_done()
    assert math.degrees(run.pose.yaw_rad) == pytest.approx(90.0, abs=2.5)
    assert math.hypot(run.pose.x_m - 0.5, run.pose.y_m) < 0.04  # in place
    turning = [p for _, p, c in run.track if c == 2]
    rates = [abs(b.yaw_rad - a.yaw_rad) / DT for a, b in itertools.pairwise(turning)]
    assert max(rates) <= math.radians(45.0) * 1.05  # the item's rate limit


def test_condition_yaw_before_a_leg_turns_while_driving_it():
    run = Run([HOME, do(0, YAW, 90.0, 0.0, 0.0, 0.0), local_wp(0, 1.5, 0.0)]).until_done()
    reached_yaw_at = next(t for t, p, _ in run.track if abs(p.yaw_rad - math.pi / 2) < 0.05)
    arrived_at = run.track[-1][0]
    assert reached_yaw_at < arrived_at - 1.0  # turned early, while driving
    assert max(abs(p.y_m) for _, p, _ in run.track) < 0.05  # and the path stayed straight


def test_condition_yaw_with_a_direction_turns_the_long_way():
    run = Run([HOME, local_wp(0, 0.0, 0.0), do(0, YAW, 270.0, 0.0, 1.0, 0.0)]).until_done()
    poses = [p for _, p, _ in run.track]
    turned = itertools.accumulate(wrap_pi(b.yaw_rad - a.yaw_rad) for a, b in pairwise(poses))
    assert max(turned) > math.radians(200)  # clockwise through south, not -90 the short way
    assert math.degrees(math.remainder(run.pose.yaw_rad, 2 * math.pi)) == pytest.approx(
        -90.0, abs=2.5)


def test_face_next_waypoint_turns_along_each_leg():
    run = Run([HOME, local_wp(0, 0.0, 1.5)], WP_YAW_BEHAVIOR=1).until_done()
    assert math.degrees(run.pose.yaw_rad) == pytest.approx(90.0, abs=2.0)


def test_waypoint_yaw_param4_sets_the_heading_from_that_leg_on():
    run = Run([HOME, local_wp(0, 1.0, 0.0, param4=-45.0), local_wp(0, 1.0, 1.0)]).until_done()
    assert math.degrees(run.pose.yaw_rad) == pytest.approx(-45.0, abs=2.0)


def test_loiter_time_holds_the_point_for_its_time():
    run = Run([HOME, local_wp(0, 0.5, 0.0, command=LOITER, param1=2.0), local_wp(0, 0.0, 0.0)])
    run.until_done()
    at_loiter = [t for t, p, c in run.track if c == 1 and math.hypot(p.x_m - 0.5, p.y_m) < 0.03]
    assert at_loiter[-1] - at_loiter[0] >= 2.0


def test_return_to_launch_drives_home():
    run = Run([HOME, local_wp(0, 1.0, 0.5), MissionItem(0, 2, RTL)]).until_done()
    assert math.hypot(run.pose.x_m, run.pose.y_m) < 0.03
    assert run.reached() == [1, 2]


def test_do_jump_repeats_and_the_counters_reset_when_the_mission_restarts():
    items = [HOME, local_wp(0, 0.2, 0.0), local_wp(0, 0.0, 0.0), do(0, JUMP, 1, 1)]
    run = Run(items).until_done()
    assert run.reached() == [1, 2, 3, 1, 2, 3]
    run.events.clear()
    assert run.ex.start(run.pose, run.t, None) is None  # AUTO again after the end: restart
    run.until_done(limit_s=run.t + 30)
    assert run.reached() == [1, 2, 3, 1, 2, 3]


def test_a_jump_loop_without_waypoints_advances_one_item_per_tick():
    run = Run([HOME, local_wp(0, 0.0, 0.0), do(0, JUMP, 1, -1)])
    for _ in range(50):
        run.step()
    assert run.ex.running and 10 <= run.reached().count(1) <= 50


def test_unsupported_items_are_skipped_with_a_statustext_naming_them():
    servo = MissionItem(0, 2, mavlink.MAV_CMD_DO_SET_SERVO, param1=9, param2=1500)
    run = Run([HOME, servo, local_wp(0, 0.3, 0.0)]).until_done()
    assert "Skipped item 1: DO_SET_SERVO unsupported" in run.texts()
    assert run.reached() == [2]


def test_pause_keeps_the_current_item_and_start_resumes_it_from_where_the_rover_is():
    run = Run([HOME, local_wp(0, 2.0, 0.0), local_wp(0, 2.0, 1.0)])
    while run.pose.x_m < 0.8:
        run.step()
    run.ex.pause()
    assert run.ex.state == mavlink.MISSION_STATE_PAUSED and run.ex.current == 1
    run.events.clear()
    assert run.ex.start(run.pose, run.t, None) is None
    run.events += run.ex.take_events()
    assert "Mission resumed at item 1" in run.texts()
    run.until_done()
    assert run.reached() == [1, 2]


def test_a_global_mission_without_an_origin_cannot_start():
    item = MissionItem(1, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mavlink.MAV_CMD_NAV_WAYPOINT,
                       x=473977420, y=85455940)
    ex = MissionExecutor(Params())
    ex.load([HOME, item])
    assert "origin" in ex.prepare(None)


def test_pass_through_waypoints_plan_their_speed_so_the_rover_stops_at_the_next_stop():
    # six collinear 0.5 m legs at 1.5 m/s: braking must start legs before the last waypoint
    points = [(0.5 * k, 0.0) for k in range(1, 7)]
    run = Run([HOME, *(local_wp(0, n, e) for n, e in points)], WP_SPEED=1.5,
              GUID_SPD_MAX=1.7, WHL_MAX_SPD=3.0).until_done()
    last_leg = [s for (_, _, c), s in zip(run.track, run.speeds, strict=True) if c == 6]
    assert last_leg[0] <= math.sqrt(2 * 0.5 * 0.5) + 0.15  # entered the last leg braking
    assert max(p.x_m for _, p, _ in run.track) < 3.0 + 0.03
    assert max(run.speeds) > 1.0  # it did not crawl


def test_exit_speed_ahead_is_the_braking_speed_over_the_remaining_legs():
    legs = [Leg((0.0, 0.0), (1.0, 0.0)), Leg((1.0, 0.0), (2.0, 0.0)),
            Leg((2.0, 0.0), (2.5, 0.0))]
    assert exit_speed_ahead(legs, 5.0, 0.5, 0.02) == pytest.approx(math.sqrt(2 * 0.5 * 1.5))
    assert exit_speed_ahead(legs, 0.4, 0.5, 0.02) == pytest.approx(0.4)
    assert exit_speed_ahead(legs[:1], 5.0, 0.5, 0.02) == 0.0


def test_after_a_mission_ends_in_hold_the_autopilot_has_no_timer_left_and_the_loop_sleeps():
    """AUTO's control ticks end with the mission: in HOLD the autopilot asks for no wake, so
    the companion's loop sleeps until its next real timer (a past tick left behind made the
    loop wake at once, forever: 100 % of a core in HOLD after every mission)."""
    h = lockstep()
    items, _ = demo_mission(1.0)
    h.gcs.upload(items)
    h.run_for(1.0)
    h.gcs.arm()
    h.gcs.set_mode(Mode.AUTO)
    assert h.run_until(lambda: h.core.vehicle.mode is Mode.HOLD, 60.0)
    h.run_for(1.0)
    assert h.core.autopilot.next_due_s() == math.inf
    assert h.core.next_due_s() > h.now_s


def test_return_to_launch_has_no_hold_time_whatever_its_param1_holds():
    """MAV_CMD_NAV_RETURN_TO_LAUNCH's params are all empty: a 3 in param1 (a planner's
    leftover) is no hold; the mission ends on arrival, as one ending with a waypoint at home
    does."""
    there = [HOME, local_wp(0, 0.5, 0.0)]
    by_waypoint = Run([*there, local_wp(0, 0.0, 0.0)]).until_done().t
    for held in (0.0, 3.0):
        by_rtl = Run([*there, MissionItem(0, 2, RTL, param1=held)]).until_done().t
        assert by_rtl == pytest.approx(by_waypoint, abs=DT / 2), held


def test_facing_along_legs_turns_the_shorter_way_to_a_leg_behind_the_left_shoulder():
    """WP_YAW_BEHAVIOR 1, facing north, a leg to the west: counter-clockwise by 90 degrees,
    not clockwise by 270."""
    run = Run([HOME, local_wp(0, 0.0, -1.5)], WP_YAW_BEHAVIOR=1).until_done()
    poses = [p for _, p, _ in run.track]
    turned = list(itertools.accumulate(wrap_pi(b.yaw_rad - a.yaw_rad) for a, b in pairwise(poses)))
    assert max(turned) < math.radians(5.0) and min(turned) > math.radians(-100.0)
    assert math.degrees(run.pose.yaw_rad) == pytest.approx(-90.0, abs=2.0)


def test_a_waypoint_on_a_straight_line_is_passed_at_cruise_speed():
    """The next leg starts from the speed the rover has (its velocity along the new leg), so a
    waypoint between two legs in line is no stop."""
    run = Run([HOME, local_wp(0, 0.0, 2.0), local_wp(0, 0.0, 4.0)])  # (east)
    while 1 not in run.reached() and run.t < 20.0:
        run.step()
    at_waypoint = len(run.speeds)
    for _ in range(int(0.5 / DT)):
        run.step()
    cruise = float(run.params["WP_SPEED"])
    assert min(run.speeds[at_waypoint - 5:]) > 0.9 * cruise


def test_the_tick_that_passes_a_waypoint_at_speed_already_drives_the_next_leg():
    """No tick of holding the point passed: the update that reaches a pass-through waypoint
    returns the next leg's velocity (a rover that does exactly what it is told never stops)."""
    ex = MissionExecutor(Params())
    ex.load(renumber([HOME, local_wp(0, 1.0, 0.0), local_wp(0, 2.0, 0.0)]))
    pose, t, velocity = Pose2d(0.0, 0.0, 0.0), 0.0, (0.0, 0.0)
    assert ex.start(pose, t, None) is None
    while ex.current == 1 and t < 10.0:
        t += DT
        setpoint = ex.update(pose, velocity, t)
        assert setpoint.velocity_ned is not None and setpoint.position_ned is None, t
        velocity = setpoint.velocity_ned
        pose = Pose2d(pose.x_m + velocity[0] * DT, pose.y_m + velocity[1] * DT, 0.0)
    assert ex.current == 2 and velocity[0] > 0.5 * float(Params()["WP_SPEED"])
