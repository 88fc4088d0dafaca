"""Stick shaping (deadband, expo, circle) and the PWM edge."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from mecanum_mav.config.params import Params
from mecanum_mav.control.pwm import DEAD_BAND_LIVE, PwmMap, WheelOutput
from mecanum_mav.mecanum.shaping import deadband, expo, shape_stick, square_to_circle

unit = st.floats(-1.0, 1.0, allow_nan=False)


def test_deadband_matches_wpilib_apply_deadband():
    # WPILib MathUtilTest: applyDeadband(0.5, 0.02) == (0.5 - 0.02) / (1 - 0.02).
    assert deadband(0.5, 0.02) == pytest.approx((0.5 - 0.02) / (1 - 0.02))
    assert deadband(-0.5, 0.02) == pytest.approx(-(0.5 - 0.02) / (1 - 0.02))
    assert deadband(0.01, 0.02) == 0.0
    assert deadband(2.5, 0.2, max_magnitude=2.5) == pytest.approx(2.5)


@given(unit, st.floats(0.0, 0.5))
def test_deadband_is_continuous_monotonic_and_reaches_full_stick(v, band):
    out = deadband(v, band)
    assert abs(out) <= 1.0 + 1e-12
    assert out * v >= 0.0
    assert deadband(1.0, band) == pytest.approx(1.0)
    assert deadband(band + 1e-9, band) == pytest.approx(0.0, abs=1e-6)


def test_deadband_on_arrays_matches_scalars():
    v = np.linspace(-1, 1, 41)
    np.testing.assert_allclose(deadband(v, 0.1), [deadband(float(x), 0.1) for x in v])


@pytest.mark.parametrize("band", [-0.1, 1.0, math.nan])
def test_deadband_rejects_a_band_that_is_not_inside_the_range(band):
    with pytest.raises(ValueError, match="deadband"):
        deadband(0.5, band)


@given(unit, st.floats(0.0, 1.0))
def test_expo_keeps_the_end_points_and_sign_and_softens_the_centre(v, e):
    assert expo(1.0, e) == pytest.approx(1.0)
    assert expo(-1.0, e) == pytest.approx(-1.0)
    assert expo(v, e) * v >= 0.0
    assert abs(expo(v, e)) <= abs(v) + 1e-12


def test_expo_rejects_a_weight_outside_zero_to_one():
    with pytest.raises(ValueError, match="expo"):
        expo(0.5, 1.5)


def test_square_stick_corner_becomes_a_unit_diagonal():
    x, y = square_to_circle(1.0, 1.0)
    assert (x, y) == pytest.approx((math.sqrt(0.5), math.sqrt(0.5)))
    assert square_to_circle(0.3, -0.4) == (0.3, -0.4)
    xa, ya = square_to_circle(np.array([1.0, 0.3]), np.array([1.0, -0.4]))
    np.testing.assert_allclose(np.hypot(xa, ya), [1.0, 0.5])


def test_shape_stick_applies_deadband_expo_then_circle():
    assert shape_stick(0.04, -0.04, 0.04, deadband_width=0.05) == (0.0, 0.0, 0.0)
    x, y, r = shape_stick(1.0, 1.0, 0.5, deadband_width=0.05, expo_weight=0.3)
    assert math.hypot(x, y) == pytest.approx(1.0)
    assert r == pytest.approx(expo(deadband(0.5, 0.05), 0.3))
    assert shape_stick(3.0, 0.0, -3.0, circle=False) == (1.0, 0.0, -1.0)


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_shape_stick_reads_a_non_finite_axis_as_a_stop(bad):
    assert shape_stick(0.5, bad, 0.2) == (0.0, 0.0, 0.0)


# --------------------------------------------------------------------------- PWM


def test_default_pwm_is_trim_at_zero_and_ends_at_full_command():
    out = PwmMap.from_params(Params())
    assert out.pulses_us([0, 0, 0, 0]) == out.neutral() == (1500, 1500, 1500, 1500)
    assert out.pulses_us([1, -1, 0.5, -0.5]) == (2000, 1000, 1750, 1250)
    assert out.channels == (1, 2, 3, 4)


def test_reversed_wheel_maps_forward_to_its_minimum():
    params = Params()
    params.set("MOT_FR_REV", 1)
    out = PwmMap.from_params(params)
    assert out.pulses_us([1, 1, 1, 1]) == (2000, 1000, 2000, 2000)


def test_off_centre_trim_keeps_full_range_on_both_sides():
    wheel = WheelOutput(channel=1, minimum=1100, trim=1520, maximum=1900)
    assert (wheel.pulse_us(-1.0), wheel.pulse_us(0.0), wheel.pulse_us(1.0)) == (1100, 1520, 1900)
    assert wheel.pulse_us(0.5) == 1710 and wheel.pulse_us(-0.5) == 1310


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_wheel_command_gives_trim(bad):
    wheel = WheelOutput(channel=1, minimum=1000, trim=1500, maximum=2000)
    assert wheel.pulse_us(bad) == 1500


@pytest.mark.parametrize("beyond", [1.0001, 1.5, 7.0])
def test_out_of_range_wheel_command_is_limited(beyond):
    wheel = WheelOutput(channel=1, minimum=1000, trim=1500, maximum=2000)
    assert (wheel.pulse_us(beyond), wheel.pulse_us(-beyond)) == (2000, 1000)


@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=4, max_size=4))
def test_vector_pwm_matches_scalar_pwm(wheels):
    params = Params()
    params.set("MOT_RL_REV", 1)
    out = PwmMap.from_params(params)
    assert tuple(out.pulses_us_array(np.array([wheels]))[0]) == out.pulses_us(wheels)


@given(st.floats(-1.0, 1.0), st.booleans(), st.integers(1000, 1499), st.integers(1501, 2000))
def test_command_from_pulse_inverts_pulse_us_to_the_microsecond(command, rev, low, high):
    wheel = WheelOutput(channel=1, minimum=low - 100, trim=low, maximum=high, reversed=rev)
    back = wheel.command_from_pulse(wheel.pulse_us(command))
    assert wheel.pulse_us(back) == wheel.pulse_us(command)
    span = min(wheel.maximum - wheel.trim, wheel.trim - wheel.minimum)
    assert back == pytest.approx(command, abs=0.5 / span + 1e-12)  # half a microsecond


def test_command_from_pulse_limits_the_pulse_and_reads_non_finite_as_stopped():
    wheel = WheelOutput(channel=1, minimum=1100, trim=1520, maximum=1900)
    assert [wheel.command_from_pulse(p) for p in (1900, 1520, 1100)] == [1.0, 0.0, -1.0]
    assert (wheel.command_from_pulse(2500), wheel.command_from_pulse(0)) == (1.0, -1.0)
    assert wheel.command_from_pulse(1710) == pytest.approx(0.5)
    assert wheel.command_from_pulse(math.nan) == 0.0
    mirrored = WheelOutput(channel=2, minimum=1000, trim=1500, maximum=2000, reversed=True)
    assert mirrored.command_from_pulse(1250) == 0.5


@given(st.floats(-2, 2), st.floats(-2, 2), st.floats(-2, 2), st.floats(0.0, 0.5),
       st.floats(0.0, 1.0), st.booleans())
def test_shape_stick_equals_deadband_then_expo_then_circle(x, y, r, band, weight, circle):
    clip = lambda v: max(-1.0, min(1.0, v))  # noqa: E731
    ref = [expo(deadband(clip(v), band), weight) for v in (x, y, r)]
    if circle:
        ref[0], ref[1] = square_to_circle(ref[0], ref[1])
    got = shape_stick(x, y, r, deadband_width=band, expo_weight=weight, circle=circle)
    assert got == pytest.approx(tuple(ref), abs=1e-12)


@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=4, max_size=4),
       st.lists(st.booleans(), min_size=4, max_size=4))
def test_the_four_wheel_pwm_is_each_wheels_own(wheels, reversed_):
    params = Params()
    for key, rev in zip(("FL", "FR", "RL", "RR"), reversed_, strict=True):
        params.set(f"MOT_{key}_REV", int(rev))
        params.set(f"MOT_{key}_TRIM", 1480 + 10 * len(key) * rev)
    out = PwmMap.from_params(params)
    assert out.pulses_us(wheels) == tuple(w.pulse_us(c) for w, c in zip(out.wheels, wheels,
                                                                           strict=True))


# --------------------------------------------------------------------------- ESC dead band


def dead_band_map(band: float, **values: int) -> PwmMap:
    params = Params()
    params.update({"MOT_DZ": band, **values})
    return PwmMap.from_params(params)


def test_with_a_jump_dead_band_a_command_inside_it_goes_to_its_edge_one_past_it_as_it_is():
    # MOT_DZ_TYPE 1 (jump): sign(c) * max(|c|, dz) (kills pwm-dead-band-jump,
    # pwm-dead-band-type-param); 0 and <= 1 us stay, full stays full
    out = dead_band_map(0.1, MOT_DZ_TYPE=1)
    assert out.pulses_us([0.02, -0.02, 0.5, -0.5]) == (1550, 1450, 1750, 1250)
    assert out.pulses_us([0.0, 0.0019, -1.0, 1.0]) == (1500, 1501, 1000, 2000)


def test_with_a_dead_band_zero_and_commands_of_at_most_a_microsecond_stay_inside_it():
    # kills pwm-dead-band-zero (0 compensated) and pwm-dead-band-live (no threshold)
    out = dead_band_map(0.1)
    assert out.pulses_us([0.0, 0.0019, -0.002, -0.0]) == (1500, 1501, 1499, 1500)


def test_with_a_dead_band_a_small_command_jumps_over_it_and_full_stays_full():
    # 0.02 -> 0.1 + 0.9 * 0.02 = 0.118 of 500 us; 0.5 -> 0.55; 1 -> 1 (kills pwm-dead-band-add,
    # pwm-dead-band-negative, pwm-dead-band-scale, pwm-dead-band-param)
    out = dead_band_map(0.1)
    assert out.pulses_us([0.02, -0.02, 0.5, -0.5]) == (1559, 1441, 1775, 1225)
    assert out.pulses_us([1.0, -1.0, 7.0, -7.0]) == (2000, 1000, 2000, 1000)


def test_the_dead_band_is_jumped_towards_a_reversed_wheels_minimum():
    out = dead_band_map(0.1, MOT_FR_REV=1)
    assert out.pulses_us([0.02, 0.02, 0.02, -0.02]) == (1559, 1441, 1559, 1441)


def test_mot_dz_0_sends_the_commands_as_they_are():
    assert dead_band_map(0.0).pulses_us([0.02, -0.02, 0.5, 0.0019]) == (1510, 1490, 1750, 1501)


@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=4, max_size=4),
       st.floats(0.0, 0.3), st.integers(0, 1))
@example([0.01, -0.01, 0.05, -0.2], 0.1, 1)  # inside a jump ESC's band: lifted to its edge
@example([0.01, -0.01, 0.05, -0.2], 0.1, 0)
def test_vector_pwm_matches_scalar_pwm_with_a_dead_band(wheels, band, jump):
    # kills pwm-dead-band-array, pwm-dead-band-array-jump
    out = dead_band_map(band, MOT_RL_REV=1, MOT_DZ_TYPE=jump)
    assert tuple(out.pulses_us_array(np.array([wheels]))[0]) == out.pulses_us(wheels)


_WHEEL = st.tuples(st.integers(800, 1499), st.integers(1, 300), st.integers(1, 300),
                   st.booleans()).map(
    lambda t: {"trim": t[0] + 100, "low": t[0] + 100 - t[1], "high": t[0] + 100 + t[2],
               "rev": t[3]})
_COMMAND = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                     st.sampled_from([DEAD_BAND_LIVE, -DEAD_BAND_LIVE, 0.0, -0.0, 1.0, -1.0]))


@given(st.lists(_COMMAND, min_size=4, max_size=4), st.lists(_WHEEL, min_size=4, max_size=4),
       st.floats(0.0, 0.3), st.booleans())
@example([DEAD_BAND_LIVE, -DEAD_BAND_LIVE, 0.5, -0.5],
         [{"trim": 1500, "low": 1100, "high": 1700, "rev": False}] * 4, 0.1, False)
def test_the_vector_pwm_of_any_wheels_and_commands_is_the_scalar_pwm_as_integers(
        wheels, spans, band, jump):
    """Each wheel's own minimum, trim, maximum (asymmetric spans) and direction, any dead
    band, commands on the dead band's live edge: the vectorized pulses are the scalar ones,
    as integers (microseconds)."""
    out = PwmMap(tuple(WheelOutput(channel=k + 1, minimum=w["low"], trim=w["trim"],
                                   maximum=w["high"], reversed=w["rev"])
                       for k, w in enumerate(spans)), band, jump)
    vector = out.pulses_us_array(np.array([wheels, wheels]))
    assert vector.dtype.kind == "i" and vector.shape == (2, 4)
    assert tuple(int(p) for p in vector[1]) == out.pulses_us(wheels)


@given(st.floats(-1.0, 1.0), st.floats(0.0, 0.3))
def test_the_esc_sees_the_compensated_command_a_board_does_not_undo_it(command, band):
    # what SimBoard's ESC reads (command_from_pulse) is the compensated command
    out = dead_band_map(band)
    seen = out.wheels[0].command_from_pulse(out.pulses_us([command, 0.0, 0.0, 0.0])[0])
    expected = command if abs(command) <= 0.002 else math.copysign(
        band + (1.0 - band) * abs(command), command)
    assert seen == pytest.approx(expected, abs=0.5 / 500 + 1e-12)
