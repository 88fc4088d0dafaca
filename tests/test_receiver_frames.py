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
