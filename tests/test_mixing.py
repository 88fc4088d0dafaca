"""Mixing algorithms: seed golden vectors, conventions, properties, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mecanum_mav.mecanum.mixing import (
    ALGORITHM_NAMES,
    Desaturation,
    cartesian,
    chassis_from_wheels,
    desaturate,
    desaturate_prioritized,
    desaturate_prioritized_scalar,
    holonomic_2010,
    max_speed_scaled,
    mix_stick,
    normalize,
    polar_2011,
    wheels_from_stick,
)

R2 = math.sqrt(0.5)
unit = st.floats(-1.0, 1.0, allow_nan=False)
angle = st.floats(-720.0, 720.0, allow_nan=False)
anything = st.floats(allow_nan=True, allow_infinity=True)
priorities = st.sampled_from(list(Desaturation))
POLAR = (polar_2011, max_speed_scaled, holonomic_2010)


def polar_kwargs(mixer, priority):
    return {} if mixer is holonomic_2010 else {"priority": priority}


# --------------------------------------------------------------------------- conventions


def test_forward_stick_drives_every_wheel_forward():
    np.testing.assert_allclose(cartesian(1.0, 0.0, 0.0), [1, 1, 1, 1])


def test_strafe_right_spins_front_left_and_rear_right_forward():
    np.testing.assert_allclose(cartesian(0.0, 1.0, 0.0), [1, -1, -1, 1])
    np.testing.assert_allclose(polar_2011(1.0, 90.0, 0.0), [1, -1, -1, 1], atol=1e-12)


def test_clockwise_rotation_spins_left_wheels_forward():
    np.testing.assert_allclose(cartesian(0.0, 0.0, 1.0), [1, -1, 1, -1])


def test_field_oriented_north_command_facing_east_strafes_left():
    np.testing.assert_allclose(cartesian(1.0, 0.0, 0.0, 90.0), [-1, 1, 1, -1], atol=1e-12)


# --------------------------------------------------------------------------- seed 000 (WPILib)


def seed_2010(magnitude, direction, rotation):
    """HolonomicDrive as seed 000 prints it (Limit = clip to [-1, 1])."""
    m = max(-1.0, min(1.0, magnitude))
    cos_d = math.cos(math.radians(direction + 45.0))
    sin_d = math.cos(math.radians(direction - 45.0))
    lim = lambda v: max(-1.0, min(1.0, v))  # noqa: E731
    return [lim(sin_d * m + rotation), lim(cos_d * m - rotation),
            lim(cos_d * m + rotation), lim(sin_d * m - rotation)]


def seed_2011(magnitude, direction, rotation):
    """MecanumDrive_Polar as seed 000 prints it, with its Normalize."""
    m = max(-1.0, min(1.0, magnitude)) * math.sqrt(2.0)
    d = math.radians(direction + 45.0)
    w = [math.sin(d) * m + rotation, math.cos(d) * m - rotation,
         math.cos(d) * m + rotation, math.sin(d) * m - rotation]
    peak = max(abs(v) for v in w)
    return [v / peak for v in w] if peak > 1.0 else w


@given(unit, angle, unit)
def test_holonomic_2010_matches_the_seed_code(magnitude, direction, rotation):
    np.testing.assert_allclose(holonomic_2010(magnitude, direction, rotation),
                               seed_2010(magnitude, direction, rotation), atol=1e-12)


@given(unit, angle, unit)
def test_polar_2011_matches_the_seed_code(magnitude, direction, rotation):
    np.testing.assert_allclose(polar_2011(magnitude, direction, rotation),
                               seed_2011(magnitude, direction, rotation), atol=1e-12)


def test_polar_2011_gives_full_power_on_cardinals_and_pairs_on_diagonals():
    np.testing.assert_allclose(polar_2011(1.0, 0.0, 0.0), [1, 1, 1, 1])
    np.testing.assert_allclose(polar_2011(1.0, 45.0, 0.0), [1, 0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(polar_2011(1.0, -135.0, 0.0), [-1, 0, 0, -1], atol=1e-12)


def test_holonomic_2010_tops_out_at_root_half_forward():
    np.testing.assert_allclose(holonomic_2010(1.0, 0.0, 0.0), [R2] * 4)


def test_holonomic_2010_clipping_distorts_rotation_where_2011_keeps_it():
    commanded = 0.29
    w2010 = holonomic_2010(1.0, 45.0, commanded)
    w2011 = polar_2011(1.0, 45.0, commanded)
    x10, y10, r10 = chassis_from_wheels(w2010)
    x11, y11, r11 = chassis_from_wheels(w2011)
    assert r10 / math.hypot(x10, y10) != pytest.approx(commanded / 1.0, rel=0.05)
    # 2011 keeps the translation:rotation ratio of the command (magnitude 1 : rotation 0.29).
    assert r11 / math.hypot(x11, y11) == pytest.approx(commanded / 1.0)


# --------------------------------------------------------------------------- seed 001 and 002


@pytest.mark.parametrize(
    ("math_angle_rad", "fr", "fl", "bl", "br"),
    [(math.pi / 4, 0, 1, 0, 1), (3 * math.pi / 4, 1, 0, 1, 0),
     (5 * math.pi / 4, 0, -1, 0, -1), (7 * math.pi / 4, -1, 0, -1, 0)],
)
def test_seed_001_table_in_our_convention(math_angle_rad, fr, fl, bl, br):
    # Seed 001 measures the angle counter-clockwise from the stick's +x (right) axis:
    # our direction (clockwise from the nose) is 90 deg minus it.
    direction = 90.0 - math.degrees(math_angle_rad)
    for mixer in (holonomic_2010, max_speed_scaled):
        np.testing.assert_allclose(mixer(1.0, direction, 0.0), [fl, fr, bl, br], atol=1e-12)


def seed_002_wheels(speed, angle_deg, rotation):
    """'Simplistic control' V1..V4 with the angle clockwise from forward."""
    a = math.radians(angle_deg) + math.pi / 4
    return [speed * math.sin(a) + rotation, speed * math.cos(a) - rotation,
            speed * math.cos(a) + rotation, speed * math.sin(a) - rotation]


def test_seed_002_always_normalize_scales_straight_ahead_up_to_full_power():
    raw = seed_002_wheels(1.0, 0.0, 0.0)
    np.testing.assert_allclose(raw, [R2] * 4)
    np.testing.assert_allclose(normalize(raw, always=True), [1, 1, 1, 1])
    np.testing.assert_allclose(normalize(raw), raw)  # default only scales down


def test_seed_002_all_zero_wheels_normalize_to_zero_not_nan():
    out = normalize(np.zeros((3, 4)), always=True)
    assert np.all(out == 0.0)


def test_seed_002_rear_right_is_its_own_wheel_not_rear_left_read_twice():
    # Seed 002's sample code fills wheel[3] from backLeft; with rotation that is wrong.
    w = normalize(seed_002_wheels(0.5, 30.0, 0.4), always=True)
    assert w[3] != pytest.approx(w[2])
    # Seed 002 has no sqrt(2) factor: its translation is Vd * (cos + sin) / sqrt(2).
    x, y = 0.5 * R2 * math.cos(math.radians(30)), 0.5 * R2 * math.sin(math.radians(30))
    np.testing.assert_allclose(w, normalize(cartesian(x, y, 0.4), always=True))


# --------------------------------------------------------------------------- seed 004


@pytest.mark.parametrize(
    ("math_angle", "new_a", "new_b"),
    [(0, 1, -1), (15, 1, -math.sqrt(3) / 3), (45, 1, 0),
     (75, 1, math.sqrt(3) / 3), (90, 1, 1), (135, 0, 1), (180, -1, 1)],
)
def test_seed_004_scaling_table(math_angle, new_a, new_b):
    # Seed 004: A drives FL and RR, B drives FR and RL; angle CCW from the right (+x stick).
    w = max_speed_scaled(1.0, 90.0 - math_angle, 0.0)
    np.testing.assert_allclose(w, [new_a, new_b, new_b, new_a], atol=1e-12)


@pytest.mark.parametrize(("math_angle", "sign"), [(30, -1), (60, 1)])
def test_seed_004_table_misprints_the_30_and_60_degree_rows(math_angle, sign):
    # The seed prints 0.673227 for the smaller wheel; the mathematics gives tan(15 deg).
    w = max_speed_scaled(1.0, 90.0 - math_angle, 0.0)
    assert w[0] == pytest.approx(1.0)
    assert w[1] == pytest.approx(sign * math.tan(math.radians(15.0)))  # 0.268
    assert abs(w[1]) != pytest.approx(0.673227, abs=0.1)


@given(st.floats(0.0, 1.0), angle)
def test_max_speed_scaled_puts_the_larger_pair_at_the_magnitude(magnitude, direction):
    assert np.abs(max_speed_scaled(magnitude, direction, 0.0)).max() == pytest.approx(magnitude)


# --------------------------------------------------------------------------- properties


@given(unit, unit, unit)
def test_forward_kinematics_inverts_cartesian_where_nothing_saturated(x, y, r):
    if max(abs(x + y), abs(x - y)) + abs(r) > 1.0:
        return
    np.testing.assert_allclose(chassis_from_wheels(cartesian(x, y, r)), [x, y, r], atol=1e-12)


@given(anything, anything, anything, anything, priorities)
def test_every_algorithm_stays_within_limits_for_any_input(a, b, c, h, priority):
    outputs = [cartesian(a, b, c, h, priority=priority)]
    outputs += [m(a, b, c, **polar_kwargs(m, priority)) for m in POLAR]
    for name in ALGORITHM_NAMES:
        outputs.append(mix_stick(a, b, c, name, heading_deg=h, priority=priority))
    for w in outputs:
        assert w.shape == (4,)
        assert np.all(np.isfinite(w))
        assert np.all(np.abs(w) <= 1.0 + 1e-12)


@given(st.lists(st.floats(-1e6, 1e6), min_size=4, max_size=4), st.floats(0.1, 10.0))
def test_desaturate_keeps_the_ratios_between_wheels(wheels, limit):
    out = desaturate(wheels, limit)
    assert np.abs(out).max() <= limit * (1 + 1e-12)
    peak = max(abs(w) for w in wheels)
    scale = 1.0 if peak <= limit else limit / peak
    np.testing.assert_allclose(out, np.array(wheels) * scale, rtol=1e-12, atol=1e-300)


@given(unit, unit, unit, angle, st.floats(-180.0, 180.0))
def test_field_oriented_mixing_is_invariant_to_rotating_command_and_heading(x, y, r, h, turn):
    if math.hypot(x, y) > 1.0:
        return
    c, s = math.cos(math.radians(turn)), math.sin(math.radians(turn))
    # Rotate the field command by `turn` (clockwise) and the robot with it: same wheels.
    xr, yr = x * c - y * s, x * s + y * c
    np.testing.assert_allclose(cartesian(xr, yr, r, h + turn), cartesian(x, y, r, h), atol=1e-9)


@given(unit, unit, unit, angle, priorities)
def test_scalar_and_vector_paths_agree(a, b, c, h, priority):
    vec = [np.array([a, a]), np.array([b, b]), np.array([c, c])]
    np.testing.assert_allclose(cartesian(*vec, np.array([h, h]), priority=priority),
                               [cartesian(a, b, c, h, priority=priority)] * 2, atol=1e-12)
    for mixer in POLAR:
        kw = polar_kwargs(mixer, priority)
        np.testing.assert_allclose(mixer(*vec, **kw), [mixer(a, b, c, **kw)] * 2, atol=1e-12)


def test_vector_inputs_broadcast_to_the_wheel_axis():
    out = polar_2011(np.linspace(0, 1, 5)[:, None], np.array([0.0, 90.0, 180.0]), 0.1)
    assert out.shape == (5, 3, 4)


# --------------------------------------------------------------------------- priorities


@given(unit, unit, unit)
def test_rotation_priority_keeps_rotation_and_direction_of_travel(x, y, r):
    w = cartesian(x, y, r, priority=Desaturation.ROTATION_PRIORITY)
    cx, cy, cr = chassis_from_wheels(w)
    assert cr == pytest.approx(r, abs=1e-12)
    assert cx * y == pytest.approx(cy * x, abs=1e-9)  # parallel to (x, y)
    assert cx * x + cy * y >= -1e-12  # and not reversed


@given(unit, unit, unit)
def test_translation_priority_keeps_translation_that_fits(x, y, r):
    if max(abs(x + y), abs(x - y)) > 1.0:
        return
    w = cartesian(x, y, r, priority=Desaturation.TRANSLATION_PRIORITY)
    cx, cy, cr = chassis_from_wheels(w)
    assert (cx, cy) == pytest.approx((x, y), abs=1e-12)
    assert cr * r >= -1e-12 and abs(cr) <= abs(r) + 1e-12


@given(st.lists(st.floats(-3, 3), min_size=4, max_size=4),
       st.lists(st.floats(-3, 3), min_size=4, max_size=4), priorities)
def test_prioritized_desaturation_of_any_pattern_fits_within_the_limit(t, r, priority):
    out = desaturate_prioritized(t, r, priority)
    assert np.abs(out).max() <= 1.0 + 1e-9


wide = st.one_of(st.floats(-3, 3), st.floats(allow_nan=True, allow_infinity=True),
                 st.sampled_from([0.0, -0.0, 1e308, -1e308, 5e-324]))


@given(st.lists(wide, min_size=4, max_size=4), st.lists(wide, min_size=4, max_size=4),
       priorities, st.sampled_from([1.0, 0.5, 2.0]))
def test_scalar_prioritized_desaturation_gives_the_array_versions_numbers(t, r, priority,
                                                                         limit):
    expected = desaturate_prioritized(t, r, priority, limit)  # (no warning: they are errors)
    got = desaturate_prioritized_scalar(t, r, priority, limit)
    assert type(got) is tuple and all(type(v) is float for v in got)
    assert got == tuple(expected.tolist())


def test_proportional_priority_halves_both_parts_when_twice_over():
    w = cartesian(1.0, 0.0, 1.0)  # FL = 2 before desaturation
    np.testing.assert_allclose(chassis_from_wheels(w), [0.5, 0.0, 0.5])


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_command_is_a_stop(bad):
    for w in (cartesian(bad, 0.5, 0.5), cartesian(0.5, 0.5, 0.5, bad), polar_2011(0.5, bad, 0.0),
              max_speed_scaled(bad, 0.0, 0.0), holonomic_2010(0.5, 0.0, bad)):
        assert np.all(w == 0.0)


def test_non_finite_row_in_a_batch_stops_only_that_row():
    out = cartesian(np.array([0.5, np.nan, 0.5]), np.array([0.0, 0.0, np.inf]), 0.0)
    np.testing.assert_allclose(out, [[0.5] * 4, [0.0] * 4, [0.0] * 4])


def test_magnitudes_above_one_are_limited():
    np.testing.assert_allclose(polar_2011(5.0, 0.0, 0.0), [1, 1, 1, 1])
    np.testing.assert_allclose(cartesian(0.0, 0.0, -7.0), [-1, 1, -1, 1])


def test_forward_kinematics_rejects_non_finite_wheels():
    with pytest.raises(ValueError, match="finite"):
        chassis_from_wheels([0.0, np.nan, 0.0, 0.0])


@pytest.mark.parametrize("limit", [0.0, -1.0, math.nan])
def test_desaturate_rejects_a_meaningless_limit(limit):
    with pytest.raises(ValueError, match="limit"):
        desaturate([1, 2, 3, 4], limit)


@settings(max_examples=50)
@given(unit, unit, unit)
def test_mix_stick_polar_algorithms_see_the_stick_direction(x, y, r):
    np.testing.assert_allclose(mix_stick(x, y, r, "polar_2011"),
                               polar_2011(math.hypot(x, y), math.degrees(math.atan2(y, x)), r),
                               atol=1e-12)


@given(anything, anything, anything, angle, priorities, st.sampled_from(ALGORITHM_NAMES))
def test_the_control_loops_tuple_path_matches_mix_stick_with_plain_floats(x, y, r, h, p, algo):
    fast = wheels_from_stick(x, y, r, algo, heading_deg=h, priority=p)
    assert all(type(w) is float for w in fast)
    np.testing.assert_array_equal(np.array(fast), mix_stick(x, y, r, algo, heading_deg=h,
                                                            priority=p))


@pytest.mark.parametrize("wheels", [[0.5, 0.5, 0.5], [[0.5] * 5], 0.5])
def test_chassis_from_wheels_refuses_anything_but_four_wheels_on_the_last_axis(wheels):
    with pytest.raises(ValueError, match="wheels must have 4 values on the last axis"):
        chassis_from_wheels(wheels)
