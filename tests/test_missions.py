"""Missions end to end: the mission protocol with a scripted ground station, and AUTO driving
the simulated rover, in the lockstep harness (virtual time); the mission file beside the
parameter file with the real companion."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from missionitems import (
    GLOBAL_REL,
    JUMP,
    SPEED,
    YAW,
    do,
    local_wp,
    renumber,
    same,
)

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.control.pathfollow import Leg
from mecanum_mav.io.links import mavlink
from mecanum_mav.io.missionfile import load_mission
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.missionservice import ITEM_TIMEOUT_S, MAX_RETRIES
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.groundstation import ScriptedGroundStation, udp_ground_station
from mecanum_mav.sim.lockstep import Lockstep
from mecanum_mav.sim.simfc import SimFlightController

ACCEPTED = mavlink.MAV_MISSION_ACCEPTED
CMD_ACCEPTED, CMD_DENIED = mavlink.MAV_RESULT_ACCEPTED, mavlink.MAV_RESULT_DENIED
HOME = local_wp(0, 0.0, 0.0)
WP_RADIUS = float(Params()["WP_RADIUS"])
ARRIVED_M = WP_RADIUS + 0.005
"""Where the rover truly is when MISSION_ITEM_REACHED comes: within the acceptance radius
(of its odometry, a few mm from the truth)."""


def text_seen(gcs: ScriptedGroundStation, fragment: str, since: int,
              timeout_s: float = 1.0) -> bool:
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


def test_upload_then_download_returns_every_item_and_field(harness):
    gcs = harness.gcs
    ack = gcs.upload(MIXED)
    assert ack is not None and ack.type == ACCEPTED
    assert_same_mission(gcs.download(), MIXED)
    assert_same_mission(list(harness.core.mission.items), MIXED)


def test_legacy_mission_item_upload_and_mission_request_download_round_trip(harness):
    gcs = harness.gcs
    ack = gcs.upload(MIXED, legacy=True)
    assert ack is not None and ack.type == ACCEPTED
    assert_same_mission(gcs.download(), MIXED, float32_xy=True)
    assert_same_mission(gcs.download(legacy=True), MIXED, float32_xy=True)


def test_upload_survives_lost_requests_and_duplicated_items(harness):
    gcs = harness.gcs
    since = gcs.mark()
    lost = frozenset({0, 3, len(MIXED) - 1})
    ack = gcs.upload(MIXED, lose_first=lost, duplicate=True)
    assert ack is not None and ack.type == ACCEPTED
    requests = [m.seq for m in gcs.received("MISSION_REQUEST_INT", since)]
    assert requests == sorted(requests)  # in order, duplicates dropped silently
    assert sorted(set(requests)) == list(range(len(MIXED)))
    assert [s for s in set(requests) if requests.count(s) > 1] == sorted(lost)  # re-requested
    assert_same_mission(gcs.download(), MIXED)


def test_clear_all_and_a_count_of_zero_both_empty_the_mission(harness):
    gcs = harness.gcs
    for clear in ("clear_all", "count_zero"):
        assert gcs.upload(MIXED).type == ACCEPTED
        since = gcs.mark()
        if clear == "clear_all":
            gcs.mav.mission_clear_all_send(1, 1, 0)
        else:
            gcs.mav.mission_count_send(1, 1, 0, 0)
        ack = gcs.wait("MISSION_ACK", timeout_s=1.0, since=since)
        assert ack is not None and ack.type == ACCEPTED
        assert gcs.download() == []


def test_a_non_finite_coordinate_is_rejected_and_the_previous_mission_kept(harness):
    gcs = harness.gcs
    assert gcs.upload(MIXED).type == ACCEPTED
    bad = renumber([HOME, local_wp(0, 1.0, 0.0), local_wp(0, 2.0, 0.0, z=math.nan)])
    since = gcs.mark()
    ack = gcs.upload(bad)
    assert ack is not None and ack.type == mavlink.MAV_MISSION_INVALID_PARAM7
    assert text_seen(gcs, "item 2", since)
    nan_x = renumber([HOME, MissionItem(0, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                        mavlink.MAV_CMD_NAV_WAYPOINT)])
    since = gcs.mark()
    gcs.mav.mission_count_send(1, 1, 2, 0)
    assert gcs.wait("MISSION_REQUEST_INT", lambda m: m.seq == 0, 1.0, since)
    gcs.mav.mission_item_send(1, 1, 0, 1, 16, 0, 1, 0, 0, 0, 0, 0.0, 0.0, 0.0, 0)
    # after a legacy MISSION_ITEM the vehicle asks with MISSION_REQUEST
    assert gcs.wait("MISSION_REQUEST", lambda m: m.seq == 1, 1.0, since)
    gcs.mav.mission_item_send(1, 1, 1, nan_x[1].frame, 16, 0, 1, 0, 0, 0, 0, math.nan, 149.0,
                              0.0, 0)
    ack = gcs.wait("MISSION_ACK", timeout_s=1.0, since=since)
    assert ack is not None and ack.type == mavlink.MAV_MISSION_INVALID_PARAM5_X
    assert_same_mission(gcs.download(), MIXED)


def test_an_upload_abandoned_midway_times_out_and_keeps_the_previous_mission(harness):
    h, gcs = harness, harness.gcs
    assert gcs.upload(MIXED).type == ACCEPTED
    since, start_s = gcs.mark(), h.now_s
    gcs.mav.mission_count_send(1, 1, 3, 0)
    assert gcs.wait("MISSION_REQUEST_INT", lambda m: m.seq == 0, 1.0, since)
    # Silence: the vehicle asks again (250 ms, 5 retries), then cancels.
    ack = gcs.wait("MISSION_ACK", timeout_s=3.0, since=since)
    assert ack is not None and ack.type == mavlink.MAV_MISSION_OPERATION_CANCELLED
    assert h.now_s - start_s == pytest.approx((MAX_RETRIES + 1) * ITEM_TIMEOUT_S, abs=0.03)
    requests = gcs.received("MISSION_REQUEST_INT", since)
    assert [m.seq for m in requests] == [0] * (1 + MAX_RETRIES)  # the first and five retries
    assert text_seen(gcs, "Mission upload timed out at item 0", since)
    assert_same_mission(gcs.download(), MIXED)


def test_the_mission_persists_beside_the_parameter_file(tmp_path):
    """Files: the real companion on real sockets, then a companion started again."""
    param_path = tmp_path / "rover.parm"
    param_path.write_text("")
    gcs, port = udp_ground_station()
    with SimFlightController("udpin:127.0.0.1:0", Params()) as sim:
        sim.start()
        companion = Companion(Params(), port.url, f"udpout:127.0.0.1:{sim.local_port}",
                              param_path=param_path)
        companion.start()
        try:
            assert gcs.wait("HEARTBEAT", timeout_s=3.0)
            assert gcs.upload(MIXED).type == ACCEPTED
        finally:
            companion.close()
            port.close()
    saved = load_mission(tmp_path / "rover.waypoints")
    assert_same_mission(saved, MIXED)
    restarted = Companion(Params(), "udpout:127.0.0.1:9", "udpout:127.0.0.1:9",
                          param_path=param_path)
    try:
        assert_same_mission(list(restarted.core.mission.items), MIXED)
    finally:
        restarted.close()


def test_set_current_is_answered_with_mission_current(harness):
    gcs = harness.gcs
    assert gcs.upload(MIXED).type == ACCEPTED
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


def auto(h: Lockstep) -> int:
    """Arm and switch to AUTO; the index of the ground station's messages from before."""
    h.gcs.arm()
    since = h.gcs.mark()
    assert h.gcs.set_mode(Mode.AUTO) == CMD_ACCEPTED
    return since


def drive_mission(h: Lockstep, timeout_s: float = 40.0):
    """Arm, AUTO, and record until HOLD: (reached seqs with the true position at each and the
    length of the track then, the true track (north, east, yaw) at every step, the index of
    the ground station's messages from before AUTO)."""
    since = auto(h)
    reached: list[tuple[int, tuple[float, float], int]] = []
    track: list[tuple[float, float, float]] = []
    index = [since]

    def held() -> bool:
        pose = h.truth().pose
        track.append((pose.x_m, pose.y_m, pose.yaw_rad))
        h.gcs.pump(0.0)  # collect what arrived in this step
        messages = h.gcs.messages
        for msg in messages[index[0]:]:
            if msg.get_type() == "MISSION_ITEM_REACHED":
                reached.append((msg.seq, (pose.x_m, pose.y_m), len(track)))
            if msg.get_type() == "HEARTBEAT" and msg.custom_mode == Mode.HOLD:
                return True
        index[0] = len(messages)
        return False

    assert h.run_until(held, timeout_s), f"mission not finished; reached {[r[0] for r in reached]}"
    return reached, track, since


def test_auto_drives_every_item_in_order_within_wp_radius_and_4cm_cross_track(harness):
    h, gcs = harness, harness.gcs
    items = renumber([HOME, do(0, YAW, 0.0, 0.0, 0.0, 0.0),
                      *(local_wp(0, n, e) for n, e in SQUARE)])
    assert gcs.upload(items).type == ACCEPTED
    reached, track, since = drive_mission(h)
    assert [seq for seq, _, _ in reached] == list(range(1, len(items)))
    assert text_seen(gcs, "Mission started", since)
    assert text_seen(gcs, "Mission complete", since)
    points = [(0.0, 0.0), *SQUARE]
    seen_from = reached[0][2]
    for k, (seq, position, at) in enumerate(reached[1:]):
        goal = points[k + 1]
        assert math.dist(position, goal) < ARRIVED_M, (seq, position, goal)
        leg = Leg(points[k], goal)  # it starts up to WP_RADIUS from the last corner
        cross = max(leg.distance_m(p[:2]) for p in track[seen_from:at])
        assert cross < WP_RADIUS + 0.01, (seq, cross)
        seen_from = at
    assert max(abs(p[2]) for p in track) < math.radians(0.1)  # faced north all the way
    current = gcs.wait("MISSION_CURRENT", lambda m: m.mission_state == 5, 1.5, since)
    assert current is not None  # MISSION_STATE_COMPLETE


def test_do_jump_repeats_its_items(harness):
    items = renumber([HOME, local_wp(0, 0.25, 0.0), local_wp(0, 0.0, 0.0), do(0, JUMP, 1, 2)])
    assert harness.gcs.upload(items).type == ACCEPTED
    reached, _, _ = drive_mission(harness)
    assert [seq for seq, _, _ in reached] == [1, 2, 3, 1, 2, 3, 1, 2, 3]


def test_hold_pauses_the_mission_and_auto_resumes_it(harness):
    h, gcs = harness, harness.gcs
    items = renumber([HOME, local_wp(0, 2.0, 0.0), local_wp(0, 2.0, 0.3)])
    assert gcs.upload(items).type == ACCEPTED
    auto(h)
    assert h.run_until(lambda: h.truth().pose.x_m > 0.6, 5.0)
    assert gcs.set_mode(Mode.HOLD) == CMD_ACCEPTED
    paused = h.run_until(lambda: math.hypot(*h.truth().velocity_body) < 0.005 and h.truth(),
                         3.0)
    assert paused is not None
    h.run_for(0.5)
    still = h.truth().pose
    assert math.dist((still.x_m, still.y_m), (paused.pose.x_m, paused.pose.y_m)) < 0.002
    assert still.x_m < 1.9
    since = gcs.mark()
    assert gcs.set_mode(Mode.AUTO) == CMD_ACCEPTED
    assert text_seen(gcs, "Mission resumed at item 1", since)
    assert gcs.wait("MISSION_ITEM_REACHED", lambda m: m.seq == 1, 15.0, since)
    done = gcs.wait("MISSION_ITEM_REACHED", lambda m: m.seq == 2, 15.0, since)
    assert done is not None
    pose = h.truth().pose
    assert math.dist((pose.x_m, pose.y_m), (2.0, 0.3)) < ARRIVED_M


def test_disarming_in_auto_sends_neutral_and_arming_resumes(harness):
    h, gcs = harness, harness.gcs
    items = renumber([HOME, local_wp(0, 1.5, 0.0)])
    assert gcs.upload(items).type == ACCEPTED
    auto(h)
    assert h.run_until(lambda: h.truth().pose.x_m > 0.3, 5.0)
    ack = gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    assert ack is not None and ack.result == CMD_ACCEPTED
    disarmed_s = h.now_s
    assert h.run_until(lambda: math.hypot(*h.truth().velocity_body) < 0.005, 3.0)
    assert h.core.pulses_us == h.core.pwm.neutral()
    after = h.overrides_since(disarmed_s)
    assert after[0].time_s == disarmed_s  # neutral at once, and from then on
    assert all(o.channels[:4] == [1500] * 4 for o in after)
    since = gcs.mark()
    gcs.arm()
    assert gcs.wait("MISSION_ITEM_REACHED", lambda m: m.seq == 1, 10.0, since)
    pose = h.truth().pose
    assert math.dist((pose.x_m, pose.y_m), (1.5, 0.0)) < ARRIVED_M


def test_a_global_mission_needs_an_origin_and_drives_to_the_converted_point(harness):
    h, gcs = harness, harness.gcs
    origin = GlobalOrigin.from_degrees(47.397742, 8.545594)
    lat, lon = origin.to_global(0.8, -0.4)
    items = renumber([HOME, MissionItem(0, GLOBAL_REL, mavlink.MAV_CMD_NAV_WAYPOINT, x=lat,
                                        y=lon)])
    assert gcs.upload(items).type == ACCEPTED
    gcs.arm()
    since = gcs.mark()
    assert gcs.set_mode(Mode.AUTO) == CMD_DENIED
    assert text_seen(gcs, "origin", since)
    since = gcs.mark()
    gcs.mav.set_gps_global_origin_send(1, origin.lat_e7, origin.lon_e7, 0, 0)
    assert gcs.wait("GPS_GLOBAL_ORIGIN", timeout_s=1.0, since=since)
    position = gcs.wait("GLOBAL_POSITION_INT", timeout_s=1.0, since=since)
    assert position is not None and abs(position.lat - origin.lat_e7) <= 1  # 1e-7 deg
    assert abs(position.lon - origin.lon_e7) <= 1
    assert gcs.set_mode(Mode.AUTO) == CMD_ACCEPTED
    assert gcs.wait("MISSION_ITEM_REACHED", lambda m: m.seq == 1, 10.0, since)
    pose = h.truth().pose
    assert math.dist((pose.x_m, pose.y_m), (0.8, -0.4)) < ARRIVED_M


def test_mission_start_command_switches_to_auto_and_runs_from_the_given_item(harness):
    h, gcs = harness, harness.gcs
    items = renumber([HOME, local_wp(0, 3.0, 0.0), local_wp(0, 0.0, 0.3)])
    assert gcs.upload(items).type == ACCEPTED
    gcs.arm()
    since = gcs.mark()
    ack = gcs.command(mavlink.MAV_CMD_MISSION_START, 2)
    assert ack is not None and ack.result == CMD_ACCEPTED
    assert gcs.wait("HEARTBEAT", lambda m: m.custom_mode == Mode.AUTO, 1.5, since)
    reached = gcs.wait("MISSION_ITEM_REACHED", timeout_s=8.0, since=since)
    assert reached is not None and reached.seq == 2  # item 1 was skipped by param1 = 2
    pose = h.truth().pose
    assert abs(pose.x_m) < 0.001 and math.dist((pose.x_m, pose.y_m), (0.0, 0.3)) < ARRIVED_M
