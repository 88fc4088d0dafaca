"""The twin bridge's wheel map (mecanum_mav/sim/twinbridge.py ``WheelMap``): which servo
channel drives which wheel and with which sign, a pulse width read as the simulated board
reads it (``MOT_<W>_MIN/TRIM/MAX``: 1000/1500/2000 us by default), and the ESCs, which drive
only once they have seen neutral (``|command| < esc_dead_band``) and stop with no pulse (0 us,
or a channel the servo packet does not carry: 16 of them, 32 with ``SERVO_32_ENABLE``)."""

from __future__ import annotations

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.sim.twinbridge import WheelMap

NEUTRAL_32 = [1500] * 32
STOP = (0.0, 0.0, 0.0, 0.0)


def wheel_map(channels: tuple[tuple[int, float], ...] = ((1, 1.0), (2, 1.0), (3, 1.0), (4, 1.0)),
              esc_dead_band: float = 0.02) -> WheelMap:
    return WheelMap(PwmMap.from_params(Params()), channels, esc_dead_band)


def test_a_wheel_map_without_four_entries_says_it_needs_four_pairs_fl_fr_rl_rr() -> None:
    with pytest.raises(ValueError, match=r"need 4 \(channel, sign\) pairs FL, FR, RL, RR, got 3"):
        wheel_map(((1, 1.0), (2, 1.0), (3, 1.0)))


@pytest.mark.parametrize(("entry", "named"), [((33, 1.0), r"\(33, 1\.0\)"),
                                              ((3, 0.0), r"\(3, 0\.0\)")])
def test_a_bad_wheel_map_entry_is_named_in_the_error(entry: tuple[int, float],
                                                      named: str) -> None:
    with pytest.raises(ValueError, match=r"bad wheel map entry " + named):
        wheel_map(((1, 1.0), (2, 1.0), entry, (4, 1.0)))


def test_servo_channels_up_to_32_can_drive_the_wheels() -> None:
    """SERVO29..32 of a 32-channel packet (the map takes channels 1..32)."""
    wheels = wheel_map(((29, 1.0), (30, 1.0), (31, 1.0), (32, 1.0)))
    assert wheels.commands(NEUTRAL_32) == STOP  # (arms them)
    pwm = [1500] * 28 + [2000, 1000, 1750, 1250]
    assert wheels.pulses(pwm) == (2000, 1000, 1750, 1250)
    assert wheels.commands(pwm) == pytest.approx((1.0, -1.0, 0.5, -0.5))


def test_a_wheel_whose_channel_the_packet_does_not_carry_has_no_pulse_and_stops() -> None:
    """Wheels on SERVO17..20 drive from 32-channel packets; a 16-channel packet carries none
    of them: no pulse (0), the wheels stop, and each ESC waits for neutral again."""
    wheels = wheel_map(((17, 1.0), (18, 1.0), (19, 1.0), (20, 1.0)))
    drive = [1500] * 16 + [1750] * 4 + [1500] * 12
    assert wheels.commands(NEUTRAL_32) == STOP
    assert wheels.commands(drive) == pytest.approx((0.5, 0.5, 0.5, 0.5))
    assert wheels.pulses(drive) == (1750, 1750, 1750, 1750)
    sixteen = [1500] * 16
    assert wheels.pulses(sixteen) == (0, 0, 0, 0)
    assert wheels.commands(sixteen) == STOP
    assert wheels.commands(drive) == STOP  # (lost signal: not again until neutral)


def test_only_the_sign_of_a_wheel_maps_sign_counts() -> None:
    """A negative sign is a motor wired the other way round; its size does not scale."""
    wheels = wheel_map(((1, 0.5), (2, -2.0), (3, 1.0), (4, -1.0)))
    assert wheels.commands([1500] * 16) == STOP
    assert wheels.commands([1750] * 16) == pytest.approx((0.5, -0.5, 0.5, -0.5))


def test_every_esc_holds_its_wheel_from_power_up_until_it_sees_neutral() -> None:
    wheels = wheel_map()
    assert wheels.commands([1750, 1250, 1750, 1250]) == STOP
    assert wheels.commands([1500] * 4) == STOP
    assert wheels.commands([1750, 1250, 1750, 1250]) == pytest.approx((0.5, -0.5, 0.5, -0.5))


def test_a_pulse_on_the_dead_bands_edge_does_not_arm_an_esc_one_inside_it_does() -> None:
    """Neutral is ``|command| < esc_dead_band``: 1510 us is 0.02 of full, 1509 us inside."""
    wheels = wheel_map(esc_dead_band=0.02)
    assert wheels.commands([1510] * 4) == STOP
    assert wheels.commands([1750] * 4) == STOP  # (not armed)
    assert wheels.commands([1509] * 4) == STOP
    assert wheels.commands([1750] * 4) == pytest.approx((0.5, 0.5, 0.5, 0.5))


def test_only_a_pulse_of_0_is_no_output_a_pulse_below_the_range_is_full_reverse() -> None:
    """Pulses outside MOT_<W>_MIN..MAX are limited to them (WheelOutput.command_from_pulse);
    0 alone means the channel puts nothing out."""
    wheels = wheel_map()
    assert wheels.commands([1500] * 4) == STOP
    assert wheels.commands([1, 1500, 1500, 1500]) == (-1.0, 0.0, 0.0, 0.0)
    assert wheels.commands([2000, 1500, 1500, 1500]) == (1.0, 0.0, 0.0, 0.0)  # (still armed)
