"""A mission driven in the simulator, watched from outside: the ground station's script and
what truly happened.

:func:`waypoint_mission` builds a mission of waypoints (local NED, metres), optionally after a
CONDITION_YAW that sets the heading, each waypoint optionally with its own heading (param4).
:func:`fly` is a scripted ground station's whole run on any port (the lockstep harness in
virtual time, or UDP in real time): upload, arm, AUTO, then watch until the rover holds at the
end. The watch (:class:`MissionWatch`, one look at a time) records into a :class:`MissionRun`:

- the true pose (from the simulator: ``truth()``) at least every :data:`WATCH_PERIOD_S` and
  whenever a message arrives, with its time and its cross-track error: the distance from the
  true position to the current leg (a segment, from the previous waypoint to the next; the
  first leg starts at the origin), while a leg is current;
- per leg (:class:`LegReport`, told to ``on_leg`` as the leg ends): its time, largest
  cross-track error, and the true arrival error when its MISSION_ITEM_REACHED arrives:
  distance to the waypoint (m) and heading error against the waypoint's heading (deg);
- a waypoint the mission passes at speed (:func:`passed_at_speed`: not the last, and the
  path turns there by less than 90 degrees, as the executor drives it) is arrived at where the
  rover truly crosses the line through it square to its leg (interpolated between two looks),
  if that comes before its MISSION_ITEM_REACHED: the report comes a control tick and a link's
  delay later (on the twin 2-30 ms, 2-3 cm further along at 1 m/s and up to 2 degrees further
  round at 60 degrees/s), and what the rover does then is its next leg's. From that crossing
  the cross-track is measured to the next leg (a straight line on through the waypoint is not
  a leg overshot);
- a waypoint the rover stops at (a corner of 90 degrees or more) is arrived at where the rover
  came closest to it, once it drives off along its next leg (farther than
  :data:`DEPART_M` from that point and nearer the next leg than its own) before its
  MISSION_ITEM_REACHED is read: a ground station that reads the report late (a busy
  machine) would otherwise measure the next leg's first metres as this one's error. From
  there too the cross-track is measured to the next leg;
- the odometry the companion reports (LOCAL_POSITION_NED) and, with the last one, the truth at
  the moment it arrived (for the odometry's drift).

Times are the ground station's: wall-clock seconds in real time, simulated seconds in virtual
time. Positions are local NED metres (north, east); yaw radians clockwise from north.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from mecanum_mav.control.pathfollow import Leg, stops_between
from mecanum_mav.mecanum.geometry import Pose2d, wrap_pi
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.board import SimState
from mecanum_mav.sim.groundstation import ScriptedGroundStation

__all__ = ["DEPART_M", "MISSION_COMPLETE", "WATCH_PERIOD_S", "LegReport", "MissionRun",
           "MissionWatch", "OnLeg", "Waypoint", "fly", "ignore_leg", "passed_at_speed",
           "waypoint_mission"]

Vec = tuple[float, float]
WATCH_PERIOD_S = 0.02
"""The ground station looks at the rover at least this often while the mission runs."""
DEPART_M = 0.02
"""A rover this much farther (m) from a waypoint it stopped at than its closest approach, and
nearer the next leg than its own, has driven off along the next leg."""
MISSION_COMPLETE = "Mission complete"
"""The companion's STATUSTEXT as the mission ends (the HOLD after it shows in the next 1 Hz
HEARTBEAT: the mission's time ends at the text)."""


@dataclass(frozen=True)
class Waypoint:
    """A NAV_WAYPOINT of the mission as planned: item ``seq``, at (``north_m``, ``east_m``),
    the heading the rover should have there (degrees clockwise from north; None: any)."""

    seq: int
    north_m: float
    east_m: float
    yaw_deg: float | None = None

    @property
    def point(self) -> Vec:
        """(north, east), metres."""
        return self.north_m, self.east_m


def waypoint_mission(points: Sequence[Vec], yaws_deg: Sequence[float | None] | None = None,
                     *, heading_deg: float | None = 0.0
                     ) -> tuple[list[MissionItem], list[Waypoint]]:
    """A mission through ``points`` (north, east metres) and its waypoints as planned.

    Args:
        points: the waypoints in order (the rover starts at the origin).
        yaws_deg: each waypoint's own heading (param4, degrees clockwise from north), or None
            for a waypoint that leaves the heading alone (param4 NaN); None: all leave it.
        heading_deg: a CONDITION_YAW to this absolute heading first (item 1), so the rover
            keeps it where a waypoint does not set one; None: no CONDITION_YAW.
    """
    yaws = list(yaws_deg) if yaws_deg is not None else [None] * len(points)
    items = [MissionItem(0, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_CMD_NAV_WAYPOINT)]  # home
    if heading_deg is not None:
        items.append(MissionItem(1, mavlink.MAV_FRAME_MISSION, mavlink.MAV_CMD_CONDITION_YAW,
                                 param1=heading_deg))
    held = heading_deg
    waypoints = []
    for (n, e), yaw in zip(points, yaws, strict=True):
        seq = len(items)
        items.append(MissionItem(seq, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_CMD_NAV_WAYPOINT,
                                 param4=math.nan if yaw is None else yaw,
                                 x=round(n * 1e4), y=round(e * 1e4)))
        held = held if yaw is None else yaw
        waypoints.append(Waypoint(seq, n, e, held))
    return items, waypoints


@dataclass
class LegReport:
    """One leg of a mission: from the previous waypoint to ``goal`` (item ``seq``)."""

    seq: int
    start: Vec
    goal: Vec
    time_s: float
    max_cross_track_m: float
    arrival_error_m: float
    """True distance to ``goal`` when its MISSION_ITEM_REACHED arrived, or where the rover
    crossed the line through it if it is passed at speed and that came first, metres."""
    arrival_heading_deg: float = math.nan
    """True heading minus the waypoint's heading there, degrees (NaN: the waypoint has none)."""


@dataclass
class MissionRun:
    """What the ground station saw of a mission and what truly happened (module docstring)."""

    legs: list[LegReport]
    planned: list[Vec]
    """The origin, then every waypoint (north, east)."""
    true_path: list[tuple[float, float, float]] = field(default_factory=list)
    """The true pose (north m, east m, yaw rad) at each look."""
    times_s: list[float] = field(default_factory=list)
    """When each :attr:`true_path` pose was taken, seconds from AUTO."""
    cross_track_m: list[float] = field(default_factory=list)
    """Each :attr:`true_path` pose's distance to the leg current then (NaN: none current)."""
    odometry_path: list[Vec] = field(default_factory=list)
    """The companion's LOCAL_POSITION_NED (north, east), as they arrived."""
    final_estimate: Vec | None = None
    """The last LOCAL_POSITION_NED (north, east) before the end."""
    final_truth: Vec | None = None
    """The true position when :attr:`final_estimate` arrived."""
    total_s: float = 0.0
    """From AUTO to the end: the "Mission complete" text (or, without it, the HOLD), s."""
    max_yaw_deg: float = 0.0
    """The largest true heading away from north, degrees."""
    world_lag_s: float = 0.0
    """How much less time the chassis lived than the ground station's clock from AUTO to the
    end, s (the twin: :meth:`~mecanum_mav.sim.twinmission.TruthTrack.lag_s`; 0 in lockstep).
    A companion that dead-reckons its commanded wheel speeds believes the rover drove that
    long more than it did: up to this times the speed, metres short."""
    wall_span_s: tuple[float, float] | None = None
    """The wall-clock times (monotonic s) :attr:`world_lag_s` was measured from and to: AUTO
    and the last look (the twin; None in lockstep)."""


def passed_at_speed(planned: Sequence[Vec], k: int) -> bool:
    """Whether waypoint ``planned[k]`` (``planned[0]`` the origin) is passed at speed, as the
    executor drives it: it is not the last, and the rover does not stop there
    (:func:`~mecanum_mav.control.pathfollow.stops_between`: a turn of 90 degrees or more)."""
    return k + 1 < len(planned) and not stops_between(Leg(planned[k - 1], planned[k]),
                                                      Leg(planned[k], planned[k + 1]))


OnLeg = Callable[[int, LegReport], None]
"""Called with each leg's number (from 1) and report as soon as the leg ends."""


def ignore_leg(k: int, leg: LegReport) -> None:
    """An :data:`OnLeg` that does nothing."""


def fly(gcs: ScriptedGroundStation, truth: Callable[[], SimState], items: list[MissionItem],
        waypoints: Sequence[Waypoint], timeout_s: float, on_leg: OnLeg = ignore_leg,
        into: MissionRun | None = None) -> MissionRun:
    """The ground station's script: upload ``items``, arm, AUTO, watch until HOLD.

    Args:
        gcs: the scripted ground station (any port).
        truth: the simulator's true state now.
        items: the mission to upload.
        waypoints: its waypoints as planned (:func:`waypoint_mission`).
        timeout_s: the mission must end within this long (the ground station's time).
        on_leg: told each leg as soon as it ends.
        into: the record to fill (a subclass's, empty), or None for a new one.

    Raises:
        RuntimeError: a step failed (upload refused, arming refused, mission not finished).
    """
    if gcs.wait("HEARTBEAT", lambda m: m.get_srcSystem() == 1, 5.0) is None:
        raise RuntimeError("no heartbeat from the companion")
    result = gcs.upload(items).type
    if result != mavlink.MAV_MISSION_ACCEPTED:
        raise RuntimeError(f"mission upload refused (MISSION_ACK {result})")
    # The companion arms once it hears the flight controller (its first heartbeat may still
    # be on its way): wait for that rather than retry into a refusal.
    if gcs.wait("STATUSTEXT", lambda m: m.text == "Flight controller link up", 5.0,
                since=0) is None:
        raise RuntimeError("no flight controller link")
    try:
        gcs.arm()
    except RuntimeError:
        raise RuntimeError("arming refused") from None
    if gcs.set_mode(Mode.AUTO) != mavlink.MAV_RESULT_ACCEPTED:
        raise RuntimeError("AUTO refused")
    return _watch(gcs, truth, list(waypoints), timeout_s, on_leg, into)


def _watch(gcs: ScriptedGroundStation, truth: Callable[[], SimState], waypoints: list[Waypoint],
           timeout_s: float, on_leg: OnLeg, into: MissionRun | None) -> MissionRun:
    clock = gcs.port.now
    watch = MissionWatch(waypoints, clock(), on_leg, into)
    deadline = clock() + timeout_s
    while clock() < deadline:
        messages = gcs.pump(WATCH_PERIOD_S)
        if watch.look(clock(), truth().pose, messages):
            return watch.run
    raise RuntimeError("the mission did not finish in time")


class MissionWatch:
    """Measures a mission while it is driven, one look at a time (:meth:`look`), into
    :attr:`run` (see the module docstring).

    Args:
        waypoints: the mission's waypoints as planned, in order.
        start_s: when the mission started (AUTO), in the clock :meth:`look` is given.
        on_leg: told each leg as soon as it ends.
        into: the record to fill (its :attr:`MissionRun.planned` is set here), or None.
    """

    def __init__(self, waypoints: Sequence[Waypoint], start_s: float = 0.0,
                 on_leg: OnLeg = ignore_leg, into: MissionRun | None = None) -> None:
        self.waypoints = list(waypoints)
        self.run = into if into is not None else MissionRun([], [])
        self.run.planned = [(0.0, 0.0), *(w.point for w in self.waypoints)]
        self.start_s = start_s
        self.on_leg = on_leg
        self._leg_start_s = start_s
        self._leg_cross = 0.0
        self._passed = [passed_at_speed(self.run.planned, k + 1)
                        for k in range(len(self.waypoints))]  # each waypoint passed at speed?
        self._crossed: Pose2d | None = None  # where the rover crossed the current waypoint's
        self._next_cross = 0.0  # line (passed at speed), and the next leg's cross-track since
        self._closest: tuple[float, Pose2d] | None = None  # a stop's closest approach so far
        self._last: Pose2d | None = None  # the pose at the look before

    def look(self, now_s: float, pose: Pose2d, messages: Sequence[Any]) -> bool:
        """The true ``pose`` at ``now_s`` and the messages that arrived since the last look;
        True once the mission has ended (the rover holds after its last waypoint).

        Raises:
            RuntimeError: the rover holds before its last waypoint.
        """
        out, waypoints = self.run, self.waypoints
        here = (pose.x_m, pose.y_m)
        out.true_path.append((pose.x_m, pose.y_m, pose.yaw_rad))
        out.times_s.append(now_s - self.start_s)
        out.max_yaw_deg = max(out.max_yaw_deg, abs(math.degrees(pose.yaw_rad)))
        k = len(out.legs)
        cross = math.nan
        if k < len(waypoints):
            cross = self._cross_track(k, pose)
        out.cross_track_m.append(cross)
        self._last = pose
        for msg in messages:
            kind = msg.get_type()
            if kind == "LOCAL_POSITION_NED":
                out.odometry_path.append((msg.x, msg.y))
                out.final_estimate, out.final_truth = (msg.x, msg.y), here
            elif kind == "MISSION_ITEM_REACHED" and k < len(waypoints) \
                    and msg.seq == waypoints[k].seq:
                self._reached(k, now_s, pose)
                k = len(out.legs)
            elif kind == "STATUSTEXT" and msg.text == MISSION_COMPLETE and not out.total_s:
                out.total_s = now_s - self.start_s
            elif kind == "HEARTBEAT" and msg.get_srcSystem() == 1 and msg.custom_mode == Mode.HOLD:
                if len(out.legs) == len(waypoints):
                    out.total_s = out.total_s or now_s - self.start_s
                    return True
                raise RuntimeError(f"the rover stopped after {len(out.legs)} legs")
        return False

    def _cross_track(self, k: int, pose: Pose2d) -> float:
        """The distance from ``pose`` to leg ``k`` (to the next leg once the rover crossed
        the line through a waypoint it passes at speed), kept as the leg's largest."""
        planned, here = self.run.planned, (pose.x_m, pose.y_m)
        leg = Leg(planned[k], planned[k + 1])
        if self._crossed is None and not self._passed[k] and k + 2 < len(planned):
            self._departure(leg, Leg(planned[k + 1], planned[k + 2]), pose)
        if self._crossed is None and self._last is not None and self._passed[k]:
            along, _ = leg.errors(here)
            if along >= leg.length_m:
                before, _ = leg.errors((self._last.x_m, self._last.y_m))
                f = 1.0 if along == before else min(max(
                    (leg.length_m - before) / (along - before), 0.0), 1.0)
                last = self._last
                self._crossed = Pose2d(last.x_m + f * (pose.x_m - last.x_m),
                                       last.y_m + f * (pose.y_m - last.y_m),
                                       last.yaw_rad + f * wrap_pi(pose.yaw_rad - last.yaw_rad))
        if self._crossed is not None:
            cross = Leg(planned[k + 1], planned[k + 2]).distance_m(here)
            self._next_cross = max(self._next_cross, cross)
            return cross
        cross = leg.distance_m(here)
        self._leg_cross = max(self._leg_cross, cross)
        return cross

    def _departure(self, leg: Leg, next_leg: Leg, pose: Pose2d) -> None:
        """At a waypoint the rover stops at: keep its closest approach; once it drove off
        along ``next_leg``, that is where it arrived (module description)."""
        here = (pose.x_m, pose.y_m)
        distance = math.dist(here, leg.end_ned)
        if self._closest is None or distance < self._closest[0]:
            self._closest = (distance, pose)
        elif (distance > self._closest[0] + DEPART_M
              and next_leg.distance_m(here) < leg.distance_m(here)):
            self._crossed = self._closest[1]

    def _reached(self, k: int, now_s: float, pose: Pose2d) -> None:
        wp, planned = self.waypoints[k], self.run.planned
        at = self._crossed or pose  # arrived where it crossed, if before the report
        heading = math.nan if wp.yaw_deg is None else math.degrees(
            wrap_pi(at.yaw_rad - math.radians(wp.yaw_deg)))
        self.run.legs.append(LegReport(wp.seq, planned[k], planned[k + 1],
                                       now_s - self._leg_start_s, self._leg_cross,
                                       math.dist((at.x_m, at.y_m), wp.point), heading))
        self.on_leg(len(self.run.legs), self.run.legs[-1])
        self._leg_start_s, self._leg_cross = now_s, self._next_cross
        self._crossed, self._next_cross, self._closest = None, 0.0, None
