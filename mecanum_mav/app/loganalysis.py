"""What a tlog says about a drive: pure analysis of its messages (no files, no plotting).

:func:`analyse` takes the messages of a tlog (:mod:`mecanum_mav.io.tlog`) and returns a
:class:`LogAnalysis`: the path, the simulator's true path where the log has one, the planned
mission, stick input, PWM, modes, failsafe events and mission progress over time, and the
summary figures (distance, time per mode, worst cross-track per leg). Whatever the log lacks is
left empty; nothing here raises on a message with unexpected contents.

Where things come from (``vehicle`` is the system the ground station talks to: the sender of
ODOMETRY or MISSION_CURRENT, else of the most vehicle HEARTBEATs):

- path: the vehicle's ODOMETRY, else LOCAL_POSITION_NED, else GLOBAL_POSITION_INT; metres north
  and east of the local origin.
- true path: SIM_STATE (the simulated board of ``mecanum-mav sim``, ArduPilot's simulators) or
  ArduPilot's SIMSTATE.
- global positions (GLOBAL_POSITION_INT, SIM_STATE, global mission items) are placed about the
  origin the log gives: GPS_GLOBAL_ORIGIN or SET_GPS_GLOBAL_ORIGIN; else the one that puts the
  vehicle's GLOBAL_POSITION_INT on its local position; else latitude and longitude 0, 0 if the
  positions are within a degree of it (a simulator without an origin); else the first one.
- planned mission: the last MISSION_COUNT's MISSION_ITEM_INT / MISSION_ITEM (uploads and
  downloads alike); items with a position from seq 1 on (item 0 is home).
- sticks: MANUAL_CONTROL x, y, r (-1000..1000 -> -1..1), and the pilot's RC_CHANNELS_OVERRIDE
  (MAVProxy's ``rc``) read as the rover reads it with its default parameters
  (:data:`RC_STICKS`; :class:`~mecanum_mav.control.sticks.RcStickState`), by sender.
- PWM: the companion's RC_CHANNELS_OVERRIDE to its flight controller, by sender and target,
  and SERVO_OUTPUT_RAW. Normalized wheel commands are not on the wire and are not shown.
  Which override is whose: :func:`override_from_pilot`.
- modes: the vehicle's HEARTBEAT (``custom_mode`` and the armed flag); a change is placed at
  the accepted mode or arming command (COMMAND_ACK), failsafe or reached item that caused it
  since the heartbeat before, else at the heartbeat that first shows it.
- events: STATUSTEXT, a long text's chunks (MAVLink 2 ``id`` != 0, ``chunk_seq`` 0, 1, ...)
  joined into one text per sender and ``id``, at its first chunk's time. Failsafes:
  :func:`is_failsafe`.
- progress: MISSION_CURRENT and MISSION_ITEM_REACHED (a reached item makes the next one
  current at once). A leg is the line from the previous mission position (or, for the first,
  from where the vehicle was when it became current) to an item; its cross-track is the
  largest distance of the path from that segment while the item was current in AUTO (in any
  mode if the log has no HEARTBEAT).

Two senders can share a system and component id: the companion and its flight controller are
both 1/1 by default, the companion's flight-controller link and a Mission Planner-like ground
station both 255/190, and a tlog has no link tag. Such senders are told apart by their
sequence numbers (each sender counts its own packets): a packet continues the sender whose
last sequence number is closest below its own. A sender that sends ODOMETRY is the companion,
one that sends MANUAL_CONTROL, COMMAND_LONG, SET_MODE or mission uploads a ground station; the
vehicle's modes come from the companion's HEARTBEATs only.
"""

from __future__ import annotations

import bisect
import itertools
import math
import re
from collections import Counter, defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import RcInputConfig
from mecanum_mav.control.core import FC_LINK_COMPID
from mecanum_mav.control.pathfollow import Leg
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.control.sticks import InputError, RcStickState
from mecanum_mav.io.tlog import TlogEntry
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.dialect import mavlink, mavutil
from mecanum_mav.protocol.mission import MissionItem, item_from_fields, position_ned
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.rcoverride import LEAVE, field_action
from mecanum_mav.protocol.statustext import STATUSTEXT_LEN

__all__ = ["INPUT_TIMEOUT_S", "OVERRIDE_TIMEOUT_S", "RC_STICKS", "LegStat", "LogAnalysis",
           "ModeSpan", "StatusEvent", "analyse", "is_failsafe", "override_from_pilot"]

Vec = tuple[float, float]
PathPoint = tuple[float, float, float]
"""(time s from the log's start, north m, east m)."""

AXIS_INVALID = 0x7FFF
MAX_SEQ_GAP = 16
"""A packet continues a sender whose last sequence number is at most this far below (lost
packets); farther, it is a new sender."""
MAX_SENDERS = 4
"""Senders kept apart per system and component id."""
_VEHICLE_ANCHORS = frozenset({"ODOMETRY"})
_GCS_ANCHORS = frozenset({"MANUAL_CONTROL", "COMMAND_LONG", "COMMAND_INT", "SET_MODE",
                          "MISSION_COUNT", "PARAM_SET", "SET_POSITION_TARGET_LOCAL_NED"})
_NOT_VEHICLES = frozenset({mavlink.MAV_TYPE_GCS, mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
                           mavlink.MAV_TYPE_GIMBAL, mavlink.MAV_TYPE_ADSB,
                           mavlink.MAV_TYPE_CAMERA})
_DEFAULTS = Params()
RC_STICKS: RcInputConfig = RcInputConfig.from_params(_DEFAULTS)
"""How a pilot's RC override is read as sticks: the rover's defaults (RCMAP_THROTTLE 3 forward,
RCMAP_LATERAL 4 right, RCMAP_STEER 1 clockwise; RCIN_MIN/TRIM/MAX 1000/1500/2000 us)."""
INPUT_TIMEOUT_S = float(_DEFAULTS["FS_INPUT_TMO"])
"""Stick input older than this no longer drives the rover (FS_INPUT_TMO's default, s)."""
OVERRIDE_TIMEOUT_S = float(_DEFAULTS["SIM_RC_TMO"])
"""A flight controller lets an override lapse after this long without one (ArduPilot's
RC_OVERRIDE_TIME default, which the simulator's SIM_RC_TMO defaults to; s)."""
_WHEEL_CHANNELS = frozenset(PwmMap.from_params(_DEFAULTS).channels)
"""The channels the companion's overrides set by default (MOT_FL_CH ... MOT_RR_CH)."""
_FAILSAFE_TEXT = re.compile(r"fail\s*-?safe|\blost\b", re.IGNORECASE)
_REFUSAL_TEXT = re.compile(r"^\s*(?:pre\s*-?arm|arm)\s*:", re.IGNORECASE)
_CLEARED_TEXT = re.compile(
    r"\b(?:cleared|restored|regained|resumed|recovered|reconnected|link\s+up|ok)\b",
    re.IGNORECASE)
_ACTION_TEXT = re.compile(r"^\s*disarmed\b", re.IGNORECASE)
_NAV_COMMANDS = frozenset({
    mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_LOITER_UNLIM,
    mavlink.MAV_CMD_NAV_LOITER_TURNS, mavlink.MAV_CMD_NAV_LOITER_TIME,
    mavlink.MAV_CMD_NAV_SPLINE_WAYPOINT, mavlink.MAV_CMD_NAV_LAND,
    mavlink.MAV_CMD_NAV_LOITER_TO_ALT})
_RTL = mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH
_MODE_COMMANDS = frozenset({mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_CMD_COMPONENT_ARM_DISARM,
                            mavlink.MAV_CMD_MISSION_START, 11})  # 11: SET_MODE's acknowledgement
_NEAR_NULL_ISLAND_E7 = 10_000_000


def is_failsafe(severity: int, text: str) -> bool:
    """Whether a STATUSTEXT (``severity`` MAV_SEVERITY, whole ``text``) starts a failsafe.

    A failsafe is an event that starts one: a text that says "failsafe" or "lost", or any
    text of severity CRITICAL or worse, unless it is one of these, which are not:

    - a pre-arm or arming refusal: the text begins "PreArm:" or "Arm:" (ArduPilot sends
      them at CRITICAL, e.g. "PreArm: Radio failsafe on"; the companion words its refusals
      the same way, e.g. "PreArm: radio failsafe (receiver)");
    - a clearance: the text says "cleared", "restored", "regained", "resumed",
      "recovered", "reconnected", "link up" or "OK" (ArduPilot's "Radio Failsafe Cleared",
      "GCS Failsafe Cleared"; the companion's "GCS link regained, mode HOLD", "Manual input
      resumed", "Flight controller link up", "Radio receiver OK, mode MANUAL", "... link
      reconnected");
    - a failsafe's action, not its start: the text begins "Disarmed" (the companion's
      "Disarmed: GCS failsafe" follows its "GCS link lost: failsafe").

    So ArduPilot's "Radio Failsafe" and "GCS Failsafe", and the companion's "GCS link lost:
    failsafe" (CRITICAL), "Flight controller link lost" (CRITICAL), "Radio failsafe: ..."
    (CRITICAL) and "Manual input lost: wheels neutral" (WARNING) are failsafes.
    """
    if _REFUSAL_TEXT.match(text) or _CLEARED_TEXT.search(text) or _ACTION_TEXT.match(text):
        return False
    return severity <= mavlink.MAV_SEVERITY_CRITICAL or bool(_FAILSAFE_TEXT.search(text))


def override_from_pilot(msg: Any, channels: Sequence[int],
                        vehicle: tuple[int, int] | None) -> bool:
    """Whether an RC_CHANNELS_OVERRIDE (``channels``: its 18 ``chanN_raw``) is the pilot's
    stick input (a ground station's, e.g. MAVProxy's ``rc 3 1700``, sent to the vehicle)
    rather than the companion's PWM output (sent from its flight-controller link, system
    FC_GCS_SYSID (255) component 190, to the flight controller). In order:

    1. sent to another system than ``vehicle``'s (target not 0): the companion's, to its
       flight controller (whose FC_SYSID is not the companion's SYSID_THISMAV);
    2. sent from another component than 190: the pilot's (MAVProxy sends as component 0
       or 230, and the companion's flight-controller link is always 190; the system id
       does not tell, ground stations send as 255 too and FC_GCS_SYSID may be set to
       another);
    3. else (sender and target alike, as a Mission Planner-like 255/190 pilot and the
       companion by default): the companion's if it sets or releases exactly the default
       wheel channels (MOT_x_CH: 1-4) and leaves every other, the pilot's otherwise
       (MAVProxy's ``rc`` sets its channels and releases the rest of 1-8).
    """
    target = msg.target_system
    if vehicle is not None and target not in (0, vehicle[0]):
        return False
    if msg.get_srcComponent() != FC_LINK_COMPID:
        return True
    touched = {n for n, raw in enumerate(channels, start=1) if field_action(n, raw) != LEAVE}
    return touched != _WHEEL_CHANNELS


class _StatusChunks:
    """Joins the chunks of long STATUSTEXTs (see the module docstring).

    A chunk (``id`` != 0) opens or continues the text of its sender and ``id``; a chunk whose
    text is shorter than :data:`STATUSTEXT_LEN` bytes (NUL-terminated) ends it, and so does a
    chunk_seq already held (the ``id`` reused for a new text). Texts still open at the log's
    end are given as they are.
    """

    def __init__(self) -> None:
        self._open: dict[tuple[int, int, int], tuple[float, int, dict[int, str]]] = {}

    def add(self, t: float, msg: Any) -> list[tuple[float, int, str]]:
        """The (time, severity, text) completed by one STATUSTEXT at ``t``."""
        text = str(msg.text).split("\x00", 1)[0]
        ident = getattr(msg, "id", 0) or 0
        if not ident:
            return [(t, msg.severity, text)]
        key = (msg.get_srcSystem(), msg.get_srcComponent(), ident)
        seq = getattr(msg, "chunk_seq", 0) or 0
        done = []
        if key in self._open and seq in self._open[key][2]:
            done.append(self._close(key))
        chunks = self._open.setdefault(key, (t, msg.severity, {}))[2]
        chunks[seq] = text
        if len(text.encode("utf-8", "replace")) < STATUSTEXT_LEN:
            done.append(self._close(key))
        return done

    def flush(self) -> list[tuple[float, int, str]]:
        """The texts still open (their last chunk not in the log)."""
        return [self._close(key) for key in list(self._open)]

    def _close(self, key: tuple[int, int, int]) -> tuple[float, int, str]:
        t, severity, chunks = self._open.pop(key)
        return t, severity, "".join(chunks[seq] for seq in sorted(chunks))


def _length(path: Sequence[PathPoint]) -> float:
    """Length of a path, metres."""
    return sum(math.dist(a[1:], b[1:]) for a, b in itertools.pairwise(path))


@dataclass(frozen=True)
class ModeSpan:
    """The vehicle in one mode from ``start_s`` to ``end_s`` (seconds from the log's start)."""

    start_s: float
    end_s: float
    mode: str
    armed: bool

    @property
    def duration_s(self) -> float:
        """Length of the span, seconds."""
        return self.end_s - self.start_s


@dataclass(frozen=True)
class StatusEvent:
    """A STATUSTEXT at ``time_s`` (seconds from the log's start)."""

    time_s: float
    severity: int
    text: str
    failsafe: bool


@dataclass(frozen=True)
class LegStat:
    """One mission leg as driven: to item ``seq`` at ``goal`` (north m, east m)."""

    seq: int
    start: Vec
    goal: Vec
    time_s: float
    max_cross_track_m: float
    samples: int


@dataclass
class LogAnalysis:
    """What :func:`analyse` found; times are seconds from the log's first message.

    Attributes:
        start_unix_s: Unix time of the first message.
        duration_s: from the first message to the last.
        messages: messages analysed.
        vehicle: (system, component) of the vehicle, or None.
        path: the vehicle's position over time; ``path_source`` names the message.
        true_path: the simulator's true position over time (empty for a real vehicle).
        planned: the mission's positions by item (seq, north m, east m), seq 1 on.
        sticks: (time, x, y, r) of every MANUAL_CONTROL, normalized (NaN: axis invalid).
        pilot_overrides: sender ("255/230") -> (time, 18 channels) of the pilot's
            RC_CHANNELS_OVERRIDE (:func:`override_from_pilot`).
        pilot_sticks: sender -> (time, x, y, r), the pilot's overrides that set or release a
            stick channel read as sticks (:data:`RC_STICKS`), x forward, y right,
            r clockwise, -1..1.
        overrides: sender and target ("255/190 -> 1/1") -> (time, 18 channels) of the
            companion's RC_CHANNELS_OVERRIDE (PWM to the flight controller).
        servo: (time, 16 pulses) of SERVO_OUTPUT_RAW (port 0 outputs 1-16).
        modes: the vehicle's modes, in order, without gaps.
        events: every STATUSTEXT, chunks joined, in time order (``failsafe`` marks the
            failsafes, :func:`is_failsafe`).
        mission_current: (time, seq) whenever the current item changed.
        reached: (time, seq) of every MISSION_ITEM_REACHED.
        legs: the mission legs driven in AUTO, in order.
        origin: the global origin used for global positions, or None.
    """

    start_unix_s: float = 0.0
    duration_s: float = 0.0
    messages: int = 0
    vehicle: tuple[int, int] | None = None
    path: list[PathPoint] = field(default_factory=list)
    path_source: str = ""
    true_path: list[PathPoint] = field(default_factory=list)
    planned: list[tuple[int, float, float]] = field(default_factory=list)
    sticks: list[tuple[float, float, float, float]] = field(default_factory=list)
    pilot_overrides: dict[str, list[tuple[float, list[int]]]] = field(default_factory=dict)
    pilot_sticks: dict[str, list[tuple[float, float, float, float]]] = field(
        default_factory=dict)
    overrides: dict[str, list[tuple[float, list[int]]]] = field(default_factory=dict)
    servo: list[tuple[float, list[int]]] = field(default_factory=list)
    modes: list[ModeSpan] = field(default_factory=list)
    events: list[StatusEvent] = field(default_factory=list)
    mission_current: list[tuple[float, int]] = field(default_factory=list)
    reached: list[tuple[float, int]] = field(default_factory=list)
    legs: list[LegStat] = field(default_factory=list)
    origin: GlobalOrigin | None = None

    @property
    def distance_m(self) -> float:
        """Length of :attr:`path`, metres."""
        return _length(self.path)

    @property
    def true_distance_m(self) -> float:
        """Length of :attr:`true_path`, metres."""
        return _length(self.true_path)

    @property
    def failsafes(self) -> list[StatusEvent]:
        """The failsafe events."""
        return [e for e in self.events if e.failsafe]

    def time_per_mode(self) -> dict[str, float]:
        """Seconds spent in each mode, in the order the modes first appear."""
        out: dict[str, float] = {}
        for span in self.modes:
            out[span.mode] = out.get(span.mode, 0.0) + span.duration_s
        return out

    def armed_s(self) -> float:
        """Seconds armed."""
        return sum(span.duration_s for span in self.modes if span.armed)


# ---------------------------------------------------------------------- senders


@dataclass
class _Chain:
    """One sender's packets so far."""

    number: int
    last_seq: int
    last_index: int
    kinds: set[str] = field(default_factory=set)


class _Senders:
    """Tells apart senders sharing a system and component id (see the module docstring).

    A packet continues the sender whose last sequence number is closest below its own; where
    two are equally close (their counts met), the one that has sent this message before, then
    the one silent longest.
    """

    def __init__(self) -> None:
        self._chains: dict[tuple[int, int], list[_Chain]] = defaultdict(list)
        self._anchors: dict[int, list[tuple[int, str]]] = defaultdict(list)
        self._siblings: dict[int, list[int]] = {}
        """chain number -> the numbers of every chain of its id."""
        self.chain_of: list[int] = []
        self._count = 0

    def add(self, index: int, msg: Any) -> None:
        """Assign message number ``index`` to a sender."""
        seq, kind = msg.get_seq(), msg.get_type()
        chains = self._chains[(msg.get_srcSystem(), msg.get_srcComponent())]
        best: _Chain | None = None
        best_rank = (MAX_SEQ_GAP + 1, False, 0)
        for chain in chains:
            rank = ((seq - chain.last_seq - 1) % 256, kind not in chain.kinds, chain.last_index)
            if rank < best_rank:
                best, best_rank = chain, rank
        if best is None:
            best = _Chain(self._count, seq, index)
            self._count += 1
            chains.append(best)
            siblings = self._siblings.get(chains[0].number, [])
            siblings.append(best.number)
            self._siblings[best.number] = siblings
            if len(chains) > MAX_SENDERS:  # forget the one silent longest
                chains.remove(min(chains, key=lambda c: c.last_index))
        best.last_seq, best.last_index = seq, index
        best.kinds.add(kind)
        self.chain_of.append(best.number)
        if kind in _VEHICLE_ANCHORS:
            self._anchor(chains, best.number, index, "vehicle")
        elif kind in _GCS_ANCHORS:
            self._anchor(chains, best.number, index, "gcs")

    def _anchor(self, chains: list[_Chain], chain: int, index: int, role: str) -> None:
        """``chain`` has ``role`` from message ``index`` on; a sender of the same id that had
        it (the two were confused where their sequence numbers met) no longer has."""
        for other in chains:
            anchors = self._anchors[other.number]
            if other.number == chain:
                if not anchors or anchors[-1][1] != role:
                    anchors.append((index, role))
            elif anchors and anchors[-1][1] == role:
                anchors.append((index, "other"))

    def role(self, index: int) -> str | None:
        """The role of message ``index``'s sender: "vehicle", "gcs", "other" or None
        (unknown): the sender's last anchor before it; before its first anchor, that anchor's
        role unless another sender of its id had that role then."""
        chain = self.chain_of[index]
        before = self._role_before(chain, index)
        if before is not None:
            return before
        anchors = self._anchors.get(chain)
        if not anchors:
            return None
        role = anchors[0][1]
        taken = any(self._role_before(other, index) == role
                    for other in self._siblings[chain] if other != chain)
        return None if taken else role

    def _role_before(self, chain: int, index: int) -> str | None:
        role = None
        for at, kind in self._anchors.get(chain, ()):
            if at > index:
                break
            role = kind
        return role


# ---------------------------------------------------------------------- analysis


def _vehicle(entries: Sequence[TlogEntry]) -> tuple[int, int] | None:
    beats: Counter[tuple[int, int]] = Counter()
    for e in entries:
        kind = e.msg.get_type()
        if kind in ("ODOMETRY", "MISSION_CURRENT"):
            return e.msg.get_srcSystem(), e.msg.get_srcComponent()
        if (kind == "HEARTBEAT" and e.msg.type not in _NOT_VEHICLES
                and e.msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID):
            beats[(e.msg.get_srcSystem(), e.msg.get_srcComponent())] += 1
    return beats.most_common(1)[0][0] if beats else None


def _mode_name(msg: Any) -> str:
    if (msg.type == mavlink.MAV_TYPE_GROUND_ROVER
            and msg.autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA):
        try:
            return Mode(msg.custom_mode).name
        except ValueError:
            pass
    try:
        return str(mavutil.mode_string_v10(msg))
    except Exception:  # pymavlink's tables may not know the type
        return f"mode {msg.custom_mode}"


def _origin(entries: Sequence[TlogEntry], vehicle: tuple[int, int] | None
            ) -> GlobalOrigin | None:
    """The log's global origin (see the module docstring), None if it has no global
    position."""
    local: Vec | None = None
    first_global: tuple[int, int] | None = None
    for e in entries:
        msg, kind = e.msg, e.msg.get_type()
        try:
            if kind in ("GPS_GLOBAL_ORIGIN", "SET_GPS_GLOBAL_ORIGIN"):
                return GlobalOrigin(msg.latitude, msg.longitude)
            if kind in ("LOCAL_POSITION_NED", "ODOMETRY") and _from(msg, vehicle):
                local = (msg.x, msg.y)
            elif kind == "GLOBAL_POSITION_INT" and _from(msg, vehicle):
                if local is not None and (msg.lat, msg.lon) != (0, 0):
                    return _origin_under(msg.lat, msg.lon, local)
                first_global = first_global or (msg.lat, msg.lon)
            elif kind in ("SIM_STATE", "SIMSTATE") and first_global is None:
                first_global = _sim_latlon(msg)
        except ValueError:
            continue
    if first_global is None:
        return None
    if max(abs(first_global[0]), abs(first_global[1])) < _NEAR_NULL_ISLAND_E7:
        return GlobalOrigin(0, 0)
    return GlobalOrigin(*first_global)


def _origin_under(lat_e7: int, lon_e7: int, local: Vec) -> GlobalOrigin:
    """The origin from which (lat_e7, lon_e7) is at ``local`` (north m, east m)."""
    guess = GlobalOrigin(lat_e7, lon_e7)
    for _ in range(2):  # the east scale depends on the origin's latitude: refine once
        n, e = guess.to_local(lat_e7, lon_e7)
        back_lat, back_lon = guess.to_global(n - local[0], e - local[1])
        guess = GlobalOrigin(back_lat, back_lon)
    return guess


def _sim_latlon(msg: Any) -> tuple[int, int]:
    if msg.get_type() == "SIMSTATE":
        return int(msg.lat), int(msg.lng)
    lat_int, lon_int = getattr(msg, "lat_int", 0), getattr(msg, "lon_int", 0)
    if lat_int or lon_int:
        return int(lat_int), int(lon_int)
    return round(msg.lat * 1e7), round(msg.lon * 1e7)


def _from(msg: Any, who: tuple[int, int] | None) -> bool:
    return who is None or msg.get_srcSystem() == who[0]


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


def _mission(entries: Sequence[TlogEntry]) -> list[MissionItem]:
    """The last mission in the log (see the module docstring)."""
    count: int | None = None
    items: dict[int, MissionItem] = {}
    for e in entries:
        msg, kind = e.msg, e.msg.get_type()
        if kind == "MISSION_COUNT" and msg.mission_type == mavlink.MAV_MISSION_TYPE_MISSION:
            count, items = msg.count, {}
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM") and (
                msg.mission_type == mavlink.MAV_MISSION_TYPE_MISSION):
            try:
                items[msg.seq] = item_from_fields(
                    msg.seq, msg.frame, msg.command, msg.current, msg.autocontinue,
                    (msg.param1, msg.param2, msg.param3, msg.param4), msg.x, msg.y, msg.z,
                    encoded=kind == "MISSION_ITEM_INT")
            except (ValueError, OverflowError):
                continue
    return [items[s] for s in sorted(items) if count is None or s < count]


def _planned(items: Iterable[MissionItem], origin: GlobalOrigin | None
             ) -> list[tuple[int, float, float]]:
    out = []
    for item in items:
        if item.seq < 1:
            continue
        if item.command == _RTL:
            out.append((item.seq, 0.0, 0.0))
        elif item.command in _NAV_COMMANDS:
            try:
                n, e = position_ned(item, origin)
            except ValueError:
                continue
            if _finite(n, e):
                out.append((item.seq, n, e))
    return out


def _mode_spans(beats: list[tuple[float, str, bool]], causes: Sequence[float],
                end_s: float) -> list[ModeSpan]:
    """Spans from the vehicle's heartbeats (time, mode, armed). A change first seen in a
    heartbeat is placed at the first of ``causes`` (sorted times of accepted mode and arming
    commands, failsafes, reached items) since the heartbeat before, else at the heartbeat
    (the first: a command that resumes AUTO comes before the item it then reaches)."""
    starts: list[tuple[float, str, bool]] = []
    previous_t = -math.inf
    for t, mode, armed in beats:
        if not starts or (starts[-1][1], starts[-1][2]) != (mode, armed):
            k = bisect.bisect_right(causes, previous_t)
            at = causes[k] if k < len(causes) and causes[k] <= t and starts else t
            starts.append((at, mode, armed))
        previous_t = t
    if not starts:  # no heartbeat of the vehicle
        return []
    ends = [t for t, _, _ in starts[1:]] + [end_s]
    return [ModeSpan(t, max(t_end, t), mode, armed)
            for (t, mode, armed), t_end in zip(starts, ends, strict=True)]


def _mode_at(spans: Sequence[ModeSpan], t: float) -> str | None:
    for span in spans:
        if span.start_s <= t < span.end_s or (span is spans[-1] and t >= span.start_s):
            return span.mode
    return None


def _legs(result: LogAnalysis) -> list[LegStat]:
    """Per leg: time current in AUTO and the largest distance of the path from it."""
    positions = {seq: (n, e) for seq, n, e in result.planned}
    order = [seq for seq, _, _ in result.planned]
    changes = sorted([(t, seq, 0) for t, seq in result.mission_current]
                     + [(t, seq, 1) for t, seq in result.reached])
    stats: dict[int, dict[str, Any]] = {}
    current: int | None = None
    k = 0
    has_modes = bool(result.modes)
    previous_t: float | None = None
    for t, n, e in result.path:
        while k < len(changes) and changes[k][0] <= t:
            _, seq, reached = changes[k]
            current = seq + 1 if reached and (current is None or current <= seq) else (
                current if reached else seq)
            k += 1
        in_auto = not has_modes or _mode_at(result.modes, t) == Mode.AUTO.name
        if current is None or current not in positions or not in_auto:
            previous_t = None
            continue
        stat = stats.get(current)
        if stat is None:
            earlier = [s for s in order if s < current]
            start = positions[earlier[-1]] if earlier else (n, e)
            stat = stats[current] = {"leg": Leg(start, positions[current]), "time": 0.0,
                                     "max": 0.0, "samples": 0, "order": len(stats)}
        if previous_t is not None:
            stat["time"] += t - previous_t
        stat["max"] = max(stat["max"], stat["leg"].distance_m((n, e)))
        stat["samples"] += 1
        previous_t = t
    return [LegStat(seq, s["leg"].start_ned, s["leg"].end_ned, s["time"], s["max"],
                    s["samples"])
            for seq, s in sorted(stats.items(), key=lambda kv: kv[1]["order"])]


def _pilot_stick(result: LogAnalysis, states: dict[str, RcStickState], sender: str, t: float,
                 channels: list[int]) -> None:
    """Add the sticks a pilot's override gives (as the rover reads it; a channel left alone
    keeps its pulse) to ``result.pilot_sticks``; an override the rover would reject (a pulse
    outside 800..2200 us) or that touches no stick channel gives none."""
    state = states.setdefault(sender, RcStickState())
    try:
        state.apply(channels)
    except InputError:
        return
    if state.touches_sticks(channels, RC_STICKS):
        x, y, r = state.stick(RC_STICKS)
        result.pilot_sticks.setdefault(sender, []).append((t, x, y, r))


def analyse(entries: Sequence[TlogEntry]) -> LogAnalysis:
    """Analyse a tlog's messages (see the module docstring); never raises on odd contents."""
    result = LogAnalysis(messages=len(entries))
    if not entries:
        return result
    t0 = entries[0].time_s
    result.start_unix_s = t0
    result.duration_s = max(e.time_s for e in entries) - t0
    senders = _Senders()
    for index, e in enumerate(entries):
        senders.add(index, e.msg)
    vehicle = result.vehicle = _vehicle(entries)
    origin = result.origin = _origin(entries, vehicle)
    vehicle_split = any(e.msg.get_type() in _VEHICLE_ANCHORS for e in entries)
    paths: dict[str, list[PathPoint]] = defaultdict(list)
    beats: list[tuple[float, str, bool]] = []
    causes: list[float] = []
    last_current: int | None = None
    pilot_states: dict[str, RcStickState] = {}
    status = _StatusChunks()
    texts: list[tuple[float, int, str]] = []
    for index, e in enumerate(entries):
        msg, kind, t = e.msg, e.msg.get_type(), e.time_s - t0
        try:
            if kind == "HEARTBEAT":
                if (vehicle is not None
                        and (msg.get_srcSystem(), msg.get_srcComponent()) == vehicle
                        and (not vehicle_split or senders.role(index) == "vehicle")):
                    armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
                    beats.append((t, _mode_name(msg), armed))
            elif kind in ("ODOMETRY", "LOCAL_POSITION_NED") and _from(msg, vehicle):
                if _finite(msg.x, msg.y):
                    paths[kind].append((t, msg.x, msg.y))
            elif kind == "GLOBAL_POSITION_INT" and _from(msg, vehicle) and origin is not None:
                if (msg.lat, msg.lon) != (0, 0):
                    paths[kind].append((t, *origin.to_local(msg.lat, msg.lon)))
            elif kind in ("SIM_STATE", "SIMSTATE") and origin is not None:
                lat, lon = _sim_latlon(msg)
                result.true_path.append((t, *origin.to_local(lat, lon)))
            elif kind == "MANUAL_CONTROL":
                axes = [math.nan if v == AXIS_INVALID else v / 1000.0
                        for v in (msg.x, msg.y, msg.r)]
                result.sticks.append((t, axes[0], axes[1], axes[2]))
            elif kind == "RC_CHANNELS_OVERRIDE":
                channels = [getattr(msg, f"chan{i}_raw", 0) for i in range(1, 19)]
                sender = f"{msg.get_srcSystem()}/{msg.get_srcComponent()}"
                if override_from_pilot(msg, channels, vehicle):
                    result.pilot_overrides.setdefault(sender, []).append((t, channels))
                    _pilot_stick(result, pilot_states, sender, t, channels)
                else:
                    label = f"{sender} -> {msg.target_system}/{msg.target_component}"
                    result.overrides.setdefault(label, []).append((t, channels))
            elif kind == "SERVO_OUTPUT_RAW" and msg.port == 0:
                pulses = [getattr(msg, f"servo{i}_raw", 0) for i in range(1, 17)]
                result.servo.append((t, pulses))
            elif kind == "STATUSTEXT":
                texts += status.add(t, msg)
            elif kind == "MISSION_CURRENT" and _from(msg, vehicle):
                if msg.seq != last_current:
                    result.mission_current.append((t, msg.seq))
                    last_current = msg.seq
            elif (kind == "COMMAND_ACK" and _from(msg, vehicle) and msg.command in _MODE_COMMANDS
                  and msg.result == mavlink.MAV_RESULT_ACCEPTED):
                causes.append(t)
            elif kind == "MISSION_ITEM_REACHED" and _from(msg, vehicle):
                result.reached.append((t, msg.seq))
        except (AttributeError, TypeError, ValueError):
            continue
    texts += status.flush()
    result.events = [StatusEvent(t, severity, text, is_failsafe(severity, text))
                     for t, severity, text in sorted(texts, key=lambda x: x[0])]
    for source in ("ODOMETRY", "LOCAL_POSITION_NED", "GLOBAL_POSITION_INT"):
        if paths.get(source):
            result.path, result.path_source = paths[source], source
            break
    result.planned = _planned(_mission(entries), origin)
    causes = sorted([*causes, *(e.time_s for e in result.failsafes),
                     *(t for t, _ in result.reached)])
    result.modes = _mode_spans(beats, causes, result.duration_s)
    result.legs = _legs(result)
    return result
