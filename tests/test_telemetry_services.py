"""Telemetry streams, message intervals, REQUEST_MESSAGE, PING, FTP refusal, home reset."""

from __future__ import annotations

import time

from mecanum_mav.io.links import mavlink

CMD = mavlink


def count_over(rig, mtype: str, seconds: float) -> int:
    since = rig.gcs.mark()
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rig.gcs.pump(end - time.monotonic())
    return sum(1 for m in rig.gcs.messages[since:] if m.get_type() == mtype)


def test_default_streams_arrive_at_their_parameter_rates(rig):
    assert 7 <= count_over(rig, "ODOMETRY", 1.0) <= 13  # TLM_POS_RATE 10 Hz
    assert 1 <= count_over(rig, "SYS_STATUS", 1.0) <= 4  # TLM_EXT_RATE 2 Hz


def test_set_message_interval_changes_one_stream_and_get_reports_it(rig):
    ack = rig.command(CMD.MAV_CMD_SET_MESSAGE_INTERVAL, CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE, 50000)
    assert ack.result == CMD.MAV_RESULT_ACCEPTED
    assert 14 <= count_over(rig, "WHEEL_DISTANCE", 1.0) <= 26  # 20 Hz
    since = rig.gcs.mark()
    ack = rig.command(CMD.MAV_CMD_GET_MESSAGE_INTERVAL, CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE)
    assert ack.result == CMD.MAV_RESULT_ACCEPTED
    reply = rig.gcs.wait("MESSAGE_INTERVAL", timeout_s=1.0, since=since)
    assert reply.interval_us == 50000
    rig.command(CMD.MAV_CMD_SET_MESSAGE_INTERVAL, CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE, -1)
    rig.gcs.pump(0.2)
    assert count_over(rig, "WHEEL_DISTANCE", 0.6) == 0


def test_message_interval_for_a_message_we_do_not_stream_is_denied(rig):
    ack = rig.command(CMD.MAV_CMD_SET_MESSAGE_INTERVAL, CMD.MAVLINK_MSG_ID_GPS_RAW_INT, 100000)
    assert ack.result == CMD.MAV_RESULT_DENIED


def test_request_message_answers_autopilot_version_and_home_position(rig):
    for msg_id, mtype in ((CMD.MAVLINK_MSG_ID_AUTOPILOT_VERSION, "AUTOPILOT_VERSION"),
                          (CMD.MAVLINK_MSG_ID_HOME_POSITION, "HOME_POSITION")):
        since = rig.gcs.mark()
        assert rig.command(CMD.MAV_CMD_REQUEST_MESSAGE, msg_id).result == 0
        msg = rig.gcs.wait(mtype, timeout_s=1.0, since=since)
        assert msg is not None
    since = rig.gcs.mark()
    rig.command(CMD.MAV_CMD_REQUEST_MESSAGE, CMD.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    version = rig.gcs.wait("AUTOPILOT_VERSION", timeout_s=1.0, since=since)
    assert version.capabilities & CMD.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    assert version.capabilities & CMD.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT


def test_request_message_for_an_unknown_message_is_denied(rig):
    assert rig.command(CMD.MAV_CMD_REQUEST_MESSAGE, 99999).result == CMD.MAV_RESULT_DENIED


def test_ping_is_answered_to_its_sender(rig):
    since = rig.gcs.mark()
    rig.gcs.mav.ping_send(123456, 42, 0, 0)
    reply = rig.gcs.wait("PING", lambda m: m.seq == 42, 1.0, since)
    assert reply is not None and reply.time_usec == 123456
    assert (reply.target_system, reply.target_component) == (255, 190)


def test_file_transfer_requests_are_refused_as_file_not_found(rig):
    since = rig.gcs.mark()
    request = [7, 0, 0, 4, 12, 0, 0, 0, 0, 0, 0, 0, *b"@PARAM/param.pck"]  # seq 7 OpenFileRO
    rig.gcs.mav.file_transfer_protocol_send(0, 1, 1, request + [0] * (251 - len(request)))
    reply = rig.gcs.wait("FILE_TRANSFER_PROTOCOL", timeout_s=1.0, since=since)
    assert reply is not None
    payload = bytes(reply.payload)
    assert payload[0] | payload[1] << 8 == 8  # seq + 1
    assert (payload[3], payload[4], payload[5], payload[12]) == (129, 1, 4, 10)


def test_set_home_to_here_resets_the_odometry_origin_and_counter(rig):
    before = rig.companion.core.estimator.reset_counter
    ack = rig.command(CMD.MAV_CMD_DO_SET_HOME, 1)
    assert ack.result == CMD.MAV_RESULT_ACCEPTED
    assert rig.companion.core.estimator.reset_counter == before + 1
    since = rig.gcs.mark()
    odom = rig.gcs.wait("ODOMETRY", lambda m: m.reset_counter == before + 1, 1.0, since)
    assert odom is not None and (odom.x, odom.y) == (0.0, 0.0)
    assert rig.command(CMD.MAV_CMD_DO_SET_HOME, 0).result == CMD.MAV_RESULT_DENIED


def test_servo_output_raw_shows_the_commanded_pwm(rig):
    rig.arm()
    deadline = time.monotonic() + 3.0
    seen = None
    while seen is None and time.monotonic() < deadline:
        since = rig.gcs.mark()
        rig.gcs.mav.manual_control_send(1, 1000, 0, 500, 0, 0)
        seen = rig.gcs.wait("SERVO_OUTPUT_RAW", lambda m: m.servo1_raw == 2000, 0.1, since)
    assert seen is not None
    assert (seen.servo2_raw, seen.servo3_raw, seen.servo4_raw, seen.servo5_raw) == (
        2000, 2000, 2000, 0)
