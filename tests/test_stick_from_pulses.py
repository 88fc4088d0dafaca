"""Pulse widths to a normalized stick (control/sticks.py, ``stick_from_pulses``): RCIN_TRIM is
0, RCIN_MIN and RCIN_MAX are -1 and +1, each side scaled on its own span (a trim off centre),
clamped beyond them; x, y, r in the order given."""

from __future__ import annotations

import pytest

from mecanum_mav.config.views import RcInputConfig
from mecanum_mav.control.sticks import stick_from_pulses

OFF_CENTRE = RcInputConfig(3, 4, 1, min_us=1000, trim_us=1400, max_us=2000)
"""400 us below the trim, 600 above."""


@pytest.mark.parametrize(("pulse", "value"), [
    (1400, 0.0), (2000, 1.0), (1700, 0.5), (1000, -1.0), (1200, -0.5), (1100, -0.75),
    (1999, 599 / 600), (1001, -399 / 400)])
def test_each_side_of_the_trim_is_scaled_on_its_own_span(pulse: int, value: float) -> None:
    assert stick_from_pulses(pulse, 1400, 1400, OFF_CENTRE) == pytest.approx((value, 0.0, 0.0))


@pytest.mark.parametrize(("pulse", "value"), [(2200, 1.0), (2600, 1.0), (800, -1.0),
                                               (500, -1.0), (0, -1.0)])
def test_a_pulse_beyond_min_or_max_is_full_deflection(pulse: int, value: float) -> None:
    assert stick_from_pulses(1400, pulse, 1400, OFF_CENTRE) == (0.0, value, 0.0)


def test_the_three_pulses_are_x_y_r_in_order() -> None:
    assert stick_from_pulses(2000, 1000, 1700, OFF_CENTRE) == (1.0, -1.0, 0.5)
