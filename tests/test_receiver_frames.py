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
