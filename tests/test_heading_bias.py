"""Issue 26: the companion copes with a flight controller whose heading is degrees off. The
simulated board reports its yaw ``SIM_YAW_BIAS`` off and its true position in
LOCAL_POSITION_NED (``SIM_POS_RATE``); the bench's 3 m square at 1.0 m/s in the lockstep
harness (virtual time, the same figures every run), judged against the truth."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))

import bench_control
from conftest import lockstep

from mecanum_mav.control.fclink import FC_POSITION_INTERVAL_US
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
    asked = [m for m in h.fc_received if m.get_type() == "COMMAND_LONG"
             and m.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL
             and int(m.param1) == mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED]
    assert [m.param2 for m in asked] == [FC_POSITION_INTERVAL_US] == [100_000]
