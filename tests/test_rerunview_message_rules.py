"""Which messages the Rerun view draws, and which it leaves out (mecanum_mav.app.rerunview's
module docstring, and the MAVLink fields' own rules): each test feeds a few messages to a
:class:`ViewMapping`, flushes it to an ``.rrd`` file and reads the rows back with Rerun's
reader."""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path
from typing import Any

import pytest

rr = pytest.importorskip("rerun", reason="the view extra (rerun-sdk) is not installed")
from rerun.chunk import RrdReader  # noqa: E402
from support import Sender  # noqa: E402

from mecanum_mav.app.rerunview import (  # noqa: E402
    _GRIP_COLOUR,
    _SLIP_COLOUR,
    ViewMapping,
    to_map,
)
from mecanum_mav.config.params import Params  # noqa: E402
from mecanum_mav.control.pwm import PwmMap  # noqa: E402
from mecanum_mav.mecanum.geo import GlobalOrigin  # noqa: E402
from mecanum_mav.protocol.dialect import mavlink  # noqa: E402
from mecanum_mav.protocol.mission import LOCAL_XY_SCALE  # noqa: E402
from mecanum_mav.protocol.modes import Mode  # noqa: E402
from mecanum_mav.sim.truthsender import TRUTH_SOURCE  # noqa: E402

NAN = math.nan
Rows = dict[str, list[dict[str, Any]]]


COMPANION = Sender(1, 1)
GCS = Sender(255, 190)


def _fed(messages: list[Any]) -> ViewMapping:
    mapping = ViewMapping()
    mapping.feed_all((1.0 + 0.1 * k, msg) for k, msg in enumerate(messages))
    return mapping


def _rows(mapping: ViewMapping, tmp_path: Path) -> tuple[Rows, Rows]:
    """Entity -> its temporal rows in time order, and entity -> its static rows."""
    return _flushed(mapping, [[]], tmp_path)


def _flushed(mapping: ViewMapping, batches: list[list[Any]], tmp_path: Path
             ) -> tuple[Rows, Rows]:
    """:func:`_rows` of ``mapping`` fed each batch of messages and flushed after each, as the
    live view does (one recording)."""
    path = tmp_path / "view.rrd"
    recording = rr.RecordingStream("test")
    recording.save(str(path))
    for batch in batches:
        mapping.feed_all((2.0 + 0.1 * k, msg) for k, msg in enumerate(batch))
        mapping.flush(recording)
    recording.flush()
    recording.disconnect()
    temporal: dict[str, list[tuple[int, dict[str, Any]]]] = defaultdict(list)
    static: Rows = defaultdict(list)
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        columns = {n: batch.column(n).to_pylist() for n in batch.schema.names if ":" in n}
        entity = chunk.entity_path.lstrip("/")
        if chunk.is_static:
            static[entity].append({n: v[-1] for n, v in columns.items()})
            continue
        times = batch.column("time").cast("int64").to_pylist()
        temporal[entity] += [(t, {n: v[k] for n, v in columns.items()})
                             for k, t in enumerate(times)]
    return ({e: [row for _, row in sorted(rows, key=lambda r: r[0])]
             for e, rows in temporal.items()}, static)


def _scalars(rows: Rows, entity: str) -> list[float]:
    return [row["Scalars:scalars"][0] for row in rows.get(entity, [])]


def _yaws(rows: Rows) -> list[float]:
    return [2.0 * math.atan2(row["Transform3D:quaternion"][0][2],
                             row["Transform3D:quaternion"][0][3])
            for row in rows["map/rover"]]


def _odometry(north: float, east: float, q: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0)) -> Any:
    return COMPANION("odometry", 0, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_BODY_FRD,
                     north, east, 0.0, list(q), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                     [NAN] * 21, [NAN] * 21)


def _position(north: float, east: float, vn: float = 0.0, sender: Sender = COMPANION) -> Any:
    return sender("local_position_ned", 0, north, east, 0.0, vn, 0.0, 0.0)


# --------------------------------------------------------------------------- the pose


def test_odometry_from_another_system_than_the_vehicles_is_not_drawn(tmp_path: Path) -> None:
    # The vehicle is the sender of the first ODOMETRY; another system's (a second rover on
    # the same stream) moves neither the path nor the pose.
    other = Sender(7, 1)
    other_odometry = other("odometry", 0, mavlink.MAV_FRAME_LOCAL_NED,
                           mavlink.MAV_FRAME_BODY_FRD, 50.0, 50.0, 0.0, [1.0, 0.0, 0.0, 0.0],
                           0.0, 0.0, 0.0, 0.0, 0.0, 0.0, [NAN] * 21, [NAN] * 21)
    temporal, _ = _rows(_fed([_odometry(1.0, 2.0), other_odometry, _odometry(1.0, 3.0)]),
                        tmp_path)
    strips = [row["LineStrips2D:strips"][0] for row in temporal["map/path"]]
    assert strips == [[list(to_map(1.0, 2.0)), list(to_map(1.0, 3.0))]]
    assert len(temporal["map/rover"]) == 2


def test_an_odometry_without_a_finite_heading_keeps_the_last_heading(tmp_path: Path) -> None:
    east = (math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4))  # yaw 90 deg: east
    temporal, _ = _rows(_fed([_odometry(0.0, 0.0, east), _odometry(0.0, 1.0, (NAN,) * 4)]),
                        tmp_path)
    assert _yaws(temporal) == pytest.approx([math.pi / 2, math.pi / 2])


def test_without_odometry_the_heading_is_the_attitudes_yaw(tmp_path: Path) -> None:
    attitude = COMPANION("attitude", 0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0)
    temporal, _ = _rows(_fed([attitude, _position(1.0, 1.0)]), tmp_path)
    assert _yaws(temporal) == pytest.approx([0.5])


def test_a_position_without_a_finite_speed_draws_the_pose_and_no_speed(tmp_path: Path) -> None:
    temporal, _ = _rows(_fed([_position(1.0, 1.0, vn=NAN), _position(1.0, 2.0, vn=0.5)]),
                        tmp_path)
    assert len(temporal["map/rover"]) == 2
    assert _scalars(temporal, "speed/estimated") == [0.5]


# --------------------------------------------------------------------------- the truth


def test_the_true_path_is_placed_about_the_streams_gps_global_origin(tmp_path: Path) -> None:
    # GPS_GLOBAL_ORIGIN on the stream: SIM_STATE is placed about it (not guessed from where
    # the estimate is, which would put the first true position at 0, 0).
    origin = GlobalOrigin(473_977_420, 85_455_940)
    states = []
    for north, east in ((3.0, 4.0), (3.0, 5.0)):
        lat, lon = origin.to_global(north, east)
        states.append(COMPANION("sim_state", 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                                0.0, 0.0, 0.0, lat / 1e7, lon / 1e7, 0.0, 0.0, 0.0, 0.0, 0.0,
                                0.0, lat, lon))
    announced = COMPANION("gps_global_origin", origin.lat_e7, origin.lon_e7, 0)
    temporal, _ = _rows(_fed([announced, *states]), tmp_path)
    (strip,) = [row["LineStrips2D:strips"][0] for row in temporal["map/truth"]]
    assert strip == [pytest.approx(list(to_map(3.0, 4.0)), abs=0.01),
                     pytest.approx(list(to_map(3.0, 5.0)), abs=0.01)]


def _sim_states(origin: GlobalOrigin, points: list[tuple[float, float]]) -> list[Any]:
    states = []
    for north, east in points:
        lat, lon = origin.to_global(north, east)
        states.append(COMPANION("sim_state", 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                                0.0, 0.0, 0.0, lat / 1e7, lon / 1e7, 0.0, 0.0, 0.0, 0.0, 0.0,
                                0.0, lat, lon))
    return states


FAR_FROM_0_0 = GlobalOrigin(-353_632_621, 1_491_652_374)  # Canberra: no simulator's 0, 0


def test_without_an_origin_the_first_true_position_is_taken_as_where_the_estimate_is(
        tmp_path: Path) -> None:
    # ViewMapping's origin None, no GPS_GLOBAL_ORIGIN, a simulator far from 0, 0: the first
    # true position is placed where the estimate is then, and the true path goes on from there.
    states = _sim_states(FAR_FROM_0_0, [(100.0, -50.0), (102.0, -49.0)])
    temporal, _ = _rows(_fed([_odometry(3.0, 4.0), *states]), tmp_path)
    (strip,) = [row["LineStrips2D:strips"][0] for row in temporal["map/truth"]]
    assert strip == [pytest.approx(list(to_map(3.0, 4.0)), abs=0.01),
                     pytest.approx(list(to_map(5.0, 5.0)), abs=0.01)]


def test_without_an_origin_or_an_estimate_the_first_true_position_is_at_0_0(
        tmp_path: Path) -> None:
    states = _sim_states(FAR_FROM_0_0, [(100.0, -50.0), (102.0, -49.0)])
    temporal, _ = _rows(_fed(states), tmp_path)
    (strip,) = [row["LineStrips2D:strips"][0] for row in temporal["map/truth"]]
    assert strip == [pytest.approx(list(to_map(0.0, 0.0)), abs=0.01),
                     pytest.approx(list(to_map(2.0, 1.0)), abs=0.01)]


def test_a_contact_without_a_finite_force_draws_its_slip_and_no_force(tmp_path: Path) -> None:
    twin = Sender(*TRUTH_SOURCE)
    temporal, _ = _rows(_fed([twin("debug_vect", b"CONTACT_FL", 0, NAN, 0.0, 1.0),
                              twin("debug_vect", b"CONTACT_FR", 0, 12.5, 0.0, 0.0),
                              twin("debug_vect", b"CONTACT_RR", 0, 12.5, 0.0, 1.0)]), tmp_path)
    assert "contacts/normal/FL" not in temporal
    assert _scalars(temporal, "contacts/normal/FR") == [12.5]
    slips = [row["Boxes2D:colors"] for row in temporal["map/rover/slip"]]
    # One box per wheel, a row at the first contact and when a wheel starts slipping: FL red,
    # the others green; then RR red too.
    assert slips == [[RED, GREEN, GREEN, GREEN], [RED, GREEN, GREEN, RED]]


def _packed(rgba: tuple[int, int, int, int]) -> int:
    r, g, b, a = rgba
    return (r << 24) | (g << 16) | (b << 8) | a


RED, GREEN = _packed(_SLIP_COLOUR), _packed(_GRIP_COLOUR)
"""A slipping wheel's box colour and a gripping one's, as Rerun stores them."""


def _contact(sender: Sender, wheel: str, normal_n: float, slipping: bool) -> Any:
    return sender("debug_vect", f"CONTACT_{wheel}".encode(), 0, normal_n, 0.0,
                  1.0 if slipping else 0.0)


def _flight_controller() -> Sender:
    """The flight controller: FC_SYSID/FC_COMPID (1/1, the companion's ids too), counting its
    own sequence numbers far from the companion's."""
    fc = Sender(1, 1)
    fc.mav.seq = 100
    return fc


def test_the_flight_controllers_contact_right_after_the_companions_message_is_drawn(
        tmp_path: Path) -> None:
    # The companion (the sender of ODOMETRY) and the flight controller share 1/1: the contact
    # is told by its own sender, whatever came just before it.
    temporal, _ = _rows(_fed([_odometry(0.0, 0.0), _contact(_flight_controller(), "FL", 9.5,
                                                              False)]), tmp_path)
    assert _scalars(temporal, "contacts/normal/FL") == [9.5]


def test_a_contact_from_a_ground_station_under_the_flight_controllers_ids_is_not_drawn(
        tmp_path: Path) -> None:
    # Contacts are the flight controller's (or the twin's truth's): a sender of 1/1 that sent
    # MANUAL_CONTROL (only a ground station does) is not the flight controller.
    station = Sender(1, 1)
    messages = [station("manual_control", 1, 0, 0, 500, 0, 0),
                _contact(station, "FL", 5.0, True),
                _contact(_flight_controller(), "FR", 9.5, False)]
    temporal, _ = _rows(_fed(messages), tmp_path)
    assert "contacts/normal/FL" not in temporal
    assert _scalars(temporal, "contacts/normal/FR") == [9.5]


def test_the_first_contact_after_a_flush_sends_the_chassis_slip_boxes(tmp_path: Path) -> None:
    # The live view flushes a few times a second: the chassis was sent before any contact,
    # so the first contact sends it again with its four wheels' boxes (their colours are
    # the slip rows).
    twin = Sender(*TRUTH_SOURCE)
    _, static = _flushed(ViewMapping(), [[_odometry(0.0, 0.0)],
                                         [_contact(twin, "FL", 9.8, False)]], tmp_path)
    (boxes,) = static["map/rover/slip"]
    assert len(boxes["Boxes2D:centers"]) == 4


# --------------------------------------------------------------------------- sticks and PWM


def test_a_stick_axis_marked_invalid_is_not_drawn(tmp_path: Path) -> None:
    # MANUAL_CONTROL: INT16_MAX (0x7FFF) means the axis is invalid or unused.
    temporal, _ = _rows(_fed([GCS("manual_control", 1, 500, -200, 500, 0x7FFF, 0)]), tmp_path)
    assert _scalars(temporal, "sticks/x") == [0.5]
    assert _scalars(temporal, "sticks/y") == [-0.2]
    assert "sticks/r" not in temporal


def test_a_pilots_rc_override_is_not_drawn_as_the_wheels_pwm(tmp_path: Path) -> None:
    # MAVProxy's 'rc 3 1700' (component 0, to the vehicle) is stick input; the companion's
    # override of the wheel channels 1-4 (255/190 to its flight controller) is the PWM.
    mavproxy = Sender(255, 0)
    pilot = mavproxy("rc_channels_override", 1, 1, 65535, 65535, 1700, 65535, 65535, 65535,
                     65535, 65535)
    wheels = GCS("rc_channels_override", 1, 1, 1600, 1400, 1600, 1400, 65535, 65535, 65535,
                 65535)
    temporal, _ = _rows(_fed([pilot, wheels]), tmp_path)
    assert [_scalars(temporal, f"wheels/pwm/{w}") for w in ("FL", "FR", "RL", "RR")] == [
        [1600.0], [1400.0], [1600.0], [1400.0]]


WHEELS = ("FL", "FR", "RL", "RR")
ROVER_HEARTBEAT = COMPANION("heartbeat", mavlink.MAV_TYPE_GROUND_ROVER,
                            mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3)
"""The vehicle (1/1) announced: until an ODOMETRY, the sender of the first rover HEARTBEAT."""


def _servo_output(sender: Sender, port: int, *pulses: int) -> Any:
    return sender("servo_output_raw", 0, port, *pulses, *[0] * (8 - len(pulses)))


def _pwm(temporal: Rows) -> list[list[float]]:
    return [_scalars(temporal, f"wheels/pwm/{w}") for w in WHEELS]


def test_the_vehicles_servo_output_raw_is_the_wheels_pwm(tmp_path: Path) -> None:
    # Without the companion's overrides on the stream, wheels/pwm is the vehicle's
    # SERVO_OUTPUT_RAW: the wheels' channels (MOT_x_CH: 1-4), and the wheel commands read back.
    temporal, _ = _rows(_fed([ROVER_HEARTBEAT, _servo_output(COMPANION, 0, 1600, 1400, 1500,
                                                             1900, 1100)]), tmp_path)
    assert _pwm(temporal) == [[1600.0], [1400.0], [1500.0], [1900.0]]
    rr_wheel = PwmMap.from_params(Params()).wheels[3]
    assert _scalars(temporal, "wheels/command/RR") == pytest.approx(
        [rr_wheel.command_from_pulse(1900)])


def test_servo_output_raw_of_another_port_or_system_is_not_the_wheels_pwm(
        tmp_path: Path) -> None:
    # SERVO_OUTPUT_RAW's port: a set of outputs (0 the first, servo1..servo16); the wheels'
    # channels 1-4 are port 0's. Another system's outputs are not the vehicle's.
    messages = [ROVER_HEARTBEAT, _servo_output(COMPANION, 1, 1900, 1900, 1900, 1900),
                _servo_output(Sender(7, 1), 0, 1100, 1100, 1100, 1100),
                _servo_output(COMPANION, 0, 1600, 1600, 1600, 1600)]
    temporal, _ = _rows(_fed(messages), tmp_path)
    assert _pwm(temporal) == [[1600.0]] * 4


def test_once_the_companions_overrides_came_servo_output_raw_is_not_drawn(
        tmp_path: Path) -> None:
    # The companion's RC_CHANNELS_OVERRIDE to its flight controller is every output; the
    # vehicle's SERVO_OUTPUT_RAW (a 2 Hz report of the same) is left out once they came.
    override = GCS("rc_channels_override", 1, 1, 1600, 1400, 1600, 1400, 65535, 65535, 65535,
                   65535)
    temporal, _ = _rows(_fed([ROVER_HEARTBEAT, override,
                              _servo_output(COMPANION, 0, 1900, 1900, 1900, 1900)]), tmp_path)
    assert _pwm(temporal) == [[1600.0], [1400.0], [1600.0], [1400.0]]


# --------------------------------------------------------------------------- the mission


def _item(seq: int, north: float, east: float, mission_type: int) -> Any:
    return GCS("mission_item_int", 1, 1, seq, mavlink.MAV_FRAME_LOCAL_NED,
               mavlink.MAV_CMD_NAV_WAYPOINT, 0, 1, 0.0, 0.0, 0.0, 0.0,
               round(north * LOCAL_XY_SCALE), round(east * LOCAL_XY_SCALE), 0.0,
               mission_type=mission_type)


def _upload(points: list[tuple[float, float]], mission_type: int) -> list[Any]:
    return [GCS("mission_count", 1, 1, len(points), mission_type=mission_type),
            *(_item(seq, n, e, mission_type) for seq, (n, e) in enumerate(points))]


SQUARE = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0)]


def test_a_geofence_upload_does_not_change_the_mission_plan(tmp_path: Path) -> None:
    fence = _upload([(-5.0, -5.0), (-5.0, 20.0), (20.0, 20.0)], mavlink.MAV_MISSION_TYPE_FENCE)
    mapping = _fed([*_upload(SQUARE, mavlink.MAV_MISSION_TYPE_MISSION), *fence])
    assert mapping.plan == [(1, 10.0, 0.0), (2, 10.0, 10.0)]
    _, static = _rows(mapping, tmp_path)
    assert static["map/plan/items"][-1]["Points2D:positions"] == [
        list(to_map(10.0, 0.0)), list(to_map(10.0, 10.0))]


def test_a_stale_or_another_systems_item_reached_leaves_the_current_leg(tmp_path: Path) -> None:
    # In AUTO with item 2 current, the leg runs from item 1 (10, 0) to item 2 (10, 10): at
    # (5, 5) the cross-track is 5 m. MISSION_ITEM_REACHED of item 0 (before the current one)
    # or from another system does not make another item current.
    heartbeat = COMPANION("heartbeat", mavlink.MAV_TYPE_GROUND_ROVER,
                          mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                          mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
                          | mavlink.MAV_MODE_FLAG_SAFETY_ARMED, int(Mode.AUTO), 4)
    messages = [*_upload(SQUARE, mavlink.MAV_MISSION_TYPE_MISSION), heartbeat,
                COMPANION("mission_current", 2),
                COMPANION("mission_item_reached", 0),
                Sender(7, 1)("mission_item_reached", 2),
                _position(5.0, 5.0)]
    temporal, _ = _rows(_fed(messages), tmp_path)
    assert _scalars(temporal, "track/cross_track") == pytest.approx([5.0])
