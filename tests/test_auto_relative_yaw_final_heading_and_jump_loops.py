"""The mission executor's rules for a relative CONDITION_YAW, for a heading still being turned
when the mission ends, and for a DO_JUMP loop with no navigation item in it (the module
docstring of mecanum_mav.control.executor; docs/companion.md, AUTO): the executor alone,
stepped with a perfect rover that is where it is told and turns at the commanded rate, and the
whole companion in the lockstep harness where the ground station sees the result."""

from __future__ import annotations

import math

import pytest
from conftest import lockstep
from missionitems import JUMP, SPEED, YAW, do, local_wp, renumber

from mecanum_mav.config.params import Params
from mecanum_mav.control.executor import YAW_ACCEPT_RAD, ExecutorEvent, MissionExecutor
from mecanum_mav.control.guided import Setpoint
from mecanum_mav.io.links import mavlink
from mecanum_mav.mecanum.geometry import Pose2d, wrap_pi
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.statustext import Severity

HOME = local_wp(0, 0.0, 0.0)
DT = 0.02
TURN_RATE = math.radians(45.0)
"""The perfect rover's turn rate (rad/s), toward the setpoint's heading."""


class PerfectRover:
    """The executor driving a rover that stands still where it is and turns toward each
    setpoint's heading at :data:`TURN_RATE` (so only the heading logic is exercised); the
    headings it passed through, unwrapped, in :attr:`turned`."""

    def __init__(self, items: list[MissionItem], start: Pose2d | None = None) -> None:
        self.ex = MissionExecutor(Params())
        self.ex.load(renumber(items))
        self.pose, self.t = start or Pose2d(0.0, 0.0, 0.0), 0.0
        self.turned = [0.0]
        self.events: list[ExecutorEvent] = []
        self.setpoints: list[Setpoint] = []
        self.poses: list[Pose2d] = []  # (the pose each setpoint was asked with)
        assert self.ex.start(self.pose, 0.0, None) is None
        self.events += self.ex.take_events()

    def step(self) -> None:
        self.poses.append(self.pose)
        setpoint = self.ex.update(self.pose, (0.0, 0.0), self.t)
        self.setpoints.append(setpoint)
        self.events += self.ex.take_events()
        if setpoint.yaw is not None:
            error = wrap_pi(setpoint.yaw - self.pose.yaw_rad)
            turn = max(-TURN_RATE * DT, min(TURN_RATE * DT, error))
            self.pose = Pose2d(self.pose.x_m, self.pose.y_m, wrap_pi(self.pose.yaw_rad + turn))
            self.turned.append(self.turned[-1] + turn)
        self.t += DT

    def until_done(self, limit_s: float = 30.0) -> PerfectRover:
        while self.ex.running and self.t < limit_s:
            self.step()
        assert not self.ex.running, "mission did not finish"
        return self


def test_a_relative_condition_yaw_turns_by_its_angle_from_the_current_target():
    """param4 = 1: param1 degrees relative to the heading commanded so far; a negative angle
    with no direction (param3 0) turns counter-clockwise."""
    run = PerfectRover([HOME, do(0, YAW, -60.0, 0.0, 0.0, 1.0)]).until_done()
    assert abs(wrap_pi(run.pose.yaw_rad + math.radians(60.0))) <= YAW_ACCEPT_RAD
    assert min(run.turned) < math.radians(-55.0) and max(run.turned) <= 0.0


def test_relative_condition_yaws_in_a_row_add_up_even_before_the_rover_has_turned():
    """Relative to the current target, not to where the rover happens to face: two items of
    +90 relative before a leg make 180 degrees, although the rover has not turned yet when the
    second is read (the mission moves on at once while the rover turns on its leg)."""
    items = [HOME, do(0, YAW, 90.0, 0.0, 0.0, 1.0), do(0, YAW, 90.0, 0.0, 0.0, 1.0),
             local_wp(0, 3.0, 0.0)]
    run = PerfectRover(items)
    assert run.ex.current == 3  # both yaw items done before the rover turned at all
    for _ in range(int(6.0 / DT)):
        run.step()
    assert abs(wrap_pi(run.pose.yaw_rad - math.pi)) <= YAW_ACCEPT_RAD


@pytest.mark.parametrize("direction", [1.0, -1.0])
@pytest.mark.parametrize("angle", [270.0, 180.0])
def test_a_relative_turn_of_half_a_circle_or_more_keeps_its_asked_direction(
        angle: float, direction: float) -> None:
    """param3 1 (clockwise) with 270 degrees relative: the rover turns clockwise through south
    to -90, not 90 degrees the short way; param3 -1 counter-clockwise to +90. Half a circle
    has no shorter way: it turns the way asked too."""
    run = PerfectRover([HOME, do(0, YAW, angle, 0.0, direction, 1.0)]).until_done()
    turned = [direction * t for t in run.turned]  # (in the asked direction)
    assert max(turned) > math.radians(angle - 10.0) and min(turned) >= 0.0
    if angle > 180.0:  # the way asked is the long way: the heading leads by a quarter turn
        first = run.setpoints[0].yaw
        assert first is not None
        assert wrap_pi(first - run.poses[0].yaw_rad) == pytest.approx(direction * math.pi / 2)
    assert abs(wrap_pi(run.pose.yaw_rad - direction * math.radians(angle))) <= YAW_ACCEPT_RAD


def test_a_small_positive_relative_angle_without_a_direction_turns_clockwise():
    run = PerfectRover([HOME, do(0, YAW, 0.5, 0.0, 0.0, 1.0)])
    for _ in range(int(1.0 / DT)):
        run.step()
    assert max(run.turned) == pytest.approx(math.radians(0.5)) and min(run.turned) >= 0.0


def test_a_relative_turn_under_half_a_circle_with_a_direction_turns_that_way():
    """param3 -1 (counter-clockwise) with 90 degrees relative: 90 counter-clockwise."""
    run = PerfectRover([HOME, do(0, YAW, 90.0, 0.0, -1.0, 1.0)]).until_done()
    assert min(run.turned) < math.radians(-85.0) and max(run.turned) <= 0.0
    assert abs(wrap_pi(run.pose.yaw_rad + math.pi / 2)) <= YAW_ACCEPT_RAD


def test_the_mission_completes_only_once_the_last_waypoints_heading_is_reached():
    """A last waypoint whose heading (param4) is not yet reached when the rover arrives: it is
    reached (MISSION_ITEM_REACHED) on arrival, and the mission ends ("Mission complete") only
    once the rover faces that heading, turned in place."""
    run = PerfectRover([HOME, local_wp(0, 0.0, 0.0, param4=120.0)])
    while not any(e.kind == "reached" for e in run.events):
        run.step()
    assert abs(math.degrees(run.pose.yaw_rad)) < 10.0  # arrived, still facing about north
    assert run.ex.running and not run.ex.complete
    run.until_done()
    assert abs(wrap_pi(run.pose.yaw_rad - math.radians(120.0))) <= YAW_ACCEPT_RAD
    texts = [e.text for e in run.events if e.kind == "say"]
    assert texts[-1] == "Mission complete"
    assert [e.kind for e in run.events].count("finished") == 1
    # MISSION_ITEM_REACHED names items of the mission only: the turn is no item of its own
    assert [e.seq for e in run.events if e.kind == "reached"] == [1]


def test_the_last_turn_in_place_holds_where_the_rover_arrived_and_so_does_the_end():
    """Arrived at the last waypoint facing north, its heading 120: the turn in place holds
    the position (a position setpoint, no velocity), and the mission's end holds it too."""
    arrived = (1.5, -0.5)
    run = PerfectRover([HOME, local_wp(0, *arrived, param4=120.0)],
                       start=Pose2d(*arrived, 0.0))
    while "reached" not in [e.kind for e in run.events] and run.t < 1.0:
        run.step()
    assert run.ex.running and abs(math.degrees(run.pose.yaw_rad)) < 10.0  # (yet to turn)
    turning = len(run.setpoints)
    run.until_done()
    assert len(run.setpoints) - turning > 10  # (it turned for a while)
    for setpoint in run.setpoints[turning:]:
        assert setpoint.velocity_ned is None and setpoint.position_ned == arrived
    after = run.ex.update(run.pose, (0.0, 0.0), run.t)
    assert after.position_ned == arrived and after.velocity_ned is None


def test_a_jump_loop_without_a_navigation_item_stops_the_mission_with_an_error():
    """DO items that jump back to each other with no navigation item between would never
    reach a point: the executor stops the mission (an ERROR naming the loop), marks it
    complete and reports the end."""
    ex = MissionExecutor(Params())
    ex.load(renumber([HOME, do(0, SPEED, 1.0, 0.3), do(0, JUMP, 1.0, -1.0)]))
    assert ex.start(Pose2d(0.0, 0.0, 0.0), 0.0, None) is None
    events = ex.take_events()
    said = [(e.severity, e.text) for e in events if e.kind == "say"]
    assert said[-1] == (Severity.ERROR, "Mission stopped: DO_JUMP loop without a waypoint")
    assert events[-1].kind == "finished"
    assert not ex.running and ex.state == mavlink.MISSION_STATE_COMPLETE


def test_a_jump_loop_without_a_navigation_item_ends_auto_in_hold_saying_why():
    """The same mission uploaded to the companion: AUTO ends at once in HOLD (the end of a
    mission), the ground station told why; the wheels never move."""
    h = lockstep()
    items = renumber([HOME, do(0, SPEED, 1.0, 0.3), do(0, JUMP, 1.0, -1.0)])
    assert h.gcs.upload(items).type == mavlink.MAV_MISSION_ACCEPTED
    h.gcs.arm()
    since = h.gcs.mark()
    h.gcs.set_mode(Mode.AUTO)
    assert h.run_until(lambda: h.core.vehicle.mode is Mode.HOLD, 2.0)
    assert h.gcs.wait("STATUSTEXT", lambda m: m.text == "Mission stopped: DO_JUMP loop without "
                      "a waypoint" and m.severity == mavlink.MAV_SEVERITY_ERROR, 1.0, since)
    assert all(o.channels[:4] == [1500] * 4 for o in h.overrides_since(0.0))


def _yaw_reached_at_heading_deg(next_wp: tuple[float, float]) -> float:
    """A rover at (5, 3) facing north; CONDITION_YAW to 90 then a waypoint at ``next_wp``:
    the heading (deg) the rover had when the yaw item was reported reached. While the yaw
    item is current the rover holds where it is."""
    run = PerfectRover([HOME, do(0, YAW, 90.0, 0.0, 0.0, 0.0), local_wp(0, *next_wp)],
                       start=Pose2d(5.0, 3.0, 0.0))
    while not any(e.kind == "reached" and e.seq == 1 for e in run.events):
        run.step()
        if run.ex.current == 1:
            assert run.setpoints[-1].position_ned == (5.0, 3.0)
            assert run.setpoints[-1].velocity_ned is None
        assert run.t < 5.0, "the yaw item was never reached"
    return math.degrees(run.pose.yaw_rad)


def test_a_condition_yaw_before_a_waypoint_where_the_rover_stands_is_turned_first():
    """Nothing to drive to (the next waypoint within its radius of the rover): the heading is
    turned in place, and the yaw item reached once it is."""
    assert abs(_yaw_reached_at_heading_deg((5.02, 3.0)) - 90.0) <= math.degrees(YAW_ACCEPT_RAD)


def test_a_condition_yaw_before_a_waypoint_farther_away_is_turned_on_the_way():
    """(The mission moves on at once; the rover turns while it drives.)"""
    assert abs(_yaw_reached_at_heading_deg((8.0, 3.0))) < 5.0


def test_a_mission_ending_in_a_do_item_holds_the_last_waypoint():
    end = (1.5, -0.5)
    run = PerfectRover([HOME, local_wp(0, *end), do(0, SPEED, 1.0, 0.3)],
                       start=Pose2d(*end, 0.0)).until_done()
    after = run.ex.update(run.pose, (0.0, 0.0), run.t)
    assert after.position_ned == end and after.velocity_ned is None


def test_a_long_way_turn_asked_before_a_leg_is_turned_the_long_way_while_driving_it():
    """CONDITION_YAW 270 clockwise (relative), then a waypoint 3 m north: the mission moves on
    at once and the heading turns clockwise through south while the rover drives."""
    run = PerfectRover([HOME, do(0, YAW, 270.0, 0.0, 1.0, 1.0), local_wp(0, 3.0, 0.0)])
    for _ in range(int(8.0 / DT)):
        run.step()
    assert run.ex.current == 2
    assert max(run.turned) > math.radians(260.0) and min(run.turned) >= 0.0


def test_a_condition_yaws_rate_limit_holds_on_a_leg_that_turns_to_a_waypoints_heading():
    """CONDITION_YAW's rate (param2, deg/s) limits the turns that follow, also the heading
    scheduled along a leg to a waypoint's own heading (param4)."""
    run = PerfectRover([HOME, do(0, YAW, 0.0, 10.0, 0.0, 0.0), local_wp(0, 3.0, 0.0, param4=90.0)])
    for _ in range(5):
        run.step()
    assert [s.yaw_rate_max for s in run.setpoints[1:]] == pytest.approx(
        [math.radians(10.0)] * 4)
