"""The RC receiver read through the flight controller (RCIN_ENABLE), in virtual time: the
simulated board's receiver, its RC_CHANNELS stream, the sticks, switches and failsafes."""

from __future__ import annotations

import pytest
from conftest import lockstep
from support import status_texts as texts

from mecanum_mav.control.chain import manual_output
from mecanum_mav.control.rcinput import (
    RC_CHANNELS_INTERVAL_US,
    arm_switch_position,
    mode_switch_position,
)
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.lockstep import Lockstep

WHEELS_9_12 = {"MOT_FL_CH": 9, "MOT_FR_CH": 10, "MOT_RL_CH": 11, "MOT_RR_CH": 12}
RECEIVER = {"RCIN_ENABLE": 1, **WHEELS_9_12, "RCIN_ARM_CH": 7, "MODE3": 4, "MODE6": 10}
CENTRE = (1500, 1500, 1500, 1500, 1500, 1500, 1000, 1100)
"""Sticks centred, arm switch low (ch 7), mode switch position 1 (ch 8)."""


def rx(h: Lockstep, **channels: int) -> None:
    """Set the board's receiver: CENTRE with ``chN=pulse`` changes."""
    pulses = list(CENTRE)
    for name, pulse in channels.items():
        pulses[int(name[2:]) - 1] = pulse
    h.board.receiver = tuple(pulses)


def receiver_harness(**values: float) -> Lockstep:
    h = lockstep({**RECEIVER, **values})
    rx(h)
    h.board.receiver = CENTRE
    assert h.run_until(lambda: not h.core.vehicle.rc_failsafe, 1.0), "receiver never OK"
    h.run_for(0.3)  # the mode switch's first position is read (debounced)
    return h


def wheels(h: Lockstep) -> tuple[int, ...]:
    """The pulses on the wheel channels 9-12 the board obeys now."""
    pwm = h.truth().channel_pwm
    return tuple(pwm.get(ch, 0) for ch in (9, 10, 11, 12))


def arm_by_switch(h: Lockstep) -> None:
    rx(h, ch7=2000)
    assert h.run_until(lambda: h.core.vehicle.armed, 1.0), texts(h)


def test_the_companion_asks_the_flight_controller_for_rc_channels_at_25_hz():
    h = lockstep(RECEIVER)
    asks = [m for m in h.fc_received if m.get_type() == "COMMAND_LONG"
            and m.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL
            and int(m.param1) == mavlink.MAVLINK_MSG_ID_RC_CHANNELS]
    assert [a.param2 for a in asks] == [RC_CHANNELS_INTERVAL_US]


def test_without_rcin_enable_the_receiver_is_neither_asked_for_nor_read():
    h = lockstep(WHEELS_9_12)
    h.board.receiver = (1500, 1500, 2000, 1500, 1500, 1500, 2000, 1800)
    h.run_for(1.0)
    assert not any(m.get_type() == "COMMAND_LONG" and int(m.param1) == 65
                   for m in h.fc_received)
    assert not h.core.vehicle.armed and h.core.vehicle.mode is Mode.MANUAL


@pytest.mark.parametrize("pulse, position", [
    (901, 0), (1230, 0), (1231, 1), (1360, 1), (1361, 2), (1490, 2), (1491, 3), (1620, 3),
    (1621, 4), (1749, 4), (1750, 5), (2199, 5), (900, None), (2200, None), (0, None)])
def test_the_mode_switch_has_ardupilots_six_bands(pulse, position):
    assert mode_switch_position(pulse) == position


@pytest.mark.parametrize("pulse, position", [
    (801, 0), (1199, 0), (1200, 1), (1800, 1), (1801, 2), (2199, 2), (800, None), (0, None),
    (2200, None), (2201, None)])
def test_the_arm_switch_is_low_below_1200_and_high_above_1800(pulse, position):
    assert arm_switch_position(pulse) == position


def test_the_arm_switch_arms_and_disarms_on_a_change_held_a_fifth_of_a_second():
    h = receiver_harness()
    rx(h, ch7=2000)
    h.run_for(0.15)
    assert not h.core.vehicle.armed  # not yet debounced
    assert h.run_until(lambda: h.core.vehicle.armed, 0.2)
    rx(h, ch7=1000)
    assert h.run_until(lambda: not h.core.vehicle.armed, 0.4)


def test_an_arm_switch_already_high_when_the_receiver_appears_does_not_arm():
    h = lockstep(RECEIVER)
    rx(h, ch7=2000)
    h.run_for(1.0)
    assert not h.core.vehicle.rc_failsafe and not h.core.vehicle.armed


def test_the_arm_switch_is_refused_with_a_stick_deflected():
    h = receiver_harness()
    rx(h, ch3=1800, ch7=2000)
    h.run_for(0.5)
    assert not h.core.vehicle.armed
    assert any("sticks not centred" in t for t in texts(h))


@pytest.mark.parametrize("start, start_mode, pulse, mode", [
    (1425, Mode.HOLD, 1100, Mode.MANUAL),  # MODE3 -> MODE1
    (1100, Mode.MANUAL, 1425, Mode.HOLD),  # MODE1 -> MODE3
    (1425, Mode.HOLD, 1700, Mode.MANUAL),  # MODE3 -> MODE5
])
def test_each_mode_switch_position_selects_its_mode_parameter(start, start_mode, pulse, mode):
    """Each case starts in another mode, set by the switch, so the mode it expects is a change
    the switch made (not the start-up MANUAL kept)."""
    h = receiver_harness()
    rx(h, ch8=start)
    h.run_for(0.5)
    assert h.core.vehicle.mode is start_mode != mode
    rx(h, ch8=pulse)
    h.run_for(0.5)
    assert h.core.vehicle.mode is mode


def test_a_mode_switch_position_whose_mode_cannot_start_is_refused_and_said():
    h = receiver_harness()
    rx(h, ch8=1900)  # MODE6: AUTO, and there is no mission
    h.run_for(0.5)
    assert h.core.vehicle.mode is Mode.MANUAL
    assert any(t.startswith("AUTO refused") for t in texts(h))


def test_a_ground_stations_mode_change_stands_until_the_switch_moves():
    h = receiver_harness()
    assert h.gcs.set_mode(Mode.HOLD) == mavlink.MAV_RESULT_ACCEPTED
    h.run_for(0.5)
    assert h.core.vehicle.mode is Mode.HOLD
    rx(h, ch8=1300)  # MODE2: MANUAL
    assert h.run_until(lambda: h.core.vehicle.mode is Mode.MANUAL, 0.5)


def test_receiver_sticks_map_shape_and_mix_exactly_as_manual_control():
    h = receiver_harness()
    arm_by_switch(h)
    # throttle (ch 3) 1750, lateral (ch 4) 1300, steering (ch 1) 1600
    rx(h, ch7=2000, ch1=1600, ch3=1750, ch4=1300)
    h.run_for(0.3)
    x, y, r = 250 / 500, -200 / 500, 100 / 500
    assert h.core.stick == pytest.approx((x, y, r))
    _, expected = manual_output(x, y, r, h.core.input, h.core.pwm)
    assert wheels(h) == expected
    # the same stick as MANUAL_CONTROL from a ground station gives the same pulses
    g = lockstep(WHEELS_9_12)
    g.gcs.arm()
    g.every(0.05, lambda now: g.gcs.sticks(500, -400, 200))
    g.run_for(0.3)
    assert wheels(g) == expected


def test_a_ground_stations_fresh_sticks_take_over_from_the_receiver_and_hand_back():
    h = receiver_harness()
    arm_by_switch(h)
    rx(h, ch7=2000, ch3=2000)  # receiver: full forward
    h.run_for(0.3)
    assert h.core.stick[0] == 1.0
    stop = h.every(0.05, lambda now: h.gcs.sticks(0, 1000, 0))  # ground station: full right
    h.run_for(0.3)
    assert h.core.stick == (0.0, 1.0, 0.0)
    stop()
    h.run_for(0.5 + 0.1)  # FS_INPUT_TMO after its last stick the receiver drives again
    assert h.core.stick[0] == 1.0


@pytest.mark.parametrize("how", ["silence", "chancount 0", "rssi 0", "throttle low"])
def test_each_receiver_failsafe_stops_the_wheels_and_switches_to_hold(how):
    h = receiver_harness()
    arm_by_switch(h)
    rx(h, ch7=2000, ch3=2000)
    h.run_for(0.3)
    assert wheels(h) == (2000,) * 4
    start = h.now_s
    if how == "silence":
        h.board._rc_channels.period_s = h.board._rc_channels.next_s = float("inf")
    elif how == "chancount 0":
        h.board.receiver = ()
    elif how == "rssi 0":
        h.board.rssi = 0
    else:
        rx(h, ch7=2000, ch3=900)  # below FS_THR_VALUE 910
    limit = 0.5 + 0.1 if how == "silence" else 0.1  # FS_INPUT_TMO; else the next frame
    assert h.run_until(lambda: wheels(h) == (1500,) * 4, limit), how
    assert h.core.vehicle.rc_failsafe and h.core.vehicle.mode is Mode.HOLD
    assert h.core.vehicle.armed
    why = {"silence": "no RC_CHANNELS",
           "chancount 0": "no channels", "rssi 0": "RSSI 0",
           "throttle low": "throttle 900 us < FS_THR_VALUE"}[how]
    assert [t for t in texts(h) if t.startswith("Radio failsafe")] == [
        f"Radio failsafe: {why}"]
    assert h.now_s - start <= limit
    rx(h, ch7=2000)  # the receiver back, sticks centred
    h.board.rssi = 255
    h.board._rc_channels.period_s = h.board._rc_channels.next_s = 0.04
    assert h.run_until(lambda: not h.core.vehicle.rc_failsafe, 0.6)
    assert "Radio receiver OK, mode HOLD" in texts(h)
    assert not h.core.faulted


def test_the_receiver_failsafe_can_disarm_and_blocks_arming_until_the_receiver_is_back():
    h = receiver_harness(FS_RC_ACTION=1)
    arm_by_switch(h)
    h.board.rssi = 0
    assert h.run_until(lambda: not h.core.vehicle.armed, 0.2)
    assert "Disarmed: radio failsafe" in texts(h)
    assert h.gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == (
        mavlink.MAV_RESULT_DENIED)
    h.board.rssi = 255
    assert h.run_until(lambda: not h.core.vehicle.rc_failsafe, 0.2)
    assert h.gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == (
        mavlink.MAV_RESULT_ACCEPTED)


def test_with_fs_thr_enable_off_a_failing_receiver_still_stops_the_wheels_but_keeps_the_mode():
    h = receiver_harness(FS_THR_ENABLE=0)
    arm_by_switch(h)
    rx(h, ch7=2000, ch3=2000)
    h.run_for(0.3)
    rx(h, ch7=2000, ch3=900)
    assert h.run_until(lambda: wheels(h) == (1500,) * 4, 0.1)
    assert h.core.vehicle.mode is Mode.MANUAL and h.core.vehicle.armed


@pytest.mark.parametrize("fs_thr_enable", [0, 1])
def test_a_failing_receiver_frame_stops_the_wheels_at_once_not_at_the_next_refresh(
        fs_thr_enable: int) -> None:
    """The wheels stop "now, whatever the action" (control/fclink.py): the neutral override
    goes out as the failing frame arrives, even with OUT_RATE at its slowest (a refresh every
    half second), and a failing receiver is no error of the companion's."""
    h = receiver_harness(FS_THR_ENABLE=fs_thr_enable, OUT_RATE=2)
    arm_by_switch(h)
    rx(h, ch7=2000, ch3=2000)
    assert h.run_until(lambda: wheels(h) == (2000,) * 4, 0.5)
    rx(h, ch7=2000, ch3=900)  # below FS_THR_VALUE 910
    assert h.run_until(lambda: wheels(h) == (1500,) * 4, 0.06)  # the next frame (25 Hz)
    assert not h.core.faulted
    assert not any("Error" in t for t in texts(h))


def test_the_arm_switch_says_it_disarmed():
    h = receiver_harness()
    arm_by_switch(h)
    rx(h, ch7=1000)
    assert h.run_until(lambda: not h.core.vehicle.armed, 0.4)
    assert "Disarmed: by RC switch" in texts(h)


def test_a_ground_stations_override_that_leaves_the_stick_channels_alone_is_not_a_stick():
    """(MAVProxy's ``rc 6 1500``: channel 6 only; 65535 leaves the others, ch 1-8.)"""
    h = receiver_harness()
    arm_by_switch(h)
    rx(h, ch7=2000, ch3=2000)  # receiver: full forward
    h.run_for(0.3)
    leave = [65535] * 8
    aux_only = [*leave[:5], 1500, *leave[6:]]
    h.every(0.05, lambda now: h.gcs.mav.rc_channels_override_send(1, 1, *aux_only))
    h.run_for(0.5)
    assert h.core.stick[0] == 1.0  # the receiver still drives
    assert wheels(h) == (2000,) * 4


def test_a_receiver_failing_while_a_ground_station_drives_does_not_blip_its_wheels_to_neutral():
    """(FS_THR_ENABLE 0 keeps the mode: the ground station's pilot, whose sticks are fresh,
    drives on; the failsafe's stop is for a rover the receiver was driving.)"""
    h = receiver_harness(FS_THR_ENABLE=0)
    arm_by_switch(h)
    h.every(0.05, lambda now: h.gcs.sticks(0, 1000, 0))  # ground station: full right
    h.run_for(0.3)
    driving = h.truth().channel_pwm
    failed_s = h.now_s
    h.board.rssi = 0  # (the receiver's frames come at 25 Hz: several fail in 0.3 s)
    h.run_for(0.3)
    seen = {tuple(o.channels) for o in h.overrides_since(failed_s)}
    assert len(seen) == 1 and h.truth().channel_pwm == driving  # no neutral, not once
    assert h.core.vehicle.mode is Mode.MANUAL


def test_with_the_receiver_on_a_wheel_may_not_sit_on_a_receiver_channel():
    from mecanum_mav.config.params import ParamError, Params
    params = Params()
    params.update(WHEELS_9_12)
    params.set("RCIN_ENABLE", 1)
    with pytest.raises(ParamError, match="receiver"):
        params.set("MOT_FL_CH", 8)  # MODE_CH
