"""Rover mode numbers: ArduPilot Rover's custom_mode, as the dialect defines them."""

from __future__ import annotations

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.modes import Mode


def test_mode_numbers_are_ardupilot_rovers():
    assert [(m.name, int(m)) for m in Mode] == [
        ("MANUAL", 0), ("HOLD", 4), ("AUTO", 10), ("GUIDED", 15)]


def test_mode_numbers_match_the_dialects_rover_mode_enum():
    for mode in Mode:
        assert int(mode) == getattr(mavlink, f"ROVER_MODE_{mode.name}")
