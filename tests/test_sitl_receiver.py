"""The RC receiver through real ArduPilot Rover firmware (SITL): the firmware's simulated
receiver (UDP ``--rc-in-port``) is fed sticks and switches, the companion reads them in
RC_CHANNELS and drives the wheels on SERVO9..12 (set up as ``mecanum-mav setup-fc`` would),
read on the firmware's second port. Skipped when the firmware is not there."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from sitl import Rig, Sitl, find_sitl

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import InputConfig
from mecanum_mav.control.chain import manual_output
from mecanum_mav.control.pwm import PwmMap

BINARY, WHY_NOT = find_sitl()
pytestmark = [pytest.mark.sitl, pytest.mark.skipif(BINARY is None, reason=WHY_NOT)]

COMPANION = {"MOT_FL_CH": 9, "MOT_FR_CH": 10, "MOT_RL_CH": 11, "MOT_RR_CH": 12,
             "RCIN_ENABLE": 1, "RCIN_ARM_CH": 7, "MODE3": 4}
"""Wheels on 9-12, the receiver read, arm switch on channel 7, mode switch position 3 HOLD."""
CENTRE = (1500, 1500, 1500, 1500, 1500, 1500, 1000, 1100)
TRIM = (1500, 1500, 1500, 1500)


def receiver(**channels: int) -> tuple[int, ...]:
    pulses = list(CENTRE)
    for name, pulse in channels.items():
        pulses[int(name[2:]) - 1] = pulse
    return tuple(pulses)


@pytest.fixture
def rig(tmp_path) -> Iterator[Rig]:
    assert BINARY is not None
    sets = [a for k, v in COMPANION.items() for a in ("--set", f"{k}={v}")]
    with Sitl(BINARY, "udp", receiver=CENTRE, first_servo=9, boot_timeout_s=Rig.boot_s) as fc:
        # The user's path: setup-fc moves the radio failsafe to wheel channel 9
        # (RCMAP_THROTTLE, read at boot), so it takes a reboot; what --apply wrote must
        # survive it (ArduPilot gives the new throttle channel's dead zone a default of 30
        # at boot: a 0 written while 0 was the default would not have been stored).
        pending = fc.setup_fc("--apply", *sets)
        assert pending.returncode == 3 and "REBOOT PENDING" in pending.stdout, pending.stdout
        assert "set up safely" not in pending.stdout
        fc.set_up("--reboot", *sets)  # the check after the reboot, without --apply
        with Rig.on(fc, tmp_path, *sets) as rig:
            yield rig


def test_receiver_sticks_and_switches_drive_ardupilots_servo9_to_12_and_its_failsafe_stops_them(
        rig):
    fc, monitor = rig.fc, rig.monitor
    assert rig.said("Radio receiver OK"), rig.why()
    assert rig.said("FC setup checked: safe"), rig.why()  # then the pilot arms
    fc.receiver = receiver(ch7=2000)  # the arm switch
    assert rig.said("Armed"), rig.why()
    forward = receiver(ch7=2000, ch3=1750)
    params = Params()
    params.update(COMPANION)
    _, expected = manual_output(250 / 500, 0.0, 0.0, InputConfig.from_params(params),
                                PwmMap.from_params(params))
    assert expected[0] > 1700 and len(set(expected)) == 1
    fc.receiver = forward
    assert monitor.wait_servos(lambda s: s == expected, rig.react_s), rig.why()
    fc.receiver = receiver(ch7=2000, ch3=1750, ch8=1425)  # mode switch position 3: HOLD
    assert rig.said("Mode HOLD"), rig.why()
    assert monitor.wait_servos(lambda s: s == TRIM, rig.react_s), rig.why()
    fc.receiver = forward  # position 1: MANUAL again
    assert rig.said("Mode MANUAL"), rig.why()
    assert monitor.wait_servos(lambda s: s == expected, rig.react_s), rig.why()
    fc.receiver = receiver(ch7=2000, ch3=880)  # the receiver's failsafe: throttle low
    assert monitor.wait_servos(lambda s: s == TRIM, rig.react_s), rig.why()
    assert rig.said("Radio failsafe"), rig.why()
