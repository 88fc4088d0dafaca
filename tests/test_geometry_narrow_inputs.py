""":func:`~mecanum_mav.mecanum.geometry.pose_exp_array` "returns float64 poses": poses or twists
given in float32 (a log's columns, a GPU's batch) move as their float64 values do, to the
last bit; the narrower type is never the precision of the arithmetic."""

from __future__ import annotations

import numpy as np
import pytest

from mecanum_mav.mecanum.geometry import pose_exp_array, wrap_pi

POSES = np.array([[0.0, 0.0, 0.7], [12.5, -3.25, -2.9], [-1.0, 4.0, 1.3]])
TWISTS = np.array([[1.5, 0.25, 0.4], [0.75, -0.5, -1.1], [2.0, 1.0, 3.0]])


@pytest.mark.parametrize("narrow", ["poses", "twists", "both"])
def test_float32_poses_or_twists_move_as_their_float64_values_do(narrow):
    poses32 = POSES.astype(np.float32) if narrow in ("poses", "both") else POSES
    twists32 = TWISTS.astype(np.float32) if narrow in ("twists", "both") else TWISTS
    got = pose_exp_array(poses32, twists32)
    want = pose_exp_array(poses32.astype(np.float64), twists32.astype(np.float64))
    assert got.dtype == np.float64
    np.testing.assert_array_equal(got, want)


def test_wrap_pi_of_float32_or_integer_angles_is_that_of_their_float64_values():
    """Its docstring: "returns a float64 ndarray of the same shape", wrapped in float64."""
    angles = np.array([[0.5, 4.0, -7.25], [3.0, -3.5, 100.0]])
    for narrow in (angles.astype(np.float32), angles.astype(np.int32)):
        got = wrap_pi(narrow)
        assert got.dtype == np.float64 and got.shape == (2, 3)
        np.testing.assert_array_equal(got, wrap_pi(narrow.astype(np.float64)))
