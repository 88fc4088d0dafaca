"""GUIDED: SET_POSITION_TARGET_LOCAL_NED drives the simulated rover holonomically.

The rover runs in the lockstep harness (core + simulated board + scripted ground station in
virtual time), so every figure below is exact and repeatable."""

from __future__ import annotations

import math

import pytest
from conftest import lockstep
from support import status_texts

from mecanum_mav.config.params import Params
from mecanum_mav.control.guided import GuidedController, Setpoint, SetpointError, decode_setpoint
from mecanum_mav.io.links import mavlink
from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.lockstep import Lockstep

IGNORE_POS, IGNORE_VEL, IGNORE_ACC = 1 | 2 | 4, 8 | 16 | 32, 64 | 128 | 256
IGNORE_YAW, IGNORE_RATE = 1024, 2048
VELOCITY_ONLY = IGNORE_POS | IGNORE_ACC | IGNORE_YAW | IGNORE_RATE
NED, BODY = mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_BODY_FRD
SETPOINT_PERIOD_S = 0.05
"""A ground station streaming setpoints at 20 Hz."""


def target(h: Lockstep, frame=NED, mask=VELOCITY_ONLY, x=0.0, y=0.0, vx=0.0, vy=0.0, yaw=0.0,
           rate=0.0) -> None:
    h.gcs.mav.set_position_target_local_ned_send(0, 1, 1, frame, mask, x, y, 0.0, vx, vy, 0.0,
                                                 0.0, 0.0, 0.0, yaw, rate)


def stream(h: Lockstep, seconds: float, **kwargs) -> list[float]:
    """Send the setpoint at 20 Hz for ``seconds`` of virtual time; the times it was sent."""
    sent: list[float] = []

    def send(now_s: float) -> None:
        target(h, **kwargs)
        sent.append(now_s)

    stop = h.every(SETPOINT_PERIOD_S, send)
    h.run_for(seconds)
    stop()
    return sent


def moved_m(h: Lockstep) -> float:
    pose = h.truth().pose
    return math.hypot(pose.x_m, pose.y_m) + abs(pose.yaw_rad)


@pytest.fixture
def rover(request) -> Lockstep:
    """A harness armed in GUIDED; parametrize indirectly with a dict of parameter values."""
    h = lockstep(getattr(request, "param", None))
    h.gcs.arm()
    assert h.gcs.set_mode(Mode.GUIDED) == mavlink.MAV_RESULT_ACCEPTED
    return h


def test_velocity_north_moves_north_without_turning(rover):
    stream(rover, 1.5, vx=0.5)
    s = rover.truth()
    assert s.velocity_body == pytest.approx((0.5, 0.0), abs=0.005)
    # a 0.5 s ramp (GUID_ACC_MAX 1 m/s/s) and the motors' 80 ms lag: 0.5 * (1.5 - 0.25 - 0.08)
    assert s.pose.x_m == pytest.approx(0.58, abs=0.02)
    assert abs(s.pose.y_m) < 1e-3 and abs(math.degrees(s.pose.yaw_rad)) < 0.1


def test_body_frame_velocity_right_strafes_without_turning(rover):
    stream(rover, 1.5, frame=BODY, vy=0.5)
    s = rover.truth()
    assert s.velocity_body == pytest.approx((0.0, 0.5), abs=0.005)
    assert s.pose.y_m == pytest.approx(0.58, abs=0.02)
    assert abs(s.pose.x_m) < 1e-3 and abs(math.degrees(s.pose.yaw_rad)) < 0.1


def test_turning_to_a_yaw_target_does_not_disturb_the_translation(rover):
    stream(rover, 2.5, mask=IGNORE_POS | IGNORE_ACC | IGNORE_RATE, vx=0.4, yaw=math.pi / 2)
    s = rover.truth()
    assert math.degrees(s.pose.yaw_rad) == pytest.approx(90.0, abs=0.5)
    assert abs(s.yaw_rate) < math.radians(0.5)  # settled on the target
    assert s.pose.x_m > 0.8 and abs(s.pose.y_m) < 0.02  # straight north while it turned
    assert s.velocity_body == pytest.approx((0.0, -0.4), abs=0.005)  # facing east: left


def test_a_position_target_is_reached_within_1cm_and_half_a_degree_without_overshoot(rover):
    h, goal = rover, (1.2, 0.8)
    target(h, mask=IGNORE_VEL | IGNORE_ACC | IGNORE_RATE, x=goal[0], y=goal[1],
           yaw=math.radians(45))
    distance = math.hypot(*goal)
    direction = (goal[0] / distance, goal[1] / distance)
    overshoot = [0.0]

    def arrived():
        s = h.truth()
        along = s.pose.x_m * direction[0] + s.pose.y_m * direction[1]
        overshoot[0] = max(overshoot[0], along - distance)
        core = h.core
        return (math.hypot(*s.velocity_body) < 0.005
                and core.autopilot.guided.arrived(core.estimator.pose, 0.03) and s)

    final = h.run_until(arrived, 8.0)
    assert final is not None, h.truth()
    assert math.hypot(final.pose.x_m - goal[0], final.pose.y_m - goal[1]) < 0.01
    assert abs(math.degrees(final.pose.yaw_rad) - 45.0) < 0.5
    assert overshoot[0] < 0.005
    h.run_for(2.0)  # and it stays there
    pose = h.truth().pose
    assert math.hypot(pose.x_m - goal[0], pose.y_m - goal[1]) < 0.01


def face_east(h: Lockstep) -> None:
    """Turn in place to heading 90 degrees (a yaw target) and settle there."""
    target(h, mask=IGNORE_POS | IGNORE_VEL | IGNORE_ACC | IGNORE_RATE, yaw=math.pi / 2)
    assert h.run_until(lambda: abs(math.degrees(h.truth().pose.yaw_rad) - 90.0) < 0.2
                       and abs(h.truth().yaw_rate) < 1e-3, 5.0)


@pytest.mark.parametrize(
    ("frame", "goal"),
    [(mavlink.MAV_FRAME_BODY_NED, (0.0, 1.0)), (mavlink.MAV_FRAME_BODY_OFFSET_NED, (0.0, 1.0)),
     (mavlink.MAV_FRAME_LOCAL_OFFSET_NED, (1.0, 0.0)), (NED, (1.0, 0.0))],
    ids=["BODY_NED", "BODY_OFFSET_NED", "LOCAL_OFFSET_NED", "LOCAL_NED"],
)
def test_position_1_0_facing_east_goes_1m_ahead_in_body_frames_as_mavproxy_expects(
        rover, frame, goal):
    h = rover
    face_east(h)
    start = h.truth().pose
    target(h, frame=frame, mask=IGNORE_VEL | IGNORE_ACC | IGNORE_YAW | IGNORE_RATE, x=1.0)
    assert h.run_until(lambda: h.core.autopilot.guided.arrived(h.core.estimator.pose, 0.01)
                       and math.hypot(*h.truth().velocity_body) < 0.005, 8.0)
    pose = h.truth().pose
    assert (pose.x_m, pose.y_m) == pytest.approx(
        (start.x_m + goal[0] if frame != NED else goal[0], start.y_m + goal[1]), abs=0.02)


def test_body_velocity_facing_east_moves_east(rover):
    h = rover
    face_east(h)
    start = h.truth().pose
    stream(h, 1.0, frame=mavlink.MAV_FRAME_BODY_NED, vx=0.5)  # MAVProxy's "velocity 0.5 0 0"
    pose = h.truth().pose
    assert pose.y_m - start.y_m > 0.3 and abs(pose.x_m - start.x_m) < 0.01  # ramped at 1 m/s/s


@pytest.mark.parametrize("rover", [{"GUID_TIMEOUT": 0.5}], indirect=True)
def test_a_velocity_setpoint_lapses_and_the_rover_stops(rover):
    h = rover
    last = stream(h, 0.6, vx=0.5)[-1]
    assert h.truth().velocity_body[0] > 0.45
    h.run_until(lambda: h.now_s >= last + 0.5 - 1e-9, 1.0)
    assert h.truth().velocity_body[0] > 0.49  # still driving until the setpoint is 0.5 s old
    stopped = h.run_until(lambda: abs(h.truth().velocity_body[0]) < 0.01 and h.truth(), 3.0)
    assert stopped is not None
    assert 0.5 < stopped.time_s - last < 0.5 + 1.0  # lapsed, then braked at GUID_ACC_MAX
    assert stopped.pose.x_m < 0.6
    assert all(o.channels[:4] == [1500] * 4 for o in h.overrides_since(stopped.time_s + 0.2))


@pytest.mark.parametrize(
    ("fields", "reason"),
    [({"frame": 3}, "frame 3 not supported"), ({"vx": math.nan}, "velocity not finite"),
     ({"vx": 300.0, "vy": 400.0}, "velocity absurd (500)"),
     ({"mask": VELOCITY_ONLY | 8}, "give both"),
     ({"mask": 0xFFF}, "nothing usable"),
     ({"mask": VELOCITY_ONLY & ~IGNORE_YAW, "yaw": math.nan}, "yaw not finite"),
     ({"mask": VELOCITY_ONLY & ~IGNORE_RATE, "rate": math.inf},
      "yaw rate not finite or absurd")],
)
def test_bad_setpoints_are_rejected_with_a_reason_and_never_move_it(rover, fields, reason):
    h = rover
    since, start_s = h.gcs.mark(), h.now_s
    stream(h, 0.4, **{"vx": 0.5, **fields})
    # Nine setpoints rejected, said once (the same rejection at most once a second).
    said = status_texts(h, since)
    assert said[0].startswith("Rejected: setpoint: ")
    assert sum(reason in t for t in said) == 1
    assert moved_m(h) == 0.0
    assert all(o.channels[:4] == [1500] * 4 for o in h.overrides_since(start_s))


def test_setpoints_outside_guided_are_refused_with_a_reason():
    h = lockstep()
    h.gcs.arm()
    since, start_s = h.gcs.mark(), h.now_s
    stream(h, 0.3, vx=0.5)
    assert status_texts(h, since) == ["Rejected: setpoint: not in GUIDED"]  # said once
    assert moved_m(h) == 0.0
    assert all(o.channels[:4] == [1500] * 4 for o in h.overrides_since(start_s))


# --------------------------------------------------------------------------- decoding


FACING_EAST = Pose2d(1.0, 2.0, math.pi / 2)


def decode(frame, mask, x=0.0, y=0.0, vx=0.0, vy=0.0, yaw=0.0, rate=0.0):
    return decode_setpoint(frame, mask, x, y, vx, vy, yaw, rate, FACING_EAST, 0.0)


def test_local_offset_frame_positions_are_relative_to_the_rover():
    sp = decode(7, IGNORE_VEL | IGNORE_ACC | IGNORE_YAW | IGNORE_RATE, x=1.0, y=0.0)
    assert sp.position_ned == pytest.approx((2.0, 2.0))


def test_body_frames_rotate_offsets_velocities_and_yaw_by_the_heading():
    sp = decode(12, IGNORE_ACC | IGNORE_RATE, x=1.0, y=0.0, vx=1.0, vy=0.0, yaw=0.5)
    assert sp.position_ned == pytest.approx((1.0, 3.0))  # 1 m forward = east
    assert sp.velocity_ned == pytest.approx((0.0, 1.0))
    assert sp.yaw == pytest.approx(math.pi / 2 + 0.5)


@pytest.mark.parametrize(
    ("frame", "position", "velocity", "yaw"),
    [(1, (5.0, 6.0), (1.0, 0.0), 0.5),                       # absolute, NED
     (7, (6.0, 8.0), (1.0, 0.0), 0.5),                       # NED offset from (1, 2)
     (8, (1.0 - 6.0, 2.0 + 5.0), (0.0, 1.0), 0.5),           # body offset, as ArduPilot Rover
     (9, (1.0 - 6.0, 2.0 + 5.0), (0.0, 1.0), math.pi / 2 + 0.5),
     (12, (1.0 - 6.0, 2.0 + 5.0), (0.0, 1.0), math.pi / 2 + 0.5)],
    ids=["LOCAL_NED", "LOCAL_OFFSET_NED", "BODY_NED", "BODY_OFFSET_NED", "BODY_FRD"],
)
def test_every_frame_at_heading_90_gives_ardupilot_rovers_position_velocity_and_yaw(
        frame, position, velocity, yaw):
    # facing east at (1, 2): 5 m forward is 5 m east, 6 m right is 6 m south
    sp = decode(frame, IGNORE_ACC | IGNORE_RATE, x=5.0, y=6.0, vx=1.0, yaw=0.5)
    assert sp.position_ned == pytest.approx(position)
    assert sp.velocity_ned == pytest.approx(velocity, abs=1e-12)
    assert sp.yaw == pytest.approx(yaw)


def test_accelerations_flagged_as_ignored_are_accepted_and_z_is_ignored():
    sp = decode(1, IGNORE_POS | IGNORE_ACC | IGNORE_YAW | IGNORE_RATE, vx=0.3)
    assert sp.velocity_ned == (0.3, 0.0) and sp.yaw is None and sp.yaw_rate is None


@pytest.mark.parametrize("rate", [math.inf, 100.0])
def test_an_absurd_yaw_rate_is_rejected(rate):
    with pytest.raises(SetpointError):
        decode(1, IGNORE_POS | IGNORE_VEL | IGNORE_ACC | IGNORE_YAW, rate=rate)


@pytest.mark.parametrize(("sender", "system", "component", "obeyed"), [
    (255, 1, 1, True), (255, 1, 0, True), (255, 0, 0, True),  # the rover, or everyone
    (255, 2, 1, False), (255, 1, 5, False), (200, 1, 1, False)],
    ids=["to the rover", "to all its components", "to everyone", "to another system",
         "to another component", "from another ground station"])
def test_a_setpoint_is_obeyed_only_from_the_pilot_and_addressed_to_the_rover(
        sender: int, system: int, component: int, obeyed: bool) -> None:
    """MAVLink addressing: target 0 is everyone; SYSID_MYGCS names the ground station whose
    setpoints are obeyed (here 255)."""
    h = lockstep({"SYSID_MYGCS": 255})
    h.gcs.arm()
    assert h.gcs.set_mode(Mode.GUIDED) == mavlink.MAV_RESULT_ACCEPTED
    h.gcs.mav.srcSystem = sender
    stop = h.every(SETPOINT_PERIOD_S, lambda now: h.gcs.mav.set_position_target_local_ned_send(
        0, system, component, NED, VELOCITY_ONLY, 0, 0, 0, 0.5, 0.0, 0, 0, 0, 0, 0, 0))
    h.run_for(1.0)
    stop()
    assert (h.truth().pose.x_m > 0.2) is obeyed


@pytest.mark.parametrize(("sender", "system", "component", "obeyed"), [
    (255, 1, 1, True), (255, 0, 0, True), (255, 2, 1, False), (255, 1, 5, False),
    (200, 1, 1, False)],
    ids=["to the rover", "to everyone", "to another system", "to another component",
         "from another ground station"])
def test_an_rc_override_drives_only_from_the_pilot_and_addressed_to_the_rover(
        sender: int, system: int, component: int, obeyed: bool) -> None:
    h = lockstep({"SYSID_MYGCS": 255})
    h.gcs.arm()
    h.gcs.mav.srcSystem = sender
    forward = [65535, 65535, 1750, 65535, 65535, 65535, 65535, 65535]  # "rc 3 1750"
    stop = h.every(SETPOINT_PERIOD_S, lambda now: h.gcs.mav.rc_channels_override_send(
        system, component, *forward))
    h.run_for(1.0)
    stop()
    assert (h.truth().pose.x_m > 0.2) is obeyed


def test_a_setpoint_without_heading_holds_the_heading_the_rover_had_when_it_came():
    """GuidedController.accept: "its heading is held if it sets none", the heading at that
    moment (not the one GUIDED started with): a rover pushed off it turns back to it."""
    guided = GuidedController(Params())
    guided.start(Pose2d(0.0, 0.0, 0.0), 0.0)
    guided.accept(Setpoint(None, (0.5, 0.0), None, None, 1.0), Pose2d(0.0, 0.0, 0.3))
    pushed = guided.update(Pose2d(0.0, 0.0, 0.5), 1.02)
    assert pushed.yaw_rate < 0.0  # back counter-clockwise, towards 0.3
    held = guided.update(Pose2d(0.0, 0.0, 0.3), 1.04)
    assert held.yaw_rate == 0.0
