"""The wheel output at its edges: each wheel's own trim is neutral on the wire, and a mix that
overflows stops the wheels instead of sending NaN (control/pwm.py, mecanum/mixing.py)."""

from __future__ import annotations

import math

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.control.core import RoverCore
from mecanum_mav.mecanum.mixing import Desaturation, desaturate_prioritized_scalar
from mecanum_mav.protocol.rcoverride import override_fields

TRIMS = {"MOT_FL_TRIM": 1490, "MOT_FR_TRIM": 1505, "MOT_RL_TRIM": 1510, "MOT_RR_TRIM": 1520}


def test_neutral_on_the_wire_is_each_wheels_own_off_centre_trim():
    params = Params()
    params.update(TRIMS)
    core = RoverCore(params, now_s=0.0)
    override = core.tick(0.0).override
    assert override is not None  # disarmed: neutral, at once
    assert override.channels == override_fields((1, 2, 3, 4), list(TRIMS.values()))
    assert [o.channels for o in core.shutdown()[:2]] == [override.channels] * 2


@pytest.mark.parametrize("priority", list(Desaturation))
def test_a_mix_whose_sum_overflows_stops_the_wheels(priority):
    huge = (1e308, -1e308, 1e308, -1e308)
    wheels = desaturate_prioritized_scalar(huge, huge, priority)
    assert all(math.isfinite(w) for w in wheels)
    if priority is Desaturation.PROPORTIONAL:
        assert wheels == (0.0, 0.0, 0.0, 0.0)
