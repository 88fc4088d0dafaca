"""The companion between a real pymavlink ground station and a real flight-controller peer."""

from __future__ import annotations

import math
import time

import pytest
from conftest import Rig
from mavpeers import channels

from mecanum_mav.config.params import Params
from mecanum_mav.io.links import mavlink

ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
SET_MODE = mavlink.MAV_CMD_DO_SET_MODE
CUSTOM = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
NEUTRAL = [1500, 1500, 1500, 1500]


def heartbeat(rig: Rig, predicate=lambda m: True, timeout_s: float = 3.0):
    return rig.gcs.wait("HEARTBEAT", predicate, timeout_s, rig.gcs.mark())


def statustext(rig: Rig, fragment: str, since: int = 0, timeout_s: float = 3.0):
    return rig.gcs.wait("STATUSTEXT", lambda m: fragment in m.text, timeout_s, since)


def params(**values: float) -> Params:
    p = Params()
    p.update(values)
    return p


def drive(rig: Rig, x: int = 0, y: int = 0, r: int = 0, want=None, timeout_s: float = 2.0):
    """Send sticks until the flight controller sees the wanted wheel PWM (first 4 channels)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        since = rig.sticks(x, y, r)
        msg = rig.wait_override(lambda ch: want is None or ch[:4] == want, since, 0.1)
        if msg is not None:
            return msg
    return None


# --------------------------------------------------------------------------- identity


def test_heartbeat_shows_a_disarmed_ardupilot_rover_in_manual(rig):
    hb = heartbeat(rig)
    assert hb.get_srcSystem() == 1 and hb.get_srcComponent() == 1
    assert hb.type == mavlink.MAV_TYPE_GROUND_ROVER
    assert hb.autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    assert hb.base_mode & CUSTOM and not hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    assert hb.custom_mode == 0 and hb.system_status == mavlink.MAV_STATE_STANDBY
    assert hb.get_msgbuf()[0] == 0xFD  # MAVLink 2


def test_companion_heartbeats_the_flight_controller_as_a_ground_station(rig):
    hb = rig.fc.wait("HEARTBEAT", timeout_s=3.0)
    assert hb.type == mavlink.MAV_TYPE_GCS and hb.get_srcSystem() == 255


# --------------------------------------------------------------------------- commands


def test_arm_is_acknowledged_within_half_a_second_and_reported(rig):
    since = rig.gcs.mark()
    start = time.monotonic()
    ack = rig.command(ARM, 1)
    assert ack.result == mavlink.MAV_RESULT_ACCEPTED
    assert time.monotonic() - start < 0.5
    assert ack.target_system == 255 and ack.target_component == 190
    assert statustext(rig, "Armed", since)
    hb = heartbeat(rig, lambda m: m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
    assert hb.system_status == mavlink.MAV_STATE_ACTIVE
    assert hb.base_mode & mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED


def test_repeated_arm_and_disarm_commands_are_harmless(rig):
    for _ in range(2):
        assert rig.command(ARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
    for _ in range(2):
        assert rig.command(ARM, 0).result == mavlink.MAV_RESULT_ACCEPTED
    assert heartbeat(rig, lambda m: not m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)


def test_nan_in_unused_command_params_is_accepted(rig):
    ack = rig.command(ARM, 1, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan)
    assert ack.result == mavlink.MAV_RESULT_ACCEPTED


def test_broadcast_target_is_accepted(rig):
    since = rig.gcs.mark()
    rig.gcs.mav.command_long_send(0, 0, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
    assert rig.gcs.wait("COMMAND_ACK", lambda m: m.command == ARM, 1.0, since).result == 0


def test_commands_for_another_system_get_no_answer(rig):
    since = rig.gcs.mark()
    rig.gcs.mav.command_long_send(7, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
    assert rig.gcs.wait("COMMAND_ACK", timeout_s=0.5, since=since) is None


def test_command_int_arms_too(rig):
    since = rig.gcs.mark()
    rig.gcs.mav.command_int_send(1, 1, 0, ARM, 0, 0, 1, 0, 0, 0, 0, 0, 0)
    assert rig.gcs.wait("COMMAND_ACK", lambda m: m.command == ARM, 1.0, since).result == 0


def test_set_mode_hold_by_command_and_by_message(rig):
    assert rig.command(SET_MODE, CUSTOM, 4).result == mavlink.MAV_RESULT_ACCEPTED
    assert heartbeat(rig, lambda m: m.custom_mode == 4)
    since = rig.gcs.mark()
    rig.gcs.mav.set_mode_send(1, CUSTOM, 0)
    ack = rig.gcs.wait("COMMAND_ACK", lambda m: m.command == mavlink.MAVLINK_MSG_ID_SET_MODE,
                       0.5, since)
    assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED
    assert heartbeat(rig, lambda m: m.custom_mode == 0)


@pytest.mark.parametrize(("mode", "name"), [(10, "AUTO"), (3, "3")])
def test_auto_without_a_mission_and_unknown_modes_are_denied_with_a_reason(rig, mode, name):
    since = rig.gcs.mark()
    assert rig.command(SET_MODE, CUSTOM, mode).result == mavlink.MAV_RESULT_DENIED
    assert statustext(rig, name, since)


def test_unknown_command_is_unsupported(rig):
    assert rig.command(31999).result == mavlink.MAV_RESULT_UNSUPPORTED


def test_arm_with_a_bad_param1_is_denied(rig):
    assert rig.command(ARM, math.nan).result == mavlink.MAV_RESULT_DENIED


# --------------------------------------------------------------------------- manual driving


@pytest.mark.parametrize(
    ("x", "y", "r", "pwm"),
    [(1000, 0, 0, [2000, 2000, 2000, 2000]),       # forward: every wheel forward
     (0, 1000, 0, [2000, 1000, 1000, 2000]),       # strafe right
     (0, 0, 1000, [2000, 1000, 2000, 1000]),       # clockwise
     (1000, 1000, 0, [2000, 1500, 1500, 2000]),    # diagonal forward-right
     (-1000, 0, 0, [1000, 1000, 1000, 1000])],     # backward
)
def test_sticks_drive_the_right_pwm_pattern_on_the_right_channels(rig, x, y, r, pwm):
    rig.arm()
    msg = drive(rig, x, y, r, pwm)
    assert msg is not None, f"never saw {pwm}"
    assert msg.get_srcSystem() == 255, "ArduPilot drops overrides not from its GCS id"
    assert (msg.target_system, msg.target_component) == (1, 1)
    assert channels(msg)[4:8] == [65535] * 4  # channels it does not own: left alone
    assert channels(msg)[8:] == [0] * 10


def test_sticks_while_disarmed_leave_the_wheels_at_neutral(rig):
    since = rig.sticks(1000, 0, 0)
    msg = rig.wait_override(lambda ch: True, since)
    assert channels(msg)[:4] == NEUTRAL
    time.sleep(0)  # nothing to wait for: a second override must be neutral as well
    assert all(channels(m)[:4] == NEUTRAL for m in rig.fc.overrides(since))


def test_hold_mode_keeps_neutral_while_armed(rig):
    rig.arm()
    assert rig.command(SET_MODE, CUSTOM, 4).result == 0
    since = rig.sticks(1000)
    assert rig.wait_override(lambda ch: True, since) is not None
    assert all(channels(m)[:4] == NEUTRAL for m in rig.fc.overrides(since))


def test_reverse_and_channel_map_parameters_move_the_output(rig_factory):
    rig = rig_factory(params(MOT_FR_REV=1, MOT_FL_CH=6, MOT_RR_CH=12))
    rig.arm()
    msg = drive(rig, 1000, 0, 0, None)
    ok = rig.wait_override(lambda ch: ch[5] == 2000, rig.sticks(1000))
    assert ok is not None and msg is not None
    ch = channels(ok)
    assert ch[5] == 2000 and ch[1] == 1000 and ch[2] == 2000 and ch[11] == 2000
    assert ch[0] == 65535 and ch[3] == 65535  # FL moved to 6, RR moved to 12


def test_invalid_axis_reads_as_zero(rig):
    rig.arm()
    assert drive(rig, 0x7FFF, 1000, 0x7FFF, [2000, 1000, 1000, 2000]) is not None


def test_out_of_range_stick_is_rejected_and_never_moves_the_robot(rig):
    rig.arm()
    since = rig.gcs.mark()
    fc_since = rig.sticks(1500, 0, 0)
    assert statustext(rig, "x=1500 not in +-1000", since)
    assert all(channels(m)[:4] == NEUTRAL for m in rig.fc.overrides(fc_since))


def test_manual_control_for_another_system_is_ignored(rig):
    rig.arm()
    since = rig.fc.mark()
    for _ in range(5):
        rig.sticks(1000, target=9)
    rig.fc.pump(0.3)
    assert all(channels(m)[:4] == NEUTRAL for m in rig.fc.overrides(since))


def test_a_restricted_ground_station_id_ignores_other_senders(rig_factory):
    rig = rig_factory(params(SYSID_MYGCS=200))
    since = rig.gcs.mark()
    rig.gcs.mav.command_long_send(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
    assert rig.gcs.wait("COMMAND_ACK", timeout_s=0.5, since=since) is None


def test_ground_station_rc_override_drives_like_a_stick(rig):
    rig.arm()
    deadline = time.monotonic() + 2.0
    msg = None
    while msg is None and time.monotonic() < deadline:
        since = rig.fc.mark()
        # MAVProxy "rc 3 2000": throttle (forward) channel 3, everything else left alone.
        rig.gcs.mav.rc_channels_override_send(1, 1, 65535, 65535, 2000, 65535, 65535, 65535,
                                              65535, 65535)
        msg = rig.wait_override(lambda ch: ch[:4] == [2000] * 4, since, 0.1)
    assert msg is not None
    since = rig.fc.mark()
    rig.gcs.mav.rc_channels_override_send(1, 1, 65535, 65535, 0, 65535, 65535, 65535, 65535,
                                          65535)  # release throttle -> centre
    assert rig.wait_override(lambda ch: ch[:4] == NEUTRAL, since) is not None


def test_ground_station_rc_override_with_an_absurd_pulse_is_rejected(rig):
    rig.arm()
    since = rig.gcs.mark()
    rig.gcs.mav.rc_channels_override_send(1, 1, 65535, 65535, 40000, 65535, 65535, 65535,
                                          65535, 65535)
    assert statustext(rig, "ch3=40000 not in 800..2200", since)


# --------------------------------------------------------------------------- output timing


def test_overrides_are_refreshed_while_idle_so_the_fc_timeout_never_lapses(rig):
    since = rig.fc.mark()
    deadline = time.monotonic() + 0.5
    while time.monotonic() < deadline:
        rig.fc.pump(deadline - time.monotonic())
    count = len(rig.fc.overrides(since))
    assert 6 <= count <= 14, count  # 20 Hz for 0.5 s


# --------------------------------------------------------------------------- failsafes


def test_stale_manual_control_returns_wheels_to_neutral_and_resumes(rig_factory):
    rig = rig_factory(params(FS_INPUT_TMO=0.3))
    rig.arm()
    assert drive(rig, 1000, 0, 0, [2000] * 4) is not None
    stopped_at = time.monotonic()
    since = rig.gcs.mark()
    msg = rig.wait_override(lambda ch: ch[:4] == NEUTRAL, rig.fc.mark(), 2.0)
    elapsed = time.monotonic() - stopped_at
    assert msg is not None and 0.2 <= elapsed <= 1.0, elapsed
    assert statustext(rig, "Manual input lost", since)
    assert drive(rig, 1000, 0, 0, [2000] * 4) is not None
    assert statustext(rig, "Manual input resumed", since)


@pytest.mark.parametrize(("action", "armed_after"), [(0, True), (1, False)])
def test_ground_station_loss_triggers_the_failsafe_action(rig_factory, action, armed_after):
    rig = rig_factory(params(FS_GCS_TMO=1.0, FS_GCS_ACTION=action))
    rig.arm()
    assert drive(rig, 1000, 0, 0, [2000] * 4) is not None
    rig.gcs.beating.clear()
    lost_at = time.monotonic()
    since = rig.gcs.mark()
    text = statustext(rig, "GCS link lost", since, 4.0)
    assert text is not None and text.severity == mavlink.MAV_SEVERITY_CRITICAL
    assert time.monotonic() - lost_at <= 2.5
    hb = heartbeat(rig)
    assert hb.system_status == mavlink.MAV_STATE_CRITICAL
    assert bool(hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED) == armed_after
    if armed_after:
        assert hb.custom_mode == 4  # HOLD
    since = rig.sticks(1000)  # sticks keep coming, the wheels stay neutral
    assert rig.wait_override(lambda ch: True, since) is not None
    assert all(channels(m)[:4] == NEUTRAL for m in rig.fc.overrides(since))


def test_flight_controller_loss_disarms_reports_and_refuses_to_arm(rig_factory):
    rig = rig_factory(params(FS_FC_TMO=1.0))
    rig.arm()
    since = rig.gcs.mark()
    rig.fc.beating.clear()
    assert statustext(rig, "Flight controller link lost", since, 4.0)
    assert statustext(rig, "Disarmed", since)
    assert heartbeat(rig).system_status == mavlink.MAV_STATE_CRITICAL
    since = rig.gcs.mark()
    assert rig.command(ARM, 1).result == mavlink.MAV_RESULT_DENIED
    assert statustext(rig, "flight controller link down", since)
    rig.fc.beating.set()
    assert statustext(rig, "Flight controller link up", since, 4.0)
    assert rig.command(ARM, 1).result == mavlink.MAV_RESULT_ACCEPTED


# --------------------------------------------------------------------------- robustness


def test_random_bytes_and_truncated_packets_on_both_links_do_not_crash_it(rig):
    rig.gcs.mav.heartbeat_send(6, 8, 0, 0, 4)
    good = rig.gcs.link.conn.mav.command_long_encode(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
    packet = bytes(good.pack(rig.gcs.link.conn.mav))
    junk = [bytes(range(256)), b"\xfd" * 300, packet[:7], packet[:-3], b"\xfd\x09\x00\x00",
            packet[:10] + b"\x00" * 50]
    for peer in (rig.gcs, rig.fc):
        for address in list(peer.link.conn.clients):
            for blob in junk * 5:
                peer.link.conn.port.sendto(blob, address)
    c = rig.companion
    deadline = time.monotonic() + 5.0
    while (c.gcs.bad < 30 or c.fc.bad < 30) and time.monotonic() < deadline:
        rig.gcs.pump(0.05)
    assert c.gcs.bad >= 30 and c.fc.bad >= 30, (c.gcs.bad, c.fc.bad)
    assert rig.command(ARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
    assert drive(rig, 1000, 0, 0, [2000] * 4) is not None


def test_clean_shutdown_sends_neutral_then_releases_the_channels(rig):
    rig.arm()
    assert drive(rig, 1000, 0, 0, [2000] * 4) is not None
    since = rig.fc.mark()
    rig.companion.stop()
    release = rig.wait_override(lambda ch: ch[:4] == [0, 0, 0, 0], since)
    assert release is not None
    ordered = [channels(m)[:4] for m in rig.fc.overrides(since)]
    assert NEUTRAL in ordered and ordered.index(NEUTRAL) < ordered.index([0, 0, 0, 0])
    assert channels(release)[4:8] == [65535] * 4


def test_an_exception_in_the_control_path_ends_at_neutral(rig, monkeypatch):
    rig.arm()
    assert drive(rig, 1000, 0, 0, [2000] * 4) is not None

    def broken(*args, **kwargs):
        raise RuntimeError("mixer bug")

    monkeypatch.setattr("mecanum_mav.control.chain.wheels_from_stick", broken)
    since = rig.gcs.mark()
    assert drive(rig, 1000, 0, 0, NEUTRAL) is not None
    assert statustext(rig, "Error computing output: neutral", since)
