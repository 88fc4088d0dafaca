"""Prioritized desaturation's promises about the kept part and the limit
(mecanum/desaturation.py): the kept part is scaled *down* only, never up; a wheel the kept
part already fills takes nothing of the other part; a full turn on the spot fits with
rotation priority; a translation beyond the wheels with translation priority and no rotation
is the translation scaled to fit; and a limit of any number type gives plain floats, the
numbers of the same limit as a float."""

from __future__ import annotations

import numpy as np
import pytest

from mecanum_mav.mecanum.desaturation import (
    Desaturation,
    desaturate_prioritized,
    desaturate_prioritized_scalar,
    mix_pairs,
    normalize,
)

KEPT_FIRST = (Desaturation.ROTATION_PRIORITY, Desaturation.TRANSLATION_PRIORITY)


def parts(priority, kept, other):
    """(translation, rotation) with ``kept`` as the part the priority keeps."""
    return (other, kept) if priority is Desaturation.ROTATION_PRIORITY else (kept, other)


@pytest.mark.parametrize("priority", KEPT_FIRST)
def test_a_kept_part_inside_the_limit_is_not_scaled_up_to_it(priority):
    kept, other = (0.2, -0.2, 0.2, -0.2), (0.5, 0.5, 0.5, 0.5)
    translation, rotation = parts(priority, kept, other)
    want = tuple(t + r for t, r in zip(translation, rotation, strict=True))
    assert desaturate_prioritized_scalar(translation, rotation, priority) == want
    np.testing.assert_array_equal(desaturate_prioritized(translation, rotation, priority), want)


@pytest.mark.parametrize("priority", KEPT_FIRST)
def test_a_kept_part_of_zero_leaves_the_other_part_as_it_is_when_it_fits(priority):
    kept, other = (0.0, 0.0, 0.0, 0.0), (0.5, -0.25, 0.0, 0.75)
    translation, rotation = parts(priority, kept, other)
    assert desaturate_prioritized_scalar(translation, rotation, priority) == other


# A limit at which the kept part scaled to it rounds one ulp above it on its largest wheel
# (2.214764007027597 * (L / 2.214764007027597) > L): the wheel is full, and the other part,
# pushing that wheel the same way, must give way entirely, not come back whole.
ROUNDED_UP_LIMIT = 1.369836973036735


@pytest.mark.parametrize("limit", [1.0, 0.5, ROUNDED_UP_LIMIT])
@pytest.mark.parametrize("priority", KEPT_FIRST)
def test_a_wheel_the_kept_part_fills_takes_nothing_of_the_other_part(priority, limit):
    kept = (2.214764007027597, -2.214764007027597, 2.214764007027597, -2.214764007027597)
    other = (0.5, -0.5, 0.5, -0.5)  # the same way as the kept part on every wheel
    translation, rotation = parts(priority, kept, other)
    kept_alone = desaturate_prioritized_scalar(*parts(priority, kept, (0.0,) * 4), priority,
                                               limit)
    assert desaturate_prioritized_scalar(translation, rotation, priority, limit) == kept_alone
    np.testing.assert_array_equal(
        desaturate_prioritized(translation, rotation, priority, limit), kept_alone)
    assert max(map(abs, kept_alone)) == pytest.approx(limit, rel=1e-15)


@pytest.mark.parametrize("r", [1.0, -1.0])
def test_a_full_turn_on_the_spot_with_rotation_priority_gives_every_wheel_full_rotation(r):
    assert mix_pairs(0.0, 0.0, r, Desaturation.ROTATION_PRIORITY) == (r, -r, r, -r)


def test_translation_priority_without_rotation_scales_a_translation_beyond_the_wheels_to_fit():
    # x = y = 1: the FL/RR pair's translation is 2, the FR/RL pair's 0
    assert mix_pairs(2.0, 0.0, 0.0, Desaturation.TRANSLATION_PRIORITY) == (1.0, 0.0, 0.0, 1.0)
    assert mix_pairs(-1.5, 0.75, 0.0, Desaturation.TRANSLATION_PRIORITY) == (-1.0, 0.5, 0.5,
                                                                             -1.0)


@pytest.mark.parametrize("limit", [np.float32(1.0), np.float64(1.0), 1, np.float32(0.5), 2])
@pytest.mark.parametrize("priority", list(Desaturation))
def test_a_limit_of_any_number_type_gives_plain_floats_the_numbers_of_that_limit_as_a_float(
        limit, priority):
    translation, rotation = (0.9, 0.9, 0.9, 0.9), (0.5, -0.5, 0.5, -0.5)
    got = desaturate_prioritized_scalar(translation, rotation, priority, limit)
    assert all(type(w) is float for w in got)
    assert got == desaturate_prioritized_scalar(translation, rotation, priority, float(limit))


def test_normalize_by_default_brings_wheels_over_1_down_to_a_largest_of_1_and_leaves_the_rest():
    got = normalize(np.array([[2.0, -1.0, 0.5, 0.0], [0.5, -0.25, 0.1, 0.0]]))
    np.testing.assert_array_equal(got, [[1.0, -0.5, 0.25, 0.0], [0.5, -0.25, 0.1, 0.0]])
