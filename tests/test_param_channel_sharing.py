"""Two outputs on one RC channel are refused (config/params.py's DistinctChannels rule)."""

from __future__ import annotations

import pytest

from mecanum_mav.config.params import ParamError, Params
from mecanum_mav.io.paramfile import ParamFileError, parse_text


def test_two_wheels_on_one_channel_are_refused_in_a_file():
    with pytest.raises(ParamFileError, match="MOT_FR_CH and MOT_RR_CH share RC channel 2"):
        parse_text("MOT_RR_CH 2\n", "two.parm")


def test_two_wheels_on_one_channel_are_refused_when_set():
    params = Params()
    with pytest.raises(ParamError, match="share RC channel"):
        params.update({"MOT_RR_CH": int(params["MOT_FR_CH"])})
    assert params["MOT_RR_CH"] != params["MOT_FR_CH"]
