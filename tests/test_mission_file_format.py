"""A saved mission is a QGC WPL 110 file as QGroundControl, Mission Planner and MAVProxy write
it (io/missionfile.py): one tab-separated line per item, latitude and longitude in degrees to
7 decimals (1 cm), local x/y in metres to 4 decimals (their MISSION_ITEM_INT resolution),
other frames' x/y as the plain numbers they are; and it loads back to the same items."""

from __future__ import annotations

from pathlib import Path

from mecanum_mav.io.missionfile import load_mission, save_mission
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import MissionItem

WP = mavlink.MAV_CMD_NAV_WAYPOINT
ITEMS = [
    MissionItem(0, mavlink.MAV_FRAME_LOCAL_NED, WP, x=0, y=0),
    MissionItem(1, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, WP, x=473_977_420, y=85_455_941),
    MissionItem(2, mavlink.MAV_FRAME_LOCAL_NED, WP, x=12_345, y=-5_000),
    MissionItem(3, mavlink.MAV_FRAME_MISSION, mavlink.MAV_CMD_DO_CHANGE_SPEED, param2=0.5),
]


def test_a_saved_mission_writes_degrees_to_7_decimals_and_metres_to_4(tmp_path: Path):
    path = tmp_path / "m.waypoints"
    save_mission(ITEMS, path)
    lines = path.read_text(encoding="utf-8").splitlines()
    assert lines[0] == "QGC WPL 110"
    rows = [line.split("\t") for line in lines[1:]]
    assert [row[8:10] for row in rows] == [
        ["0.0000", "0.0000"], ["47.3977420", "8.5455941"], ["1.2345", "-0.5000"], ["0", "0"]]
    assert all(len(row) == 12 for row in rows)


def test_a_saved_mission_loads_back_to_the_same_items(tmp_path: Path):
    path = tmp_path / "m.waypoints"
    save_mission(ITEMS, path)
    assert load_mission(path) == ITEMS
