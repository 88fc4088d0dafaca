"""One definition of the wheel order and the "X" roller signs, and every user agrees with it.

The mixers and the kinematics keep closed forms on their fast paths (plain arithmetic, no
tables); these tests hold those closed forms to :mod:`mecanum_mav.mecanum.wheels`.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import mecanum_mav
from mecanum_mav import kinematics, mixing, pwm
from mecanum_mav.config import params
from mecanum_mav.mecanum import wheels
from mecanum_mav.mecanum.kinematics import MecanumKinematics

axis = st.floats(-1.0, 1.0, allow_nan=False)


def pattern(x: float, y: float, r: float) -> list[float]:
    """Wheel commands FL, FR, RL, RR from the sign tables: x + s*y + q*r."""
    return [x + s * y + q * r for s, q in zip(wheels.LATERAL_SIGNS, wheels.ROTATION_SIGNS,
                                              strict=True)]


def test_the_pattern_is_the_conventions_x_arrangement():
    # CONVENTIONS.md: FL = x + y + r, FR = x - y - r, RL = x - y + r, RR = x + y - r.
    assert pattern(1.0, 10.0, 100.0) == [111.0, -109.0, 91.0, -89.0]


def test_documented_names_are_the_one_definition():
    assert mecanum_mav.WHEEL_NAMES is wheels.WHEEL_NAMES
    assert wheels.WHEEL_NAMES == ("front_left", "front_right", "rear_left", "rear_right")
    assert pwm.WHEEL_KEYS is wheels.WHEEL_KEYS
    assert params.WHEELS is wheels.WHEEL_KEYS
    assert kinematics.ROLLER_SIGNS is wheels.LATERAL_SIGNS
    assert mixing.LATERAL_SIGNS.tolist() == list(wheels.LATERAL_SIGNS)
    assert mixing.ROTATION_SIGNS.tolist() == list(wheels.ROTATION_SIGNS)


def test_keys_abbreviate_names_in_the_same_order():
    initials = tuple("".join(w[0] for w in name.split("_")).upper() for name in wheels.WHEEL_NAMES)
    assert initials == wheels.WHEEL_KEYS


def test_rotation_signs_follow_from_roller_signs_and_corners():
    for s, q, (cx, cy) in zip(wheels.LATERAL_SIGNS, wheels.ROTATION_SIGNS, wheels.CORNER_SIGNS,
                              strict=True):
        assert math.copysign(1.0, s * cx - cy) == q


@given(axis, axis, axis)
def test_scalar_mixer_is_the_pattern_below_saturation(x, y, r):
    scale = max(1.0, abs(x) + abs(y) + abs(r))  # no wheel beyond 1: nothing desaturates
    x, y, r = x / scale, y / scale, r / scale
    assert mixing.wheels_from_stick(x, y, r) == pytest.approx(pattern(x, y, r), abs=1e-12)
    assert mixing.cartesian(np.array([x]), y, r)[0].tolist() == pytest.approx(
        pattern(x, y, r), abs=1e-12)


@given(axis, axis, axis, axis)
def test_normalized_forward_kinematics_is_the_least_squares_of_the_pattern(a, b, c, d):
    matrix = np.column_stack((np.ones(4), wheels.LATERAL_SIGNS, wheels.ROTATION_SIGNS))
    expected = np.linalg.lstsq(matrix, [a, b, c, d], rcond=None)[0]
    assert mixing.chassis_from_wheels([a, b, c, d]) == pytest.approx(expected, abs=1e-12)


def test_kinematics_uses_the_corners_and_the_signs():
    k = MecanumKinematics.from_half_extents(0.3, 0.2)
    assert k.positions == tuple((0.3 * sx, 0.2 * sy) for sx, sy in wheels.CORNER_SIGNS)
    m = k.matrix
    assert m[:, 0].tolist() == [1.0] * 4
    assert m[:, 1].tolist() == list(wheels.LATERAL_SIGNS)
    assert (np.sign(m[:, 2]) == wheels.ROTATION_SIGNS).all()
    # The scalar fast path agrees with the matrix.
    assert k.to_wheel_speeds(0.1, 0.2, 0.3).tolist() == pytest.approx(
        (m @ [0.1, 0.2, 0.3]).tolist(), abs=1e-12)
