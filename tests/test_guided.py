"""GUIDED: SET_POSITION_TARGET_LOCAL_NED drives the simulated rover holonomically."""

from __future__ import annotations

import math
import time

import pytest
from conftest import simulated_rover
from test_end_to_end import arm

from mecanum_mav.config.params import Params
from mecanum_mav.control.guided import SetpointError, decode_setpoint
from mecanum_mav.io.links import mavlink
from mecanum_mav.mecanum.geometry import Pose2d

IGNORE_POS, IGNORE_VEL, IGNORE_ACC = 1 | 2 | 4, 8 | 16 | 32, 64 | 128 | 256
IGNORE_YAW, IGNORE_RATE = 1024, 2048
VELOCITY_ONLY = IGNORE_POS | IGNORE_ACC | IGNORE_YAW | IGNORE_RATE
NED, BODY = mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_BODY_FRD


def guided(gcs) -> None:
    arm(gcs)
    since = gcs.mark()
    gcs.mav.command_long_send(1, 1, mavlink.MAV_CMD_DO_SET_MODE, 0, 1, 15, 0, 0, 0, 0, 0)
    ack = gcs.wait("COMMAND_ACK", lambda m: m.command == mavlink.MAV_CMD_DO_SET_MODE, 1, since)
    assert ack is not None and ack.result == 0


def target(gcs, frame=NED, mask=VELOCITY_ONLY, x=0.0, y=0.0, vx=0.0, vy=0.0, yaw=0.0, rate=0.0):
    gcs.mav.set_position_target_local_ned_send(0, 1, 1, frame, mask, x, y, 0.0, vx, vy, 0.0,
                                               0.0, 0.0, 0.0, yaw, rate)


def stream(gcs, seconds: float, **kwargs) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        target(gcs, **kwargs)
        gcs.pump(0.05)


@pytest.fixture
def rover(request):
    params = Params()
    params.update(getattr(request, "param", {}))
    with simulated_rover(params) as parts:
        guided(parts[1])
        yield parts


def test_velocity_north_moves_north_without_turning(rover):
    sim, gcs, _ = rover
    stream(gcs, 1.5, vx=0.5)
    pose = sim.snapshot().pose
    assert pose.x_m > 0.4 and abs(pose.y_m) < 0.02
    assert abs(math.degrees(pose.yaw_rad)) < 1.0


def test_body_frame_velocity_right_strafes_without_turning(rover):
    sim, gcs, _ = rover
    stream(gcs, 1.5, frame=BODY, vy=0.5)
    pose = sim.snapshot().pose
    assert pose.y_m > 0.4 and abs(pose.x_m) < 0.02 and abs(math.degrees(pose.yaw_rad)) < 1.0


def test_turning_to_a_yaw_target_does_not_disturb_the_translation(rover):
    sim, gcs, _ = rover
    stream(gcs, 2.5, mask=IGNORE_POS | IGNORE_ACC | IGNORE_RATE, vx=0.4, yaw=math.pi / 2)
    pose = sim.snapshot().pose
    assert math.degrees(pose.yaw_rad) == pytest.approx(90.0, abs=2.0)
    assert pose.x_m > 0.6 and abs(pose.y_m) < 0.03  # straight north while it turned


def test_a_position_target_is_reached_within_5cm_and_2deg_without_overshoot(rover):
    sim, gcs, companion = rover
    goal = (1.2, 0.8)
    target(gcs, mask=IGNORE_VEL | IGNORE_ACC | IGNORE_RATE, x=goal[0], y=goal[1],
           yaw=math.radians(45))
    direction = (goal[0] / math.hypot(*goal), goal[1] / math.hypot(*goal))
    overshoot = 0.0
    deadline = time.monotonic() + 8.0
    while time.monotonic() < deadline:
        s = sim.snapshot()
        along = s.pose.x_m * direction[0] + s.pose.y_m * direction[1]
        overshoot = max(overshoot, along - math.hypot(*goal))
        core = companion.core
        if s.time_s > 0 and math.hypot(*s.velocity_body) < 0.005 and (
                core.autopilot.guided.arrived(core.estimator.pose, 0.03)):
            break
        gcs.pump(0.02)
    final = sim.snapshot().pose
    assert math.hypot(final.x_m - goal[0], final.y_m - goal[1]) < 0.05
    assert abs(math.degrees(final.yaw_rad) - 45.0) < 2.0
    assert overshoot < 0.05


@pytest.mark.parametrize("rover", [{"GUID_TIMEOUT": 0.5}], indirect=True)
def test_a_velocity_setpoint_lapses_and_the_rover_stops(rover):
    sim, gcs, _ = rover
    stream(gcs, 0.6, vx=0.5)
    assert sim.snapshot().velocity_body[0] > 0.3
    stopped = sim.wait_for(lambda s: abs(s.velocity_body[0]) < 0.01, timeout_s=3.0)
    assert stopped is not None and stopped.pose.x_m < 1.0


@pytest.mark.parametrize(
    ("fields", "reason"),
    [({"frame": 3}, "frame 3 not supported"), ({"vx": math.nan}, "velocity not finite"),
     ({"vx": 500.0}, "velocity absurd"), ({"mask": VELOCITY_ONLY | 8}, "give both"),
     ({"mask": 0xFFF}, "nothing usable")],
)
def test_bad_setpoints_are_rejected_with_a_reason_and_never_move_it(rover, fields, reason):
    sim, gcs, _ = rover
    since = gcs.mark()
    stream(gcs, 0.4, **{"vx": 0.5, **fields})
    assert gcs.wait("STATUSTEXT", lambda m: reason in m.text, 1.0, since) is not None
    assert abs(sim.snapshot().pose.x_m) < 0.005


def test_setpoints_outside_guided_are_refused_with_a_reason():
    with simulated_rover() as (sim, gcs, _):
        arm(gcs)
        since = gcs.mark()
        stream(gcs, 0.3, vx=0.5)
        assert gcs.wait("STATUSTEXT", lambda m: "not in GUIDED" in m.text, 1.0, since)
        assert abs(sim.snapshot().pose.x_m) < 0.005


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


def test_body_ned_takes_absolute_positions_and_body_velocities():
    sp = decode(8, IGNORE_ACC | IGNORE_YAW | IGNORE_RATE, x=5.0, y=6.0, vx=1.0)
    assert sp.position_ned == (5.0, 6.0) and sp.velocity_ned == pytest.approx((0.0, 1.0))


def test_accelerations_flagged_as_ignored_are_accepted_and_z_is_ignored():
    sp = decode(1, IGNORE_POS | IGNORE_ACC | IGNORE_YAW | IGNORE_RATE, vx=0.3)
    assert sp.velocity_ned == (0.3, 0.0) and sp.yaw is None and sp.yaw_rate is None


@pytest.mark.parametrize("rate", [math.inf, 100.0])
def test_an_absurd_yaw_rate_is_rejected(rate):
    with pytest.raises(SetpointError):
        decode(1, IGNORE_POS | IGNORE_VEL | IGNORE_ACC | IGNORE_YAW, rate=rate)
