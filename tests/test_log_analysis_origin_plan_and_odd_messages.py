"""What ``mecanum-mav log`` reads from a tlog (mecanum_mav.app.loganalysis, app.logmission):
the origin global positions are placed about, the planned mission, the legs as driven in AUTO,
the modes of other vehicles, the pilot's sticks, and messages whose contents the analysis
leaves out rather than raise on (the modules' docstrings)."""

from __future__ import annotations

import math
from typing import Any

import pytest
from support import Sender

from mecanum_mav.app.loganalysis import analyse
from mecanum_mav.app.logmission import log_origin, mission_items, planned_positions, sim_latlon
from mecanum_mav.io.tlog import TlogEntry
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import LOCAL_XY_SCALE
from mecanum_mav.protocol.modes import Mode

NAN = math.nan
START_S = 1_800_000_000.0
ZURICH = GlobalOrigin(473_977_420, 85_455_940)


ROVER = Sender(1, 1)
GCS = Sender(255, 190)


def _log(*timed: tuple[float, Any]) -> list[TlogEntry]:
    """Tlog entries of (seconds from the start, message)."""
    return [TlogEntry(START_S + t, k, msg) for k, (t, msg) in enumerate(timed)]


def _rover_heartbeat(mode: Mode = Mode.MANUAL) -> Any:
    return ROVER("heartbeat", mavlink.MAV_TYPE_GROUND_ROVER, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                 mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_SAFETY_ARMED,
                 int(mode), 4)


def _global(lat_e7: int, lon_e7: int) -> Any:
    return ROVER("global_position_int", 0, lat_e7, lon_e7, 0, 0, 0, 0, 0, 0)


def _local(north: float, east: float) -> Any:
    return ROVER("local_position_ned", 0, north, east, 0.0, 0.0, 0.0, 0.0)


def _sim_state(lat_deg: float, lon_deg: float, lat_e7: int = 0, lon_e7: int = 0) -> Any:
    """SIM_STATE: degrees as floats, and degE7 (0, 0: none, as ArduPilot's older ones)."""
    return ROVER("sim_state", 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                 lat_deg, lon_deg, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, lat_e7, lon_e7)


def _item(seq: int, command: int, x: int, y: int, *, frame: int = mavlink.MAV_FRAME_LOCAL_NED
          ) -> Any:
    return GCS("mission_item_int", 1, 1, seq, frame, command, 0, 1, 0.0, 0.0, 0.0, 0.0, x, y,
               0.0)


def _waypoint(seq: int, north: float, east: float) -> Any:
    return _item(seq, mavlink.MAV_CMD_NAV_WAYPOINT, round(north * LOCAL_XY_SCALE),
                 round(east * LOCAL_XY_SCALE))


def _upload(*items: Any) -> list[tuple[float, Any]]:
    return [(0.0, GCS("mission_count", 1, 1, len(items))), *((0.0, it) for it in items)]


# --------------------------------------------------------------------------- the origin


def test_an_announced_gps_global_origin_is_the_logs_origin() -> None:
    far = ZURICH.to_global(500.0, 500.0)
    entries = _log((0.0, _global(*far)),
                   (1.0, ROVER("gps_global_origin", ZURICH.lat_e7, ZURICH.lon_e7, 0)))
    assert log_origin(entries, (1, 1)) == ZURICH


def test_without_an_announced_origin_the_global_position_lands_on_the_local_one() -> None:
    lat, lon = ZURICH.to_global(120.0, -70.0)
    entries = _log((0.0, _local(12.0, -7.0)), (0.1, _global(lat, lon)))
    origin = log_origin(entries, (1, 1))
    assert origin is not None
    north, east = origin.to_local(lat, lon)
    assert (north, east) == (pytest.approx(12.0, abs=0.02), pytest.approx(-7.0, abs=0.02))


def test_a_simulator_state_without_a_finite_position_is_skipped() -> None:
    # The first SIM_STATE's NaN position gives neither the origin nor a true position.
    lat, lon = ZURICH.to_global(0.0, 0.0)
    entries = _log((0.0, _rover_heartbeat()), (0.1, _sim_state(NAN, NAN)),
                   (0.2, _sim_state(lat / 1e7, lon / 1e7, lat, lon)))
    result = analyse(entries)
    assert result.origin == GlobalOrigin(lat, lon)
    assert [t for t, _, _ in result.true_path] == [pytest.approx(0.2)]


# --------------------------------------------------------------------------- the plan


def test_rtl_is_planned_at_the_origin_and_items_without_a_position_are_not_planned() -> None:
    entries = _log(*_upload(
        _waypoint(0, 0.0, 0.0),  # home
        _waypoint(1, 5.0, 0.0),
        _item(2, mavlink.MAV_CMD_DO_CHANGE_SPEED, 0, 0),
        _item(3, mavlink.MAV_CMD_NAV_WAYPOINT, 7, 7, frame=mavlink.MAV_FRAME_MISSION),
        _item(4, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0)))
    assert planned_positions(mission_items(entries), None) == [(1, 5.0, 0.0), (4, 0.0, 0.0)]


def test_global_items_are_planned_only_where_the_log_has_an_origin() -> None:
    lat, lon = ZURICH.to_global(3.0, 4.0)
    upload = _upload(_waypoint(0, 0.0, 0.0),
                     _item(1, mavlink.MAV_CMD_NAV_WAYPOINT, lat, lon,
                           frame=mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT))
    assert analyse(_log(*upload)).planned == []
    announced = (0.0, ROVER("gps_global_origin", ZURICH.lat_e7, ZURICH.lon_e7, 0))
    ((seq, north, east),) = analyse(_log(announced, *upload)).planned
    assert (seq, north, east) == (1, pytest.approx(3.0, abs=0.02), pytest.approx(4.0, abs=0.02))


def test_a_legacy_mission_item_that_does_not_fit_is_left_out_of_the_plan() -> None:
    # MISSION_ITEM (floats): a local x of 1e12 m has no MISSION_ITEM_INT form.
    def legacy(seq: int, north: float) -> Any:
        return GCS("mission_item", 1, 1, seq, mavlink.MAV_FRAME_LOCAL_NED,
                   mavlink.MAV_CMD_NAV_WAYPOINT, 0, 1, 0.0, 0.0, 0.0, 0.0, north, 0.0, 0.0)

    entries = _log(*_upload(legacy(0, 0.0), legacy(1, 1e12), legacy(2, 6.0)))
    assert [it.seq for it in mission_items(entries)] == [0, 2]
    assert analyse(entries).planned == [(2, 6.0, 0.0)]


def test_the_path_before_the_first_heartbeat_is_not_part_of_a_leg_driven_in_auto() -> None:
    # Item 2 current from the start, the leg from item 1 (10, 0) to item 2 (10, 10); the
    # vehicle's first HEARTBEAT (AUTO) comes at 1 s: a position 50 m off the leg before it
    # does not count, the one 1 m off after it does.
    entries = _log(*_upload(_waypoint(0, 0.0, 0.0), _waypoint(1, 10.0, 0.0),
                            _waypoint(2, 10.0, 10.0)),
                   (0.1, ROVER("mission_current", 2)),
                   (0.5, _local(-40.0, 5.0)),
                   (1.0, _rover_heartbeat(Mode.AUTO)),
                   (1.5, _local(9.0, 5.0)))
    (leg,) = analyse(entries).legs
    assert (leg.seq, leg.start, leg.goal) == (2, (10.0, 0.0), (10.0, 10.0))
    assert (leg.max_cross_track_m, leg.samples) == (pytest.approx(1.0), 1)


# --------------------------------------------------------------------------- modes and sticks


def test_the_modes_of_a_vehicle_other_than_an_ardupilot_rover_are_pymavlinks_names() -> None:
    copter = Sender(1, 1)("heartbeat", mavlink.MAV_TYPE_QUADROTOR,
                          mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                          mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 5, 4)  # Copter's LOITER
    assert [span.mode for span in analyse(_log((0.0, copter))).modes] == ["LOITER"]


def test_a_pilot_override_the_rover_would_reject_or_without_sticks_gives_no_stick() -> None:
    # MAVProxy's 'rc' (component 0): 2500 us is outside 800..2200 (the rover rejects the
    # whole message); channel 7 alone touches no stick; 'rc 3 1700' is 0.4 forward.
    mavproxy = Sender(255, 0)

    def rc(chan3: int, chan7: int) -> Any:
        return mavproxy("rc_channels_override", 1, 1, 65535, 65535, chan3, 65535, 65535,
                        65535, chan7, 65535)

    entries = _log((0.0, _rover_heartbeat()), (0.1, rc(2500, 65535)), (0.2, rc(65535, 1900)),
                   (0.3, rc(1700, 65535)))
    result = analyse(entries)
    assert len(result.pilot_overrides["255/0"]) == 3
    assert result.pilot_sticks == {"255/0": [(pytest.approx(0.3), pytest.approx(0.4), 0.0, 0.0)]}


# --------------------------------------------------------------------------- the path


def test_an_empty_log_is_an_empty_analysis() -> None:
    result = analyse([])
    assert (result.messages, result.path, result.modes, result.events) == (0, [], [], [])


def test_a_position_that_is_not_finite_is_left_out_of_the_path() -> None:
    result = analyse(_log((0.0, _local(1.0, 1.0)), (0.1, _local(NAN, 2.0)),
                          (0.2, _local(1.0, 3.0))))
    assert result.path == [(0.0, 1.0, 1.0), (pytest.approx(0.2), 1.0, 3.0)]


def test_a_global_position_at_0_0_is_no_fix_and_left_out_of_the_path() -> None:
    lat, lon = ZURICH.to_global(2.0, 1.0)
    result = analyse(_log((0.0, ROVER("gps_global_origin", ZURICH.lat_e7, ZURICH.lon_e7, 0)),
                          (0.1, _global(0, 0)), (0.2, _global(lat, lon))))
    assert result.path_source == "GLOBAL_POSITION_INT"
    ((t, north, east),) = result.path
    assert (t, north, east) == (pytest.approx(0.2), pytest.approx(2.0, abs=0.02),
                                pytest.approx(1.0, abs=0.02))


# --------------------------------------------------------------------------- whose messages

OTHER = Sender(7, 1)  # another vehicle on the same link (a second rover, a drone)


def _local_of(sender: Sender, north: float, east: float) -> Any:
    return sender("local_position_ned", 0, north, east, 0.0, 0.0, 0.0, 0.0)


def _global_of(sender: Sender, lat_e7: int, lon_e7: int) -> Any:
    return sender("global_position_int", 0, lat_e7, lon_e7, 0, 0, 0, 0, 0, 0)


def test_another_systems_positions_are_neither_the_vehicles_path_nor_its_origin() -> None:
    # The rover's ODOMETRY names it the vehicle; the other system's positions, local and
    # global, come first and must not place the origin nor join the path.
    lat, lon = ZURICH.to_global(12.0, -7.0)
    far_lat, far_lon = ZURICH.to_global(900.0, 900.0)
    odometry = ROVER("odometry", 0, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_BODY_FRD,
                     12.0, -7.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                     [NAN] * 21, [NAN] * 21, 0, mavlink.MAV_ESTIMATOR_TYPE_NAIVE, 100)
    entries = _log((0.0, _local_of(OTHER, 300.0, 300.0)),
                   (0.0, _global_of(OTHER, far_lat, far_lon)),
                   (0.1, odometry), (0.2, _global(lat, lon)),
                   (0.3, _global_of(OTHER, far_lat, far_lon)))
    result = analyse(entries)
    assert result.vehicle == (1, 1)
    assert result.origin is not None
    assert result.origin.to_local(lat, lon) == (pytest.approx(12.0, abs=0.02),
                                                pytest.approx(-7.0, abs=0.02))
    assert result.path_source == "ODOMETRY"
    assert result.path == [(pytest.approx(0.1), 12.0, -7.0)]


def test_another_systems_global_positions_are_not_the_vehicles_path() -> None:
    lat, lon = ZURICH.to_global(2.0, 1.0)
    far_lat, far_lon = ZURICH.to_global(900.0, 900.0)
    entries = _log((0.0, ROVER("gps_global_origin", ZURICH.lat_e7, ZURICH.lon_e7, 0)),
                   (0.0, _rover_heartbeat()), (0.1, _global_of(OTHER, far_lat, far_lon)),
                   (0.2, _global(lat, lon)))
    result = analyse(entries)
    assert result.vehicle == (1, 1)
    assert [t for t, _, _ in result.path] == [pytest.approx(0.2)]


def test_a_disarmed_vehicle_is_disarmed_in_the_modes_and_arming_starts_a_span() -> None:
    def beat(armed: bool) -> Any:
        flags = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (
            mavlink.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0)
        return ROVER("heartbeat", mavlink.MAV_TYPE_GROUND_ROVER,
                     mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, flags, int(Mode.MANUAL), 4)

    result = analyse(_log((0.0, beat(False)), (1.0, beat(False)), (2.0, beat(True))))
    assert [(span.start_s, span.armed) for span in result.modes] == [(0.0, False), (2.0, True)]


def test_a_mode_change_starts_at_the_accepted_command_not_at_the_heartbeat_that_shows_it() -> None:
    # MAV_CMD_DO_SET_MODE accepted at 1.3 s; the vehicle's next heartbeat (2 s) is in AUTO:
    # AUTO began when the command was accepted.
    ack = ROVER("command_ack", mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_RESULT_ACCEPTED)
    result = analyse(_log((0.0, _rover_heartbeat(Mode.MANUAL)), (1.0, _rover_heartbeat()),
                          (1.3, ack), (2.0, _rover_heartbeat(Mode.AUTO))))
    assert [(span.mode, span.start_s) for span in result.modes] == [
        ("MANUAL", 0.0), ("AUTO", pytest.approx(1.3))]


def test_manual_control_axes_are_read_per_mille_and_an_invalid_axis_is_nan() -> None:
    # MANUAL_CONTROL: x, y, r in -1000..1000; INT16_MAX marks an axis invalid.
    stick = GCS("manual_control", 1, 250, -500, 0, 32767, 0)
    ((t, x, y, r),) = analyse(_log((0.0, stick))).sticks
    assert (t, x, y) == (0.0, 0.25, -0.5)
    assert math.isnan(r)


def test_each_pilots_overrides_are_read_as_sticks_of_their_own() -> None:
    # Two ground stations override by turns: 255/0 pushes channel 3 (forward), 254/0
    # channel 1 (yaw); neither's stick carries the other's channel.
    def rc(sender: Sender, chan1: int, chan3: int) -> Any:
        return sender("rc_channels_override", 1, 1, chan1, 65535, chan3, 65535, 65535,
                      65535, 65535, 65535)

    first, second = Sender(255, 0), Sender(254, 0)
    entries = _log((0.0, _rover_heartbeat()), (0.1, rc(first, 65535, 1700)),
                   (0.2, rc(second, 1700, 65535)))
    result = analyse(entries)
    assert result.pilot_sticks["255/0"] == [(pytest.approx(0.1), pytest.approx(0.4), 0.0, 0.0)]
    assert result.pilot_sticks["254/0"] == [(pytest.approx(0.2), 0.0, 0.0, pytest.approx(0.4))]
    assert result.pilot_overrides["255/0"] == [
        (pytest.approx(0.1), [65535, 65535, 1700, *[65535] * 5, *[0] * 10])]


def test_ardupilots_simstate_is_the_true_path() -> None:
    lat, lon = ZURICH.to_global(3.0, -4.0)
    simstate = ROVER("simstate", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, lat, lon)
    result = analyse(_log((0.0, ROVER("gps_global_origin", ZURICH.lat_e7, ZURICH.lon_e7, 0)),
                          (0.5, simstate)))
    ((t, north, east),) = result.true_path
    assert (t, north, east) == (0.5, pytest.approx(3.0, abs=0.02),
                                pytest.approx(-4.0, abs=0.02))


def test_a_sample_at_the_instant_of_the_last_mode_change_is_in_the_new_mode() -> None:
    # AUTO begins with the log's last message, where the position is logged too.
    entries = _log(*_upload(_waypoint(0, 0.0, 0.0), _waypoint(1, 10.0, 0.0)),
                   (0.0, _rover_heartbeat(Mode.MANUAL)), (0.1, ROVER("mission_current", 1)),
                   (0.5, _local(1.0, 0.0)), (1.0, _rover_heartbeat(Mode.AUTO)),
                   (1.0, _local(2.0, 0.5)))
    (leg,) = analyse(entries).legs
    assert (leg.seq, leg.samples) == (1, 1)


# --------------------------------------------------------------------------- simulator states


def test_a_sim_states_whole_degE7_position_wins_over_its_float_degrees() -> None:
    # SIM_STATE's lat/lon are float32 degrees (about a metre at 47 deg); lat_int/lon_int
    # (degE7) are exact, also on the equator or the prime meridian (one of them 0).
    assert sim_latlon(_sim_state(47.39774, 8.54559, 473_977_421, 85_455_939)) == (
        473_977_421, 85_455_939)
    assert sim_latlon(_sim_state(0.0, 8.5, 0, 85_000_001)) == (0, 85_000_001)
    assert sim_latlon(_sim_state(47.5, 0.0, 475_000_001, 0)) == (475_000_001, 0)


def test_a_sim_state_without_degE7_fields_is_read_from_its_degrees() -> None:
    # Both 0 (ArduPilot before the fields existed) or absent (pymavlink 2.4.40, the oldest
    # this project supports, has no lat_int/lon_int in SIM_STATE).
    assert sim_latlon(_sim_state(47.25, -8.5)) == (472_500_000, -85_000_000)
    old = _sim_state(47.25, -8.5)
    del old.lat_int, old.lon_int
    assert sim_latlon(old) == (472_500_000, -85_000_000)


def test_ardupilots_simstate_is_in_degE7() -> None:
    simstate = ROVER("simstate", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 473_977_421,
                     -85_455_939)
    assert sim_latlon(simstate) == (473_977_421, -85_455_939)
