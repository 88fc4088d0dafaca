"""Stick shaping's settings and number types (mecanum/shaping.py): the drive path's
``shape_stick`` defaults to no dead zone, no expo and the circle clamp, refuses either
setting out of its range (naming both), and keeps the ends of each range; the shaping
functions take a float and give a float, as their module says, whatever the number type."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mecanum_mav.mecanum.shaping import deadband, expo, shape_stick, square_to_circle


def test_shape_stick_by_default_has_no_dead_zone_and_no_expo_and_clamps_to_the_circle():
    assert shape_stick(0.5, -0.3, 0.2) == (0.5, -0.3, 0.2)
    assert shape_stick(0.01, -0.01, 0.01) == (0.01, -0.01, 0.01)
    x, y, r = shape_stick(1.0, 1.0, 0.0)
    assert (x, y, r) == pytest.approx((math.sqrt(0.5), math.sqrt(0.5), 0.0), abs=1e-15)


@pytest.mark.parametrize(("band", "weight"), [
    (-0.1, 0.0), (1.0, 0.0), (1.5, 0.0), (math.nan, 0.0),
    (0.0, -0.1), (0.0, 1.5), (0.0, math.nan), (1.5, 0.5), (0.5, 2.0),
])
def test_shape_stick_refuses_a_dead_zone_or_expo_out_of_range_naming_both(band, weight):
    with pytest.raises(ValueError) as refused:
        shape_stick(0.5, 0.5, 0.5, deadband_width=band, expo_weight=weight)
    assert str(refused.value) == f"deadband {band!r} or expo {weight!r} out of range"


def test_shape_stick_takes_the_ends_of_each_range():
    assert shape_stick(0.5, 0.0, -0.5, expo_weight=1.0) == (0.125, 0.0, -0.125)
    assert shape_stick(0.995, 0.0, 0.0, deadband_width=0.99) == pytest.approx((0.5, 0.0, 0.0))


@pytest.mark.parametrize("number", [float, int, np.float64, np.float32])
def test_a_plain_number_in_gives_a_plain_float_out(number):
    value = number(1) if number is int else number(0.5)
    for shaped in (deadband(value, 0.1), expo(value, 0.3), *square_to_circle(value, value)):
        assert type(shaped) is float
    assert deadband(value, 0.1) == deadband(float(value), 0.1)
    assert expo(value, 0.3) == expo(float(value), 0.3)
    assert square_to_circle(value, value) == square_to_circle(float(value), float(value))


def test_a_plain_number_beside_an_array_gives_arrays():
    x, y = square_to_circle(np.array([3.0, 0.3]), 4.0)
    np.testing.assert_allclose(x, [0.6, 0.3 / math.hypot(0.3, 4.0)])
    np.testing.assert_allclose(y, [0.8, 4.0 / math.hypot(0.3, 4.0)])
    x, y = square_to_circle(0.6, np.array([0.8, 0.0]))
    np.testing.assert_allclose(x, [0.6, 0.6])
    np.testing.assert_allclose(y, [0.8, 0.0])
