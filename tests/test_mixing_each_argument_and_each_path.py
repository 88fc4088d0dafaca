"""The mixing module's promises argument by argument and path by path (mecanum/mixing.py,
mecanum/scalarmix.py): a non-finite value in *any one* argument is a stop, for plain floats
and for the one row of a batch that holds it; plain numbers give exactly the numbers of the
control loop's plain-float functions; the polar algorithms drive field-oriented the way
``cartesian`` does (the heading is subtracted from the direction); the defaults are the
cartesian algorithm and proportional desaturation; narrower arrays mix in float64."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mecanum_mav.mecanum.mixing import (
    ALGORITHM_NAMES,
    ALGORITHMS,
    Desaturation,
    cartesian,
    chassis_from_wheels,
    mix_stick,
    wheels_from_stick,
)
from mecanum_mav.mecanum.scalarmix import (
    cartesian_scalar,
    holonomic_2010_scalar,
    max_speed_scaled_scalar,
    polar_2011_scalar,
)

GOOD = {  # a command inside every limit, with the arguments each algorithm takes
    "cartesian": (0.5, -0.25, 0.25, 30.0),
    "polar_2011": (0.5, 30.0, 0.25),
    "max_speed_scaled": (0.5, 30.0, 0.25),
    "holonomic_2010": (0.5, 30.0, 0.25),
}
PLAIN = {
    "cartesian": lambda x, y, r, h: cartesian_scalar(x, y, r, h, Desaturation.PROPORTIONAL),
    "polar_2011": lambda m, d, r: polar_2011_scalar(m, d, r, Desaturation.PROPORTIONAL),
    "max_speed_scaled": lambda m, d, r: max_speed_scaled_scalar(m, d, r,
                                                                Desaturation.PROPORTIONAL),
    "holonomic_2010": holonomic_2010_scalar,
}
BAD = (math.nan, math.inf, -math.inf)


def with_one_bad(args, position, bad):
    return tuple(bad if i == position else a for i, a in enumerate(args))


@pytest.mark.parametrize("bad", BAD)
@pytest.mark.parametrize("name", ALGORITHM_NAMES)
def test_a_non_finite_value_in_any_one_argument_stops_all_four_wheels(name, bad):
    for position in range(len(GOOD[name])):
        args = with_one_bad(GOOD[name], position, bad)
        assert PLAIN[name](*args) == (0.0, 0.0, 0.0, 0.0), (name, position)
        np.testing.assert_array_equal(ALGORITHMS[name](*args), np.zeros(4))


@pytest.mark.parametrize("bad", BAD)
@pytest.mark.parametrize("name", ALGORITHM_NAMES)
def test_a_non_finite_value_in_one_argument_of_a_batch_stops_only_its_row(name, bad):
    good = ALGORITHMS[name](*GOOD[name])
    assert np.abs(good).min() > 0.0  # (so that a stopped row shows)
    for position in range(len(GOOD[name])):
        columns = [np.full(3, a) for a in GOOD[name]]
        columns[position][1] = bad
        out = ALGORITHMS[name](*columns)
        np.testing.assert_allclose(out[[0, 2]], [good, good], rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(out[1], np.zeros(4), err_msg=f"{name} {position}")


@pytest.mark.parametrize("bad", BAD)
@pytest.mark.parametrize("name", ALGORITHM_NAMES)
def test_a_non_finite_stick_axis_or_heading_stops_the_control_loops_path(name, bad):
    stick = (0.5, -0.25, 0.25, 30.0)
    for position in range(4):
        x, y, r, h = with_one_bad(stick, position, bad)
        assert wheels_from_stick(x, y, r, name, heading_deg=h) == (0.0, 0.0, 0.0, 0.0)


# Commands where the array path's general desaturation and the plain-float closed form
# round apart (found by search): a plain-number call must take the plain-float path.
ROUNDING_APART = [
    ("cartesian", (0.9264690343829047, 0.5444558933936987, -0.8195599172838106), 0),
    ("cartesian", (-0.4920066289367755, 0.5533281405075203, 0.19066441232739373), 2),
    ("polar_2011", (-0.9226839677457708, -38.59116344759599, -0.9392506433994423), 0),
    ("max_speed_scaled", (0.794949312962304, 174.8627172240847, 0.29971525064725135), 0),
]


@pytest.mark.parametrize(("name", "args", "priority"), ROUNDING_APART)
def test_plain_numbers_give_exactly_the_control_loops_plain_float_numbers(name, args, priority):
    scalar = {"cartesian": lambda x, y, r, p: cartesian_scalar(x, y, r, 0.0, p),
              "polar_2011": polar_2011_scalar, "max_speed_scaled": max_speed_scaled_scalar}
    want = scalar[name](*args, priority)
    for number in (float, np.float64):
        got = ALGORITHMS[name](*map(number, args), priority=priority)
        assert got.dtype == np.float64 and got.shape == (4,)
        assert tuple(got.tolist()) == want
    as_arrays = ALGORITHMS[name](*map(np.array, args), priority=priority)
    assert not np.array_equal(as_arrays, want)  # (the example still shows the two paths)
    np.testing.assert_allclose(as_arrays, want, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("name", ["polar_2011", "max_speed_scaled", "holonomic_2010"])
@pytest.mark.parametrize("heading", [90.0, -90.0, 180.0, 30.0])
def test_polar_algorithms_drive_field_oriented_where_cartesian_does(name, heading):
    """A north stick on a robot facing ``heading`` drives north: body direction -heading."""
    want = ALGORITHMS[name](0.5, -heading, 0.0)
    got = wheels_from_stick(0.5, 0.0, 0.0, name, heading_deg=heading)
    np.testing.assert_allclose(got, want, atol=1e-12)
    moved = chassis_from_wheels(np.array(got))[:2]
    cartesian_moved = chassis_from_wheels(cartesian(0.5, 0.0, 0.0, heading))[:2]
    assert math.atan2(moved[1], moved[0]) == pytest.approx(
        math.atan2(cartesian_moved[1], cartesian_moved[0]), abs=1e-12)  # the same way


def test_the_default_algorithm_is_cartesian_with_proportional_desaturation():
    stick = (0.9, 0.6, -0.7)  # saturates: the strategy shows
    want = cartesian_scalar(*stick, 0.0, Desaturation.PROPORTIONAL)
    assert wheels_from_stick(*stick) == want
    assert tuple(mix_stick(*stick).tolist()) == want
    assert tuple(cartesian(*stick).tolist()) == want
    assert want != cartesian_scalar(*stick, 0.0, Desaturation.ROTATION_PRIORITY)


@pytest.mark.parametrize("name", ALGORITHM_NAMES)
def test_float32_and_integer_arrays_mix_to_the_float64_numbers_of_their_values(name):
    columns = [np.array([a, -a, 0.5 * a]) for a in GOOD[name]]
    for narrow in (np.float32, np.int64):
        values = [c.astype(narrow) for c in columns]
        got = ALGORITHMS[name](*values)
        assert got.dtype == np.float64
        np.testing.assert_array_equal(got, ALGORITHMS[name](*(v.astype(np.float64)
                                                              for v in values)))


def test_forward_kinematics_of_float32_and_integer_wheels_is_float64():
    wheels = np.array([[0.3, -0.7, 0.1, 0.9], [1.0, 2.0, -3.0, 4.0]])
    for narrow in (np.float32, np.int64):
        got = chassis_from_wheels(wheels.astype(narrow))
        assert got.dtype == np.float64
        np.testing.assert_array_equal(got, chassis_from_wheels(wheels.astype(narrow)
                                                               .astype(np.float64)))


def test_forward_kinematics_says_which_function_refused_and_why():
    with pytest.raises(ValueError) as refused:
        chassis_from_wheels([0.0, 0.0, math.inf, 0.0])
    assert str(refused.value) == "chassis_from_wheels: wheel values must be finite"

