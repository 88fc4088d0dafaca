"""Missions end to end: the mission protocol with a pymavlink ground station on loopback, and
AUTO driving the simulated rover."""

from __future__ import annotations

import math
import time
from dataclasses import replace

from conftest import simulated_rover
from missionpeer import (
    GLOBAL_REL,
    JUMP,
    SPEED,
    YAW,
    do,
    download,
    local_wp,
    renumber,
    same,
    upload,
)
from test_end_to_end import arm

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.control.pathfollow import Leg
from mecanum_mav.io.links import mavlink
from mecanum_mav.io.missionfile import load_mission
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.mission import MissionItem

SET_MODE = mavlink.MAV_CMD_DO_SET_MODE
ACCEPTED = mavlink.MAV_MISSION_ACCEPTED
HOME = local_wp(0, 0.0, 0.0)


def set_mode(gcs, mode: int) -> int:
    since = gcs.mark()
    gcs.mav.command_long_send(1, 1, SET_MODE, 0, 1, mode, 0, 0, 0, 0, 0)
    ack = gcs.wait("COMMAND_ACK", lambda m: m.command == SET_MODE, 1.0, since)
    assert ack is not None
    return ack.result


def text_seen(gcs, fragment: str, since: int, timeout_s: float = 1.0) -> bool:
    return gcs.wait("STATUSTEXT", lambda m: fragment in m.text, timeout_s, since) is not None


# --------------------------------------------------------------------------- the protocol

MIXED = renumber([
    HOME,
    local_wp(0, 1.25, -0.5, param1=2.0, param2=0.25, param4=math.nan),
    do(0, YAW, 90.0, 30.0, 1.0, 0.0),
    do(0, SPEED, 1.0, 0.375, -1.0),
    MissionItem(0, GLOBAL_REL, mavlink.MAV_CMD_NAV_WAYPOINT, x=-353632610, y=1491652300,
                z=5.0),
    do(0, JUMP, 1.0, 2.0),
    MissionItem(0, mavlink.MAV_FRAME_MISSION, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH),
])


def assert_same_mission(got, want, *, float32_xy: bool = False):
    """Item by item; ``float32_xy``: x/y went through the legacy MISSION_ITEM's floats, so
    latitudes and longitudes keep only float32's ~7 significant digits."""
    assert got is not None and len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        if float32_xy:
            assert abs(a.x - b.x) <= abs(b.x) * 2**-22 and abs(a.y - b.y) <= abs(b.y) * 2**-22
            a = replace(a, x=b.x, y=b.y)
        assert same(a, b), (a, b)


def test_upload_then_download_returns_every_item_and_field(rover):
    _, gcs, _ = rover
    ack = upload(gcs, MIXED)
    assert ack is not None and ack.type == ACCEPTED
    assert_same_mission(download(gcs), MIXED)


def test_legacy_mission_item_upload_and_mission_request_download_round_trip(rover):
    _, gcs, _ = rover
    ack = upload(gcs, MIXED, legacy=True)
    assert ack is not None and ack.type == ACCEPTED
    assert_same_mission(download(gcs), MIXED, float32_xy=True)
    assert_same_mission(download(gcs, legacy=True), MIXED, float32_xy=True)


def test_upload_survives_lost_requests_and_duplicated_items(rover):
    _, gcs, _ = rover
    ack = upload(gcs, MIXED, ignore_first=frozenset({0, 3, len(MIXED) - 1}), duplicate=True)
    assert ack is not None and ack.type == ACCEPTED
    assert_same_mission(download(gcs), MIXED)


def test_clear_all_and_a_count_of_zero_both_empty_the_mission(rover):
    _, gcs, _ = rover
    for clear in ("clear_all", "count_zero"):
        assert upload(gcs, MIXED).type == ACCEPTED
        since = gcs.mark()
        if clear == "clear_all":
            gcs.mav.mission_clear_all_send(1, 1, 0)
        else:
            gcs.mav.mission_count_send(1, 1, 0, 0)
        ack = gcs.wait("MISSION_ACK", timeout_s=1.0, since=since)
        assert ack is not None and ack.type == ACCEPTED
        assert download(gcs) == []


def test_a_non_finite_coordinate_is_rejected_and_the_previous_mission_kept(rover):
    _, gcs, _ = rover
    assert upload(gcs, MIXED).type == ACCEPTED
    bad = renumber([HOME, local_wp(0, 1.0, 0.0), local_wp(0, 2.0, 0.0, z=math.nan)])
    since = gcs.mark()
    ack = upload(gcs, bad)
    assert ack is not None and ack.type == mavlink.MAV_MISSION_INVALID_PARAM7
    assert text_seen(gcs, "item 2", since)
    nan_x = renumber([HOME, MissionItem(0, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                        mavlink.MAV_CMD_NAV_WAYPOINT)])
    since = gcs.mark()
    gcs.mav.mission_count_send(1, 1, 2, 0)
    assert gcs.wait("MISSION_REQUEST_INT", lambda m: m.seq == 0, 1.0, since)
    gcs.mav.mission_item_send(1, 1, 0, 1, 16, 0, 1, 0, 0, 0, 0, 0.0, 0.0, 0.0, 0)
    assert gcs.wait("MISSION_REQUEST_INT", lambda m: m.seq == 1, 1.0, since) or gcs.wait(
        "MISSION_REQUEST", lambda m: m.seq == 1, 1.0, since)
    gcs.mav.mission_item_send(1, 1, 1, nan_x[1].frame, 16, 0, 1, 0, 0, 0, 0, math.nan, 149.0,
                              0.0, 0)
    ack = gcs.wait("MISSION_ACK", timeout_s=1.0, since=since)
    assert ack is not None and ack.type == mavlink.MAV_MISSION_INVALID_PARAM5_X
    assert_same_mission(download(gcs), MIXED)


def test_an_upload_abandoned_midway_times_out_and_keeps_the_previous_mission(rover):
    _, gcs, _ = rover
    assert upload(gcs, MIXED).type == ACCEPTED
    since = gcs.mark()
    gcs.mav.mission_count_send(1, 1, 3, 0)
    assert gcs.wait("MISSION_REQUEST_INT", lambda m: m.seq == 0, 1.0, since)
    # Silence: the vehicle asks again (250 ms, 5 retries), then cancels.
    ack = gcs.wait("MISSION_ACK", timeout_s=3.0, since=since)
    assert ack is not None and ack.type == mavlink.MAV_MISSION_OPERATION_CANCELLED
    requests = [m for m in gcs.messages[since:] if m.get_type() == "MISSION_REQUEST_INT"]
    assert len(requests) == 6  # the first request and five retries
    assert_same_mission(download(gcs), MIXED)


def test_the_mission_persists_beside_the_parameter_file(tmp_path):
    param_path = tmp_path / "rover.parm"
    param_path.write_text("")
    with simulated_rover(Params(), param_path=param_path) as (_, gcs, _):
        assert upload(gcs, MIXED).type == ACCEPTED
    saved = load_mission(tmp_path / "rover.waypoints")
    assert_same_mission(saved, MIXED)
    restarted = Companion(Params(), "udpout:127.0.0.1:9", "udpout:127.0.0.1:9",
                          param_path=param_path)
    try:
        assert_same_mission(list(restarted.core.mission.items), MIXED)
    finally:
        restarted.close()


def test_set_current_is_answered_with_mission_current(rover):
    _, gcs, _ = rover
    assert upload(gcs, MIXED).type == ACCEPTED
    since = gcs.mark()
    gcs.mav.mission_set_current_send(1, 1, 4)
    current = gcs.wait("MISSION_CURRENT", lambda m: m.seq == 4, 1.0, since)
    assert current is not None and current.total == len(MIXED) - 1
    since = gcs.mark()
    gcs.mav.command_long_send(1, 1, mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, 0, 2, 0, 0, 0, 0,
                              0, 0)
    assert gcs.wait("MISSION_CURRENT", lambda m: m.seq == 2, 1.0, since)
    since = gcs.mark()
    gcs.mav.mission_set_current_send(1, 1, 99)
    assert text_seen(gcs, "no item 99", since)


# --------------------------------------------------------------------------- AUTO

SQUARE = [(1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.0, 0.0), (1.0, 1.0)]  # then the diagonal


def drive_mission(sim, gcs, timeout_s: float = 40.0):
    """Arm, AUTO, and record until HOLD: (reached seqs with the true position at each,
    true positions with the time)."""
    arm(gcs)
    since = gcs.mark()
    assert set_mode(gcs, 10) == mavlink.MAV_RESULT_ACCEPTED
    reached: list[tuple[int, tuple[float, float]]] = []
    track: list[tuple[float, float, float]] = []
    index = since
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        gcs.pump(0.01)
        pose = sim.snapshot().pose
        track.append((pose.x_m, pose.y_m, pose.yaw_rad))
        while index < len(gcs.messages):
            msg = gcs.messages[index]
            index += 1
            if msg.get_type() == "MISSION_ITEM_REACHED":
                reached.append((msg.seq, (pose.x_m, pose.y_m), len(track)))
            if msg.get_type() == "HEARTBEAT" and msg.custom_mode == 4:
                return reached, track, since
    raise AssertionError(f"mission did not finish; reached {[r[0] for r in reached]}")


def test_auto_drives_every_item_in_order_within_10cm_arrival_and_5cm_cross_track(rover):
    sim, gcs, _ = rover
    items = renumber([HOME, do(0, YAW, 0.0, 0.0, 0.0, 0.0),
                      *(local_wp(0, n, e) for n, e in SQUARE)])
    assert upload(gcs, items).type == ACCEPTED
    reached, track, since = drive_mission(sim, gcs)
    assert [seq for seq, _, _ in reached] == list(range(1, len(items)))
    assert text_seen(gcs, "Mission started", since) and text_seen(gcs, "Mission complete", since)
    start, points = (0.0, 0.0), [(0.0, 0.0), *SQUARE]
    seen_from = reached[0][2]
    for k, (seq, position, at) in enumerate(reached[1:]):
        goal = points[k + 1]
        assert math.dist(position, goal) < 0.10, (seq, position, goal)
        leg = Leg(points[k], goal)
        cross = max(leg.distance_m(p[:2]) for p in track[seen_from:at])
        assert cross < 0.05, (seq, cross)
        seen_from = at
        start = goal
    assert start == SQUARE[-1]
    assert max(abs(p[2]) for p in track) < math.radians(2.0)  # faced north all the way
    current = gcs.wait("MISSION_CURRENT", lambda m: m.mission_state == 5, 1.5, since)
    assert current is not None  # MISSION_STATE_COMPLETE


def test_do_jump_repeats_its_items(rover):
    sim, gcs, _ = rover
    items = renumber([HOME, local_wp(0, 0.25, 0.0), local_wp(0, 0.0, 0.0), do(0, JUMP, 1, 2)])
    assert upload(gcs, items).type == ACCEPTED
    reached, _, _ = drive_mission(sim, gcs)
    assert [seq for seq, _, _ in reached] == [1, 2, 3, 1, 2, 3, 1, 2, 3]


def test_hold_pauses_the_mission_and_auto_resumes_it(rover):
    sim, gcs, _ = rover
    items = renumber([HOME, local_wp(0, 2.0, 0.0), local_wp(0, 2.0, 0.3)])
    assert upload(gcs, items).type == ACCEPTED
    arm(gcs)
    assert set_mode(gcs, 10) == mavlink.MAV_RESULT_ACCEPTED
    assert sim.wait_for(lambda s: s.pose.x_m > 0.6, 5.0)
    assert set_mode(gcs, 4) == mavlink.MAV_RESULT_ACCEPTED
    paused = sim.wait_for(lambda s: math.hypot(*s.velocity_body) < 0.005, 3.0)
    assert paused is not None
    gcs.pump(0.5)
    still = sim.snapshot().pose
    assert math.dist((still.x_m, still.y_m), (paused.pose.x_m, paused.pose.y_m)) < 0.01
    assert still.x_m < 1.9
    since = gcs.mark()
    assert set_mode(gcs, 10) == mavlink.MAV_RESULT_ACCEPTED
    assert text_seen(gcs, "Mission resumed at item 1", since)
    done = gcs.wait("MISSION_ITEM_REACHED", lambda m: m.seq == 2, 15.0, since)
    assert done is not None
    pose = sim.snapshot().pose
    assert math.dist((pose.x_m, pose.y_m), (2.0, 0.3)) < 0.1


def test_disarming_in_auto_sends_neutral_and_arming_resumes(rover):
    sim, gcs, companion = rover
    items = renumber([HOME, local_wp(0, 1.5, 0.0)])
    assert upload(gcs, items).type == ACCEPTED
    arm(gcs)
    assert set_mode(gcs, 10) == mavlink.MAV_RESULT_ACCEPTED
    assert sim.wait_for(lambda s: s.pose.x_m > 0.3, 5.0)
    gcs.mav.command_long_send(1, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 0, 0, 0, 0, 0,
                              0)
    assert sim.wait_for(lambda s: math.hypot(*s.velocity_body) < 0.005, 3.0)
    assert companion.core.pulses_us == companion.core.pwm.neutral()
    since = gcs.mark()
    arm(gcs)
    assert gcs.wait("MISSION_ITEM_REACHED", lambda m: m.seq == 1, 10.0, since)


def test_a_global_mission_needs_an_origin_and_drives_to_the_converted_point(rover):
    sim, gcs, _ = rover
    origin = GlobalOrigin.from_degrees(47.397742, 8.545594)
    lat, lon = origin.to_global(0.8, -0.4)
    items = renumber([HOME, MissionItem(0, GLOBAL_REL, mavlink.MAV_CMD_NAV_WAYPOINT, x=lat,
                                        y=lon)])
    assert upload(gcs, items).type == ACCEPTED
    arm(gcs)
    since = gcs.mark()
    assert set_mode(gcs, 10) == mavlink.MAV_RESULT_DENIED
    assert text_seen(gcs, "origin", since)
    since = gcs.mark()
    gcs.mav.set_gps_global_origin_send(1, origin.lat_e7, origin.lon_e7, 0, 0)
    assert gcs.wait("GPS_GLOBAL_ORIGIN", timeout_s=1.0, since=since)
    position = gcs.wait("GLOBAL_POSITION_INT", timeout_s=1.0, since=since)
    assert position is not None and abs(position.lat - origin.lat_e7) < 20  # ~2 mm
    assert abs(position.lon - origin.lon_e7) < 20
    assert set_mode(gcs, 10) == mavlink.MAV_RESULT_ACCEPTED
    assert gcs.wait("MISSION_ITEM_REACHED", lambda m: m.seq == 1, 10.0, since)
    pose = sim.snapshot().pose
    assert math.dist((pose.x_m, pose.y_m), (0.8, -0.4)) < 0.05


def test_mission_start_command_switches_to_auto_and_runs_from_the_given_item(rover):
    sim, gcs, _ = rover
    items = renumber([HOME, local_wp(0, 3.0, 0.0), local_wp(0, 0.0, 0.3)])
    assert upload(gcs, items).type == ACCEPTED
    arm(gcs)
    since = gcs.mark()
    gcs.mav.command_long_send(1, 1, mavlink.MAV_CMD_MISSION_START, 0, 2, 0, 0, 0, 0, 0, 0)
    ack = gcs.wait("COMMAND_ACK", lambda m: m.command == mavlink.MAV_CMD_MISSION_START, 1.0,
                   since)
    assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED
    assert gcs.wait("HEARTBEAT", lambda m: m.custom_mode == 10, 1.5, since)
    reached = gcs.wait("MISSION_ITEM_REACHED", timeout_s=8.0, since=since)
    assert reached is not None and reached.seq == 2  # item 1 was skipped by param1 = 2
    assert sim.snapshot().pose.x_m < 0.1
