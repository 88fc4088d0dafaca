"""Parameter rules that refuse a setup that cannot work (config/rules.py, config/schema.py):
a mode switch position naming a mode the rover does not have, and one RC channel given two
jobs (two receiver functions, or a wheel on a channel the receiver drives). A refused value is
never stored, whether it comes by PARAM_SET / ``Params.set`` or in a parameter file."""

from __future__ import annotations

import pytest

from mecanum_mav.config.params import MODE_NUMBERS, ParamError, Params
from mecanum_mav.config.schema import WHEELS
from mecanum_mav.io.paramfile import ParamFileError, parse_text
from mecanum_mav.protocol.modes import Mode

WHEELS_9_12 = {f"MOT_{w}_CH": 9 + i for i, w in enumerate(WHEELS)}
"""The wheels on channels no receiver function uses (docs/receiver.md: outputs 9-12)."""
RECEIVER = {"RCIN_ENABLE": 1, **WHEELS_9_12, "RCIN_ARM_CH": 7}
"""A receiver setup that is accepted: sticks on 1, 3, 4 (RCMAP defaults), mode switch on 8,
arm switch on 7, wheels on 9-12."""


def file_errors(text: str) -> list[str]:
    with pytest.raises(ParamFileError) as caught:
        parse_text(text, source="rover.parm")
    return caught.value.errors


# ------------------------------------------------------------------------------ mode numbers

def test_the_mode_numbers_a_switch_may_name_are_ardupilot_rovers_for_the_modes_it_has():
    """MODE1..MODE6: "0 MANUAL, 4 HOLD, 10 AUTO or 15 GUIDED (ArduPilot Rover MODEn)", the
    numbers the mode switch sends to the vehicle as its custom_mode."""
    assert {mode.value: mode.name for mode in Mode} == MODE_NUMBERS
    assert MODE_NUMBERS == {0: "MANUAL", 4: "HOLD", 10: "AUTO", 15: "GUIDED"}


@pytest.mark.parametrize("position", range(1, 7))
def test_every_switch_position_takes_exactly_the_four_mode_numbers(position):
    """Every number 0..15 the range allows is tried: 1, 2, 3 (ACRO, STEERING, ...) and the
    other Rover modes this companion does not have are refused, the old value kept."""
    name = f"MODE{position}"
    params = Params()
    for number in range(16):
        if number in (0, 4, 10, 15):
            params.set(name, number)
            assert params[name] == number
        else:
            with pytest.raises(ParamError, match=(
                    f"{name} {number} is not a mode: one of 0 MANUAL, 4 HOLD, 10 AUTO, "
                    f"15 GUIDED")):
                params.set(name, number)
            assert params[name] in (0, 4, 10, 15)


def test_a_file_naming_a_mode_the_rover_does_not_have_is_refused_at_its_line():
    assert file_errors("MODE2 15\nMODE6 3\n") == [
        "rover.parm:2: MODE6 3 is not a mode: one of 0 MANUAL, 4 HOLD, 10 AUTO, 15 GUIDED"]


# --------------------------------------------------------------- receiver functions' channels

@pytest.mark.parametrize(("first", "second"), [
    ("MODE_CH", "RCIN_ARM_CH"), ("MODE_CH", "RCMAP_STEER"), ("MODE_CH", "RCMAP_THROTTLE"),
    ("RCIN_ARM_CH", "RCMAP_LATERAL"), ("RCIN_ARM_CH", "MODE_CH")])
def test_two_receiver_functions_on_one_channel_are_refused(first, second):
    """"The mode and arm switches on channels of their own" (config/rules.py's RULES): a
    switch on a stick's channel, or both switches on one, would act on the other's moves."""
    params = Params(RECEIVER)
    channel = params[second]
    with pytest.raises(ParamError, match=f"share RC channel {channel}; one function each"):
        params.set(first, channel)
    assert params[first] != channel


def test_both_switches_may_be_none():
    """A switch channel 0 is none (RCIN_ARM_CH, MODE_CH: "0 = none"): two of them are not a
    shared channel."""
    params = Params(RECEIVER)
    params.set("RCIN_ARM_CH", 0)
    params.set("MODE_CH", 0)
    assert (params["RCIN_ARM_CH"], params["MODE_CH"]) == (0, 0)


# ----------------------------------------------------------- wheels on the receiver's channels

@pytest.mark.parametrize("wheel", WHEELS)
def test_with_the_receiver_on_no_wheel_may_be_on_a_channel_the_receiver_uses(wheel):
    """RCIN_ENABLE: "the wheels need channels the receiver does not use (MOT_x_CH)": the
    flight controller reports the companion's overrides in RC_CHANNELS, so a wheel on a stick
    or switch channel would read back as that stick or switch."""
    params = Params(RECEIVER)
    name = f"MOT_{wheel}_CH"
    for function in ("RCMAP_STEER", "RCMAP_THROTTLE", "RCMAP_LATERAL", "MODE_CH",
                     "RCIN_ARM_CH"):
        channel = params[function]
        with pytest.raises(ParamError, match=(
                f"{name} {channel} is the receiver's {function} channel; with RCIN_ENABLE 1")):
            params.set(name, channel)
        assert params[name] == WHEELS_9_12[name]


def test_a_switch_moved_onto_a_wheel_channel_is_refused_with_the_receiver_on():
    params = Params(RECEIVER)
    with pytest.raises(ParamError, match="MOT_FL_CH 9 is the receiver's MODE_CH channel"):
        params.set("MODE_CH", 9)
    with pytest.raises(ParamError, match="MOT_RR_CH 12 is the receiver's RCMAP_LATERAL"):
        params.set("RCMAP_LATERAL", 12)
    assert (params["MODE_CH"], params["RCMAP_LATERAL"]) == (8, 4)


def test_turning_the_receiver_on_with_the_wheels_on_stick_channels_is_refused_at_that_line():
    """The default wheels (1-4) share the default sticks' channels 1, 3 and 4: a file that
    only turns the receiver on is refused, each wheel on a stick named, at RCIN_ENABLE's line."""
    assert file_errors("# a receiver\nRCIN_ENABLE 1\n") == [
        f"rover.parm:2: {wheel} is the receiver's {function} channel; with RCIN_ENABLE 1 the "
        f"wheels need channels the receiver does not use (e.g. 9-12)"
        for wheel, function in (("MOT_FL_CH 1", "RCMAP_STEER"),
                                ("MOT_RL_CH 3", "RCMAP_THROTTLE"),
                                ("MOT_RR_CH 4", "RCMAP_LATERAL"))]
    with pytest.raises(ParamError, match="MOT_FL_CH 1 is the receiver's RCMAP_STEER channel"):
        Params().set("RCIN_ENABLE", 1)


def test_with_the_receiver_off_the_wheels_may_use_the_stick_channels_numbers():
    """Without a receiver the sticks are the ground station's (RC_CHANNELS_OVERRIDE to the
    companion) and the wheels the companion's overrides to the flight controller: the default
    setup has wheel 1 and the steering stick both on channel 1, and a wheel on the mode switch's
    channel is no clash either."""
    params = Params()
    assert params["RCIN_ENABLE"] == 0
    assert params["MOT_FL_CH"] == params["RCMAP_STEER"] == 1
    params.update({"MOT_FR_CH": params["MODE_CH"]})
    assert params["MOT_FR_CH"] == 8
