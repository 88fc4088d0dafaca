"""AUTO: the mission executor. Pure logic; the pose and the time are passed in.

The executor walks the mission from item 1 (item 0 is home) and turns the current item into a
:class:`~mecanum_mav.control.guided.Setpoint` for the same velocity and heading layer GUIDED uses
(``GUID_SPD_MAX``, ``GUID_ACC_MAX``, ``GUID_YAW_P``, ``GUID_YAW_RATE``, ``GUID_YAW_LEAD``).

Items:

- ``NAV_WAYPOINT``: drive the leg from the previous waypoint (or from where the rover is when
  the mission starts, resumes or jumps) to this one, following the line
  (:mod:`mecanum_mav.control.pathfollow`) at the mission speed, pulled onto the line with
  ``WP_POS_P``. A waypoint where the rover stops (it holds, a turn of 90 degrees or more, the
  last) is reached within param2 metres (0 or NaN: ``WP_RADIUS``) once the commanded speed has
  settled below :data:`SETTLED_MPS` (so it converges onto the point rather than report at the
  edge of the radius), or :data:`SETTLE_TIMEOUT_S` after it came within it (stalled); one passed
  at speed is reached where the rover crosses the line through it square to the leg. Then it
  holds the point for param1 seconds. param4, if a number, is a heading (degrees clockwise from
  north) to take on this leg and keep, turned in proportion to the distance along the leg (its
  rate fed forward); NaN (what QGroundControl and MAVSDK send) leaves the
  heading alone. Mission Planner and MAVProxy files often carry 0 there, which means north.
  Between two legs the rover passes the waypoint at the speed
  :func:`~mecanum_mav.control.pathfollow.corner_speed` allows for ``WP_OVERSHOOT`` (it stops
  for turns of 90 degrees or more, and where it holds), and never faster than it can still
  stop at the next stop waypoint braking at ``WP_ACCEL`` over the legs in between
  (:func:`~mecanum_mav.control.pathfollow.exit_speed_ahead`).
- ``NAV_LOITER_TIME``: drive there, hold the point for param1 seconds.
- In a global frame a latitude and longitude of 0 (both) mean "here", for ``NAV_WAYPOINT`` and
  ``NAV_LOITER_TIME`` alike (ArduPilot Rover's ``Location::sanitize``): the point where the
  rover is when the item starts. In MAV_FRAME_LOCAL_NED 0/0 is the origin.
- ``NAV_RETURN_TO_LAUNCH``: drive to home (the local origin, as HOME_POSITION reports).
- ``CONDITION_YAW``: param1 degrees, absolute (param4 = 0) or relative to the current target
  (1); param2 the turn rate in deg/s (0: ``GUID_YAW_RATE``); param3 the direction (1
  clockwise, -1 counter-clockwise, 0 the shorter way). The heading is kept until changed. If
  the next navigation item leads somewhere, the mission moves on at once and the rover turns
  while it drives; otherwise (the next point is where the rover is, or the mission ends) it
  turns in place and the item completes when the heading is within 2 degrees.
- ``DO_CHANGE_SPEED``: param2 m/s becomes the mission speed (-2: back to ``WP_SPEED``; -1 or
  0: no change); more than ``GUID_SPD_MAX`` is limited to it, with a STATUSTEXT.
- ``DO_JUMP``: to item param1, param2 times (-1: for ever). Counters reset when the mission
  restarts.
- anything else is skipped with a STATUSTEXT naming it.

Heading between commands follows ``WP_YAW_BEHAVIOR``: 0 hold the heading the mission started
with, 1 face along each leg. A mecanum base drives the path the same either way.

Each item emits MISSION_ITEM_REACHED when done (navigation items on arrival); the current item
is announced whenever it changes. At the end the executor reports "finished" (the companion
switches to HOLD). Leaving AUTO pauses; AUTO again resumes the current item from where the
rover is. After the end, AUTO restarts from item 1.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import MissionConfig
from mecanum_mav.control.guided import Setpoint
from mecanum_mav.control.pathfollow import (
    Leg,
    LegFollower,
    corner_lead,
    exit_speed_ahead,
    heading_schedule,
)
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.mecanum.geometry import Pose2d, wrap_pi
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import (
    GLOBAL_FRAMES,
    NAV_COMMANDS,
    POSITION_COMMANDS,
    MissionItem,
    command_name,
    position_ned,
)
from mecanum_mav.protocol.statustext import Severity

__all__ = ["ExecutorEvent", "MissionExecutor"]

_NO_MISSION: int = mavlink.MISSION_STATE_NO_MISSION
_NOT_STARTED: int = mavlink.MISSION_STATE_NOT_STARTED
_ACTIVE: int = mavlink.MISSION_STATE_ACTIVE
_PAUSED: int = mavlink.MISSION_STATE_PAUSED
_COMPLETE: int = mavlink.MISSION_STATE_COMPLETE
"""MAVLink MISSION_STATE values (MISSION_CURRENT.mission_state)."""
YAW_ACCEPT_RAD = math.radians(2.0)
CORNER_LEAD_S = 0.15
"""How early the turn onto the next leg begins at a waypoint passed at speed, s: the time the
rover's velocity trails the command (motor lag 0.08 s, the acceleration limit's slew about
0.07 s at a 22.5 degree corner). Measured on the figure eight at 1 m/s (kinematic): worst
cross-track 2.59 cm at 0, 1.78 at 0.1, 1.46 at 0.15, 1.43 at 0.25 (MuJoCo: 3.03, 2.69, 2.99,
3.45)."""
SETTLED_MPS = 0.02
"""A stop waypoint is reached within its radius once the commanded speed is below this, m/s."""
SETTLE_TIMEOUT_S = 1.0
"""...or once it has been within the radius this long (s): a rover that stalls short of the
point (an ESC dead band, a wheel against an obstacle) still goes on."""
LOOK_AHEAD_LEGS = 50
"""The speed plan looks this many legs ahead for the next stop (beyond: as if it stopped)."""
MAX_STEPS_PER_UPDATE = 1000  # DO items chained without a navigation item in between
Vec = tuple[float, float]


def _passes_through(item: MissionItem) -> bool:
    """A waypoint that does not hold: the rover may pass it at speed (if another follows)."""
    return item.command == mavlink.MAV_CMD_NAV_WAYPOINT and not item.param1 > 0.0


class ExecutorEvent(NamedTuple):
    """Something the companion reports: ``kind`` is "current", "reached", "say" or
    "finished"; ``seq`` the item; ``text``/``severity`` for "say"."""

    kind: str
    seq: int = 0
    text: str = ""
    severity: Severity = Severity.INFO


@dataclass
class _Step:
    """The navigation item being driven (or the final turn in place)."""

    seq: int
    target: Vec
    leg: Leg
    exit_speed: float
    radius: float
    hold_s: float
    reached_s: float | None = None
    turn_only: bool = False
    yaw_from: float | None = None
    """Where the leg's heading schedule starts (rad); None: no schedule (the heading is
    commanded at once)."""
    inside_s: float | None = None
    """When the rover first came within the radius of a stop, still moving (s)."""
    next_direction: Vec = (0.0, 0.0)
    """Unit vector of the leg after a waypoint passed at speed (north, east); (0, 0): none."""


class MissionExecutor:
    """Runs a mission (see the module docstring).

    Args:
        params: the ``WP_*`` parameters and the GUIDED limits they share are read from it
            here and by :meth:`reconfigure` (after a parameter changed).
    """

    def __init__(self, params: Params) -> None:
        self.config = MissionConfig.from_params(params)
        self.items: tuple[MissionItem, ...] = ()
        self.current = 0
        self.started = False
        self.running = False
        self.complete = False
        self.arrival_errors: dict[int, float] = {}
        self._positions: dict[int, Vec] = {}
        self._jumps: dict[int, int] = {}
        self.events: list[ExecutorEvent] = []
        """The events since :meth:`take_events`, oldest first (empty: none)."""
        self._follower = LegFollower()
        self.corner_lead_s = CORNER_LEAD_S
        """How early the turn at a waypoint passed at speed begins, s (0: at the waypoint)."""
        self._step: _Step | None = None
        self._speed: float | None = None
        self._yaw = 0.0  # the heading to hold, rad NED (the rover's own at start)
        self._yaw_dir = 0
        self._yaw_rate_max: float | None = None
        self._last_s = 0.0  # the last update's time (s; the start's before the first)
        self._hold: Vec = (0.0, 0.0)

    # ------------------------------------------------------------------ mission and state

    def reconfigure(self, params: Params) -> None:
        """Take the ``WP_*`` parameters (and the GUIDED limits they share) from ``params``."""
        self.config = MissionConfig.from_params(params)

    def load(self, items: Sequence[MissionItem]) -> None:
        """A new mission (upload, clear, or the file at start-up). The current item stays if
        it still exists; a running mission goes on from it (the caller resumes it)."""
        self.items = tuple(items)
        self._jumps.clear()
        self.complete = False
        if len(self.items) <= 1:
            self.current, self.started = 0, False
        elif not 1 <= self.current < len(self.items):
            self.current = 1

    @property
    def has_mission(self) -> bool:
        """Whether there is anything to run beyond home."""
        return len(self.items) > 1

    @property
    def state(self) -> int:
        """The MAVLink MISSION_STATE to report in MISSION_CURRENT."""
        if not self.has_mission:
            return _NO_MISSION
        if self.complete:
            return _COMPLETE
        if self.running:
            return _ACTIVE
        return _PAUSED if self.started else _NOT_STARTED

    def set_current(self, seq: int, pose: Pose2d, *, reset: bool = False) -> str | None:
        """MISSION_SET_CURRENT / DO_SET_MISSION_CURRENT; the reason if refused (then nothing
        changes).

        Item 0 (home) means item 1. While running, the rover goes to the new item from where
        it is. ``reset`` first starts the mission over (:meth:`restart`: DO_JUMP counters and
        the end forgotten).
        """
        if not self.has_mission:
            return "no mission"
        if not 0 <= seq < len(self.items):
            return f"no item {seq} (mission has {len(self.items) - 1})"
        if reset:
            self.restart()
        self.current = max(seq, 1)
        self.complete = False
        if self.running:
            self._begin(self.current, pose, from_point=None)
        else:
            self._emit("current", self.current)
        return None

    def restart(self) -> None:
        """Next start runs from item 1 with fresh DO_JUMP counters."""
        self.current = 1 if self.has_mission else 0
        self.complete = False
        self.started = False
        self._jumps.clear()

    def prepare(self, origin: GlobalOrigin | None) -> str | None:
        """Resolve every position to local NED; the reason AUTO cannot run, or None.

        Refused: no mission; a global item and no origin.
        """
        if not self.has_mission:
            return "no mission"
        positions: dict[int, Vec] = {}
        for item in self.items[1:]:
            if item.command not in POSITION_COMMANDS:
                continue
            if item.frame in GLOBAL_FRAMES and item.x == 0 and item.y == 0:
                continue  # "here", resolved when it starts
            try:
                positions[item.seq] = position_ned(item, origin)
            except ValueError as exc:
                return str(exc)
        self._positions = positions
        return None

    def start(self, pose: Pose2d, now_s: float, origin: GlobalOrigin | None) -> str | None:
        """AUTO may drive: resume the current item (or restart after the end).

        Returns the reason the mission cannot run (see :meth:`prepare`), or None.
        """
        reason = self.prepare(origin)
        if reason is not None:
            return reason
        if self.complete:
            self.restart()
        if not self.started:
            self._jumps.clear()
            self._speed = None
            self._yaw = pose.yaw_rad
            self._yaw_dir, self._yaw_rate_max = 0, None
        resumed = self.started
        self.started, self.running = True, True
        self._last_s = now_s
        self._hold = (pose.x_m, pose.y_m)
        self._emit("say", 0, f"Mission {'resumed' if resumed else 'started'} at item "
                   f"{self.current}")
        self._begin(self.current, pose, from_point=None)
        return None

    def pause(self) -> None:
        """Leaving AUTO: stop executing; the current item is kept for a resume."""
        self.running = False
        self._step = None

    def take_events(self) -> list[ExecutorEvent]:
        """Events since the last call, oldest first."""
        events, self.events = self.events, []
        return events

    # ------------------------------------------------------------------ the loop

    def update(self, pose: Pose2d, velocity_ned: Vec, now_s: float) -> Setpoint:
        """The setpoint for the velocity and heading layer now (local NED).

        At most one item completes per call, so a mission that loops over points the rover
        already stands on advances one item per control tick instead of spinning.
        """
        dt = max(0.0, now_s - self._last_s)  # (read only while running: after a start)
        self._last_s = now_s
        here = (pose.x_m, pose.y_m)
        step = self._step
        if self.running and step is not None and self._done(step, pose, here, now_s,
                                                            velocity_ned, dt):
            self._finish_item(step, pose, velocity_ned)
            step = self._step
        if not self.running or step is None:
            return self._setpoint(None, self._hold, pose, now_s)
        if step.turn_only or step.reached_s is not None:
            return self._setpoint(None, step.target, pose, now_s)
        velocity = self._follower.velocity_ned(
            step.leg, here, dt, cruise=self._cruise(), accel=self._accel(),
            exit_speed=step.exit_speed, gain=self.config.position_gain)
        if step.exit_speed > 0.0:
            velocity = corner_lead(step.leg, step.next_direction, here, velocity,
                                   step.exit_speed, self.corner_lead_s)
        if step.yaw_from is not None:
            un, ue = step.leg.direction  # the speed along as commanded last tick (slewed)
            along_mps = max(0.0, velocity_ned[0] * un + velocity_ned[1] * ue)
            yaw, rate = heading_schedule(step.leg, here, step.yaw_from, self._yaw, along_mps)
            return Setpoint(None, velocity, yaw, None, now_s, self._yaw_rate_max, rate)
        return self._setpoint(velocity, None, pose, now_s)

    def _done(self, step: _Step, pose: Pose2d, here: Vec, now_s: float,
              velocity_ned: Vec, tick_s: float) -> bool:
        """Whether the step is complete (arrival is recorded the first time it happens).

        A waypoint passed at speed is reached at the tick nearest to where the rover crosses
        the line through it square to the leg (within half a tick's travel of it, ``tick_s``
        the time since the last tick; its arrival error is the cross-track there); a stop is
        reached
        within the radius once the commanded speed has settled below :data:`SETTLED_MPS`, or
        :data:`SETTLE_TIMEOUT_S` after it came within the radius.
        """
        if step.turn_only:
            return abs(wrap_pi(self._yaw_target(pose) - pose.yaw_rad)) <= YAW_ACCEPT_RAD
        if step.reached_s is None:
            distance = math.hypot(step.target[0] - here[0], step.target[1] - here[1])
            if step.exit_speed > 0.0:
                half_tick_m = self._follower.speed_along * tick_s / 2.0
                if step.leg.errors(here)[0] + half_tick_m < step.leg.length_m:
                    return False
            elif distance > step.radius:
                return False
            elif math.hypot(*velocity_ned) > SETTLED_MPS:
                if step.inside_s is None:
                    step.inside_s = now_s
                if now_s - step.inside_s < SETTLE_TIMEOUT_S:
                    return False  # still converging (a stalled rover counts after the timeout)
            step.reached_s = now_s
            self.arrival_errors[step.seq] = distance
        return now_s - step.reached_s >= step.hold_s

    # ------------------------------------------------------------------ items

    def _finish_item(self, step: _Step, pose: Pose2d,
                     velocity_ned: Vec = (0.0, 0.0)) -> None:
        if step.seq < len(self.items):  # (the turn in place after the last item is no item)
            self._emit("reached", step.seq)
        self._hold = step.target
        self._begin(step.seq + 1, pose, from_point=step.target,
                    velocity_ned=velocity_ned)

    def _begin(self, seq: int, pose: Pose2d, *, from_point: Vec | None,
               velocity_ned: Vec = (0.0, 0.0)) -> None:
        """Make item ``seq`` current, carrying out DO items on the way to a navigation item."""
        here = (pose.x_m, pose.y_m)
        start = here if from_point is None else from_point
        self._step = None
        for _ in range(MAX_STEPS_PER_UPDATE):
            if seq >= len(self.items):
                self._end(pose, start)
                return
            self.current = seq
            self._emit("current", seq)
            item = self.items[seq]
            cmd = item.command
            if cmd in NAV_COMMANDS:
                self._start_nav(item, start, here, velocity_ned)
                return
            if cmd == mavlink.MAV_CMD_DO_JUMP:
                target = self._jump(item)
                self._emit("reached", seq)
                seq = seq + 1 if target is None else target
                continue
            if cmd == mavlink.MAV_CMD_DO_CHANGE_SPEED:
                self._change_speed(item)
            elif cmd == mavlink.MAV_CMD_CONDITION_YAW:
                self._condition_yaw(item)
                if not self._leads_somewhere(seq + 1, start):
                    self._turn_in_place(seq, start)
                    return
            else:
                self._emit("say", seq, f"Skipped item {seq}: {command_name(cmd)} unsupported",
                           Severity.WARNING)
                seq += 1
                continue
            self._emit("reached", seq)
            seq += 1
        self._emit("say", seq, "Mission stopped: DO_JUMP loop without a waypoint",
                   Severity.ERROR)
        self.running = False
        self.complete = True
        self._emit("finished", seq)

    def _target(self, item: MissionItem, here: Vec) -> Vec:
        if item.command == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return 0.0, 0.0
        return self._positions.get(item.seq, here)

    def _start_nav(self, item: MissionItem, start: Vec, here: Vec, velocity_ned: Vec) -> None:
        target = self._target(item, here)
        leg = Leg(start, target)
        waypoint = item.command == mavlink.MAV_CMD_NAV_WAYPOINT
        hold = 0.0 if item.command == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH else item.param1
        hold = 0.0 if math.isnan(hold) else hold
        radius = item.param2 if waypoint and item.param2 > 0.0 else self.config.radius_m
        yaw_from = None
        if waypoint and math.isfinite(item.param4):
            if self._yaw_dir == 0 and leg.length_m > 2 * radius:
                yaw_from = self._yaw
            self._yaw, self._yaw_dir = math.radians(item.param4), 0
        elif self.config.face_along_legs and leg.length_m > 2 * radius:
            self._yaw, self._yaw_dir = math.atan2(*reversed(leg.direction)), 0
        un, ue = leg.direction
        self._follower.reset(velocity_ned[0] * un + velocity_ned[1] * ue)
        legs = self._legs_ahead(item, leg)
        exit_speed = exit_speed_ahead(legs, self._cruise(), self._accel(),
                                      self.config.overshoot_m)
        self._step = _Step(item.seq, target, leg, exit_speed, radius, hold, yaw_from=yaw_from,
                           next_direction=legs[1].direction if len(legs) > 1 else (0.0, 0.0))

    def _legs_ahead(self, item: MissionItem, leg: Leg) -> list[Leg]:
        """``leg`` and the legs after it up to the next stop (a waypoint that holds, another
        navigation item, the end, a DO_JUMP), at most :data:`LOOK_AHEAD_LEGS` in all."""
        legs = [leg]
        while len(legs) < LOOK_AHEAD_LEGS and _passes_through(item):
            following = self._next_nav(item.seq + 1)
            if following is None:
                break
            legs.append(Leg(legs[-1].end_ned, self._target(following, legs[-1].end_ned)))
            item = following
        return legs

    def _next_nav(self, seq: int) -> MissionItem | None:
        """The next navigation item from ``seq`` in list order (DO_JUMP not followed)."""
        for item in self.items[seq:]:
            if item.command in NAV_COMMANDS:
                return item
            if item.command == mavlink.MAV_CMD_DO_JUMP:
                return None
        return None

    def _leads_somewhere(self, seq: int, here: Vec) -> bool:
        following = self._next_nav(seq)
        if following is None:
            return False
        target = self._target(following, here)
        return math.hypot(target[0] - here[0], target[1] - here[1]) > self.config.radius_m

    def _turn_in_place(self, seq: int, point: Vec) -> None:
        """Hold ``point`` (north, east m) while the heading turns (item ``seq``; the number
        past the last item for the last heading): a step of no leg, done once the heading is
        reached (:meth:`_done`)."""
        self._step = _Step(seq, point, Leg(point, point), 0.0, 0.0, 0.0, turn_only=True)

    def _end(self, pose: Pose2d, here: Vec) -> None:
        if abs(wrap_pi(self._yaw_target(pose) - pose.yaw_rad)) > YAW_ACCEPT_RAD and (
                self._step is None or not self._step.turn_only):
            self._turn_in_place(len(self.items), here)  # the heading before the end
            return
        self.running = False
        self.complete = True
        self._hold = here
        self._emit("say", 0, "Mission complete")
        self._emit("finished", self.current)

    def _jump(self, item: MissionItem) -> int | None:
        repeat = self._jumps.setdefault(item.seq, int(item.param2))
        if repeat == 0:
            return None
        if repeat > 0:
            self._jumps[item.seq] = repeat - 1
        return int(item.param1)

    def _change_speed(self, item: MissionItem) -> None:
        speed = item.param2
        if speed == -2.0:
            self._speed = None
        elif speed > 0.0:
            limit = self.config.speed_limit_mps
            if speed > limit:
                self._emit("say", item.seq, f"Speed {speed:g} limited to GUID_SPD_MAX {limit:g}",
                           Severity.WARNING)
            self._speed = min(speed, limit)

    def _condition_yaw(self, item: MissionItem) -> None:
        angle, rate, direction, relative = item.params
        direction = 0 if math.isnan(direction) else int(direction)
        if relative == 1.0:
            step = math.radians(abs(angle)) * (direction or (1 if angle >= 0 else -1))
            self._yaw = wrap_pi(self._yaw + step)
            # under half a circle the shorter way is the asked way; from half a circle on,
            # the way asked is kept
            self._yaw_dir = 0 if abs(step) < math.pi else (1 if step > 0 else -1)
        else:
            self._yaw = wrap_pi(math.radians(angle))
            self._yaw_dir = direction
        self._yaw_rate_max = math.radians(rate) if rate > 0.0 else None

    # ------------------------------------------------------------------ outputs

    def _cruise(self) -> float:
        return self.config.speed_mps if self._speed is None else self._speed

    def _accel(self) -> float:
        return self.config.accel_mps2

    def _yaw_target(self, pose: Pose2d) -> float:
        """The heading to command; a forced turn direction leads by a quarter turn."""
        target = self._yaw
        if self._yaw_dir:
            delta = wrap_pi(target - pose.yaw_rad)
            if delta * self._yaw_dir < 0.0 and abs(delta) > YAW_ACCEPT_RAD:
                return wrap_pi(pose.yaw_rad + self._yaw_dir * math.pi / 2)
            self._yaw_dir = 0
        return target

    def _setpoint(self, velocity: Vec | None, position: Vec | None, pose: Pose2d,
                  now_s: float) -> Setpoint:
        return Setpoint(position, velocity, self._yaw_target(pose), None, now_s,
                        self._yaw_rate_max)

    def _emit(self, kind: str, seq: int, text: str = "",
              severity: Severity = Severity.INFO) -> None:
        self.events.append(ExecutorEvent(kind, seq, text, severity))
