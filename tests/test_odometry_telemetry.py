"""The companion's dead reckoning and position telemetry against the simulator's true pose."""

from __future__ import annotations

import math
import time

import pytest
from test_end_to_end import arm, stream_sticks

from mecanum_mav.io.links import mavlink


def settle(sim, gcs, companion, timeout_s: float = 3.0):
    """Wait until the simulated chassis stands still and the companion has caught up."""
    state = sim.wait_for(lambda s: abs(s.velocity_body[0]) + abs(s.velocity_body[1]) < 1e-3
                         and abs(s.yaw_rate) < 1e-3, timeout_s)
    assert state is not None
    gcs.pump(0.4)  # a few WHEEL_DISTANCE/ATTITUDE updates after the stop
    return sim.snapshot()


def drive_legs(sim, gcs):
    arm(gcs)
    for x, y, r, seconds in ((1000, 0, 0, 1.2), (0, 1000, 0, 1.0), (0, 0, 600, 0.8),
                             (700, -700, 0, 0.8)):
        end = time.monotonic() + seconds
        stream_sticks(gcs, lambda end=end: time.monotonic() > end, x, y, r, seconds + 1.0)


@pytest.mark.parametrize(
    ("rover", "tolerance_m"),
    [({}, 0.01), ({"ODOM_SRC": 2}, 0.08)],
    ids=["wheel-distance-and-gyro", "commanded-speeds"],
    indirect=["rover"],
)
def test_dead_reckoning_tracks_the_simulated_true_pose(rover, tolerance_m):
    sim, gcs, companion = rover
    drive_legs(sim, gcs)
    truth = settle(sim, gcs, companion)
    pose = companion.core.estimator.pose
    travelled = math.hypot(truth.pose.x_m, truth.pose.y_m)
    assert travelled > 1.0
    assert math.hypot(pose.x_m - truth.pose.x_m, pose.y_m - truth.pose.y_m) < tolerance_m
    yaw_error = (pose.yaw_rad - truth.pose.yaw_rad + math.pi) % (2 * math.pi) - math.pi
    assert abs(math.degrees(yaw_error)) < 1.0


def test_position_telemetry_reports_the_odometry_in_ned(rover):
    sim, gcs, companion = rover
    drive_legs(sim, gcs)
    truth = settle(sim, gcs, companion)
    since = gcs.mark()
    odom = gcs.wait("ODOMETRY", timeout_s=1.0, since=since)
    local = gcs.wait("LOCAL_POSITION_NED", timeout_s=1.0, since=since)
    att = gcs.wait("ATTITUDE", timeout_s=1.0, since=since)
    assert odom.frame_id == mavlink.MAV_FRAME_LOCAL_NED
    assert odom.child_frame_id == mavlink.MAV_FRAME_BODY_FRD
    assert math.isnan(odom.pose_covariance[0]) and math.isnan(odom.velocity_covariance[0])
    assert (odom.x, odom.y) == pytest.approx((truth.pose.x_m, truth.pose.y_m), abs=0.02)
    assert (local.x, local.y) == pytest.approx((odom.x, odom.y), abs=0.02)
    yaw_from_q = 2 * math.atan2(odom.q[3], odom.q[0])
    assert math.cos(yaw_from_q - truth.pose.yaw_rad) > math.cos(math.radians(1.0))
    assert math.cos(att.yaw - truth.pose.yaw_rad) > math.cos(math.radians(1.0))


def test_moving_north_shows_as_north_velocity(rover):
    sim, gcs, _ = rover
    arm(gcs)
    state = stream_sticks(gcs, lambda: sim.snapshot().velocity_body[0] > 0.6 and sim.snapshot(),
                          1000)
    assert state is not None
    local = gcs.wait("LOCAL_POSITION_NED", lambda m: m.vx > 0.5, 1.0, gcs.mark())
    assert local is not None and abs(local.vy) < 0.05
