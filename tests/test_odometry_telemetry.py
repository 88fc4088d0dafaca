"""The companion's dead reckoning and position telemetry against the simulator's true pose,
in the lockstep harness (virtual time: the same legs give the same figures every run)."""

from __future__ import annotations

import math

import pytest
from conftest import lockstep
from test_end_to_end import sticks_for, stream_sticks

from mecanum_mav.control.refusals import Refusal
from mecanum_mav.io.links import mavlink
from mecanum_mav.sim.board import SimState
from mecanum_mav.sim.lockstep import Lockstep

LEGS = ((1000, 0, 0, 1.2), (0, 1000, 0, 1.0), (0, 0, 600, 0.8), (700, -700, 0, 0.8))
"""Sticks (x forward, y right, r clockwise) and how long each is held, seconds."""


def still(s: SimState) -> bool:
    return (abs(s.velocity_body[0]) + abs(s.velocity_body[1]) < 1e-3
            and abs(s.yaw_rate) < 1e-3)


def settle(h: Lockstep) -> SimState:
    """Run until the simulated chassis stands still, then a few WHEEL_DISTANCE/ATTITUDE
    updates more so the companion has caught up; the true state then."""
    assert h.run_until(lambda: still(h.truth()), 3.0)
    h.run_for(0.4)
    return h.truth()


def drive_legs(h: Lockstep) -> None:
    h.gcs.arm()
    for x, y, r, seconds in LEGS:
        sticks_for(h, seconds, x, y, r)


def yaw_error_deg(a: float, b: float) -> float:
    return abs(math.degrees(math.remainder(a - b, 2 * math.pi)))


@pytest.mark.parametrize(
    ("harness", "tolerance_m"),
    [({}, 0.005), ({"ODOM_SRC": 2}, 0.03)],
    ids=["wheel-distance-and-gyro", "commanded-speeds"],
    indirect=["harness"],
)
def test_dead_reckoning_tracks_the_simulated_true_pose(harness, tolerance_m):
    h = harness
    drive_legs(h)
    truth = settle(h)
    pose = h.core.estimator.pose
    assert math.hypot(truth.pose.x_m, truth.pose.y_m) > 2.0
    assert math.degrees(truth.pose.yaw_rad) > 80.0  # every leg drove: north, east, a turn
    assert math.hypot(pose.x_m - truth.pose.x_m, pose.y_m - truth.pose.y_m) < tolerance_m
    assert yaw_error_deg(pose.yaw_rad, truth.pose.yaw_rad) < 0.1


def test_position_telemetry_reports_the_odometry_in_ned(harness):
    h = harness
    drive_legs(h)
    truth = settle(h)
    since = h.gcs.mark()
    odom = h.gcs.wait("ODOMETRY", timeout_s=1.0, since=since)
    local = h.gcs.wait("LOCAL_POSITION_NED", timeout_s=1.0, since=since)
    att = h.gcs.wait("ATTITUDE", timeout_s=1.0, since=since)
    assert odom is not None and local is not None and att is not None
    assert odom.frame_id == mavlink.MAV_FRAME_LOCAL_NED
    assert odom.child_frame_id == mavlink.MAV_FRAME_BODY_FRD
    assert math.isnan(odom.pose_covariance[0]) and math.isnan(odom.velocity_covariance[0])
    assert (odom.x, odom.y) == pytest.approx((truth.pose.x_m, truth.pose.y_m), abs=0.005)
    assert (local.x, local.y) == pytest.approx((odom.x, odom.y), abs=1e-4)
    assert (odom.vx, odom.vy, local.vx, local.vy) == pytest.approx((0, 0, 0, 0), abs=1e-3)
    yaw_from_q = 2 * math.atan2(odom.q[3], odom.q[0])
    assert yaw_error_deg(yaw_from_q, truth.pose.yaw_rad) < 0.1
    assert yaw_error_deg(att.yaw, truth.pose.yaw_rad) < 0.1


def test_moving_north_shows_as_north_velocity():
    h = lockstep()
    h.gcs.arm()
    since = h.gcs.mark()
    state = stream_sticks(h, lambda: h.truth().velocity_body[0] > 0.6 and h.truth(), 1000)
    assert state is not None
    local = h.gcs.wait("LOCAL_POSITION_NED", lambda m: m.vx > 0.5, 1.0, since)
    assert local is not None and abs(local.vy) < 1e-3


def test_impossible_wheel_distances_and_attitudes_are_counted_and_odometry_stays_finite():
    # Found by tools/fuzz.py (issue 11.1): the estimator took any finite number.
    h = lockstep()
    fc = h._fc_to_core.sender  # the board's side of the wire
    since = h.gcs.mark()
    for step in range(50):
        fc.wheel_distance_send(0, 4, [1e308 * (-1) ** step] * 4 + [0.0] * 12)
        fc.attitude_send(0, 0.0, 0.0, 1e38, 0.0, 0.0, -3.4e38)
        h.step()
    h.run_for(0.5)
    assert h.core.refusals.counts[Refusal.SENSOR] == 100
    texts = [m.text for m in h.gcs.received("STATUSTEXT", since)]
    assert any(t.startswith("Ignored: WHEEL_DISTANCE") for t in texts)
    odometry = h.gcs.received("ODOMETRY", since)
    assert odometry and all(math.isfinite(v) for m in odometry
                            for v in (m.x, m.y, m.vx, m.vy, m.yawspeed, *m.q))
    assert all(abs(v) < 1.0 for v in h.core.estimator.pose)
