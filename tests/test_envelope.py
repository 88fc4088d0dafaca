"""The numbers behind seed 000's figures, and the figures themselves."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mecanum_mav.mecanum.envelope import non_clipping_limit_2010, robot_speed, speed_grid
from mecanum_mav.mecanum.mixing import chassis_from_wheels, polar_2011

R2 = math.sqrt(0.5)
HEADINGS = np.linspace(0.0, 360.0, 361)
CARDINALS = np.array([0.0, 90.0, 180.0, 270.0])
DIAGONALS = CARDINALS + 45.0


def test_2010_peaks_at_root_half_in_every_heading():
    _, _, speed = speed_grid("holonomic_2010", 0.0)
    assert speed.max() == pytest.approx(R2)
    np.testing.assert_allclose(robot_speed("holonomic_2010", 1.0, HEADINGS), R2)


def test_2011_reaches_full_speed_on_cardinals_and_root_half_on_diagonals():
    np.testing.assert_allclose(robot_speed("polar_2011", 1.0, CARDINALS), 1.0)
    np.testing.assert_allclose(robot_speed("polar_2011", 1.0, DIAGONALS), R2)


def test_2011_at_half_velocity_matches_2010_at_root_half():
    np.testing.assert_allclose(robot_speed("polar_2011", 0.5, HEADINGS, 0.29),
                               robot_speed("holonomic_2010", R2, HEADINGS, 0.29), atol=1e-12)


def test_2011_rotation_keeps_the_translation_to_rotation_ratio_in_every_heading():
    wheels = polar_2011(1.0, HEADINGS, 0.29)
    chassis = chassis_from_wheels(wheels)
    np.testing.assert_allclose(chassis[:, 2] / np.hypot(chassis[:, 0], chassis[:, 1]), 0.29)


def test_2011_rotation_shrinks_cardinals_more_than_diagonals_unlike_the_seed_says():
    # Seed 000 says the 2011 curve keeps its shape with rotation and is "scaled down equally".
    # The mathematics: at full velocity every wheel set is normalized by (t + 0.29) where t is
    # the translation peak (1 on cardinals, sqrt(2) on diagonals), so the factor is
    # t / (t + 0.29): 0.775 on cardinals, 0.830 on diagonals. The cone below saturation is
    # indeed unchanged (speed = velocity).
    ratio = robot_speed("polar_2011", 1.0, HEADINGS, 0.29) / robot_speed("polar_2011", 1.0,
                                                                         HEADINGS)
    np.testing.assert_allclose(ratio[::90], 1.0 / 1.29)
    np.testing.assert_allclose(ratio[45::90], math.sqrt(2) / (math.sqrt(2) + 0.29))
    np.testing.assert_allclose(robot_speed("polar_2011", 0.5, HEADINGS, 0.29), 0.5)


def test_2010_clipping_dents_the_cone_along_the_cardinals():
    # With rotation 0.29 the 2010 surface is no longer a cone: at full velocity the
    # diagonals fall below the undistorted speed sqrt(2)/2.
    speed = robot_speed("holonomic_2010", 1.0, DIAGONALS, 0.29)
    assert np.all(speed < R2 - 0.05)


def test_2010_non_clipping_limit_is_0_71_on_the_diagonals_for_rotation_0_29():
    np.testing.assert_allclose(non_clipping_limit_2010(DIAGONALS, 0.29), 0.71)
    np.testing.assert_allclose(non_clipping_limit_2010(CARDINALS, 0.29), 1.0)
    # Below the limit nothing clips: 2010 is then exactly linear in velocity.
    limit = non_clipping_limit_2010(HEADINGS, 0.29)
    np.testing.assert_allclose(robot_speed("holonomic_2010", limit, HEADINGS, 0.29), limit * R2)


def test_max_speed_scaled_matches_2011_at_full_velocity_and_is_linear_below():
    np.testing.assert_allclose(robot_speed("max_speed_scaled", 1.0, HEADINGS),
                               robot_speed("polar_2011", 1.0, HEADINGS), atol=1e-12)
    np.testing.assert_allclose(robot_speed("max_speed_scaled", 0.5, HEADINGS),
                               0.5 * robot_speed("max_speed_scaled", 1.0, HEADINGS), atol=1e-12)


def test_cartesian_square_stick_reaches_full_speed_on_cardinals_and_diagonals_alike():
    # A square stick pushed into its corner asks for (1, 1): the pair wheels saturate and the
    # robot makes sqrt(2)/2 along the diagonal, as 2011 does.
    np.testing.assert_allclose(robot_speed("cartesian", 1.0, CARDINALS), 1.0)
    np.testing.assert_allclose(robot_speed("cartesian", 1.0, DIAGONALS), R2)

