"""The sanity limits on what a message may ask: one module, both users, messages unchanged."""

from __future__ import annotations

import math

import pytest

from mecanum_mav.control.guided import SetpointError, decode_setpoint
from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.protocol import limits
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import MissionItem, MissionItemError, check_item

HERE = Pose2d(0.0, 0.0, 0.0)
IGNORE_ALL_BUT_VEL = 1 | 2 | 4 | 64 | 128 | 256 | 1024 | 2048
IGNORE_ALL_BUT_POS = 8 | 16 | 32 | 64 | 128 | 256 | 1024 | 2048
IGNORE_ALL_BUT_RATE = 1 | 2 | 4 | 8 | 16 | 32 | 64 | 128 | 256 | 1024


def test_values_and_units():
    assert limits.MAX_SPEED_MPS == 50.0
    assert limits.MAX_SETPOINT_POSITION_M == 10_000.0
    assert limits.MAX_SETPOINT_YAW_RATE_RADPS == 20.0
    assert limits.MAX_MISSION_LOCAL_M == 100_000.0
    assert limits.MAX_MISSION_YAW_RATE_DPS == 3600.0
    assert limits.MAX_MISSION_HOLD_S == 86_400.0
    assert limits.MAX_MISSION_RADIUS_M == 1000.0


def setpoint(mask: int, **fields: float):
    f = {"x": 0.0, "y": 0.0, "vx": 0.0, "vy": 0.0, "yaw": 0.0, "yaw_rate": 0.0, **fields}
    return decode_setpoint(1, mask, f["x"], f["y"], f["vx"], f["vy"], f["yaw"], f["yaw_rate"],
                           HERE, 0.0)


def test_guided_setpoints_stop_at_the_limits():
    speed, far = limits.MAX_SPEED_MPS, limits.MAX_SETPOINT_POSITION_M
    rate = limits.MAX_SETPOINT_YAW_RATE_RADPS
    assert setpoint(IGNORE_ALL_BUT_VEL, vx=speed).velocity_ned == (speed, 0.0)
    with pytest.raises(SetpointError, match="velocity absurd"):
        setpoint(IGNORE_ALL_BUT_VEL, vx=speed * 0.8, vy=speed * 0.8)
    assert setpoint(IGNORE_ALL_BUT_POS, x=far).position_ned == (far, 0.0)
    with pytest.raises(SetpointError, match="position absurd"):
        setpoint(IGNORE_ALL_BUT_POS, x=math.nextafter(far, math.inf))
    assert setpoint(IGNORE_ALL_BUT_RATE, yaw_rate=-rate).yaw_rate == -rate
    with pytest.raises(SetpointError, match="yaw rate"):
        setpoint(IGNORE_ALL_BUT_RATE, yaw_rate=math.nextafter(rate, math.inf))


def refusal(**item: float) -> str:
    with pytest.raises(MissionItemError) as info:
        check_item(MissionItem(seq=1, **item), count=3)
    return str(info.value)


def test_mission_messages_name_the_limits_as_before():
    wp, local = mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_LOCAL_NED
    too_far = int(limits.MAX_MISSION_LOCAL_M * 1e4) + 1
    assert refusal(frame=local, command=wp, x=too_far) == "item 1: x beyond 100 km"
    assert refusal(frame=local, command=wp, y=-too_far) == "item 1: y beyond 100 km"
    assert refusal(frame=local, command=wp, param1=86_401.0) == (
        "item 1: time must be 0 .. 86400 s")
    assert refusal(frame=local, command=wp, param2=1000.5) == (
        "item 1: radius must be 0 .. 1000 m")
    assert refusal(frame=local, command=mavlink.MAV_CMD_DO_CHANGE_SPEED, param2=50.5) == (
        "item 1: speed must be 0 .. 50 m/s")
    assert refusal(frame=local, command=mavlink.MAV_CMD_CONDITION_YAW, param2=3600.5) == (
        "item 1: yaw rate must be >= 0 deg/s")


def test_mission_items_at_the_limits_pass():
    wp, local = mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_FRAME_LOCAL_NED
    edge = int(limits.MAX_MISSION_LOCAL_M * 1e4)
    check_item(MissionItem(seq=1, frame=local, command=wp, x=edge, y=-edge,
                           param1=limits.MAX_MISSION_HOLD_S, param2=limits.MAX_MISSION_RADIUS_M),
               count=3)
    check_item(MissionItem(seq=1, frame=local, command=mavlink.MAV_CMD_DO_CHANGE_SPEED,
                           param2=limits.MAX_SPEED_MPS), count=3)
    check_item(MissionItem(seq=1, frame=local, command=mavlink.MAV_CMD_CONDITION_YAW,
                           param2=limits.MAX_MISSION_YAW_RATE_DPS), count=3)
