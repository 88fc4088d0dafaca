"""One RC_CHANNELS from the receiver (control/rcinput.py): a stick channel without a valid
pulse is the radio failsafe, never read as a full deflection."""

from __future__ import annotations

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import RcInputConfig, ReceiverConfig
from mecanum_mav.control.rcinput import ReceiverInput

CENTRED = [1500] * 18


def frame(pulses: list[int], chancount: int = 18):
    params = Params()
    return ReceiverInput().frame(chancount, pulses, 255, ReceiverConfig.from_params(params),
                                 RcInputConfig.from_params(params), 0.0)


def test_centred_sticks_are_a_valid_frame_at_rest():
    got = frame(CENTRED)
    assert got.problem is None and got.stick == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("pulse", [0, 799, 2201, 65535])
@pytest.mark.parametrize("axis", ["RCMAP_STEER", "RCMAP_LATERAL"])
def test_a_stick_channel_without_a_valid_pulse_is_the_radio_failsafe(axis, pulse):
    pulses = CENTRED.copy()
    pulses[int(Params()[axis]) - 1] = pulse
    got = frame(pulses)
    assert got.problem == f"no pulse on ch{int(Params()[axis])}"
    assert got.stick is None


def test_a_stick_channel_beyond_the_channel_count_is_the_radio_failsafe():
    highest = max(int(Params()[n]) for n in ("RCMAP_STEER", "RCMAP_THROTTLE", "RCMAP_LATERAL"))
    got = frame(CENTRED, chancount=highest - 1)
    assert got.problem is not None and got.stick is None


def test_a_mode_or_arm_switch_beyond_the_channel_count_is_not_read_and_the_sticks_still_are():
    params = Params()
    params.update({"RCIN_ARM_CH": 7})
    highest = max(int(params[n]) for n in ("RCMAP_STEER", "RCMAP_THROTTLE", "RCMAP_LATERAL"))
    assert highest < 7 and int(params["MODE_CH"]) > highest
    pulses = CENTRED.copy()
    pulses[int(params["MODE_CH"]) - 1] = 1900  # what a stale channel would read as a mode
    pulses[6] = 1900  # and as "arm"
    receiver_of = {count: ReceiverInput() for count in (highest, 18)}

    def frames(count: int) -> list:  # two, a second apart: past the switches' debounce
        return [receiver_of[count].frame(count, pulses, 255, ReceiverConfig.from_params(params),
                                         RcInputConfig.from_params(params), t)
                for t in (0.0, 1.0)]

    for got in frames(highest):
        assert got.problem is None and got.stick == (0.0, 0.0, 0.0)
        assert got.mode is None and got.arm is None
    within = frames(18)[-1]  # (the same pulses within the count: a mode)
    assert within.mode is not None


@pytest.mark.parametrize("arm_ch, chancount, moving", [
    (0, 18, 18),  # RCIN_ARM_CH 0: no arm switch, whichever channel moves
    (7, 6, 7),  # the arm switch's channel beyond the count: no pulse, whatever it reads
])
def test_no_arm_switch_or_one_beyond_the_channel_count_never_arms(arm_ch, chancount, moving):
    params = Params()
    params.update({"RCIN_ARM_CH": arm_ch})
    receiver = ReceiverInput()
    arms = []
    for t, pulse in ((0.0, 1000), (0.5, 2000), (1.0, 2000), (1.5, 2000)):  # low, then high
        pulses = CENTRED.copy()
        pulses[moving - 1] = pulse
        got = receiver.frame(chancount, pulses, 255, ReceiverConfig.from_params(params),
                             RcInputConfig.from_params(params), t)
        assert got.problem is None
        arms.append(got.arm)
    assert arms == [None] * 4


def test_no_channels_and_rssi_0_are_the_radio_failsafe_and_say_which():
    params = Params()
    config, sticks = ReceiverConfig.from_params(params), RcInputConfig.from_params(params)
    assert ReceiverInput().frame(0, CENTRED, 255, config, sticks, 0.0).problem == "no channels"
    assert ReceiverInput().frame(18, CENTRED, 0, config, sticks, 0.0).problem == "RSSI 0"
    assert ReceiverInput().frame(1, CENTRED, 255, config, sticks, 0.0).problem is not None


def test_a_throttle_channel_beyond_the_count_reads_as_no_pulse_below_fs_thr_value():
    throttle = int(Params()["RCMAP_THROTTLE"])
    assert frame(CENTRED, chancount=throttle - 1).problem == "throttle 0 us < FS_THR_VALUE"


def test_a_throttle_at_fs_thr_value_is_valid_and_one_microsecond_below_is_the_failsafe():
    """ArduPilot: the throttle failsafe is a pulse below FS_THR_VALUE."""
    value = int(Params()["FS_THR_VALUE"])
    pulses = CENTRED.copy()
    pulses[int(Params()["RCMAP_THROTTLE"]) - 1] = value
    assert frame(pulses).problem is None
    pulses[int(Params()["RCMAP_THROTTLE"]) - 1] = value - 1
    assert frame(pulses).problem == f"throttle {value - 1} us < FS_THR_VALUE"


@pytest.mark.parametrize("pulse", [800, 2200])
def test_a_stick_pulse_at_the_ends_of_the_valid_range_is_read(pulse):
    pulses = CENTRED.copy()
    pulses[int(Params()["RCMAP_STEER"]) - 1] = pulse
    got = frame(pulses)
    assert got.problem is None and got.stick is not None and abs(got.stick[2]) == 1.0


def _arm_frames(times: list[float], arm_ch: int = 8, chancount: int = 18) -> list:
    """Frames at ``times``: the arm switch (``arm_ch``) low at the first, high after."""
    params = Params()
    params.update({"RCIN_ARM_CH": arm_ch, "MODE_CH": 0})
    receiver = ReceiverInput()
    config, sticks = ReceiverConfig.from_params(params), RcInputConfig.from_params(params)
    out = []
    for k, t in enumerate(times):
        pulses = CENTRED.copy()
        pulses[arm_ch - 1] = 1000 if k == 0 else 2000
        out.append(receiver.frame(chancount, pulses, 255, config, sticks, t))
    return out


def test_an_arm_switch_change_counts_once_held_the_debounce_time_and_not_before():
    """ArduPilot SWITCH_DEBOUNCE_TIME_MS (200 ms): a new position counts once held that long
    (0.3 s to 0.5 s is 0.2 s, whatever the floating point sum says)."""
    first, changed, early, held = _arm_frames([0.0, 0.3, 0.4999, 0.5])
    assert [f.arm for f in (first, changed, early)] == [None, None, None]
    assert held.arm is True


def test_an_arm_switch_on_the_last_channel_the_receiver_sends_is_read():
    *_, held = _arm_frames([0.0, 0.3, 0.5], arm_ch=8, chancount=8)
    assert held.arm is True
