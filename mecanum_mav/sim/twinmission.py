"""Missions on the twin (:mod:`mecanum_mav.sim.twin`): in real time over MAVLink, graded
against the chassis's truth matched by wall time.

Two drivers fly the same missions (:func:`~mecanum_mav.sim.missionrun.waypoint_mission`):

- the companion (:func:`fly_companion`): a scripted ground station on :attr:`Twin.gcs_url
  <mecanum_mav.sim.twin.Twin.gcs_url>` uploads the mission, arms (the companion's pre-arm
  checks on), switches to AUTO and listens until the rover holds
  (:func:`~mecanum_mav.sim.missionrun.fly`);
- ArduPilot Rover's own omni frame (:func:`fly_firmware`, the anchor): the ground station
  talks to the firmware itself (:attr:`Twin.firmware_url`), arms (waiting for its pre-arm
  checks: EKF, GPS; arming sets its home where the rover stands), uploads the waypoints in the
  global frame about that home (ArduPilot's missions take no local frame), AUTO, listens until
  its "Mission Complete", switches it to HOLD (it would stay in AUTO) and disarms.

Either way the ground station only records: every message with the wall time it arrived
(``time.monotonic()``, the clock of :class:`~mecanum_mav.sim.twinbridge.TruthSample`'s
``wall_s``). :func:`grade` then replays the record through the same watch as the lockstep
bench (:class:`~mecanum_mav.sim.missionrun.MissionWatch`), the true pose at each look taken
from the bridge's record (:class:`TruthTrack`: the last frame answered at or before that wall
time), so the figures (:func:`~mecanum_mav.sim.trackquality.figures`) are those of the lockstep
bench: cross-track, arrival at each MISSION_ITEM_REACHED, the odometry's drift (the driver's
LOCAL_POSITION_NED: the companion's dead reckoning, or the firmware's EKF).

Before the companion takes its first heading, the firmware's heading must have settled
(:func:`wait_heading_settled`): ArduPilot's EKF starts from the compass without the magnetic
declination (about 12 degrees at SITL's home) and turns to true north some 10 s after boot,
and shifts again by 2-3 degrees when it starts to use GPS, some 30 s after boot; a companion
that took its heading before drives that much askew all mission long.

:func:`manual_probe` drives the firmware in MANUAL with MANUAL_CONTROL (forward, strafe,
rotate, each for a while) and measures what the chassis truly did.
"""

from __future__ import annotations

import bisect
import dataclasses
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.mecanum.geometry import Pose2d, ned_to_body, wrap_pi
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.groundstation import ScriptedGroundStation, udp_ground_station
from mecanum_mav.sim.missionrun import (
    WATCH_PERIOD_S,
    MissionRun,
    MissionWatch,
    Waypoint,
    fly,
    waypoint_mission,
)
from mecanum_mav.sim.twin import Twin
from mecanum_mav.sim.twinbridge import TruthSample

__all__ = ["OMNI_PARM", "OMNI_WHEEL_MAP", "ManualStep", "Recording", "SettledTwin",
           "TruthTrack",
           "firmware_mission", "fly_companion", "fly_firmware", "grade", "manual_probe",
           "omni_firmware_params", "read_parm", "shift_estimate", "wait_heading_settled"]

Vec = tuple[float, float]

OMNI_PARM = Path(__file__).resolve().parents[2] / "params" / "ardupilot_omni.parm"
"""ArduPilot Rover's omni X frame on this chassis (FRAME_TYPE 2, motors on SERVO1..4)."""
OMNI_WHEEL_MAP: tuple[tuple[int, float], ...] = ((4, 1.0), (1, 1.0), (3, 1.0), (2, 1.0))
"""FL, FR, RL, RR: (servo channel, sign) under :data:`OMNI_PARM`: FL is motor4 on SERVO4, FR
motor1 on SERVO1, RL motor3 on SERVO3, RR motor2 on SERVO2, none reversed."""
SETTLE_TIMEOUT_S = 90.0
SETTLED_BAND_DEG = 0.3
"""The firmware's heading is settled once its difference to the truth stays within this
band (degrees) ..."""
SETTLED_FOR_S = 3.0
"""... for this long (s)."""
ARM_TIMEOUT_S = 60.0
"""The firmware's pre-arm checks (EKF, GPS) may take this long to pass."""
POSITION_INTERVAL_US = 100_000
"""LOCAL_POSITION_NED and ATTITUDE from the firmware at 10 Hz (the companion's rate)."""
HOME_TIMEOUT_S = 10.0


# ---------------------------------------------------------------------------- truth

class TruthTrack:
    """The bridge's truth by wall time.

    Args:
        samples: :class:`TruthSample` in the order the frames were answered (wall times not
            decreasing); at least one.

    Raises:
        ValueError: no sample.
    """

    def __init__(self, samples: Sequence[TruthSample]) -> None:
        if not samples:
            raise ValueError("no truth: the bridge answered no frame")
        self.samples = list(samples)
        self._walls = [s.wall_s for s in self.samples]

    @property
    def end_s(self) -> float:
        """Wall time of the last frame."""
        return self._walls[-1]

    def at(self, wall_s: float) -> TruthSample:
        """The last frame answered at or before ``wall_s`` (the first one before it began)."""
        k = bisect.bisect_right(self._walls, wall_s) - 1
        return self.samples[max(k, 0)]

    def pose_at(self, wall_s: float, origin: Vec = (0.0, 0.0)) -> Pose2d:
        """The true pose at ``wall_s``: north and east metres from ``origin`` (north, east in
        the bridge's frame), yaw radians clockwise from north."""
        s = self.at(wall_s)
        return Pose2d(s.north_m - origin[0], s.east_m - origin[1], s.yaw_rad)

    def lag_s(self, start_s: float, end_s: float) -> float:
        """Wall time minus physics time from wall time ``start_s`` to ``end_s`` (s, the physics
        time of the last frame answered by each): how long the chassis' world stood still while
        the clocks of the ground station and the companion ran on (the firmware or the bridge
        starved of CPU; SITL catches up part of a stall afterwards), a stall still going on at
        ``end_s`` included. 0 for a twin in real time (give or take a frame)."""
        first, last = self.at(start_s), self.at(end_s)
        return (end_s - start_s) - (last.time_s - first.time_s)


# ---------------------------------------------------------------------------- grading

@dataclass
class Recording:
    """What the ground station received from AUTO on: ``messages`` and the wall time each
    arrived (``arrived_s``, not decreasing), from ``start_s`` (AUTO accepted)."""

    start_s: float
    messages: list[Any]
    arrived_s: list[float]
    failure: str | None = None
    """Why the live flight stopped short (a refused step, no end in time), or None."""

    @classmethod
    def since(cls, gcs: ScriptedGroundStation, index: int, start_s: float,
              failure: str | None = None) -> Recording:
        """The ground station's record from message ``index`` on, the mission started at
        ``start_s``."""
        return cls(start_s, gcs.messages[index:], gcs.arrived_s[index:], failure)


def grade(waypoints: Sequence[Waypoint], record: Recording, truth: TruthTrack,
          period_s: float = WATCH_PERIOD_S) -> tuple[MissionRun, str | None]:
    """Replay ``record`` through a :class:`~mecanum_mav.sim.missionrun.MissionWatch` with the
    truth at each look's wall time: a look at every arrival (with what arrived then) and at
    least every ``period_s`` between (up to the last message or the last frame, whichever is
    later). Positions are from where the rover stood when AUTO was accepted (the origin of
    the driver's local frame and of the mission: the companion's odometry starts where it was
    started, the firmware's home is set where it was armed; the chassis stood still there).
    Returns the run and why it did not finish (None: it did; else the record's own failure if
    it has one, or the watch's). The run's ``world_lag_s`` is :meth:`TruthTrack.lag_s` from
    AUTO to the last look (its ``wall_span_s``)."""
    watch = MissionWatch(waypoints, record.start_s)
    home = truth.at(record.start_s)
    origin = (home.north_m, home.east_m)
    end_s = max(record.arrived_s[-1] if record.arrived_s else record.start_s, truth.end_s)
    messages, arrived = record.messages, record.arrived_s
    now, i = record.start_s, 0
    failure: str | None = None
    try:
        while True:
            due = min(now + period_s, arrived[i] if i < len(arrived) else math.inf)
            if due > end_s:
                failure = "the mission did not finish in time"
                break
            batch = []
            while i < len(arrived) and arrived[i] <= due:
                batch.append(messages[i])
                i += 1
            now = due
            if watch.look(due, truth.pose_at(due, origin), batch):
                break
    except RuntimeError as exc:
        failure = str(exc)
    watch.run.world_lag_s = truth.lag_s(record.start_s, now)
    watch.run.wall_span_s = (record.start_s, now)
    return watch.run, record.failure or failure


# ---------------------------------------------------------------------------- companion

class _LiveTruth:
    """The twin's truth now, shaped as the lockstep board's state (``.pose``)."""

    def __init__(self, twin: Twin) -> None:
        self.twin = twin

    def __call__(self) -> _LiveTruth:
        return self

    @property
    def pose(self) -> Pose2d:
        s = self.twin.truth_now()
        return Pose2d(s.north_m, s.east_m, s.yaw_rad)


def _fresh_start(gcs: ScriptedGroundStation) -> None:
    """Once the companion is heard: MAV_CMD_DO_SET_HOME "here" (its odometry's origin where
    the rover stands: the next mission starts from it) and DO_SET_MISSION_CURRENT 1 (a new
    upload keeps the current item, as ArduPilot's resume does: the last mission's would
    resume the new one at its item; refused while there is no mission, which is as good).

    Raises:
        RuntimeError: no heartbeat within 10 s, or set home refused (or not answered).
    """
    if gcs.wait("HEARTBEAT", lambda m: m.get_srcSystem() == 1, 10.0, since=0) is None:
        raise RuntimeError("no heartbeat from the vehicle")
    ack = gcs.command(mavlink.MAV_CMD_DO_SET_HOME, 1)
    if ack is None or ack.result != mavlink.MAV_RESULT_ACCEPTED:
        raise RuntimeError(f"set home refused ({None if ack is None else ack.result})")
    gcs.command(mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, 1)


def _after_auto(gcs: ScriptedGroundStation, index: int) -> tuple[int, float]:
    """The index of the first message after the COMMAND_ACK that accepted AUTO (looking from
    message ``index`` on) and when that ACK arrived; the end and now if none did. (What came
    with the ACK, in the same read, came before it: a HEARTBEAT of the mode before.)"""
    for k in range(index, len(gcs.messages)):
        msg = gcs.messages[k]
        if msg.get_type() == "COMMAND_ACK" and msg.command == mavlink.MAV_CMD_DO_SET_MODE \
                and msg.result == mavlink.MAV_RESULT_ACCEPTED:
            return k + 1, gcs.arrived_s[k]
    return len(gcs.messages), time.monotonic()


def fly_companion(twin: Twin, points: Sequence[Vec], yaws_deg: Sequence[float | None],
                  heading_deg: float | None, timeout_s: float,
                  gcs: ScriptedGroundStation | None = None) -> tuple[MissionRun, str | None]:
    """Fly a mission with the companion of ``twin`` (module docstring); its run, graded, and
    why it did not finish (None: it did). ``gcs``: the ground station on :attr:`Twin.gcs_url`
    to use (one for every mission of a twin: the companion says "Flight controller link up"
    once), or None for one of its own."""
    items, waypoints = waypoint_mission(points, yaws_deg, heading_deg=heading_deg)
    port = None
    if gcs is None:
        gcs, port = udp_ground_station(twin.gcs_url)
    try:
        index = len(gcs.messages)
        failure = None
        try:
            _fresh_start(gcs)
            fly(gcs, _LiveTruth(twin), items, waypoints, timeout_s)  # type: ignore[arg-type]
        except RuntimeError as exc:
            failure = str(exc)
        record = Recording.since(gcs, *_after_auto(gcs, index), failure)
    finally:
        if port is not None:
            port.close()
    return grade(waypoints, record, TruthTrack(twin.truth()))


# ---------------------------------------------------------------------------- the firmware

def read_parm(path: Path) -> dict[str, float]:
    """An ArduPilot parameter file (``NAME VALUE`` per line; ``#`` comments, commas allowed)."""
    params: dict[str, float] = {}
    for line in path.read_text().splitlines():
        fields = line.split("#", 1)[0].replace(",", " ").split()
        if len(fields) >= 2:
            params[fields[0]] = float(fields[1])
    return params


def firmware_mission(points: Sequence[Vec], yaws_deg: Sequence[float | None],
                     heading_deg: float | None, home: GlobalOrigin
                     ) -> tuple[list[MissionItem], list[Waypoint]]:
    """The mission for ArduPilot: home, then each point as a NAV_WAYPOINT in the global frame
    (relative altitude 0) about ``home``; no CONDITION_YAW and no waypoint heading (Rover's
    AUTO steers toward each waypoint itself). The waypoints as planned keep the headings the
    companion's mission asks for (``yaws_deg``, ``heading_deg``), so the figures show how far
    ArduPilot's AUTO strays from them."""
    local, plain = waypoint_mission(points, None, heading_deg=None)
    _, planned = waypoint_mission(points, yaws_deg, heading_deg=heading_deg)
    frame = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    items = []
    for item in local:
        lat, lon = home.to_global(item.x / 1e4, item.y / 1e4)
        items.append(dataclasses.replace(item, frame=frame, param4=0.0, x=lat, y=lon, z=0.0))
    waypoints = [dataclasses.replace(p, seq=q.seq) for p, q in zip(planned, plain, strict=True)]
    return items, waypoints


def _ask_interval(gcs: ScriptedGroundStation, msg_id: int, interval_us: int) -> None:
    gcs.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, interval_us)


def _home(gcs: ScriptedGroundStation) -> GlobalOrigin:
    """The firmware's home (HOME_POSITION, asked for; armed: where it was armed).

    Raises:
        RuntimeError: none within :data:`HOME_TIMEOUT_S`.
    """
    deadline = time.monotonic() + HOME_TIMEOUT_S
    while time.monotonic() < deadline:
        since = gcs.mark()
        gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_HOME_POSITION)
        home = gcs.wait("HOME_POSITION", timeout_s=1.0, since=since)
        if home is not None:
            return GlobalOrigin(home.latitude, home.longitude, home.altitude)
    raise RuntimeError("the firmware has no home (no GPS fix?)")


def _firmware_ground_station(twin: Twin) -> tuple[ScriptedGroundStation, Any]:
    """A ground station on the firmware's own port, its streams asked for, once heard."""
    gcs, port = udp_ground_station(twin.firmware_url)
    if gcs.wait("HEARTBEAT", lambda m: m.get_srcSystem() == 1, 10.0) is None:
        port.close()
        raise RuntimeError("no heartbeat from the firmware")
    _ask_interval(gcs, mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, POSITION_INTERVAL_US)
    _ask_interval(gcs, mavlink.MAVLINK_MSG_ID_ATTITUDE, POSITION_INTERVAL_US)
    return gcs, port


ARDUPILOT_MISSION_COMPLETE = "Mission Complete"
"""ArduPilot Rover's STATUSTEXT at a mission's end; it stays in AUTO (MIS_DONE_BEHAVE offers
no HOLD mode), so the ground station switches it to HOLD then."""


def _until_hold(gcs: ScriptedGroundStation, timeout_s: float) -> str | None:
    """Listen until the firmware says its mission is complete, switch it to HOLD and listen
    until its HEARTBEAT says so (for what is left of ``timeout_s``, at least 2 s); None, or why
    not."""
    deadline = time.monotonic() + timeout_s
    if gcs.wait("STATUSTEXT", lambda m: m.text == ARDUPILOT_MISSION_COMPLETE,
                timeout_s) is None:
        return "the mission did not finish in time"
    gcs.set_mode(Mode.HOLD)
    if gcs.wait("HEARTBEAT", lambda m: m.get_srcSystem() == 1 and m.custom_mode == Mode.HOLD,
                max(deadline - time.monotonic(), 2.0)) is None:
        return "HOLD refused at the mission's end"
    return None


def fly_firmware(twin: Twin, points: Sequence[Vec], yaws_deg: Sequence[float | None],
                 heading_deg: float | None, timeout_s: float
                 ) -> tuple[MissionRun, str | None]:
    """Fly a mission in ArduPilot's own AUTO on ``twin`` (module docstring); its run, graded,
    and why it did not finish (None: it did)."""
    gcs, port = _firmware_ground_station(twin)
    try:
        index = len(gcs.messages)
        failure = _arm(gcs)  # arming sets ArduPilot's home where the rover stands
        _, waypoints = firmware_mission(points, yaws_deg, heading_deg, GlobalOrigin(0, 0))
        if failure is None:
            items, waypoints = firmware_mission(points, yaws_deg, heading_deg, _home(gcs))
            failure = _firmware_auto(gcs, items, timeout_s)
        after, start_s = _after_auto(gcs, index)
        record = Recording.since(gcs, after, start_s, failure)
        before = [m for m, t in zip(gcs.messages, gcs.arrived_s, strict=True)
                  if t < start_s and m.get_type() == "LOCAL_POSITION_NED"]
        if failure is not None:  # stopped short (still in AUTO): the next must enter AUTO anew
            gcs.set_mode(Mode.HOLD)
        gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0)  # the next arms where it stops
    finally:
        port.close()
    run, failure = grade(waypoints, record, TruthTrack(twin.truth()))
    if before:  # its EKF's origin is where GPS first came, not where this mission started
        shift_estimate(run, (before[-1].x, before[-1].y))
    return run, failure


def shift_estimate(run: MissionRun, origin: Vec) -> None:
    """Make ``run``'s estimated positions relative to ``origin`` (the estimate's position when
    the mission started), in place."""
    n0, e0 = origin
    run.odometry_path = [(n - n0, e - e0) for n, e in run.odometry_path]
    if run.final_estimate is not None:
        run.final_estimate = (run.final_estimate[0] - n0, run.final_estimate[1] - e0)


def _arm(gcs: ScriptedGroundStation) -> str | None:
    """Arm the firmware, waiting for its pre-arm checks: None, or why it refused."""
    try:
        gcs.arm(timeout_s=ARM_TIMEOUT_S)
    except RuntimeError:
        texts = [m.text for m in gcs.received("STATUSTEXT") if "PreArm" in m.text]
        return "arming refused" + (f": {texts[-1]}" if texts else "")
    return None


def _firmware_auto(gcs: ScriptedGroundStation, items: Sequence[MissionItem],
                   timeout_s: float) -> str | None:
    """Upload, AUTO, listen until HOLD: None, or the step that failed."""
    result = gcs.upload(items).type
    if result != mavlink.MAV_MISSION_ACCEPTED:
        return f"mission upload refused (MISSION_ACK {result})"
    deadline = time.monotonic() + ARM_TIMEOUT_S
    while gcs.set_mode(Mode.AUTO) != mavlink.MAV_RESULT_ACCEPTED:
        # AUTO needs the EKF's position: ArduPilot's EKF3 takes GPS some 30 s after boot
        if time.monotonic() > deadline:
            return f"AUTO refused for {ARM_TIMEOUT_S:g} s (no EKF position?)"
        gcs.pump(0.5)
    return _until_hold(gcs, timeout_s)


def wait_heading_settled(twin: Twin, timeout_s: float = SETTLE_TIMEOUT_S
                         ) -> tuple[float, float]:
    """Wait until the firmware's EKF has an absolute position (EKF_STATUS_REPORT's
    EKF_POS_HORIZ_ABS: it uses GPS, some 30 s after boot; its heading shifts by a few degrees
    when it starts to) and then its heading's difference to the truth (ATTITUDE yaw minus the
    true yaw) has stayed within a band of :data:`SETTLED_BAND_DEG` for :data:`SETTLED_FOR_S`;
    how long that took (s) and that difference then (degrees: what the companion's heading
    will be off by). It asks the firmware for EKF_STATUS_REPORT at 2 Hz.

    Raises:
        RuntimeError: not within ``timeout_s`` (the message gives the last difference).
    """
    gcs, port = _firmware_ground_station(twin)
    try:
        _ask_interval(gcs, mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT, 500_000)
        started = time.monotonic()
        window: list[tuple[float, float]] = []  # (time, difference) since positioned
        error = math.nan
        positioned = False
        while time.monotonic() - started < timeout_s:
            for msg in gcs.pump(0.1):
                if msg.get_srcSystem() != 1:
                    continue
                if msg.get_type() == "EKF_STATUS_REPORT":
                    positioned = bool(msg.flags & mavlink.EKF_POS_HORIZ_ABS) \
                        and not msg.flags & mavlink.EKF_CONST_POS_MODE
                if msg.get_type() != "ATTITUDE":
                    continue
                now = time.monotonic()
                error = math.degrees(wrap_pi(msg.yaw - twin.truth_now().yaw_rad))
                window = [(t, e) for t, e in window if now - t <= SETTLED_FOR_S] \
                    if positioned else []
                window.append((now, error))
                errors = [e for _, e in window]
                if positioned and now - window[0][0] >= SETTLED_FOR_S - 0.2 \
                        and max(errors) - min(errors) <= SETTLED_BAND_DEG:
                    return now - started, error
    finally:
        port.close()
    raise RuntimeError(f"the firmware's heading did not settle within {timeout_s:g} s "
                       f"(last {error:+.1f} deg from the truth; EKF position "
                       f"{'absolute' if positioned else 'none'})")


class SettledTwin(Twin):
    """A :class:`~mecanum_mav.sim.twin.Twin` whose companion starts only once the firmware's
    heading has settled (:func:`wait_heading_settled`, after setup-fc's reboot), so that the
    companion's odometry anchors to the true heading. (The twin has no hook for it: this
    waits inside its setup-fc step.)"""

    settle_s = math.nan
    """How long the firmware's heading took to settle after setup-fc (s)."""
    heading_error_deg = math.nan
    """The firmware's heading minus the truth then (degrees)."""

    def _setup_fc(self, timeout_s: float) -> None:
        super()._setup_fc(timeout_s)
        self.settle_s, self.heading_error_deg = wait_heading_settled(self)


# ---------------------------------------------------------------------------- MANUAL

@dataclass(frozen=True)
class ManualStep:
    """One MANUAL_CONTROL held for a while and what the chassis truly did meanwhile.

    ``x``, ``y``, ``z``, ``r``: the fields sent (-1000..1000; z 0 is centre for Rover's
    throttle). ``forward_m``, ``right_m``: the true displacement in the body frame at the start;
    ``turn_deg``: the true turn (clockwise)."""

    name: str
    x: int
    y: int
    z: int
    r: int
    forward_m: float
    right_m: float
    turn_deg: float

    def describe(self) -> str:
        return (f"{self.name:<8} x {self.x:5d} y {self.y:5d} z {self.z:5d} r {self.r:5d}: "
                f"forward {self.forward_m * 100:7.1f} cm, right {self.right_m * 100:7.1f} cm, "
                f"turned {self.turn_deg:7.1f} deg")


MANUAL_STEPS: tuple[tuple[str, int, int, int, int], ...] = (
    ("forward", 500, 0, 500, 0),
    ("strafe", 0, 500, 0, 0),
    ("rotate", 0, 0, 0, 500),
)
"""(name, x, y, z, r) as a ground station's joystick sends them for half forward, half right
and half clockwise (x forward, y right, z throttle, r yaw), each axis its own step; Rover reads
only y (steering) and z (throttle) of MANUAL_CONTROL, so each asks for the motion on the axes a
joystick would use AND on Rover's: forward with x and z, strafe with y, rotate with r."""
MANUAL_HOLD_S = 2.0
MANUAL_SEND_PERIOD_S = 0.05


def manual_probe(twin: Twin, steps: Sequence[tuple[str, int, int, int, int]] = MANUAL_STEPS,
                 hold_s: float = MANUAL_HOLD_S) -> list[ManualStep]:
    """Arm the firmware in MANUAL and hold each MANUAL_CONTROL of ``steps`` for ``hold_s``
    (then centre for as long, so the chassis stops); the truth of each.

    Raises:
        RuntimeError: MANUAL or arming refused.
    """
    gcs, port = _firmware_ground_station(twin)
    try:
        if gcs.set_mode(Mode.MANUAL) != mavlink.MAV_RESULT_ACCEPTED:
            raise RuntimeError("MANUAL refused")
        failure = _arm(gcs)
        if failure is not None:
            raise RuntimeError(failure)
        results = []
        for name, x, y, z, r in steps:
            start = twin.truth_now()
            _hold(gcs, (x, y, z, r), hold_s)
            moved = twin.truth_now()
            _hold(gcs, (0, 0, 0, 0), hold_s)
            forward, right = ned_to_body(moved.north_m - start.north_m,
                                         moved.east_m - start.east_m, start.yaw_rad)
            turn = math.degrees(wrap_pi(moved.yaw_rad - start.yaw_rad))
            results.append(ManualStep(name, x, y, z, r, forward, right, turn))
        gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0)
        return results
    finally:
        port.close()


def _hold(gcs: ScriptedGroundStation, axes: tuple[int, int, int, int], hold_s: float) -> None:
    x, y, z, r = axes
    end = time.monotonic() + hold_s
    while time.monotonic() < end:
        gcs.sticks(x, y, r, z)
        gcs.pump(MANUAL_SEND_PERIOD_S)


def omni_firmware_params(speed_mps: float, extra: Mapping[str, float] | None = None
                         ) -> dict[str, float]:
    """:data:`OMNI_PARM` with ``WP_SPEED`` at ``speed_mps``, then ``extra``."""
    return {**read_parm(OMNI_PARM), "WP_SPEED": speed_mps, **(extra or {})}
