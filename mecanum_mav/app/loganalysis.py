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
  origin the log gives (:func:`~mecanum_mav.app.logmission.log_origin`).
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
- events: STATUSTEXT, a long text's chunks joined
  (:class:`~mecanum_mav.protocol.statustext.StatusChunks`).
  Failsafes: :func:`is_failsafe`.
- progress: MISSION_CURRENT and MISSION_ITEM_REACHED (a reached item makes the next one
  current at once); legs and their cross-track:
  :func:`~mecanum_mav.app.logmission.legs_driven`.

Senders that share a system and component id (the companion and its flight controller, both
1/1 by default) are told apart by their sequence numbers: :mod:`mecanum_mav.app.logsenders`.
The vehicle's modes come from the companion's HEARTBEATs only.

The rooms of the analysis: this module reads the messages in order (:func:`analyse`);
:mod:`~mecanum_mav.app.logresult` holds what it returns, :mod:`~mecanum_mav.app.logsenders`
who sent what, :mod:`~mecanum_mav.app.logstatus` the status texts and failsafes,
:mod:`~mecanum_mav.app.logmission` the origin, the planned mission and the legs driven. What
callers import from here (``__all__``) stays importable from here.
"""

from __future__ import annotations

import bisect
import math
from collections import defaultdict
from collections.abc import Sequence
from typing import Any

from mecanum_mav.app.logmission import (
    finite,
    legs_driven,
    log_origin,
    mission_items,
    planned_positions,
    sim_latlon,
)
from mecanum_mav.app.logresult import LegStat, LogAnalysis, ModeSpan, PathPoint, StatusEvent
from mecanum_mav.app.logsenders import (
    VEHICLE_ANCHORS,
    Senders,
    override_from_pilot,
    sent_by,
    vehicle_of,
)
from mecanum_mav.app.logstatus import is_failsafe
from mecanum_mav.config.params import Params
from mecanum_mav.config.views import RcInputConfig
from mecanum_mav.control.sticks import InputError, RcStickState
from mecanum_mav.io.tlog import TlogEntry
from mecanum_mav.protocol.dialect import mavlink, mavutil
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.statustext import StatusChunks

__all__ = ["INPUT_TIMEOUT_S", "OVERRIDE_TIMEOUT_S", "RC_STICKS", "LegStat", "LogAnalysis",
           "ModeSpan", "StatusEvent", "analyse", "is_failsafe", "override_from_pilot"]

AXIS_INVALID = 0x7FFF
_DEFAULTS = Params()
RC_STICKS: RcInputConfig = RcInputConfig.from_params(_DEFAULTS)
"""How a pilot's RC override is read as sticks: the rover's defaults (RCMAP_THROTTLE 3 forward,
RCMAP_LATERAL 4 right, RCMAP_STEER 1 clockwise; RCIN_MIN/TRIM/MAX 1000/1500/2000 us)."""
INPUT_TIMEOUT_S = float(_DEFAULTS["FS_INPUT_TMO"])
"""Stick input older than this no longer drives the rover (FS_INPUT_TMO's default, s)."""
OVERRIDE_TIMEOUT_S = float(_DEFAULTS["SIM_RC_TMO"])
"""A flight controller lets an override lapse after this long without one (ArduPilot's
RC_OVERRIDE_TIME default, which the simulator's SIM_RC_TMO defaults to; s)."""
_MODE_COMMANDS = frozenset({mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_CMD_COMPONENT_ARM_DISARM,
                            mavlink.MAV_CMD_MISSION_START, 11})  # 11: SET_MODE's acknowledgement


def _mode_name(msg: Any) -> str:
    if (msg.type == mavlink.MAV_TYPE_GROUND_ROVER
            and msg.autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA):
        try:
            return Mode(msg.custom_mode).name
        except ValueError:
            pass
    # (a type or number pymavlink's tables do not know: "Mode(N)"; it raises on none)
    return str(mavutil.mode_string_v10(msg))


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
    senders = Senders()
    for index, e in enumerate(entries):
        senders.add(index, e.msg)
    vehicle = result.vehicle = vehicle_of(entries)
    origin = result.origin = log_origin(entries, vehicle)
    vehicle_split = any(e.msg.get_type() in VEHICLE_ANCHORS for e in entries)
    paths: dict[str, list[PathPoint]] = defaultdict(list)
    beats: list[tuple[float, str, bool]] = []
    causes: list[float] = []
    last_current: int | None = None
    pilot_states: dict[str, RcStickState] = {}
    status = StatusChunks()
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
            elif kind in ("ODOMETRY", "LOCAL_POSITION_NED") and sent_by(msg, vehicle):
                if finite(msg.x, msg.y):
                    paths[kind].append((t, msg.x, msg.y))
            elif kind == "GLOBAL_POSITION_INT" and sent_by(msg, vehicle) and origin is not None:
                if (msg.lat, msg.lon) != (0, 0):
                    paths[kind].append((t, *origin.to_local(msg.lat, msg.lon)))
            elif kind in ("SIM_STATE", "SIMSTATE") and origin is not None:
                lat, lon = sim_latlon(msg)
                result.true_path.append((t, *origin.to_local(lat, lon)))
            elif kind == "MANUAL_CONTROL":
                axes = [math.nan if v == AXIS_INVALID else v / 1000.0
                        for v in (msg.x, msg.y, msg.r)]
                result.sticks.append((t, axes[0], axes[1], axes[2]))
            elif kind == "RC_CHANNELS_OVERRIDE":
                channels = [getattr(msg, f"chan{i}_raw") for i in range(1, 19)]
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
            elif kind == "MISSION_CURRENT" and sent_by(msg, vehicle):
                if msg.seq != last_current:
                    result.mission_current.append((t, msg.seq))
                    last_current = msg.seq
            elif (kind == "COMMAND_ACK" and sent_by(msg, vehicle) and msg.command in _MODE_COMMANDS
                  and msg.result == mavlink.MAV_RESULT_ACCEPTED):
                causes.append(t)
            elif kind == "MISSION_ITEM_REACHED" and sent_by(msg, vehicle):
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
    result.planned = planned_positions(mission_items(entries), origin)
    causes = sorted([*causes, *(e.time_s for e in result.failsafes),
                     *(t for t, _ in result.reached)])
    result.modes = _mode_spans(beats, causes, result.duration_s)
    result.legs = legs_driven(result)
    return result
