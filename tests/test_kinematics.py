"""Mecanum kinematics: WPILib parity, FRD sign sanity, properties and edge cases.

WPILib's MecanumDriveKinematicsTest works in NWU (x forward, y LEFT, omega
counter-clockwise). This project works in FRD (x forward, y RIGHT, yaw rate clockwise).
Every chassis quantity taken from WPILib (vy, omega, a centre of rotation's y, a wheel
position's y) is converted with y -> -y and omega -> -omega before use; wheel speeds are
the same in both frames (positive rolls the robot forward), so they are used as published.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mecanum_mav.mecanum.geometry import Twist2d
from mecanum_mav.mecanum.kinematics import MecanumKinematics

WPILIB_TOLERANCE = 0.1


def nwu_to_frd(vx: float, vy: float, omega: float) -> tuple[float, float, float]:
    """WPILib chassis (x fwd, y left, CCW+) -> this project's FRD (x fwd, y right, CW+)."""
    return vx, -vy, -omega


def wpilib_kinematics() -> MecanumKinematics:
    """WPILib's test robot: NWU fl=(12,12), fr=(12,-12), bl=(-12,12), br=(-12,-12), in FRD."""
    return MecanumKinematics((12.0, -12.0), (12.0, 12.0), (-12.0, -12.0), (-12.0, 12.0))


KIN = wpilib_kinematics()

ROBOT_CENTRE = (0.0, 0.0)
WPILIB_FL_FRD = (12.0, -12.0)  # WPILib's front-left wheel (12, 12) NWU as a FRD centre.

# (WPILib NWU ChassisSpeeds, FRD centre of rotation, wheel speeds FL, FR, RL, RR).
WPILIB_INVERSE = [
    ((5.0, 0.0, 0.0), ROBOT_CENTRE, (5.0, 5.0, 5.0, 5.0)),
    ((0.0, 4.0, 0.0), ROBOT_CENTRE, (-4.0, 4.0, 4.0, -4.0)),
    ((0.0, 0.0, 2.0 * math.pi), ROBOT_CENTRE, (-150.79645, 150.79645, -150.79645, 150.79645)),
    ((2.0, 3.0, 1.0), ROBOT_CENTRE, (-25.0, 29.0, -19.0, 23.0)),
    # Off-centre: rotating about WPILib's front-left wheel.
    ((0.0, 0.0, 1.0), WPILIB_FL_FRD, (0.0, 24.0, -24.0, 48.0)),
    ((5.0, 2.0, 1.0), WPILIB_FL_FRD, (3.0, 31.0, -17.0, 51.0)),
]

# (wheel speeds, WPILib NWU chassis result (vx, vy, omega) of the robot centre).
WPILIB_FORWARD = [
    ((3.536, 3.536, 3.536, 3.536), (3.536, 0.0, 0.0)),
    ((-2.828427, 2.828427, 2.828427, -2.828427), (0.0, 2.8284, 0.0)),
    ((-150.79645, 150.79645, -150.79645, 150.79645), (0.0, 0.0, 2.0 * math.pi)),
    ((-17.677670, 20.51, -13.44, 16.26), (1.413, 2.122, 0.707)),
    ((0.0, 16.971, -16.971, 33.941), (8.48525, -8.48525, 0.707)),
    ((2.12, 21.92, -12.02, 36.06), (12.02, -7.07, 0.707)),
]

INVERSE_METHODS = ["to_wheel_speeds", "to_wheel_accelerations"]
FORWARD_METHODS = ["to_chassis_speeds", "to_chassis_accelerations", "to_twist"]


@pytest.mark.parametrize("method", INVERSE_METHODS)
@pytest.mark.parametrize(("chassis_nwu", "centre_frd", "wheels"), WPILIB_INVERSE)
def test_inverse_kinematics_matches_wpilib_published_values(
    method, chassis_nwu, centre_frd, wheels
):
    vx, vy, yaw_rate = nwu_to_frd(*chassis_nwu)
    result = getattr(KIN, method)(vx, vy, yaw_rate, centre_frd)
    np.testing.assert_allclose(result, wheels, atol=WPILIB_TOLERANCE)


@pytest.mark.parametrize("method", FORWARD_METHODS)
@pytest.mark.parametrize(("wheels", "chassis_nwu"), WPILIB_FORWARD)
def test_forward_kinematics_matches_wpilib_published_values(method, wheels, chassis_nwu):
    result = getattr(KIN, method)(wheels)
    np.testing.assert_allclose(tuple(result), nwu_to_frd(*chassis_nwu), atol=WPILIB_TOLERANCE)


# --- Signs in FRD words --------------------------------------------------------------

SQUARE = MecanumKinematics.from_half_extents(0.2, 0.15)


def test_from_half_extents_places_wheels_on_the_frd_rectangle():
    assert SQUARE.positions == ((0.2, -0.15), (0.2, 0.15), (-0.2, -0.15), (-0.2, 0.15))


def test_driving_forward_spins_every_wheel_forward_at_the_body_speed():
    np.testing.assert_allclose(SQUARE.to_wheel_speeds(1.5, 0.0, 0.0), [1.5] * 4)


def test_pure_strafe_right_spins_front_left_and_rear_right_forward_the_others_backward():
    fl, fr, rl, rr = SQUARE.to_wheel_speeds(0.0, 1.0, 0.0)
    assert fl > 0 and rr > 0
    assert fr < 0 and rl < 0


def test_clockwise_rotation_spins_left_wheels_forward_and_right_wheels_backward():
    fl, fr, rl, rr = SQUARE.to_wheel_speeds(0.0, 0.0, 1.0)
    assert fl > 0 and rl > 0
    assert fr < 0 and rr < 0
    # Each wheel's rim speed is w * (L + W) for the rectangle.
    np.testing.assert_allclose([fl, fr, rl, rr], [0.35, -0.35, 0.35, -0.35])


def test_forward_kinematics_reads_a_strafe_right_as_positive_vy():
    vx, vy, yaw_rate = SQUARE.to_chassis_speeds([1.0, -1.0, -1.0, 1.0])
    assert vx == pytest.approx(0.0, abs=1e-12)
    assert vy == pytest.approx(1.0)
    assert yaw_rate == pytest.approx(0.0, abs=1e-12)


# --- Properties ----------------------------------------------------------------------

coord = st.floats(0.05, 1.0)
velocity = st.floats(-5.0, 5.0)
yaw_rate_st = st.floats(-10.0, 10.0)
centre_coord = st.floats(-2.0, 2.0)


@st.composite
def geometries(draw: st.DrawFn) -> MecanumKinematics:
    """Any wheel layout with each wheel in its own quadrant (non-square, asymmetric)."""
    return MecanumKinematics(
        (draw(coord), -draw(coord)),
        (draw(coord), draw(coord)),
        (-draw(coord), -draw(coord)),
        (-draw(coord), draw(coord)),
    )


@given(geometries(), velocity, velocity, yaw_rate_st, centre_coord, centre_coord)
def test_forward_after_inverse_gives_back_the_robot_centre_velocity(kin, vx, vy, w, cx, cy):
    # (vx, vy) is the velocity of the centre of rotation c; the robot centre sits at -c
    # from it, so it moves at (vx - w*(-cy), vy + w*(-cx)) = (vx + w*cy, vy - w*cx).
    wheels = kin.to_wheel_speeds(vx, vy, w, (cx, cy))
    np.testing.assert_allclose(
        kin.to_chassis_speeds(wheels), (vx + w * cy, vy - w * cx, w), rtol=1e-9, atol=1e-9
    )


@given(geometries(), velocity, velocity, yaw_rate_st)
def test_forward_after_inverse_is_identity_about_the_robot_centre(kin, vx, vy, w):
    np.testing.assert_allclose(
        kin.to_chassis_speeds(kin.to_wheel_speeds(vx, vy, w)), (vx, vy, w), atol=1e-9
    )
    twist = kin.to_twist(kin.to_wheel_speeds(vx, vy, w))
    assert isinstance(twist, Twist2d)
    np.testing.assert_allclose(twist, (vx, vy, w), atol=1e-9)


@given(geometries(), velocity, velocity, yaw_rate_st, centre_coord, centre_coord)
def test_scalar_fast_path_equals_the_array_path(kin, vx, vy, w, cx, cy):
    scalar = kin.to_wheel_speeds(vx, vy, w, (cx, cy))
    array = kin.to_wheel_speeds(np.array(vx), np.array([vy]), w, np.array([cx, cy]))
    assert scalar.shape == (4,)
    assert array.shape == (1, 4)
    np.testing.assert_allclose(scalar, array[0], rtol=1e-12, atol=1e-12)
    wheels = tuple(scalar.tolist())
    np.testing.assert_allclose(
        kin.to_chassis_speeds(wheels), kin.to_chassis_speeds(np.array(wheels)), atol=1e-12
    )


@given(geometries(), yaw_rate_st)
def test_rotation_about_a_wheel_leaves_that_wheel_still(kin, w):
    wheels = kin.to_wheel_speeds(0.0, 0.0, w, kin.positions[0])
    assert wheels[0] == pytest.approx(0.0, abs=1e-12)


def test_inputs_broadcast_to_a_batch_of_wheel_speeds():
    vx = np.linspace(-1.0, 1.0, 5)[:, None]  # (5, 1)
    vy = np.array([0.0, 0.5, -0.5])  # (3,)
    centres = np.zeros((5, 1, 2))
    wheels = SQUARE.to_wheel_speeds(vx, vy, 0.25, centres)
    assert wheels.shape == (5, 3, 4)
    for i in range(5):
        for j in range(3):
            expected = SQUARE.to_wheel_speeds(float(vx[i, 0]), float(vy[j]), 0.25)
            np.testing.assert_allclose(wheels[i, j], expected, atol=1e-12)
    assert SQUARE.to_chassis_speeds(wheels).shape == (5, 3, 3)
    assert SQUARE.to_chassis_accelerations(wheels).shape == (5, 3, 3)


def test_a_batch_of_wheel_deltas_gives_an_array_of_twists_and_one_set_gives_a_twist2d():
    deltas = np.array([[0.1, 0.1, 0.1, 0.1], [0.1, -0.1, -0.1, 0.1]])
    twists = SQUARE.to_twist(deltas)
    assert isinstance(twists, np.ndarray)
    assert twists.shape == (2, 3)
    np.testing.assert_allclose(twists, [[0.1, 0.0, 0.0], [0.0, 0.1, 0.0]], atol=1e-12)
    single = SQUARE.to_twist(deltas[1])
    assert isinstance(single, Twist2d)
    assert single == pytest.approx((0.0, 0.1, 0.0), abs=1e-12)
    assert isinstance(SQUARE.to_twist(deltas.tolist()), np.ndarray)
    assert isinstance(SQUARE.to_twist(tuple(deltas[0].tolist())), Twist2d)


def test_scalar_inverse_returns_a_float64_array_of_four():
    wheels = SQUARE.to_wheel_speeds(1, 0, 0)
    assert isinstance(wheels, np.ndarray)
    assert wheels.dtype == np.float64
    assert wheels.shape == (4,)


def test_matrix_and_pseudo_inverse_are_copies_that_invert_each_other():
    m = SQUARE.matrix
    np.testing.assert_allclose(SQUARE.pseudo_inverse @ m, np.eye(3), atol=1e-12)
    m[:] = 0.0
    assert SQUARE.matrix.any()


# --- Non-finite input and bad construction -------------------------------------------


@pytest.mark.parametrize("number", [float, np.float64, np.float32])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("where", range(5))
def test_a_non_finite_command_component_stops_every_wheel(number, bad, where):
    args = [0.5, -0.3, 0.2, 0.1, -0.1]
    args[where] = bad
    vx, vy, w, cx, cy = (number(v) for v in args)
    wheels = SQUARE.to_wheel_speeds(vx, vy, w, (cx, cy))
    assert wheels.tolist() == [0.0, 0.0, 0.0, 0.0]
    accels = SQUARE.to_wheel_accelerations(vx, vy, w, (cx, cy))
    assert accels.tolist() == [0.0, 0.0, 0.0, 0.0]


def test_a_non_finite_command_in_a_batch_stops_only_its_own_row():
    vx = np.array([1.0, math.nan, 1.0, 1.0])
    w = np.array([0.0, 0.0, math.inf, 0.0])
    wheels = SQUARE.to_wheel_speeds(vx, 0.0, w)
    assert np.isfinite(wheels).all()
    np.testing.assert_allclose(wheels, [[1.0] * 4, [0.0] * 4, [0.0] * 4, [1.0] * 4])


def test_a_command_so_large_that_a_wheel_speed_overflows_stops_every_wheel():
    assert SQUARE.to_wheel_speeds(1e308, 1e308, 0.0).tolist() == [0.0] * 4
    assert SQUARE.to_wheel_speeds(np.array([1e308]), 1e308, 0.0).tolist() == [[0.0] * 4]


@pytest.mark.parametrize("method", FORWARD_METHODS)
@pytest.mark.parametrize("bad", [math.nan, math.inf])
@pytest.mark.parametrize(
    "container",
    [list, tuple, np.array, lambda v: np.array([v, v]), lambda v: tuple(np.float64(x) for x in v)],
)
def test_forward_kinematics_rejects_non_finite_wheel_values(method, bad, container):
    with pytest.raises(ValueError, match="non-finite wheel"):
        getattr(SQUARE, method)(container([1.0, bad, 1.0, 1.0]))


@pytest.mark.parametrize("method", FORWARD_METHODS)
def test_forward_kinematics_rejects_a_wheel_axis_that_is_not_four_long(method):
    with pytest.raises(ValueError, match="length 4"):
        getattr(SQUARE, method)([1.0, 1.0, 1.0])


def test_a_centre_of_rotation_that_is_not_an_xy_pair_is_rejected():
    with pytest.raises(ValueError, match="center_of_rotation"):
        SQUARE.to_wheel_speeds(1.0, 0.0, 0.0, (1.0, 2.0, 3.0))


def test_non_finite_wheel_positions_are_rejected():
    with pytest.raises(ValueError, match="non-finite"):
        MecanumKinematics((0.2, -0.2), (0.2, math.nan), (-0.2, -0.2), (-0.2, 0.2))


def test_wheel_positions_that_cannot_resolve_rotation_are_rejected():
    # All four contact points at the centre: rotation leaves every wheel still.
    with pytest.raises(ValueError, match="rank"):
        MecanumKinematics((0.0, 0.0), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0))
    # Any single shared point: rotation then looks like a mix of forward and strafe.
    with pytest.raises(ValueError, match="rank"):
        MecanumKinematics((0.1, 0.3), (0.1, 0.3), (0.1, 0.3), (0.1, 0.3))


def test_a_wheel_position_that_is_not_an_xy_pair_is_rejected():
    with pytest.raises(ValueError, match="pair"):
        MecanumKinematics((0.2, -0.2, 0.0), (0.2, 0.2, 0.0), (-0.2, -0.2, 0.0), (-0.2, 0.2, 0.0))


_any_float = st.one_of(st.floats(-5, 5), st.floats(allow_nan=True, allow_infinity=True))


@given(_any_float, _any_float, _any_float, st.tuples(st.floats(-1, 1), st.floats(-1, 1)))
def test_plain_wheel_speeds_give_the_array_paths_numbers(vx, vy, w, centre):
    kin = MecanumKinematics.from_half_extents(0.2, 0.15)
    got = kin.wheel_speeds(vx, vy, w, centre)
    assert type(got) is tuple and all(type(v) is float for v in got)
    with np.errstate(all="ignore"):
        expected = kin._to_wheels_array(vx, vy, w, centre)
    if not np.all(np.isfinite(expected)):
        expected = np.zeros(4)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)
    assert got == tuple(kin.to_wheel_speeds(vx, vy, w, centre).tolist())


@given(st.lists(st.floats(-2, 2), min_size=4, max_size=4))
def test_plain_twist_from_wheel_deltas_equals_the_array_fit(deltas):
    kin = MecanumKinematics.from_half_extents(0.2, 0.15)
    twist = kin.to_twist(deltas)
    assert isinstance(twist, Twist2d)
    expected = kin.to_twist(np.array(deltas).reshape(1, 4))[0]
    np.testing.assert_allclose(tuple(twist), expected, rtol=1e-12, atol=1e-15)


# ------------------------------------------------------------ what the docstrings promise


def test_the_repr_rebuilds_an_equal_kinematics_with_its_strafe_efficiency_when_not_1():
    """``__repr__``: constructor-style, the wheel positions in metres."""
    for kin in (MecanumKinematics.from_half_extents(0.2, 0.15),
                MecanumKinematics.from_half_extents(0.3, 0.25, strafe_efficiency=0.8)):
        text = repr(kin)
        rebuilt = eval(text, {"MecanumKinematics": MecanumKinematics})
        assert rebuilt.positions == kin.positions
        assert rebuilt.strafe_efficiency == kin.strafe_efficiency
        assert ("strafe_efficiency" in text) == (kin.strafe_efficiency != 1.0)


@pytest.mark.parametrize(("method", "what"), [("to_chassis_speeds", "speeds"),
                                              ("to_chassis_accelerations", "accelerations"),
                                              ("to_twist", "deltas")])
def test_a_forward_kinematics_error_names_the_quantity_it_was_given(method, what):
    """Each forward method's ValueError says which wheel quantity was wrong (docstrings)."""
    kin = MecanumKinematics.from_half_extents(0.2, 0.15)
    with pytest.raises(ValueError, match=f"^non-finite wheel {what}"):
        getattr(kin, method)([0.1, math.nan, 0.0, 0.0])
    with pytest.raises(ValueError, match=f"^wheel {what} need a last axis of length 4"):
        getattr(kin, method)(np.zeros((2, 3)))


def test_wheel_and_chassis_quantities_come_back_in_float64_whatever_the_input_dtype():
    """float32 sensor readings and integer commands are computed in float64: a float32
    result would round each speed to 7 digits."""
    kin = MecanumKinematics.from_half_extents(0.2, 0.15)
    wheels32 = np.array([[0.1, 0.2, 0.3, 0.4]], dtype=np.float32)
    chassis = kin.to_chassis_speeds(wheels32)
    assert chassis.dtype == np.float64
    np.testing.assert_array_equal(chassis, wheels32.astype(np.float64) @ kin.pseudo_inverse.T)
    speeds = kin.to_wheel_speeds(np.array([1], dtype=np.int64), np.array([0], dtype=np.int64),
                                 np.array([1], dtype=np.int64),
                                 np.array([0.1, 0.0], dtype=np.float32))
    assert speeds.dtype == np.float64
    centre_x = float(np.float32(0.1))  # the float32 value, computed in float64
    np.testing.assert_allclose(speeds, kin.to_wheel_speeds(1.0, 0.0, 1.0, (centre_x, 0.0))[None],
                               rtol=0, atol=1e-12)
