"""The one mapping from MAVLink messages to the Rerun view, live and from a tlog.

:class:`ViewMapping` takes messages one at a time (:meth:`ViewMapping.feed`: the message and
its time, Unix seconds: a tlog record's stamp, or the receive time live) and keeps what the
view shows as rows; :meth:`ViewMapping.flush` sends the rows gathered since the last flush to
a Rerun recording in columns (``send_columns``: one call per entity, not per message), and the
mission plan and chassis as static data when they change. No sockets, no files: ``mecanum-mav
view`` (:mod:`~mecanum_mav.app.view`) feeds it from a link and flushes a few times a second,
``mecanum-mav log --rerun`` feeds it a whole tlog and flushes once. ``rerun`` (the ``view``
extra) is imported only when something is sent, so the package works without it.

The entities (one timeline, ``time``: Unix time, shown as a date):

- ``map/...``: top-down, east m to the right and north m *up* (Rerun's 2D views point y down,
  so a point is logged at ``(east, -north)``): ``map/plan`` the mission plan (the last
  MISSION_COUNT's MISSION_ITEM_INT / MISSION_ITEM seen, uploads and downloads alike; items
  with a position from seq 1 on), ``map/path`` the estimated path (the vehicle's ODOMETRY,
  else LOCAL_POSITION_NED), ``map/truth`` the true path (SIM_STATE or ArduPilot's SIMSTATE,
  where the stream has them: a tlog of ``sim`` or the simulator's own; once the twin's truth
  came, :data:`~mecanum_mav.sim.truthsender.TRUTH_SOURCE`'s only), each a segment per sample;
  ``map/rover`` the estimated pose (a transform: yaw from ODOMETRY, else ATTITUDE),
  under it ``map/rover/chassis`` the chassis to scale (``GEO_HALF_LEN`` by ``GEO_HALF_WID``,
  from the parameters given or PARAM_VALUE on the stream) and ``map/rover/wheels`` each wheel's
  command as an arrow from its wheel (forward = the wheel drives the rover forward; full
  command = ``GEO_HALF_LEN`` long).
- ``sticks/x``, ``sticks/y``, ``sticks/r``: MANUAL_CONTROL, -1..1 (x forward, y right, r
  clockwise).
- ``wheels/command/FL`` ... ``RR``: the normalized wheel commands, -1..1. They are not on the
  ground station's stream (the companion reports PWM, not commands), so they are the PWM read
  back through the parameters' PWM map (:meth:`~mecanum_mav.control.pwm.WheelOutput.
  command_from_pulse`: trims, ranges, reverse; the ESC dead band's lift shows as it is sent).
- ``wheels/pwm/FL`` ... ``RR``: the pulses on the wheels' channels (``MOT_<W>_CH``),
  microseconds: the companion's RC_CHANNELS_OVERRIDE to its flight controller where the
  stream has them (a tlog of both of its links: every output), else the vehicle's
  SERVO_OUTPUT_RAW (what the ground station gets, ``TLM_EXT_RATE``).
- ``speed/estimated`` (ODOMETRY or LOCAL_POSITION_NED), ``speed/true`` (SIM_STATE), m/s over
  the ground; ``track/cross_track``: the estimated position's distance from the current
  mission leg in AUTO, m (the leg from the previous planned position, or from where the rover
  was when the item became current, to the current item).
- :data:`CONTACT_ENTITIES`: each wheel's floor contact normal force (N) and its box on the
  chassis close-up, red while it slips: the DEBUG_VECTs ``CONTACT_W`` of the flight controller
  (FC_SYSID/FC_COMPID, not the companion sharing its ids) on ``sim``'s MuJoCo chassis, or of
  the twin's truth.
- ``state/mode`` and ``state/armed``: the vehicle's HEARTBEAT, as state changes (a state
  timeline); ``events``: every STATUSTEXT (long texts joined), failsafes at level ERROR, and
  each mode or arming change, as text events on the timeline.

The vehicle is the sender of the first ODOMETRY or MISSION_CURRENT, until then of the first
HEARTBEAT of a vehicle type from an autopilot. In a tlog of both of the companion's links
the companion and its flight controller share system and component id 1/1; they are told
apart by their sequence numbers (:class:`~mecanum_mav.app.logsenders.Senders`) and the
vehicle's modes and PWM come from the companion only. A message with unexpected contents is
skipped: :meth:`ViewMapping.feed` never raises.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from operator import attrgetter
from typing import TYPE_CHECKING, Any

import numpy as np

from mecanum_mav.app.loganalysis import AXIS_INVALID, _mode_name
from mecanum_mav.app.logmission import planned_positions, sim_latlon
from mecanum_mav.app.logsenders import (
    _NOT_VEHICLES,
    VEHICLE_ANCHORS,
    Senders,
    override_from_pilot,
)
from mecanum_mav.app.logstatus import is_failsafe
from mecanum_mav.app.logview import NO_OVERRIDE
from mecanum_mav.app.rerunlayout import APPLICATION_ID, TIMELINE, blueprint, rerun_module
from mecanum_mav.config.params import ParamError, Params
from mecanum_mav.control.pathfollow import Leg
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.mecanum.wheels import WHEEL_KEYS
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import MissionItem, item_from_fields
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.statustext import StatusChunks
from mecanum_mav.sim.truthsender import CONTACT_NAMES, TRUTH_SOURCE

if TYPE_CHECKING:
    import rerun as rr

__all__ = ["APPLICATION_ID", "CONTACT_ENTITIES", "ENTITIES", "TIMELINE", "ViewMapping",
           "blueprint", "rerun_module", "to_map"]

WHEELS = tuple(key.upper() for key in WHEEL_KEYS)
"""Wheel names in the entity paths, in wheel order: FL, FR, RL, RR."""
ENTITIES: tuple[str, ...] = (
    "map/plan", "map/path", "map/truth", "map/rover", "map/rover/chassis", "map/rover/wheels",
    "sticks/x", "sticks/y", "sticks/r",
    *(f"wheels/command/{w}" for w in WHEELS), *(f"wheels/pwm/{w}" for w in WHEELS),
    "speed/estimated", "speed/true", "track/cross_track", "state/mode", "state/armed",
    "events")
"""Every entity the view has (see the module docstring)."""
CONTACT_ENTITIES: tuple[str, ...] = (*(f"contacts/normal/{w}" for w in WHEELS), "map/rover/slip")
_SLIP_COLOUR, _GRIP_COLOUR = (214, 39, 40, 255), (44, 160, 44, 60)
_NEAR_NULL_ISLAND_DEG = 1.0
"""A simulator without a global origin places the rover within a degree of 0, 0."""
_PATH_COLOUR = (255, 140, 0)
_TRUTH_COLOUR = (31, 119, 180, 140)  # under the estimate, wider and see-through
_PLAN_COLOUR = (150, 150, 150)
_CHASSIS_COLOUR = (220, 220, 220)
_WHEEL_COLOUR = (44, 160, 44)
_MAP_PARAMS = ("GEO_HALF_LEN", "GEO_HALF_WID")
_channels = attrgetter(*(f"chan{i}_raw" for i in range(1, 19)))
"""An RC_CHANNELS_OVERRIDE's 18 channels, channel 1 first."""
_LEAVE = (0, 65534, 65535)
"""RC_CHANNELS_OVERRIDE values that leave a channel alone or release it (not a pulse)."""


def to_map(north_m: float, east_m: float) -> tuple[float, float]:
    """A local NED position (north m, east m) as the map draws it: (east, -north), so north
    is up in Rerun's 2D view (whose y points down)."""
    return east_m, -north_m


def _body_to_map(forward_m: float, right_m: float) -> tuple[float, float]:
    """A body-frame point (forward m, right m) in the rover's own map frame (nose up)."""
    return right_m, -forward_m


@dataclass
class _Rows:
    """One entity's rows since the last flush: times (Unix s) and one value per row."""

    kind: str
    times: list[float] = field(default_factory=list)
    values: list[Any] = field(default_factory=list)


def _columns(rr: Any, kind: str, values: list[Any]) -> Any:
    """The Rerun component columns of one entity's rows (``kind`` says which archetype)."""
    n = len(values)
    if kind == "scalar":
        return rr.Scalars.columns(scalars=np.asarray(values, dtype=np.float64))
    if kind == "segment":
        return rr.LineStrips2D.columns(
            strips=np.asarray(values, dtype=np.float32).reshape(n, 2, 2)).partition([1] * n)
    if kind == "pose":
        pose = np.asarray(values, dtype=np.float64)  # map x, map y, yaw (rad clockwise)
        half = pose[:, 2] / 2.0
        zeros = np.zeros(n)
        return rr.Transform3D.columns(
            translation=np.column_stack((pose[:, 0], pose[:, 1], zeros)),
            quaternion=np.column_stack((zeros, zeros, np.sin(half), np.cos(half))))
    if kind == "state":
        return rr.StateChange.columns(state=values)
    if kind == "slip":  # four wheels' flags a row: their boxes' colours
        colours = np.asarray((_GRIP_COLOUR, _SLIP_COLOUR), np.uint8)[np.asarray(values, int)]
        return rr.Boxes2D.columns(colors=colours.reshape(-1, 4)).partition([4] * n)
    text, level = zip(*values, strict=True)
    return rr.TextLog.columns(text=list(text), level=list(level))


class ViewMapping:
    """MAVLink messages -> the view's rows (see the module docstring).

    Args:
        params: the rover's parameters (the PWM map and the chassis size; default: the
            defaults); PARAM_VALUE on the stream updates them.
        origin: the global origin that SIM_STATE positions are placed about (a tlog's:
            :func:`~mecanum_mav.app.logmission.log_origin`); None: GPS_GLOBAL_ORIGIN when the
            stream has one, else 0, 0 for a simulator within a degree of it, else the first
            true position (taken as where the estimate is then).
    """

    def __init__(self, params: Params | None = None, origin: GlobalOrigin | None = None) -> None:
        self.params = params if params is not None else Params()
        self.pwm = PwmMap.from_params(self.params)
        self.origin = origin
        self.vehicle: tuple[int, int] | None = None
        self._vehicle_anchored = False  # the vehicle found by ODOMETRY / MISSION_CURRENT
        self._rows: dict[str, _Rows] = {}
        self._senders = Senders()
        self._index = 0
        self._split = False  # ODOMETRY seen: modes and PWM from the companion's sender only
        self._odometry = False  # ODOMETRY seen: the pose comes from it alone
        self._overrides = False  # the companion's overrides seen: PWM from them alone
        self._override_kinds: dict[tuple[Any, ...], bool] = {}
        self._yaw = 0.0
        self._position: tuple[float, float] | None = None  # estimated (north, east)
        self._true_position: tuple[float, float] | None = None
        self._twin_truth = self._origin_derived = False  # TRUTH_SOURCE seen; origin guessed
        self._mission_count: int | None = None
        self._items: dict[int, MissionItem] = {}
        self.plan: list[tuple[int, float, float]] = []
        """(seq, north m, east m) of the plan's positions."""
        self._plan_dirty = False
        self._chassis_dirty = True
        self._current: int | None = None
        self._leg: Leg | None = None
        self._mode: str | None = None
        self._armed: bool | None = None
        self._status = StatusChunks()
        self.messages = 0
        """Messages fed so far."""
        self._handlers: dict[str, Callable[[float, Any], None]] = {
            "HEARTBEAT": self._heartbeat, "ODOMETRY": self._odometry_msg,
            "LOCAL_POSITION_NED": self._local_position, "ATTITUDE": self._attitude,
            "SIM_STATE": self._sim_state, "SIMSTATE": self._sim_state,
            "GPS_GLOBAL_ORIGIN": self._global_origin,
            "SET_GPS_GLOBAL_ORIGIN": self._global_origin,
            "MANUAL_CONTROL": self._manual_control, "SERVO_OUTPUT_RAW": self._servo_output,
            "RC_CHANNELS_OVERRIDE": self._override,
            "STATUSTEXT": self._statustext, "MISSION_COUNT": self._mission_count_msg,
            "MISSION_ITEM_INT": self._mission_item, "MISSION_ITEM": self._mission_item,
            "MISSION_CURRENT": self._mission_current,
            "MISSION_ITEM_REACHED": self._item_reached, "PARAM_VALUE": self._param_value,
            "DEBUG_VECT": self._contact,
        }
        self._slipping: list[bool] | None = None  # per wheel, once a contact was seen

    # ------------------------------------------------------------------ in

    def feed(self, time_s: float, msg: Any) -> None:
        """Take one message received (or recorded) at ``time_s`` (Unix s); never raises on
        odd contents."""
        index = self._index
        self._index += 1
        self.messages += 1
        try:
            kind = msg.get_type()
            self._senders.add(index, msg)
            if kind in ("ODOMETRY", "MISSION_CURRENT") and not self._vehicle_anchored:
                self.vehicle = (msg.get_srcSystem(), msg.get_srcComponent())
                self._vehicle_anchored = True
            if kind in VEHICLE_ANCHORS:
                self._split = True
            handler = self._handlers.get(kind)
            if handler is not None:
                handler(time_s, msg)
        except (AttributeError, TypeError, ValueError, OverflowError, KeyError):
            return

    def feed_all(self, entries: Iterable[tuple[float, Any]]) -> None:
        """:meth:`feed` each (time Unix s, message)."""
        for time_s, msg in entries:
            self.feed(time_s, msg)

    def _add(self, entity: str, kind: str, time_s: float, value: Any) -> None:
        rows = self._rows.get(entity)
        if rows is None:
            rows = self._rows[entity] = _Rows(kind)
        rows.times.append(time_s)
        rows.values.append(value)

    def _from_vehicle(self, msg: Any) -> bool:
        """Whether ``msg`` is the vehicle's (its system; the companion, not its flight
        controller, where the two share an id)."""
        return (self.vehicle is None or msg.get_srcSystem() == self.vehicle[0]) and \
            self._from_companion()

    def _from_companion(self) -> bool:
        """Whether the message being fed is the companion's, not its flight controller's
        sharing its ids (asked only where it matters: the senders' roles take time)."""
        return not self._split or self._senders.role(self._index - 1) == "vehicle"

    def _event(self, time_s: float, text: str, level: str) -> None:
        self._add("events", "text", time_s, (text, level))

    # ------------------------------------------------------------------ the messages

    def _heartbeat(self, t: float, msg: Any) -> None:
        if msg.type in _NOT_VEHICLES or msg.autopilot == mavlink.MAV_AUTOPILOT_INVALID:
            return
        if self.vehicle is None:
            self.vehicle = (msg.get_srcSystem(), msg.get_srcComponent())
        if (msg.get_srcSystem(), msg.get_srcComponent()) != self.vehicle or \
                not self._from_companion():
            return
        mode = _mode_name(msg)
        armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        if mode != self._mode:
            self._add("state/mode", "state", t, mode)
            self._event(t, f"mode {mode}", "INFO")
            self._mode = mode
        if armed != self._armed:
            self._add("state/armed", "state", t, "armed" if armed else "disarmed")
            self._event(t, "armed" if armed else "disarmed", "INFO")
            self._armed = armed

    def _odometry_msg(self, t: float, msg: Any) -> None:
        if not self._from_vehicle(msg):
            return
        self._odometry = True
        q = msg.q
        yaw = math.atan2(2.0 * (q[0] * q[3] + q[1] * q[2]), 1.0 - 2.0 * (q[2] ** 2 + q[3] ** 2))
        if math.isfinite(yaw):
            self._yaw = yaw
        self._position_at(t, msg.x, msg.y, math.hypot(msg.vx, msg.vy))

    def _local_position(self, t: float, msg: Any) -> None:
        if not self._odometry and self._from_vehicle(msg):
            self._position_at(t, msg.x, msg.y, math.hypot(msg.vx, msg.vy))

    def _attitude(self, t: float, msg: Any) -> None:
        if not self._odometry and self._from_vehicle(msg) and math.isfinite(msg.yaw):
            self._yaw = msg.yaw

    def _position_at(self, t: float, north: float, east: float, speed: float) -> None:
        if not (math.isfinite(north) and math.isfinite(east)):
            return
        here = to_map(north, east)
        if self._position is not None:
            self._add("map/path", "segment", t, (*to_map(*self._position), *here))
        self._position = (north, east)
        self._add("map/rover", "pose", t, (*here, self._yaw))
        if math.isfinite(speed):
            self._add("speed/estimated", "scalar", t, speed)
        if self._mode == Mode.AUTO.name and self._current is not None:
            if self._leg is None:
                self._leg = self._leg_to(self._current, (north, east))
            if self._leg is not None:
                self._add("track/cross_track", "scalar", t, self._leg.distance_m((north, east)))

    def _truth_from(self, msg: Any) -> bool:
        """Whether ``msg`` (SIM_STATE, SIMSTATE, a contact) is truth to draw: once the twin's
        (:data:`TRUTH_SOURCE`) came, its only (the true path, and an origin guessed from
        another's, start again)."""
        twin = (msg.get_srcSystem(), msg.get_srcComponent()) == TRUTH_SOURCE
        if twin and not self._twin_truth:
            self._twin_truth, self._true_position = True, None
            self.origin = None if self._origin_derived else self.origin
        return twin or not self._twin_truth

    def _sim_state(self, t: float, msg: Any) -> None:
        if not self._truth_from(msg):
            return
        lat_e7, lon_e7 = sim_latlon(msg)
        if self.origin is None:
            near = max(abs(lat_e7), abs(lon_e7)) < _NEAR_NULL_ISLAND_DEG * 1e7
            self.origin = GlobalOrigin(0, 0) if near else self._origin_under(lat_e7, lon_e7)
            self._origin_derived = True
        north, east = self.origin.to_local(lat_e7, lon_e7)
        here = to_map(north, east)
        if self._true_position is not None:
            self._add("map/truth", "segment", t, (*to_map(*self._true_position), *here))
        self._true_position = (north, east)
        if msg.get_type() == "SIM_STATE":
            self._add("speed/true", "scalar", t, math.hypot(msg.vn, msg.ve))

    def _origin_under(self, lat_e7: int, lon_e7: int) -> GlobalOrigin:
        """The origin that puts (lat_e7, lon_e7) where the estimate is now (else at 0, 0)."""
        guess = GlobalOrigin(lat_e7, lon_e7)
        north, east = self._position or (0.0, 0.0)
        back_lat, back_lon = guess.to_global(-north, -east)
        return GlobalOrigin(back_lat, back_lon)

    def _global_origin(self, t: float, msg: Any) -> None:
        self.origin = GlobalOrigin(msg.latitude, msg.longitude)

    def _contact(self, t: float, msg: Any) -> None:
        """DEBUG_VECT ``CONTACT_W`` (x normal N, z 1 slipping) of the flight controller or the
        twin's truth only; a slip row at the first and when a wheel starts or stops slipping."""
        fc = (int(self.params["FC_SYSID"]), int(self.params["FC_COMPID"]))
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if msg.name not in CONTACT_NAMES or not self._truth_from(msg):
            return
        if source != TRUTH_SOURCE and (
                source != fc or self._senders.role(self._index - 1) in ("vehicle", "gcs")):
            return
        wheel = CONTACT_NAMES.index(msg.name)
        if math.isfinite(msg.x):
            self._add(f"contacts/normal/{WHEELS[wheel]}", "scalar", t, msg.x)
        slipping = list(self._slipping or [False] * 4)
        slipping[wheel] = msg.z >= 0.5
        if slipping != self._slipping:
            self._chassis_dirty = self._chassis_dirty or self._slipping is None
            self._slipping = slipping
            self._add("map/rover/slip", "slip", t, tuple(slipping))

    def _manual_control(self, t: float, msg: Any) -> None:
        for axis in ("x", "y", "r"):
            value = getattr(msg, axis)
            if value != AXIS_INVALID:
                self._add(f"sticks/{axis}", "scalar", t, value / 1000.0)

    def _servo_output(self, t: float, msg: Any) -> None:
        if self._overrides or msg.port != 0 or not self._from_vehicle(msg):
            return
        self._wheels(t, [getattr(msg, f"servo{w.channel}_raw", 0) if w.channel <= 16 else 0
                         for w in self.pwm.wheels])

    def _override(self, t: float, msg: Any) -> None:
        channels = list(_channels(msg))
        # Whose it is depends on the ids and which channels it leaves alone: decided once per
        # kind (the companion sends one kind 25 times a second).
        key = (msg.get_srcSystem(), msg.get_srcComponent(), msg.target_system,
               msg.target_component, self.vehicle, *[c if c in _LEAVE else -1 for c in channels])
        pilot = self._override_kinds.get(key)
        if pilot is None:
            pilot = self._override_kinds[key] = override_from_pilot(msg, channels, self.vehicle)
        if pilot:
            return
        self._overrides = True  # the companion's own output: every one, not 2 Hz reports
        self._wheels(t, [channels[w.channel - 1] for w in self.pwm.wheels])

    def _wheels(self, t: float, pulses: list[int]) -> None:
        """The wheels' pulses (us; FL, FR, RL, RR; 0 or an override's no-pulse value: no
        output): one row, made PWM, commands and arrows in columns at :meth:`flush`."""
        self._add("wheels", "wheels", t, pulses)

    def _send_wheels(self, rr: Any, recording: rr.RecordingStream, rows: _Rows) -> int:
        """The wheels' rows as ``wheels/pwm/W`` and ``wheels/command/W`` (where a wheel had a
        pulse) and the chassis's arrows: the PWM map's inverse
        (:meth:`~mecanum_mav.control.pwm.WheelOutput.command_from_pulse`) on whole columns."""
        times = np.asarray(rows.times)
        pulses = np.asarray(rows.values, dtype=np.float64)
        live = ~np.isin(pulses, NO_OVERRIDE)
        commands = np.zeros_like(pulses)
        for k, (name, wheel) in enumerate(zip(WHEELS, self.pwm.wheels, strict=True)):
            p = np.clip(pulses[:, k], wheel.minimum, wheel.maximum)
            above = p >= wheel.trim
            span = np.where(above, wheel.maximum - wheel.trim, wheel.trim - wheel.minimum)
            c = (p - wheel.trim) / np.where(span == 0, 1, span)
            commands[:, k] = np.where(live[:, k], -c if wheel.reversed else c, 0.0)
            at = [rr.TimeColumn(TIMELINE, timestamp=times[live[:, k]])]
            recording.send_columns(f"wheels/pwm/{name}", indexes=at,
                                   columns=rr.Scalars.columns(scalars=pulses[live[:, k], k]))
            recording.send_columns(f"wheels/command/{name}", indexes=at,
                                   columns=rr.Scalars.columns(scalars=commands[live[:, k], k]))
        n = len(times)
        vectors = np.zeros((n, 4, 2), dtype=np.float32)
        vectors[:, :, 1] = -commands * float(self.params["GEO_HALF_LEN"])  # forward: map -y
        recording.send_columns(
            "map/rover/wheels", indexes=[rr.TimeColumn(TIMELINE, timestamp=times)],
            columns=rr.Arrows2D.columns(vectors=vectors.reshape(n * 4, 2)).partition([4] * n))
        return n

    def _statustext(self, t: float, msg: Any) -> None:
        self._texts(self._status.add(t, msg))

    def finish(self) -> None:
        """The end of a finished drive: long texts still open are taken as they are."""
        self._texts(self._status.flush())

    def _texts(self, texts: Iterable[tuple[float, int, str]]) -> None:
        for at, severity, text in texts:
            failsafe = is_failsafe(severity, text)
            level = "ERROR" if failsafe else _LEVELS.get(severity, "INFO")
            self._event(at, f"FAILSAFE: {text}" if failsafe else text, level)

    def _mission_count_msg(self, t: float, msg: Any) -> None:
        if msg.mission_type == mavlink.MAV_MISSION_TYPE_MISSION:
            self._mission_count, self._items = msg.count, {}

    def _mission_item(self, t: float, msg: Any) -> None:
        if msg.mission_type != mavlink.MAV_MISSION_TYPE_MISSION:
            return
        self._items[msg.seq] = item_from_fields(
            msg.seq, msg.frame, msg.command, msg.current, msg.autocontinue,
            (msg.param1, msg.param2, msg.param3, msg.param4), msg.x, msg.y, msg.z,
            encoded=msg.get_type() == "MISSION_ITEM_INT")
        items = [self._items[s] for s in sorted(self._items)
                 if self._mission_count is None or s < self._mission_count]
        plan = planned_positions(items, self.origin)
        if plan != self.plan:
            self.plan, self._plan_dirty, self._leg = plan, True, None

    def _mission_current(self, t: float, msg: Any) -> None:
        if self._from_vehicle(msg) and msg.seq != self._current:
            self._current, self._leg = msg.seq, None

    def _item_reached(self, t: float, msg: Any) -> None:
        if self._from_vehicle(msg) and (self._current is None or self._current <= msg.seq):
            self._current, self._leg = msg.seq + 1, None

    def _leg_to(self, seq: int, here: tuple[float, float]) -> Leg | None:
        """The leg to planned item ``seq``: from the planned position before it, else from
        ``here``; None if ``seq`` has no planned position."""
        positions = {s: (n, e) for s, n, e in self.plan}
        if seq not in positions:
            return None
        earlier = [s for s, _, _ in self.plan if s < seq]
        return Leg(positions[earlier[-1]] if earlier else here, positions[seq])

    def _param_value(self, t: float, msg: Any) -> None:
        name = msg.param_id.rstrip("\x00") if isinstance(msg.param_id, str) else ""
        if not (name in _MAP_PARAMS or name.startswith("MOT_")) or not self._from_vehicle(msg):
            return
        try:
            self.params.update({name: float(msg.param_value)})
            self.pwm = PwmMap.from_params(self.params)
        except (ParamError, ValueError):
            return
        self._chassis_dirty = self._chassis_dirty or name in _MAP_PARAMS

    # ------------------------------------------------------------------ out

    def pending(self) -> int:
        """Rows gathered and not yet sent."""
        return sum(len(rows.times) for rows in self._rows.values())

    def flush(self, recording: rr.RecordingStream) -> int:
        """Send what was gathered since the last flush to ``recording`` (``send_columns``, one
        call per entity) and the plan and chassis if they changed (static); returns the rows
        sent."""
        rr = rerun_module()
        if self._chassis_dirty:
            self._send_chassis(rr, recording)
            self._chassis_dirty = False
        if self._plan_dirty:
            self._send_plan(rr, recording)
            self._plan_dirty = False
        sent = 0
        for entity, rows in self._rows.items():
            if not rows.times:
                continue
            if rows.kind == "wheels":
                sent += self._send_wheels(rr, recording, rows)
                rows.times, rows.values = [], []
                continue
            recording.send_columns(
                entity, indexes=[rr.TimeColumn(TIMELINE, timestamp=np.asarray(rows.times))],
                columns=_columns(rr, rows.kind, rows.values))
            sent += len(rows.times)
            rows.times, rows.values = [], []
        return sent

    def _send_chassis(self, rr: Any, recording: rr.RecordingStream) -> None:
        half_len, half_wid = (float(self.params[name]) for name in _MAP_PARAMS)
        corners = [(half_len, -half_wid), (half_len, half_wid), (-half_len, half_wid),
                   (-half_len, -half_wid), (half_len, -half_wid)]
        nose = [(0.0, 0.0), (half_len, 0.0)]
        wheels = [(half_len, -half_wid), (half_len, half_wid), (-half_len, -half_wid),
                  (-half_len, half_wid)]
        wheel_size = (half_wid * 0.5, half_len * 0.4)  # (map x, map y) half sizes
        recording.log("map/rover/chassis", rr.LineStrips2D(
            [[_body_to_map(*p) for p in corners], [_body_to_map(*p) for p in nose]],
            colors=[_CHASSIS_COLOUR], radii=[half_wid * 0.04]), static=True)
        recording.log("map/rover/chassis/wheels", rr.Boxes2D(
            centers=[_body_to_map(*p) for p in wheels], half_sizes=[wheel_size] * 4,
            colors=[_CHASSIS_COLOUR]), static=True)
        if self._slipping is not None:  # the contacts' boxes (their colours are temporal)
            recording.log("map/rover/slip", rr.Boxes2D.from_fields(
                centers=[_body_to_map(*p) for p in wheels], half_sizes=[wheel_size] * 4,
                radii=[half_wid * 0.05], draw_order=[40.0]), static=True)
        recording.log("map/rover/wheels", rr.Arrows2D.from_fields(
            origins=[_body_to_map(*p) for p in wheels], colors=[_WHEEL_COLOUR],
            radii=[half_wid * 0.06]), static=True)

    def _send_plan(self, rr: Any, recording: rr.RecordingStream) -> None:
        points = [to_map(n, e) for _, n, e in self.plan]
        recording.log("map/plan", rr.LineStrips2D([points] if len(points) > 1 else [],
                                                  colors=[_PLAN_COLOUR]), static=True)
        recording.log("map/plan/items", rr.Points2D(
            points, labels=[str(seq) for seq, _, _ in self.plan], colors=[_PLAN_COLOUR]),
            static=True)

    def start(self, recording: rr.RecordingStream) -> None:
        """Send the view's layout (:func:`blueprint`) and the map's colours (static)."""
        rr = rerun_module()
        recording.send_blueprint(blueprint())
        recording.log("map/path", rr.LineStrips2D.from_fields(
            colors=[_PATH_COLOUR], radii=[0.008], draw_order=[31.0]), static=True)
        recording.log("map/truth", rr.LineStrips2D.from_fields(
            colors=[_TRUTH_COLOUR], radii=[0.02], draw_order=[30.0]), static=True)
        for entity, name in (("speed/estimated", "speed (estimated)"),
                             ("speed/true", "speed (true)"),
                             ("track/cross_track", "cross-track")):
            recording.log(entity, rr.SeriesLines(names=[name]), static=True)


_LEVELS = {mavlink.MAV_SEVERITY_EMERGENCY: "CRITICAL", mavlink.MAV_SEVERITY_ALERT: "CRITICAL",
           mavlink.MAV_SEVERITY_CRITICAL: "CRITICAL", mavlink.MAV_SEVERITY_ERROR: "ERROR",
           mavlink.MAV_SEVERITY_WARNING: "WARN", mavlink.MAV_SEVERITY_NOTICE: "INFO",
           mavlink.MAV_SEVERITY_INFO: "INFO", mavlink.MAV_SEVERITY_DEBUG: "DEBUG"}
"""Rerun's text log level of each MAVLink severity."""
