"""Telemetry streams, message intervals, REQUEST_MESSAGE, PING, FTP refusal, home reset.

In the lockstep harness (virtual time, see tests/test_companion.py): counts and times are
exact. A stream is scheduled on a fixed grid of slots ``interval`` apart; each message rides the
core's nearest wake-up, so it goes out at most half an output period (25 ms at OUT_RATE 20 Hz)
before its slot and at most one step after it: exactly one message per slot.
"""

from __future__ import annotations

import math
from typing import Any

import pytest
from conftest import lockstep
from support import status_texts

import mecanum_mav
from mecanum_mav.config.params import Params
from mecanum_mav.control.core import RoverCore
from mecanum_mav.io.links import mavlink
from mecanum_mav.protocol import telemetry
from mecanum_mav.sim.lockstep import Lockstep

CMD = mavlink
ACCEPTED, DENIED = CMD.MAV_RESULT_ACCEPTED, CMD.MAV_RESULT_DENIED
EPS = 1e-9
EARLY_S = 0.5 / 20.0
"""How early a message may ride a wake-up before its slot: half the output period."""
EDGE_S = 0.01
"""Count windows start this long after a slot: no message is sent near that instant."""


def collect(h: Lockstep, seconds: float) -> list[tuple[float, Any]]:
    """Step for ``seconds``: every message that reached the ground station meanwhile, with
    the virtual time it arrived."""
    start = len(h.gcs.messages)
    h.run_for(seconds)
    return list(zip(h.gcs.arrived_s[start:], h.gcs.messages[start:], strict=True))


def arrivals(h: Lockstep, kind: str, seconds: float) -> list[tuple[float, Any]]:
    """Step for ``seconds``: the ``kind`` messages that arrived, with their arrival times."""
    return [(t, m) for t, m in collect(h, seconds) if m.get_type() == kind]


def run_to(h: Lockstep, t: float) -> None:
    h.run_for(t - h.now_s)


def assert_one_per_slot(h: Lockstep, times: list[float], origin: float, interval: float) -> None:
    """Each time belongs to its own slot ``origin + k * interval``, k consecutive, and lies
    between EARLY_S before the slot and one step after it."""
    slots = [math.floor((t - origin + EARLY_S + EPS) / interval) for t in times]
    assert slots == list(range(slots[0], slots[0] + len(slots))), slots
    for t, k in zip(times, slots, strict=True):
        slot = origin + k * interval
        assert slot - EARLY_S - EPS <= t <= slot + h.dt_s + EPS, (t, slot)


def per_second(times: list[float], start: float, seconds: int) -> list[int]:
    return [sum(1 for t in times if start + n <= t < start + n + 1.0) for n in range(seconds)]


# --------------------------------------------------------------------------- streams


@pytest.mark.parametrize(
    ("values", "pos_hz", "ext_hz"),
    [({}, 10, 2),  # the defaults: TLM_POS_RATE 10 Hz, TLM_EXT_RATE 2 Hz
     ({"TLM_POS_RATE": 4.0, "TLM_EXT_RATE": 5.0}, 4, 5),
     ({"TLM_POS_RATE": 20.0, "TLM_EXT_RATE": 0.0}, 20, 0)],
)
def test_default_streams_arrive_at_their_parameter_rates(values, pos_hz, ext_hz):
    h = lockstep(values)
    run_to(h, 1.0 + EDGE_S)  # the grids start at boot (t = 0): start on a clear edge
    start = h.now_s
    seconds = 5
    streams = {"ODOMETRY": pos_hz, "LOCAL_POSITION_NED": pos_hz, "ATTITUDE": pos_hz,
               "SYS_STATUS": ext_hz, "SERVO_OUTPUT_RAW": ext_hz, "WHEEL_DISTANCE": ext_hz}
    got = collect(h, seconds)
    for name, hz in streams.items():
        times = [t for t, m in got if m.get_type() == name]
        assert per_second(times, start, seconds) == [hz] * seconds, name
        if hz:
            assert_one_per_slot(h, times, 0.0, 1.0 / hz)
    # no global origin: nothing to put on a map
    assert [m for _, m in got if m.get_type() == "GLOBAL_POSITION_INT"] == []


def test_set_message_interval_changes_one_stream_and_get_reports_it(harness):
    h = harness
    h.run_for(1.0)
    since = h.gcs.mark()
    ack = h.gcs.command(CMD.MAV_CMD_SET_MESSAGE_INTERVAL, CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE,
                        50000)
    assert ack.result == ACCEPTED
    origin = h.now_s  # the new grid starts in the step the command arrived, with a message
    assert len(h.gcs.received("WHEEL_DISTANCE", since)) == 1
    run_to(h, origin + EDGE_S)
    got = arrivals(h, "WHEEL_DISTANCE", 3.0)
    times = [t for t, _ in got]
    assert per_second(times, origin + EDGE_S, 3) == [20, 20, 20]
    assert_one_per_slot(h, times, origin, 0.05)
    run_to(h, math.ceil(h.now_s) + EDGE_S)
    others = arrivals(h, "SYS_STATUS", 2.0)  # the other streams keep their rates (2 Hz)
    assert len(others) == 4

    since = h.gcs.mark()
    ack = h.gcs.command(CMD.MAV_CMD_GET_MESSAGE_INTERVAL, CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE)
    assert ack.result == ACCEPTED
    reply = h.gcs.received("MESSAGE_INTERVAL", since)  # with the ACK, in the same step
    assert len(reply) == 1 and reply[0].message_id == CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE
    assert reply[0].interval_us == 50000

    since = h.gcs.mark()
    ack = h.gcs.command(CMD.MAV_CMD_SET_MESSAGE_INTERVAL, CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE, -1)
    assert ack.result == ACCEPTED
    assert h.gcs.received("WHEEL_DISTANCE", since) == []  # none from the command's step on
    assert arrivals(h, "WHEEL_DISTANCE", 2.0) == []
    since = h.gcs.mark()
    h.gcs.command(CMD.MAV_CMD_GET_MESSAGE_INTERVAL, CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE)
    assert [m.interval_us for m in h.gcs.received("MESSAGE_INTERVAL", since)] == [-1]

    # interval 0: back to the parameter's rate (TLM_EXT_RATE 2 Hz)
    assert h.gcs.command(CMD.MAV_CMD_SET_MESSAGE_INTERVAL, CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE,
                         0).result == ACCEPTED
    since = h.gcs.mark()
    h.gcs.command(CMD.MAV_CMD_GET_MESSAGE_INTERVAL, CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE)
    assert [m.interval_us for m in h.gcs.received("MESSAGE_INTERVAL", since)] == [500000]


def test_message_interval_for_a_message_we_do_not_stream_is_denied(harness):
    h = harness
    ack = h.gcs.command(CMD.MAV_CMD_SET_MESSAGE_INTERVAL, CMD.MAVLINK_MSG_ID_GPS_RAW_INT, 100000)
    assert ack.result == DENIED
    assert arrivals(h, "GPS_RAW_INT", 1.0) == []


def test_request_message_answers_autopilot_version_and_home_position(harness):
    h = harness
    for msg_id, mtype in ((CMD.MAVLINK_MSG_ID_AUTOPILOT_VERSION, "AUTOPILOT_VERSION"),
                          (CMD.MAVLINK_MSG_ID_HOME_POSITION, "HOME_POSITION")):
        since = h.gcs.mark()
        assert h.gcs.command(CMD.MAV_CMD_REQUEST_MESSAGE, msg_id).result == ACCEPTED
        assert len(h.gcs.received(mtype, since)) == 1  # with the ACK, in the same step
    since = h.gcs.mark()
    h.gcs.command(CMD.MAV_CMD_REQUEST_MESSAGE, CMD.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    version = h.gcs.received("AUTOPILOT_VERSION", since)[0]
    assert version.capabilities & CMD.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    assert version.capabilities & CMD.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT


def test_autopilot_version_claims_what_the_companion_honours_and_gives_its_version(harness):
    """AUTOPILOT_VERSION (MAVLink): the capabilities are the protocol features a ground
    station may use with us (MAVLink 2, float parameters, COMMAND_INT, MISSION_ITEM_INT) and
    no others; flight_sw_version is the package's version as ArduPilot packs its own: major,
    minor and patch in the top three bytes, FIRMWARE_VERSION_TYPE_OFFICIAL (255) in the last."""
    h = harness
    since = h.gcs.mark()
    h.gcs.command(CMD.MAV_CMD_REQUEST_MESSAGE, CMD.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    [version] = h.gcs.received("AUTOPILOT_VERSION", since)
    assert version.capabilities == (CMD.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                                    | CMD.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
                                    | CMD.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                                    | CMD.MAV_PROTOCOL_CAPABILITY_MISSION_INT)
    sw = version.flight_sw_version
    major, minor, patch = (int(part) for part in mecanum_mav.__version__.split(".")[:3])
    assert (sw >> 24, sw >> 16 & 0xFF, sw >> 8 & 0xFF, sw & 0xFF) == (major, minor, patch, 255)
    # what the companion has no value for is 0 (MAVLink: unknown)
    assert (version.middleware_sw_version, version.os_sw_version, version.board_version,
            version.vendor_id, version.product_id, version.uid) == (0, 0, 0, 0, 0, 0)
    assert [list(version.flight_custom_version), list(version.middleware_custom_version),
            list(version.os_custom_version)] == [[0] * 8] * 3
    assert list(version.uid2) == [0] * 18


@pytest.mark.parametrize(("package_version", "parts"), [("4.7.2", (4, 7, 2)),
                                                         ("1.2.3.4", (1, 2, 3))])
def test_autopilot_version_packs_major_minor_and_patch_of_any_version(
        harness, monkeypatch, package_version, parts):
    monkeypatch.setattr(telemetry, "__version__", package_version)
    since = harness.gcs.mark()
    harness.gcs.command(CMD.MAV_CMD_REQUEST_MESSAGE, CMD.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    [version] = harness.gcs.received("AUTOPILOT_VERSION", since)
    sw = version.flight_sw_version
    assert (sw >> 24, sw >> 16 & 0xFF, sw >> 8 & 0xFF, sw & 0xFF) == (*parts, 255)


@pytest.mark.parametrize("origin", [None, (473_977_420, 85_455_940, 488_123)],
                         ids=["no global origin", "origin set"])
def test_home_position_is_the_local_origin_at_its_latitude_and_longitude_once_known(origin):
    """HOME_POSITION: home is where the local frame starts (x = y = z = 0, level: q is the
    identity), at the global origin's latitude, longitude (1e-7 deg) and altitude (mm), as
    SET_GPS_GLOBAL_ORIGIN gave them; all 0 while the rover has none. time_usec is the time
    since boot."""
    h = lockstep()
    if origin is not None:
        h.gcs.mav.set_gps_global_origin_send(1, *origin)
    assert h.gcs.wait("HEARTBEAT", timeout_s=1.5) is not None  # (some time since boot)
    since = h.gcs.mark()
    h.gcs.command(CMD.MAV_CMD_REQUEST_MESSAGE, CMD.MAVLINK_MSG_ID_HOME_POSITION)
    [home] = h.gcs.received("HOME_POSITION", since)
    assert (home.latitude, home.longitude, home.altitude) == (origin or (0, 0, 0))
    assert (home.x, home.y, home.z) == (0.0, 0.0, 0.0)
    assert (home.approach_x, home.approach_y, home.approach_z) == (0.0, 0.0, 0.0)  # (none)
    assert list(home.q) == [1.0, 0.0, 0.0, 0.0]
    assert 0 < home.time_usec <= 1e6 * h.now_s


def test_set_gps_global_origin_is_answered_with_the_origin_and_said():
    """GPS_GLOBAL_ORIGIN echoes the origin taken (1e-7 deg, mm) with the time since boot
    (us), as ArduPilot answers SET_GPS_GLOBAL_ORIGIN; the pilot sees it in a STATUSTEXT."""
    h = lockstep()
    assert h.gcs.wait("HEARTBEAT", timeout_s=1.5) is not None  # (some time since boot)
    since = h.gcs.mark()
    h.gcs.mav.set_gps_global_origin_send(1, 473_977_420, 85_455_940, 488_123)
    answer = h.gcs.wait("GPS_GLOBAL_ORIGIN", timeout_s=1.0, since=since)
    assert answer is not None
    assert (answer.latitude, answer.longitude, answer.altitude) == (
        473_977_420, 85_455_940, 488_123)
    assert 1e6 <= answer.time_usec <= 1e6 * h.now_s
    assert "Origin 47.3977420 8.5455940" in status_texts(h, since)


def test_the_origins_time_is_counted_from_the_companions_start() -> None:
    """time_usec is time since boot, for a core started at any clock reading (the companion's
    monotonic clock is seconds since the machine booted)."""
    core = RoverCore(Params(), now_s=5000.0)
    station = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    msg = station.set_gps_global_origin_encode(1, 473_977_420, 85_455_940, 0)
    msg.pack(station)  # (as received: the header names the sender)
    out = core.handle(msg, 5002.5)
    [answer] = [m for m in out.gcs if m.get_type() == "GPS_GLOBAL_ORIGIN"]
    assert answer.time_usec == 2_500_000


@pytest.mark.parametrize("sender, target", [(200, 1), (255, 7)],
                         ids=["not the pilot's ground station", "for another system"])
def test_an_origin_from_another_ground_station_or_for_another_system_is_ignored(
        sender: int, target: int) -> None:
    h = lockstep({"SYSID_MYGCS": 255})
    h.gcs.mav.srcSystem = sender
    since = h.gcs.mark()
    h.gcs.mav.set_gps_global_origin_send(target, 473_977_420, 85_455_940, 0)
    h.run_for(0.5)
    h.gcs.mark()
    assert h.gcs.received("GPS_GLOBAL_ORIGIN", since) == []
    h.gcs.mav.srcSystem = 255
    since = h.gcs.mark()
    h.gcs.command(CMD.MAV_CMD_REQUEST_MESSAGE, CMD.MAVLINK_MSG_ID_HOME_POSITION)
    [home] = h.gcs.received("HOME_POSITION", since)
    assert (home.latitude, home.longitude) == (0, 0)  # (no origin taken)


def test_request_message_for_an_unknown_message_is_denied(harness):
    assert harness.gcs.command(CMD.MAV_CMD_REQUEST_MESSAGE, 99999).result == DENIED


def test_ping_is_answered_to_its_sender(harness):
    h = harness
    since = h.gcs.mark()
    h.gcs.mav.ping_send(123456, 42, 0, 0)
    h.step()  # answered in the step it arrives
    h.gcs.mark()
    replies = h.gcs.received("PING", since)
    assert len(replies) == 1
    reply = replies[0]
    assert (reply.seq, reply.time_usec) == (42, 123456)
    assert (reply.target_system, reply.target_component) == (255, 190)


def test_file_transfer_requests_are_refused_as_file_not_found(harness):
    h = harness
    since = h.gcs.mark()
    request = [7, 0, 0, 4, 12, 0, 0, 0, 0, 0, 0, 0, *b"@PARAM/param.pck"]  # seq 7 OpenFileRO
    h.gcs.mav.file_transfer_protocol_send(0, 1, 1, request + [0] * (251 - len(request)))
    h.step()  # answered in the step it arrives
    h.gcs.mark()
    replies = h.gcs.received("FILE_TRANSFER_PROTOCOL", since)
    assert len(replies) == 1
    reply = replies[0]
    assert (reply.target_network, reply.target_system, reply.target_component) == (0, 255, 190)
    payload = bytes(reply.payload)
    assert payload[0] | payload[1] << 8 == 8  # seq + 1
    since = h.gcs.mark()
    h.gcs.mav.file_transfer_protocol_send(0, 1, 5, request + [0] * (251 - len(request)))
    h.step()  # (for another component of system 1: not ours to answer)
    h.gcs.mark()
    assert h.gcs.received("FILE_TRANSFER_PROTOCOL", since) == []
    assert (payload[3], payload[4], payload[5], payload[12]) == (129, 1, 4, 10)


def test_set_home_to_here_resets_the_odometry_origin_and_counter(harness):
    h = harness
    h.gcs.arm()
    stop = h.every(0.05, lambda now_s: h.gcs.mav.manual_control_send(1, 1000, 0, 500, 0, 0))
    h.run_for(1.0)
    stop()
    h.run_for(2.0)  # input timeout: neutral; the rover stops
    assert h.core.estimator.pose.x_m > 1.0  # it went somewhere
    before = h.core.estimator.reset_counter
    heading = h.core.estimator.pose.yaw_rad
    said = h.gcs.mark()
    ack = h.gcs.command(CMD.MAV_CMD_DO_SET_HOME, 1)
    assert ack.result == ACCEPTED
    assert "Home and odometry origin set here" in status_texts(h, said)
    assert h.core.estimator.reset_counter == before + 1
    since = h.gcs.mark()
    odom = h.gcs.wait("ODOMETRY", timeout_s=0.1 + h.dt_s, since=since)  # the next one
    assert odom is not None and odom.reset_counter == before + 1
    # (the origin is where it stood: any motion since is the chassis settling, sub-micrometre)
    assert (odom.x, odom.y) == pytest.approx((0.0, 0.0), abs=1e-6)
    assert h.core.estimator.pose.yaw_rad == pytest.approx(heading, abs=1e-6)  # (kept)
    said = h.gcs.mark()
    assert h.gcs.command(CMD.MAV_CMD_DO_SET_HOME, 0).result == DENIED
    assert h.core.estimator.reset_counter == before + 1
    assert "Set home: only 'use current position' (param1=1)" in status_texts(h, said)


def test_servo_output_raw_shows_the_commanded_pwm(harness):
    h = harness
    h.gcs.arm()
    stop = h.every(0.05, lambda now_s: h.gcs.mav.manual_control_send(1, 1000, 0, 500, 0, 0))
    h.step()  # the first stick reaches the core: the wheels are at 2000 from here on
    since = h.gcs.mark()
    seen = h.gcs.wait("SERVO_OUTPUT_RAW", timeout_s=0.5 + h.dt_s, since=since)  # 2 Hz: next
    stop()
    assert seen is not None
    assert (seen.servo1_raw, seen.servo2_raw, seen.servo3_raw, seen.servo4_raw,
            seen.servo5_raw) == (2000, 2000, 2000, 2000, 0)


# --------------------------------------------------------------------------- health, battery

MOTORS = mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
AHRS = mavlink.MAV_SYS_STATUS_AHRS
BATTERY = mavlink.MAV_SYS_STATUS_SENSOR_BATTERY
FENCE, GPS = mavlink.MAV_SYS_STATUS_GEOFENCE, mavlink.MAV_SYS_STATUS_SENSOR_GPS


def sys_status(h: Lockstep):
    since = h.gcs.mark()
    h.gcs.mav.command_long_send(1, 1, CMD.MAV_CMD_REQUEST_MESSAGE, 0,
                                mavlink.MAVLINK_MSG_ID_SYS_STATUS, 0, 0, 0, 0, 0, 0)
    return h.gcs.wait("SYS_STATUS", timeout_s=0.1, since=since)


def test_sys_status_tells_the_truth_no_fence_or_gps_alarm_and_the_boards_battery(harness):
    h = harness
    h.run_for(1.5)  # the board's SYS_STATUS (1 Hz) has been relayed
    s = sys_status(h)
    assert s.onboard_control_sensors_present == MOTORS | AHRS | BATTERY
    assert s.onboard_control_sensors_enabled == MOTORS | AHRS | BATTERY
    assert s.onboard_control_sensors_health & (FENCE | GPS | MOTORS | AHRS | BATTERY) == (
        FENCE | GPS | MOTORS | AHRS | BATTERY)  # a clear bit is an alarm in MAVProxy / QGC
    assert (s.voltage_battery, s.battery_remaining) == (12600, 100)
    assert s.current_battery == 30  # 0.3 A standing still (cA)


def test_the_flight_controller_is_asked_for_its_battery_and_attitude_once_it_is_heard(harness):
    asks = [m for m in harness.fc_received if m.get_type() == "COMMAND_LONG"]
    assert [ask.command for ask in asks] == [CMD.MAV_CMD_SET_MESSAGE_INTERVAL] * 4
    assert [(ask.param1, ask.param2) for ask in asks] == [
        (mavlink.MAVLINK_MSG_ID_SYS_STATUS, 1_000_000),
        (mavlink.MAVLINK_MSG_ID_ATTITUDE, 50_000),  # the odometry's heading at 20 Hz
        (mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 100_000),  # the heading bias's track
        (mavlink.MAVLINK_MSG_ID_GPS_RAW_INT, 100_000)]
    assert {(ask.target_system, ask.target_component) for ask in asks} == {(1, 1)}


def test_without_the_flight_controller_motors_and_ahrs_are_unhealthy_and_the_battery_unknown(
        harness):
    h = harness
    h.run_for(1.5)
    h.fc_link_up = False  # the cable is pulled
    h.run_for(5.5)  # FS_FC_TMO 3 s; the battery report is 5 s old
    s = sys_status(h)
    assert s.onboard_control_sensors_health & (MOTORS | AHRS) == 0
    assert s.onboard_control_sensors_health & FENCE == FENCE
    assert s.onboard_control_sensors_present == MOTORS | AHRS
    assert (s.voltage_battery, s.current_battery, s.battery_remaining) == (65535, -1, -1)


def test_a_message_interval_too_long_for_int32_microseconds_is_denied_and_get_still_answers(
        harness):
    # Found by tools/fuzz.py: 1e38 us was taken, and GET_MESSAGE_INTERVAL's answer then
    # could not be packed (MESSAGE_INTERVAL.interval_us is int32).
    h = harness
    odometry = CMD.MAVLINK_MSG_ID_ODOMETRY
    for interval_us in (1e38, 2.0**31, math.inf, math.nan):
        ack = h.gcs.command(CMD.MAV_CMD_SET_MESSAGE_INTERVAL, odometry, interval_us)
        assert ack.result == DENIED
    ack = h.gcs.command(CMD.MAV_CMD_SET_MESSAGE_INTERVAL, odometry, 2e9)  # exact in float32
    assert ack.result == ACCEPTED
    since = h.gcs.mark()
    assert h.gcs.command(CMD.MAV_CMD_GET_MESSAGE_INTERVAL, odometry).result == ACCEPTED
    assert [m.interval_us for m in h.gcs.received("MESSAGE_INTERVAL", since)] == [2_000_000_000]


def test_an_idle_rover_wakes_only_for_the_refresh_and_its_streams_keep_their_rates() -> None:
    # The companion's loop in virtual time: wake at next_due_s, a little late as a real wake
    # is (epoll counts whole milliseconds), then tick and housekeeping.
    core = RoverCore(Params(), now_s=0.0)
    late_s, now, wakes = 0.0007, 0.0, 0
    sent: dict[str, list[float]] = {}
    while now < 10.0:
        now = max(now, core.next_due_s()) + late_s
        wakes += 1
        for out in (core.tick(now), core.housekeeping(now)):
            if out.override is not None:
                sent.setdefault("override", []).append(now)
            for msg in out.gcs:
                sent.setdefault(msg.get_type(), []).append(now)
    assert wakes == len(sent["override"]) == 199  # each wake the refresh's (20 Hz, late)
    assert [len(sent[k]) for k in ("ODOMETRY", "SYS_STATUS", "HEARTBEAT")] == [101, 21, 11]
    ride_s = 0.5 / float(core.params["OUT_RATE"]) + late_s  # each within half a refresh
    assert all(abs(t - k * 0.1) <= ride_s for k, t in enumerate(sent["ODOMETRY"]))
    assert all(abs(t - k * 1.0) <= ride_s for k, t in enumerate(sent["HEARTBEAT"]))
