"""The sample drive's mission (mecanum_mav/sim/sampledrive.py's :func:`square_mission`): home,
then a square of the side given from the origin, clockwise, its corners waypoints with no
heading of their own (MAV_CMD_NAV_WAYPOINT's param4 yaw NaN: the vehicle's own heading mode,
MAVLink's common.xml)."""

from __future__ import annotations

import math

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import float_xy
from mecanum_mav.sim.sampledrive import square_mission


def test_the_sample_square_is_home_then_four_corners_clockwise_from_the_origin():
    items = square_mission(2.5)
    assert [it.seq for it in items] == [0, 1, 2, 3, 4]
    assert all(it.command == mavlink.MAV_CMD_NAV_WAYPOINT for it in items)
    assert all(it.frame == mavlink.MAV_FRAME_LOCAL_NED for it in items)
    # north, then east, then back south and west to the origin (north up: clockwise)
    assert [float_xy(it) for it in items[1:]] == [(2.5, 0.0), (2.5, 2.5), (0.0, 2.5),
                                                  (0.0, 0.0)]


def test_the_sample_squares_corners_ask_for_no_heading():
    assert all(math.isnan(it.param4) for it in square_mission(1.5)[1:])
