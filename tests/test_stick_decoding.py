"""Decoding a pilot's MANUAL_CONTROL (control/sticks.py): strict, never clamped into motion."""

from __future__ import annotations

import pytest

from mecanum_mav.control.sticks import InputError, stick_from_manual_control


@pytest.mark.parametrize("z", [-1, -500, -1000, 1001])
def test_with_z_scaling_a_z_outside_0_to_1000_is_refused_never_reversing_the_stick(z):
    with pytest.raises(InputError, match=f"z={z} not in 0..1000"):
        stick_from_manual_control(500, 0, 0, z, z_scale=True)


def test_with_z_scaling_z_scales_the_whole_stick_and_without_it_z_is_ignored():
    assert stick_from_manual_control(500, -1000, 200, 500, z_scale=True) == (0.25, -0.5, 0.1)
    assert stick_from_manual_control(500, -1000, 200, -500, z_scale=False) == (0.5, -1.0, 0.2)
