"""The 2010 algorithm's non-clipping limit (mecanum/envelope.py) for headings and rotations
given as float32: the float64 result of the same values, where the limit lies
strictly between 0 and 1 (a limit capped at 1, or 0 at full rotation, would hide a float32
computation)."""

from __future__ import annotations

import numpy as np

from mecanum_mav.mecanum.envelope import non_clipping_limit_2010


def test_float32_headings_and_rotations_give_the_float64_limit_of_their_values():
    heading = np.array([45.0, 30.0, 60.0, -135.0, 10.0], dtype=np.float32)
    rotation = np.array([0.29, 0.1, -0.6, 0.45, 0.3], dtype=np.float32)
    want = non_clipping_limit_2010(heading.astype(np.float64), rotation.astype(np.float64))
    assert np.all((want > 0.0) & (want < 1.0))
    for h, r in ((heading, rotation.astype(np.float64)), (heading.astype(np.float64), rotation),
                 (heading, rotation)):
        got = non_clipping_limit_2010(h, r)
        assert got.dtype == np.float64
        np.testing.assert_array_equal(got, want)

