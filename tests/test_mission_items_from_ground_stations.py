"""Mission items as ground stations write them: the special values Mission Planner, QGroundControl,
MAVProxy and MAVSDK put in them, and MISSION_SET_CURRENT's edge cases.

Each test states a rule from the MAVLink mission protocol and MAV_CMD documentation, from
ArduPilot Rover's behaviour (the reference the ground stations expect), or from this project's
own promise (docs/companion.md, the docstrings of ``protocol.mission`` and ``control.executor``).
The executor alone runs on test_auto's pure chain (:class:`test_auto.Run`); the protocol and the
commands end to end in the lockstep harness (virtual time)."""

from __future__ import annotations

import itertools
import math

import pytest
from conftest import lockstep
from missionitems import GLOBAL_REL, JUMP, LOITER, SPEED, YAW, do, local_wp, renumber
from test_auto import DT, HOME, Run

from mecanum_mav.config.params import Params
from mecanum_mav.control.executor import SETTLE_TIMEOUT_S, MissionExecutor
from mecanum_mav.io.links import mavlink
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.mecanum.geometry import Pose2d, wrap_pi
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.missionservice import MissionService
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.lockstep import Lockstep

WP = mavlink.MAV_CMD_NAV_WAYPOINT
ACCEPTED = mavlink.MAV_MISSION_ACCEPTED
CMD_ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
GCS = (255, 190)
WP_RADIUS = float(Params()["WP_RADIUS"])


def leg_speeds(run: Run, seq: int) -> list[float]:
    """The chassis's speed at every step while item ``seq`` was current."""
    return [s for (_, _, c), s in zip(run.track, run.speeds, strict=True) if c == seq]


# --------------------------------------------------------------------------- acceptance radius


def stalled_goes_on(short_m: float, params: dict | None = None, **wp_fields) -> bool:
    """Whether a rover stalled ``short_m`` before a stop waypoint (still asked for 6 cm/s, as
    an ESC dead band leaves it) goes on to the next item within 2 s after the settle timeout
    (:data:`SETTLE_TIMEOUT_S`: a stalled rover goes on once it has been inside the radius that
    long)."""
    p = Params()
    p.update(params or {})
    executor = MissionExecutor(p)
    executor.load(renumber([HOME, local_wp(0, 1.0, 0.0, **wp_fields), local_wp(0, 1.0, 1.0)]))
    stalled = Pose2d(1.0 - short_m, 0.0, 0.0)
    assert executor.start(stalled, 0.0, None) is None
    t = 0.0
    while executor.current == 1 and t < SETTLE_TIMEOUT_S + 2.0:
        t += DT
        executor.update(stalled, (0.06, 0.0), t)
    return executor.current == 2


def test_a_waypoint_is_reached_within_its_own_acceptance_radius_param2_not_wp_radius():
    """MAV_CMD_NAV_WAYPOINT param2 is the acceptance radius (docs/companion.md: "param2
    acceptance radius m, 0 = WP_RADIUS"): 10 cm short is inside a 20 cm radius although far
    outside WP_RADIUS (3 cm); 25 cm short is not."""
    assert WP_RADIUS < 0.1
    assert stalled_goes_on(0.10, param2=0.2)
    assert not stalled_goes_on(0.25, param2=0.2)


@pytest.mark.parametrize("radius", [0.0, math.nan], ids=["zero", "nan"])
def test_an_acceptance_radius_of_0_or_nan_means_the_wp_radius_parameter(radius):
    """0 (Mission Planner's and MAVProxy's files) and NaN (MAVSDK) in param2 mean "use the
    default": ``WP_RADIUS`` (protocol.mission: "NaN in a parameter that has a default means use
    the default"), neither a radius of nothing nor one of everything."""
    params = {"WP_RADIUS": 0.15}
    assert stalled_goes_on(0.10, params, param2=radius)
    assert not stalled_goes_on(0.20, params, param2=radius)


@pytest.mark.parametrize("command", [WP, LOITER], ids=["waypoint", "loiter-time"])
def test_a_hold_time_of_nan_means_no_hold(command):
    """NaN in param1 (hold / loiter time) is "use the default", 0 s: the rover goes on at
    once, as with 0, rather than holding the point for ever."""
    def run_with(hold: float) -> Run:
        return Run([HOME, local_wp(0, 0.6, 0.0, command=command, param1=hold),
                    local_wp(0, 0.6, 0.4)]).until_done(limit_s=20.0)

    nan, zero = run_with(math.nan), run_with(0.0)
    assert nan.reached() == [1, 2]
    assert nan.t == pytest.approx(zero.t, abs=2 * DT)


# --------------------------------------------------------------------------- latitude/longitude 0


ORIGIN = GlobalOrigin.from_degrees(47.397742, 8.545594)


def test_a_global_waypoint_or_loiter_at_latitude_and_longitude_0_is_where_the_rover_is():
    """ArduPilot Rover reads a latitude and longitude of 0 in a NAV_WAYPOINT or NAV_LOITER_TIME
    as the current position (``Location::sanitize`` in ``ModeAuto::do_nav_wp``), as Mission
    Planner and MAVProxy write "here": the rover stays where the previous item left it, it
    does not set off for 0 N 0 E."""
    h = lockstep()
    since = h.gcs.mark()
    h.gcs.mav.set_gps_global_origin_send(1, ORIGIN.lat_e7, ORIGIN.lon_e7, 0, 0)
    assert h.gcs.wait("GPS_GLOBAL_ORIGIN", timeout_s=1.0, since=since)
    lat, lon = ORIGIN.to_global(0.8, -0.4)
    items = renumber([
        MissionItem(0, GLOBAL_REL, WP, x=ORIGIN.lat_e7, y=ORIGIN.lon_e7),
        MissionItem(0, GLOBAL_REL, WP, x=lat, y=lon),
        MissionItem(0, GLOBAL_REL, WP, param1=0.5),  # x = y = 0: here, hold 0.5 s
        MissionItem(0, GLOBAL_REL, LOITER, param1=0.5),  # here too
    ])
    assert h.gcs.upload(items).type == ACCEPTED
    h.gcs.arm()
    since = h.gcs.mark()
    assert h.gcs.set_mode(Mode.AUTO) == CMD_ACCEPTED
    assert h.run_until(lambda: h.core.vehicle.mode is Mode.HOLD, 20.0), "mission not finished"
    reached = [m.seq for m in h.gcs.received("MISSION_ITEM_REACHED", since)]
    assert reached == [1, 2, 3]
    pose = h.truth().pose
    assert math.dist((pose.x_m, pose.y_m), (0.8, -0.4)) < WP_RADIUS + 0.005


def test_a_local_waypoint_at_0_0_is_the_origin_not_here():
    """In MAV_FRAME_LOCAL_NED x = y = 0 is a point, the local origin (home): only latitude and
    longitude 0 mean "here"."""
    run = Run([HOME, local_wp(0, 0.8, 0.3), local_wp(0, 0.0, 0.0, command=LOITER),
               local_wp(0, 0.0, 0.0)]).until_done(limit_s=20.0)
    assert run.reached() == [1, 2, 3]
    assert math.hypot(run.pose.x_m, run.pose.y_m) < WP_RADIUS + 0.005


def test_a_point_on_the_equator_or_the_prime_meridian_is_a_point_not_here():
    """Only both 0 mean "here": a latitude of exactly 0 with a longitude (or the reverse) is
    an ordinary point the rover drives to."""
    origin = GlobalOrigin.from_degrees(0.00001, 0.00001)  # 1.1 m north and east of 0 N 0 E
    for x, y in ((0, 100), (100, 0)):  # 1.1 m south, 1.1 m west of the origin
        executor = MissionExecutor(Params())
        executor.load([HOME, MissionItem(1, GLOBAL_REL, WP, x=x, y=y)])
        here = Pose2d(0.0, 0.0, 0.0)
        assert executor.start(here, 0.0, origin) is None
        setpoint = executor.update(here, (0.0, 0.0), DT)
        assert executor.current == 1 and executor.running  # not reached where it stands
        assert setpoint.velocity_ned is not None
        north, east = origin.to_local(x, y)
        vn, ve = setpoint.velocity_ned
        assert vn * north + ve * east > 0.0  # it sets off toward the point


# --------------------------------------------------------------------------- NaN in CONDITION_YAW


def test_condition_yaw_with_nan_rate_and_direction_turns_the_shorter_way_at_guid_yaw_rate():
    """CONDITION_YAW param2 (rate) and param3 (direction) NaN mean the defaults: the shorter
    way, at ``GUID_YAW_RATE`` (docs/companion.md, protocol.mission)."""
    run = Run([HOME, local_wp(0, 0.3, 0.0), do(0, YAW, -60.0, math.nan, math.nan, 0.0)],
              GUID_YAW_RATE=45.0).until_done(limit_s=20.0)
    assert math.degrees(run.pose.yaw_rad) == pytest.approx(-60.0, abs=2.5)
    poses = [p for _, p, c in run.track if c == 2]
    turned = list(itertools.accumulate(wrap_pi(b.yaw_rad - a.yaw_rad)
                                       for a, b in itertools.pairwise(poses)))
    assert min(turned) > math.radians(-65.0) and max(turned) < math.radians(5.0)  # short way
    rates = [abs(wrap_pi(b.yaw_rad - a.yaw_rad)) / DT for a, b in itertools.pairwise(poses)]
    assert max(rates) == pytest.approx(math.radians(45.0), rel=0.1)


# --------------------------------------------------------------------------- DO_CHANGE_SPEED


@pytest.mark.parametrize("no_change", [-1.0, 0.0], ids=["minus-1", "zero"])
def test_do_change_speed_minus_1_or_0_keeps_the_speed_set_before(no_change):
    """MAV_CMD_DO_CHANGE_SPEED param2: "-1 indicates no change" (MAVLink); this rover also
    reads 0 as no change (executor: "-1 or 0: no change"), never as a speed of 0 that would
    leave it standing."""
    run = Run([HOME, do(0, SPEED, 1.0, 0.25, -1.0), local_wp(0, 1.0, 0.0, param1=0.5),
               do(0, SPEED, 1.0, no_change, -1.0), local_wp(0, 2.5, 0.0)],
              WP_SPEED=0.5).until_done(limit_s=30.0)
    assert run.reached() == [1, 2, 3, 4]
    assert max(leg_speeds(run, 4)) == pytest.approx(0.25, abs=0.01)


def test_do_change_speed_minus_2_returns_to_wp_speed():
    """MAV_CMD_DO_CHANGE_SPEED param2: "-2 indicates return to default vehicle speed", the
    ``WP_SPEED`` parameter."""
    run = Run([HOME, do(0, SPEED, 1.0, 0.25, -1.0), local_wp(0, 1.0, 0.0, param1=0.5),
               do(0, SPEED, 1.0, -2.0, -1.0), local_wp(0, 2.5, 0.0)],
              WP_SPEED=0.45).until_done(limit_s=30.0)
    assert max(leg_speeds(run, 2)) == pytest.approx(0.25, abs=0.01)
    assert max(leg_speeds(run, 4)) == pytest.approx(0.45, abs=0.01)


@pytest.mark.parametrize("throttle", [-1.0, -2.0, 50.0])
def test_do_change_speed_throttle_in_param3_leaves_the_speed_to_param2(throttle):
    """param3 is a throttle ("-1 indicates no change"; QGroundControl sends -1): a rover driven
    by speed ignores it; param2 alone sets the speed."""
    run = Run([HOME, do(0, SPEED, 1.0, 0.3, throttle), local_wp(0, 1.5, 0.0)])
    run.until_done(limit_s=20.0)
    assert max(run.speeds) == pytest.approx(0.3, abs=0.01)


def test_a_speed_change_ends_when_the_mission_starts_over():
    """A DO_CHANGE_SPEED holds for the rest of the run; AUTO after the end starts the mission
    over at ``WP_SPEED`` (ArduPilot Rover's AUTO also starts at its default speed)."""
    run = Run([HOME, local_wp(0, 1.2, 0.0), do(0, SPEED, 1.0, 0.25, -1.0),
               local_wp(0, 0.0, 0.0)], WP_SPEED=0.45).until_done(limit_s=30.0)
    assert max(leg_speeds(run, 3)) == pytest.approx(0.25, abs=0.01)
    start = len(run.track)
    assert run.ex.start(run.pose, run.t, None) is None
    run.until_done(limit_s=run.t + 30.0)
    first_leg = [s for (_, _, c), s in zip(run.track[start:], run.speeds[start:], strict=True)
                 if c == 1]
    assert max(first_leg) == pytest.approx(0.45, abs=0.01)


# --------------------------------------------------------------------------- what uploads


def upload(items: list[MissionItem]) -> tuple[int, MissionService]:
    """Upload ``items`` (renumbered) to a fresh service; the final MISSION_ACK's result."""
    svc = MissionService()
    items = renumber(items)
    out = svc.on_count(GCS, len(items), mavlink.MAV_MISSION_TYPE_MISSION, 0.0)
    for it in items:
        fields = {name: getattr(it, name) for name in MissionItem.__dataclass_fields__}
        out = svc.on_item(GCS, fields, encoded=True, mission_type=mavlink.MAV_MISSION_TYPE_MISSION,
                          now=0.0)
    (ack,) = out
    assert ack.kind == "MISSION_ACK"
    return ack.result, svc


def test_the_default_values_ground_stations_send_are_accepted():
    """What QGroundControl, MAVSDK and Mission Planner write uploads: NaN hold, radius and yaw
    in a waypoint, a global 0/0 ("here"), DO_CHANGE_SPEED -1 / -2 / 0 with throttle -1, and
    CONDITION_YAW with NaN rate and direction."""
    result, svc = upload([
        HOME,
        local_wp(0, 1.0, 0.0, param1=math.nan, param2=math.nan, param3=math.nan),
        MissionItem(0, GLOBAL_REL, WP, param4=math.nan),
        MissionItem(0, GLOBAL_REL, LOITER, param1=2.0),
        do(0, SPEED, 1.0, -1.0, -1.0),
        do(0, SPEED, 1.0, -2.0, -1.0),
        do(0, SPEED, 0.0, 0.0, -1.0),
        do(0, YAW, 90.0, math.nan, math.nan, 0.0),
    ])
    assert result == ACCEPTED
    assert len(svc.items) == 8


@pytest.mark.parametrize(("bad", "result"), [
    (do(1, SPEED, 1.0, math.nan, -1.0), mavlink.MAV_MISSION_INVALID_PARAM2),
    (do(1, SPEED, 1.0, -3.0, -1.0), mavlink.MAV_MISSION_INVALID_PARAM2),
    (local_wp(1, 1.0, 0.0, param2=-0.5), mavlink.MAV_MISSION_INVALID_PARAM2),
    (local_wp(1, 1.0, 0.0, param1=-1.0), mavlink.MAV_MISSION_INVALID_PARAM1),
], ids=["speed-nan", "speed-minus-3", "negative-radius", "negative-hold"])
def test_values_without_a_meaning_are_refused_with_the_parameter_named(bad, result):
    """A speed that is neither a speed nor -1 / -2, a negative radius or hold time, is refused
    with the MAV_MISSION_RESULT naming the parameter (protocol.mission's check_item)."""
    assert upload([HOME, bad])[0] == result


# --------------------------------------------------------------------------- MISSION_SET_CURRENT


LINE = renumber([HOME, local_wp(0, 2.0, 0.0), local_wp(0, 2.0, 1.0), local_wp(0, 0.0, 0.6)])


def with_line() -> Lockstep:
    h = lockstep()
    assert h.gcs.upload(LINE).type == ACCEPTED
    return h


def current_after(h: Lockstep, send, within_s: float = 0.2) -> int | None:
    """Right after a MISSION_CURRENT (so the next 1 Hz one is far off): ``send()``, then the
    seq of the MISSION_CURRENT that answers within ``within_s``, or None."""
    assert h.gcs.wait("MISSION_CURRENT", timeout_s=1.5) is not None
    since = h.gcs.mark()
    send()
    msg = h.run_until(lambda: next(iter(h.gcs.received("MISSION_CURRENT", since)), None),
                      within_s)
    return None if msg is None else msg.seq


def test_set_current_past_the_last_item_is_refused_and_the_current_item_kept():
    """The last item is the highest that can be current; one past it is refused with a
    STATUSTEXT (by DO_SET_MISSION_CURRENT not ACCEPTED: MAVLink "will ACK with
    MAV_RESULT_FAILED if the sequence number is out of range"), and the current item stays."""
    h = with_line()
    last = len(LINE) - 1
    assert current_after(h, lambda: h.gcs.mav.mission_set_current_send(1, 1, last)) == last
    since = h.gcs.mark()
    h.gcs.mav.mission_set_current_send(1, 1, last + 1)
    refused = f"Set current item refused: no item {last + 1} (mission has {last})"
    assert h.run_until(lambda: refused in h.gcs.texts(since), 1.0), h.gcs.texts(since)
    ack = h.gcs.command(mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, last + 1)
    assert ack is not None and ack.result == mavlink.MAV_RESULT_FAILED
    assert h.core.mission.executor.current == last
    periodic = h.gcs.wait("MISSION_CURRENT", timeout_s=1.5)
    assert periodic is not None and periodic.seq == last


def test_set_current_to_the_item_already_current_is_answered_with_mission_current_at_once():
    """MISSION_SET_CURRENT: "emit MISSION_CURRENT (whether or not the mission number changed)"
    (MAVLink): a ground station waits for it as the answer."""
    h = with_line()
    assert current_after(h, lambda: h.gcs.mav.mission_set_current_send(1, 1, 2)) == 2
    assert current_after(h, lambda: h.gcs.mav.mission_set_current_send(1, 1, 2)) == 2


def test_set_current_0_home_makes_item_1_current():
    """Item 0 is home and never executed (docs/companion.md, ArduPilot): making it current
    means the first item, so AUTO never drives to home as a waypoint."""
    h = with_line()
    assert current_after(h, lambda: h.gcs.mav.mission_set_current_send(1, 1, 2)) == 2
    assert current_after(h, lambda: h.gcs.mav.mission_set_current_send(1, 1, 0)) == 1


def test_set_current_in_auto_drives_straight_to_the_new_item_skipping_those_between():
    """MISSION_SET_CURRENT while the mission runs: "continue to this new mission item on the
    shortest path, skipping any intermediate mission items" (MAVLink)."""
    h = with_line()
    h.gcs.arm()
    since = h.gcs.mark()
    assert h.gcs.set_mode(Mode.AUTO) == CMD_ACCEPTED
    assert h.run_until(lambda: h.truth().pose.x_m > 0.4, 5.0)
    h.gcs.mav.mission_set_current_send(1, 1, 3)
    farthest = [0.0]

    def done() -> bool:
        farthest[0] = max(farthest[0], h.truth().pose.x_m)
        return h.core.vehicle.mode is Mode.HOLD

    assert h.run_until(done, 15.0), "mission not finished"
    assert [m.seq for m in h.gcs.received("MISSION_ITEM_REACHED", since)] == [3]
    pose = h.truth().pose
    assert math.dist((pose.x_m, pose.y_m), (0.0, 0.6)) < WP_RADIUS + 0.005
    assert farthest[0] < 0.8  # it turned back at once, never near items 1 and 2


def test_set_current_outside_auto_neither_starts_the_mission_nor_moves_and_auto_starts_there():
    """"If the system is not in mission mode this message must not trigger a switch to mission
    mode" (MAVLink); AUTO later starts at the item made current."""
    h = with_line()
    h.gcs.arm()
    assert h.gcs.set_mode(Mode.HOLD) == CMD_ACCEPTED
    assert current_after(h, lambda: h.gcs.mav.mission_set_current_send(1, 1, 2)) == 2
    h.run_for(1.0)
    assert h.core.vehicle.mode is Mode.HOLD
    pose = h.truth().pose
    assert math.hypot(pose.x_m, pose.y_m) < 0.001
    since = h.gcs.mark()
    assert h.gcs.set_mode(Mode.AUTO) == CMD_ACCEPTED
    assert h.gcs.wait("STATUSTEXT", lambda m: "Mission started at item 2" in m.text, 1.0, since)
    first = h.gcs.wait("MISSION_ITEM_REACHED", timeout_s=15.0, since=since)
    assert first is not None and first.seq == 2


def test_after_the_end_set_current_chooses_where_auto_starts_again():
    """Set current on a finished mission, then AUTO: it runs from that item, not from item 1
    (ArduPilot's AP_Mission::set_current_cmd on a stopped or complete mission: "if the user
    resumes the mission it will begin at the specified index")."""
    run = Run([HOME, local_wp(0, 0.4, 0.0), local_wp(0, 0.4, 0.4), local_wp(0, 0.0, 0.4)])
    run.until_done(limit_s=30.0)
    run.events.clear()
    assert run.ex.set_current(2, run.pose) is None
    assert run.ex.state != mavlink.MISSION_STATE_COMPLETE
    assert run.ex.start(run.pose, run.t, None) is None
    run.until_done(limit_s=run.t + 30.0)
    assert run.reached() == [2, 3]


def test_set_current_keeps_the_do_jump_counters():
    """MISSION_SET_CURRENT: "mission jump repeat counters are not reset" (MAVLink): a jump
    already used up stays used up when the ground station sends the rover back."""
    run = Run([HOME, local_wp(0, 0.3, 0.0), local_wp(0, 0.0, 0.0), do(0, JUMP, 1, 1),
               local_wp(0, 0.0, 0.3)])
    while run.reached() != [1, 2, 3] and run.t < 30.0:
        run.step()
    assert run.ex.current == 1  # the second pass, the jump used up
    assert run.ex.set_current(1, run.pose) is None
    run.until_done(limit_s=run.t + 30.0)
    assert run.reached() == [1, 2, 3, 1, 2, 3, 4]


def test_do_set_mission_current_minus_1_with_reset_keeps_the_current_item():
    """MAV_CMD_DO_SET_MISSION_CURRENT param1 -1 is the current item, "use to reset mission
    without changing current mission item" (MAVLink); param2 = 1 resets the mission."""
    h = with_line()
    assert current_after(h, lambda: h.gcs.mav.mission_set_current_send(1, 1, 2)) == 2
    acks = []
    assert current_after(h, lambda: acks.append(h.gcs.command(
        mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, -1, 1))) == 2
    assert acks[0] is not None and acks[0].result == CMD_ACCEPTED
    assert current_after(h, lambda: acks.append(h.gcs.command(
        mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, -1, 0))) == 2
    assert acks[1] is not None and acks[1].result == CMD_ACCEPTED


def test_set_current_without_a_mission_is_refused_saying_so_and_item_0_stays_current():
    h = lockstep()
    since = h.gcs.mark()
    h.gcs.mav.mission_set_current_send(1, 1, 1)
    assert h.gcs.wait("STATUSTEXT", lambda m: m.text == "Set current item refused: no mission",
                      1.0, since)
    for reset in (0, 1):  # DO_SET_MISSION_CURRENT, "reset mission" or not
        ack = h.gcs.command(mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, -1, reset)
        assert ack is not None and ack.result == mavlink.MAV_RESULT_FAILED  # (MAVLink)
    periodic = h.gcs.wait("MISSION_CURRENT", timeout_s=1.5, since=h.gcs.mark())
    assert periodic is not None and (periodic.seq, periodic.mission_state) == (
        0, mavlink.MISSION_STATE_NO_MISSION)


@pytest.mark.parametrize("target", [(2, 1), (1, 5)], ids=["other system", "other component"])
def test_set_current_addressed_to_another_vehicle_or_component_is_ignored(target):
    h = with_line()
    assert current_after(h, lambda: h.gcs.mav.mission_set_current_send(*target, 3)) is None
    assert h.core.mission.executor.current == 1
    assert current_after(h, lambda: h.gcs.mav.mission_set_current_send(0, 0, 3)) == 3  # all


def test_set_current_from_a_ground_station_other_than_sysid_mygcs_is_ignored():
    h = lockstep({"SYSID_MYGCS": 255})
    assert h.gcs.upload(LINE).type == ACCEPTED
    stranger = mavlink.MAVLink(None, srcSystem=200, srcComponent=190)
    packet = stranger.mission_set_current_encode(1, 1, 3).pack(stranger)
    assert current_after(h, lambda: h.inject(packet)) is None
    assert h.core.mission.executor.current == 1
    assert current_after(h, lambda: h.gcs.mav.mission_set_current_send(1, 1, 3)) == 3


@pytest.mark.parametrize("param1", [-2.0, math.nan, math.inf])
def test_do_set_mission_current_below_minus_1_or_not_finite_is_refused(param1):
    h = with_line()
    since = h.gcs.mark()
    ack = h.gcs.command(mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, param1, 1)
    assert ack is not None and ack.result == mavlink.MAV_RESULT_FAILED
    assert f"Set current item refused: no item {param1:g}" in h.gcs.texts(since)
    assert h.core.mission.executor.current == 1


def test_a_restart_without_a_mission_leaves_item_0_current():
    executor = MissionExecutor(Params())
    executor.restart()
    assert (executor.current, executor.state) == (0, mavlink.MISSION_STATE_NO_MISSION)


def test_do_set_mission_current_with_reset_1_starts_the_jumps_over():
    """param2 = 1 "resets the mission" (MAVLink): DO_JUMP counters start again."""
    items = renumber([HOME, local_wp(0, 0.3, 0.0), do(0, JUMP, 1, 1), local_wp(0, 0.0, 0.0)])
    h = lockstep()
    assert h.gcs.upload(items).type == ACCEPTED
    h.gcs.arm()
    since = h.gcs.mark()
    assert h.gcs.set_mode(Mode.AUTO) == CMD_ACCEPTED
    assert h.run_until(lambda: h.core.vehicle.mode is Mode.HOLD, 30.0), "mission not finished"
    assert [m.seq for m in h.gcs.received("MISSION_ITEM_REACHED", since)] == [1, 2, 1, 2, 3]
    for reset, again in ((0, [1, 2, 3]), (1, [1, 2, 1, 2, 3])):  # (0: the jump stays used)
        ack = h.gcs.command(mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, 1, reset)
        assert ack is not None and ack.result == CMD_ACCEPTED
        since = h.gcs.mark()
        assert h.gcs.set_mode(Mode.AUTO) == CMD_ACCEPTED
        assert h.run_until(lambda: h.core.vehicle.mode is Mode.HOLD, 30.0), reset
        assert [m.seq for m in h.gcs.received("MISSION_ITEM_REACHED", since)] == again


def test_auto_again_after_the_end_reports_the_mission_active_not_complete():
    h = with_line()
    h.gcs.arm()
    assert h.gcs.set_mode(Mode.AUTO) == CMD_ACCEPTED
    assert h.run_until(lambda: h.core.vehicle.mode is Mode.HOLD, 30.0), "mission not finished"
    done = h.gcs.wait("MISSION_CURRENT", timeout_s=1.5, since=h.gcs.mark())
    assert done is not None and done.mission_state == mavlink.MISSION_STATE_COMPLETE
    assert h.gcs.set_mode(Mode.AUTO) == CMD_ACCEPTED
    again = h.gcs.wait("MISSION_CURRENT", timeout_s=1.5, since=h.gcs.mark())
    assert again is not None and (again.seq, again.mission_state) == (
        1, mavlink.MISSION_STATE_ACTIVE)


def test_mission_start_param1_chooses_the_first_item_and_0_resumes():
    """MAV_CMD_MISSION_START param1 "first_item: the first mission item to run" (MAVLink);
    0 keeps the current item."""
    h = with_line()
    h.gcs.arm()
    assert current_after(h, lambda: h.gcs.mav.mission_set_current_send(1, 1, 3)) == 3
    since = h.gcs.mark()
    ack = h.gcs.command(mavlink.MAV_CMD_MISSION_START, 1, 0)
    assert ack is not None and ack.result == CMD_ACCEPTED
    assert h.gcs.wait("STATUSTEXT", lambda m: "Mission started at item 1" in m.text, 1.0, since)
    assert h.gcs.set_mode(Mode.HOLD) == CMD_ACCEPTED
    assert current_after(h, lambda: h.gcs.mav.mission_set_current_send(1, 1, 2)) == 2
    since = h.gcs.mark()
    ack = h.gcs.command(mavlink.MAV_CMD_MISSION_START, 0, 0)
    assert ack is not None and ack.result == CMD_ACCEPTED
    assert h.gcs.wait("STATUSTEXT", lambda m: "Mission resumed at item 2" in m.text, 1.0, since)


def test_mission_start_past_the_last_item_or_while_auto_cannot_start_is_refused():
    h = with_line()
    h.gcs.arm()
    ack = h.gcs.command(mavlink.MAV_CMD_MISSION_START, len(LINE), 0)
    assert ack is not None and ack.result != CMD_ACCEPTED
    assert h.core.vehicle.mode is not Mode.AUTO
    empty = lockstep()
    empty.gcs.arm()
    ack = empty.gcs.command(mavlink.MAV_CMD_MISSION_START, 0, 0)
    assert ack is not None and ack.result != CMD_ACCEPTED  # no mission: AUTO refused
    assert empty.core.vehicle.mode is not Mode.AUTO


# --------------------------------------------------------------------------- MISSION_START


@pytest.mark.parametrize(("first", "expected"), [(1, 1), (2, 2), (0, 3)],
                         ids=["from item 1", "from item 2", "0 resumes at the current item"])
def test_mission_start_runs_auto_from_its_first_item_or_resumes_with_0(first, expected):
    """MAV_CMD_MISSION_START: param1 is the first item to run; 0 (ArduPilot) keeps the current
    one. Item 1, the first after home, is an item like any other."""
    h = with_line()
    assert current_after(h, lambda: h.gcs.mav.mission_set_current_send(1, 1, 3)) == 3
    ack = h.gcs.command(mavlink.MAV_CMD_MISSION_START, first)
    assert ack is not None and ack.result == CMD_ACCEPTED
    assert h.core.vehicle.mode is Mode.AUTO
    assert h.core.mission.executor.current == expected


@pytest.mark.parametrize("mission", [False, True], ids=["no mission", "no such item"])
def test_mission_start_that_cannot_run_is_denied_and_the_mode_kept(mission):
    h = with_line() if mission else lockstep()
    ack = h.gcs.command(mavlink.MAV_CMD_MISSION_START, len(LINE) if mission else 0)
    assert ack is not None and ack.result == mavlink.MAV_RESULT_DENIED
    assert h.core.vehicle.mode is not Mode.AUTO
