"""Issue 26: the companion copes with a flight controller whose heading is degrees off. The
simulated board reports its yaw ``SIM_YAW_BIAS`` off and its true position in
LOCAL_POSITION_NED (``SIM_POS_RATE``); the bench's 3 m square at 1.0 m/s in the lockstep
harness (virtual time, the same figures every run), judged against the truth."""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))

import bench_control
from conftest import lockstep

from mecanum_mav.control.fclink import FC_POSITION_INTERVAL_US
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.trackquality import RunFigures

GOALS = bench_control.GOALS


def square(bias_deg: float, estimate: int, position_hz: float = 10.0) -> RunFigures:
    row = bench_control.run_mission("square", 1.0, overrides=[
        ("SIM_YAW_BIAS", bias_deg), ("SIM_POS_RATE", position_hz), ("ODOM_YAW_BIAS", estimate)])
    assert row.failure is None, row.failure
    return row.fig


def test_a_heading_2_5_deg_off_meets_the_square_arrival_and_heading_goals_only_when_estimated():
    on = square(2.5, 1)
    assert on.worst_arrival_m < GOALS.arrival_m, on
    assert on.worst_heading_deg < GOALS.heading_deg, on
    off = square(2.5, 0)
    assert off.worst_arrival_m > 5 * GOALS.arrival_m, off  # 19 cm: 2.5 degrees over 4.2 m
    assert off.worst_heading_deg > 2.0, off


def test_a_heading_3_degrees_off_the_other_way_is_corrected_as_well():
    on = square(-3.0, 1, position_hz=5.0)  # a 5 Hz GPS
    assert on.worst_arrival_m < GOALS.arrival_m and on.worst_heading_deg < GOALS.heading_deg, on


def test_a_board_without_a_position_drives_exactly_as_without_the_estimator():
    assert square(2.5, 1, position_hz=0.0) == square(2.5, 0, position_hz=0.0)


def test_the_companion_asks_the_flight_controller_for_its_position_at_10_hz():
    h = lockstep()
    h.run_for(1.5)
    asked = {int(m.param1): m.param2 for m in h.fc_received if m.get_type() == "COMMAND_LONG"
             and m.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL}
    assert asked[mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED] == FC_POSITION_INTERVAL_US == 100_000
    assert asked[mavlink.MAVLINK_MSG_ID_GPS_RAW_INT] == FC_POSITION_INTERVAL_US


def test_gps_fixes_without_an_rtk_fix_are_not_a_track():
    """Each new RTK fix (float or fixed) reaches the estimator once, about the first one; an
    ordinary 3D fix (a metre of error over half-metre windows), a 2D fix or none, and a fix
    repeated (GPS_RAW_INT asked faster than the GPS's 5 Hz) do not."""
    fc = lockstep().core._fc
    seen: list[tuple[float, float]] = []
    fc.estimator = SimpleNamespace(on_gps=lambda n, e, now_s: seen.append((n, e)))
    fc.on_gps(gps_fix(2, 0.0, 1), 1.0)
    fc.on_gps(gps_fix(3, 3.0, 2), 1.05)  # a 3D fix, no RTK
    fc.on_gps(gps_fix(5, 0.0, 3), 1.1)  # RTK float
    fc.on_gps(gps_fix(5, 0.0, 3), 1.2)  # the same fix again
    fc.on_gps(gps_fix(1, 5.0, 4), 1.3)
    fc.on_gps(gps_fix(6, 1.0, 5), 1.4)  # RTK fixed
    assert [(round(n, 2), round(e, 2)) for n, e in seen] == [(0.0, 0.0), (1.0, 0.0)]


def test_an_rtk_fix_not_on_earth_is_ignored_and_the_next_good_one_is_the_first():
    """(A GPS_RAW_INT whose latitude or longitude is out of range: no origin is made of it,
    nothing reaches the estimator, and the first good fix becomes the origin.)"""
    fc = lockstep().core._fc
    seen: list[tuple[float, float]] = []
    fc.estimator = SimpleNamespace(on_gps=lambda n, e, now_s: seen.append((n, e)))
    for time_usec, (lat, lon) in enumerate([(91 * 10**7, 0), (0, 181 * 10**7)], start=1):
        fc.on_gps(SimpleNamespace(fix_type=6, time_usec=time_usec, lat=lat, lon=lon), 1.0)
    assert seen == []
    fc.on_gps(gps_fix(6, 2.0, 10), 1.1)
    fc.on_gps(gps_fix(6, 3.0, 11), 1.2)
    assert seen[0] == (0.0, 0.0)  # the first good fix: the origin
    assert seen[1] == pytest.approx((1.0, 0.0), abs=0.02)  # (1e-7 degrees: about 1.1 cm)


def gps_fix(fix_type: int, north_m: float, time_usec: int) -> Any:
    """A GPS_RAW_INT ``north_m`` north of a point in Canberra (SITL's home)."""
    lat_e7, lon_e7 = GlobalOrigin(-353632622, 1491652373).to_global(north_m, 0.0)
    return SimpleNamespace(fix_type=fix_type, time_usec=time_usec, lat=lat_e7, lon=lon_e7)
