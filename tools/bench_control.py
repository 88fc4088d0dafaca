"""Control quality in AUTO, measured from outside on the simulated chassis (issue 25).

Three missions, each at several speeds, on the chosen chassis and floors, in the lockstep
harness (virtual time: deterministic, a mission in a fraction of its driving time):

- ``square``: a 3 m square driven clockwise from the start, facing north all the way
  (CONDITION_YAW 0): it drives forward, strafes right, reverses, strafes left;
- ``eight``: a figure eight of two 1.5 m circles touching at the start (clockwise east of it,
  counter-clockwise west of it), 16 waypoints a circle (0.29 m apart), facing north;
- ``strafe-rotate``: 3 m north in six 0.5 m legs whose waypoints each turn the heading 30
  degrees further (30 ... 180): it strafes through every direction while it turns.

Per run (one row per mission x speed x chassis x floor): the mission time, worst and RMS
cross-track of the true path (distance to the current leg), the worst true arrival error at
MISSION_ITEM_REACHED (position, and heading against the waypoint's; a waypoint passed at speed is
arrived at where the rover truly crosses its line, if before the report:
:mod:`mecanum_mav.sim.missionrun`), the odometry's drift at the
end (LOCAL_POSITION_NED minus truth, % of the distance truly driven), then every waypoint's
arrival error. Goals (issue 25) are judged at 1.0 m/s: arrival under 2 cm and 1 degree, worst
cross-track under 3 cm, drift under 1 %; on friction 0.4 (any floor below 0.8) twice those;
on the MuJoCo chassis the mission time at most 10 % over the kinematic chassis's (both are run
with ``--physics mujoco``). The kinematic chassis ignores friction: it is run once. A mission
that does not run to its end (the rover stops short of a waypoint, or takes longer than
:func:`time_allowed_s`) is a row that says where it stopped ("DID NOT FINISH"); the bench goes
on with the next. The picture (``--plot``) has one panel per mission at 1.0 m/s: the planned
path, and the true and the estimated path of every chassis and floor.

Each run sets ``WP_SPEED`` to its speed, ``GUID_SPD_MAX`` to the speed plus
:data:`SPEED_MARGIN_MPS` (room for the cross-track correction), ``WHL_MAX_SPD`` to
:data:`WHEEL_MAX_MPS` (a diagonal at 1.5 m/s needs 2.1 m/s at a wheel before any turn) and
``SIM_FRICTION`` to the floor's; on the MuJoCo chassis also ``MOT_DZ`` (the companion's ESC
dead-band compensation) to ``SIM_ESC_DZ`` plus :data:`DEAD_BAND_MARGIN` (as a user sets it for
the ESCs they have: the largest command that does not turn a wheel, a little above),
``MOT_DZ_TYPE`` to 1 (jump: past its band the simulated ESC drives the command itself) and
``WHL_STRAFE_EFF`` to :data:`MUJOCO_STRAFE_EFF` (the chassis's measured strafe efficiency); every
other parameter keeps its default unless ``--set`` changes it (a ``--set MOT_DZ`` wins).

``--twin`` runs the missions on the twin instead (:mod:`mecanum_mav.sim.twin`: the real
ArduPilot Rover firmware, SITL, driving the MuJoCo chassis through its JSON backend, the
companion unchanged in the loop), in real time over MAVLink (:mod:`mecanum_mav.sim.twinmission`:
the ground station records what arrives with wall times, the truth is the bridge's, matched by
wall time), by default at 1.0 m/s on friction 0.8 only. One twin per floor and speed flies the
missions one after another (the odometry's origin set anew before each: MAV_CMD_DO_SET_HOME),
its real-time factor and dropped frames printed after them. Beside it (unless ``--no-anchor``)
ArduPilot's own omni frame (``params/ardupilot_omni.parm``: FRAME_TYPE 2, OMNIX, its four
motors on our wheels) flies the same missions in its own AUTO on a twin without the companion
(rows ``ardupilot``; its drift is its EKF's LOCAL_POSITION_NED against the truth), and a ground
station's MANUAL_CONTROL asks it to drive forward, strafe and rotate (what the chassis truly
did is printed). ArduPilot's AUTO steers toward each waypoint and drives forward: it has no
lateral command and no heading of its own at a waypoint, so its heading column says how far it
turned from the heading the missions ask for.

Usage::

    python tools/bench_control.py [--physics kinematic|mujoco] [--friction 0.8,0.4]
        [--speeds 0.5,1.0,1.5] [--missions square,eight,strafe-rotate] [--quick]
        [--plot OUT.png] [--set NAME=VALUE ...]
    python tools/bench_control.py --twin [--sitl PATH] [--no-anchor] [--friction 0.8]
        [--speeds 1.0] [--missions ...] [--set NAME=VALUE ...] [--firmware-set NAME=VALUE ...]

``--quick`` runs only the goal speed (1.0 m/s) unless ``--speeds`` is given. ``--sitl``
defaults to ``$MECANUM_SITL``, else ``../shared/ardupilot-sitl/ardurover`` beside the checkout.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

from mecanum_mav.config.params import SPECS, ParamError, Params, parse_assignment
from mecanum_mav.sim.firmware import sitl_from_env
from mecanum_mav.sim.lockstep import Lockstep
from mecanum_mav.sim.missionrun import MissionRun, fly, waypoint_mission
from mecanum_mav.sim.physics import PHYSICS, PhysicsUnavailableError
from mecanum_mav.sim.trackquality import RunFigures, figures, path_length_m

Vec = tuple[float, float]

SPEEDS = (0.5, 1.0, 1.5)
FLOORS = (0.8, 0.4)
GOAL_SPEED = 1.0
"""The goals are judged at this speed (m/s)."""
HIGH_FRICTION = 0.8
"""Floors at or above this take the goals as they are; lower ones twice them."""
WHEEL_MAX_MPS = 3.0
"""``WHL_MAX_SPD`` for every run, m/s: 1.5 m/s on a diagonal needs 1.5 * sqrt(2) = 2.1 m/s at a
wheel, turning at 90 deg/s another 0.47 m/s (default geometry); 3.0 leaves control margin."""
SPEED_MARGIN_MPS = 0.2
"""``GUID_SPD_MAX`` is the run's speed plus this (the cross-track correction adds to the
speed along the leg)."""
DEAD_BAND_MARGIN = 0.002
"""``MOT_DZ`` on the MuJoCo chassis is ``SIM_ESC_DZ`` plus this: one microsecond of PWM above
the ESC's band, so rounding to whole microseconds never lands a command inside it."""
MUJOCO_STRAFE_EFF = 0.988
"""``WHL_STRAFE_EFF`` on the MuJoCo chassis: true over odometry distance strafing steadily at
0.5, 1.0 and 1.5 m/s, on friction 0.8 and 0.4 alike (0.9879-0.9881; forward 0.9996), as
``tools/odometry_calibration.py`` measures it (on the stiff roller contact; 0.986 on the
soft one before)."""
DT_S = 0.002
"""The harness's time step, seconds."""
SHOWN = ("WP_ACCEL", "WP_RADIUS", "WP_OVERSHOOT", "GUID_ACC_MAX", "GUID_POS_P", "GUID_YAW_P",
         "GUID_YAW_RATE", "SIM_MOTOR_TAU", "SIM_ESC_DZ", "MOT_DZ",
         "MOT_DZ_TYPE", "WHL_STRAFE_EFF")
"""Parameters the figures depend on, printed at the start (as every run has them; those this
build has)."""


# ---------------------------------------------------------------------------- missions

@dataclass(frozen=True)
class Mission:
    """Waypoints (north, east m), each one's own heading (deg, None: none) and the heading a
    CONDITION_YAW sets first (None: none)."""

    points: tuple[Vec, ...]
    yaws_deg: tuple[float | None, ...]
    heading_deg: float | None = 0.0


def square(side_m: float = 3.0) -> Mission:
    """A square of ``side_m`` clockwise from the start, facing north."""
    points = ((side_m, 0.0), (side_m, side_m), (0.0, side_m), (0.0, 0.0))
    return Mission(points, (None,) * len(points))


def figure_eight(diameter_m: float = 1.5, per_circle: int = 16) -> Mission:
    """Two circles of ``diameter_m`` touching at the start, both entered heading north: the
    east one clockwise, then the west one counter-clockwise; ``per_circle`` waypoints each,
    the last back at the start. Facing north."""
    r = diameter_m / 2
    points: list[Vec] = []
    for side in (1.0, -1.0):
        for k in range(1, per_circle + 1):
            angle = 2 * math.pi * k / per_circle
            north = r * math.sin(angle)
            east = side * r * (1.0 - math.cos(angle))
            points.append((_clean(north), _clean(east)))
    return Mission(tuple(points), (None,) * len(points))


def strafe_rotate(length_m: float = 3.0, turn_deg: float = 180.0, legs: int = 6) -> Mission:
    """``length_m`` north in ``legs`` equal legs; each waypoint's heading is ``turn_deg /
    legs`` further clockwise than the last (from north), so the rover turns while it
    strafes."""
    points = tuple((length_m * k / legs, 0.0) for k in range(1, legs + 1))
    yaws = tuple(turn_deg * k / legs for k in range(1, legs + 1))
    return Mission(points, yaws)


def _clean(x: float) -> float:
    """``x`` rounded to 0.1 mm (mission items carry 0.1 mm), so -0.0 and 1e-17 read 0."""
    return round(x, 4) + 0.0


MISSIONS: dict[str, Callable[[], Mission]] = {
    "square": square, "eight": figure_eight, "strafe-rotate": strafe_rotate}


# ---------------------------------------------------------------------------- goals

@dataclass(frozen=True)
class Goals:
    """The limits a run at :data:`GOAL_SPEED` must stay under (issue 25)."""

    arrival_m: float = 0.02
    heading_deg: float = 1.0
    cross_track_m: float = 0.03
    drift_pct: float = 1.0
    time_ratio: float = 1.10
    """The MuJoCo chassis's mission time over the kinematic chassis's, at most."""

    def scaled(self, factor: float) -> Goals:
        """The error goals times ``factor`` (the time ratio stays)."""
        return Goals(self.arrival_m * factor, self.heading_deg * factor,
                     self.cross_track_m * factor, self.drift_pct * factor, self.time_ratio)


GOALS = Goals()


def goals_for(friction: float | None) -> Goals:
    """The goals on a floor of ``friction`` (None: the kinematic chassis, no floor): as
    stated at or above :data:`HIGH_FRICTION`, twice the error goals below it."""
    return GOALS if friction is None or friction >= HIGH_FRICTION else GOALS.scaled(2.0)


@dataclass(frozen=True)
class Verdict:
    """One goal judged: ``name``, the measured ``value``, the ``limit`` and whether met."""

    name: str
    value: float
    limit: float
    met: bool

    def describe(self) -> str:
        word = "met" if self.met else "NOT MET"
        if self.name == "finished":
            return f"finished: reached {self.value:.0f} of {self.limit:.0f} waypoints: {word}"
        return f"{self.name} {self.value:.2f} (goal {self.limit:.2f}): {word}"


def judge(fig: RunFigures, goals: Goals, time_ratio: float | None = None) -> list[Verdict]:
    """Each goal for one run: errors strictly under their goal (a heading goal only where
    waypoints have a heading), the time ratio at most its goal (when there is one). NaN is
    never met."""
    verdicts = [
        _under("arrival cm", fig.worst_arrival_m * 100, goals.arrival_m * 100),
        _under("cross-track cm", fig.worst_cross_track_m * 100, goals.cross_track_m * 100),
        _under("drift %", fig.drift_pct, goals.drift_pct),
    ]
    if any(not math.isnan(h) for h in fig.headings_deg):
        verdicts.insert(1, _under("heading deg", fig.worst_heading_deg, goals.heading_deg))
    if time_ratio is not None:
        verdicts.append(Verdict("time ratio", time_ratio, goals.time_ratio,
                                time_ratio <= goals.time_ratio))
    return verdicts


def _under(name: str, value: float, limit: float) -> Verdict:
    return Verdict(name, value, limit, value < limit)


# ---------------------------------------------------------------------------- runs

@dataclass
class Row:
    """One run: its conditions, the record and the figures; ``time_ratio`` against the
    kinematic chassis's run of the same mission and speed (MuJoCo rows)."""

    mission: str
    speed_mps: float
    physics: str
    friction: float | None
    run: MissionRun
    fig: RunFigures
    time_ratio: float | None = None
    failure: str | None = None
    """Why the mission did not run to its end (None: it did); the figures are then of the
    part it drove."""

    @property
    def judged(self) -> bool:
        """Whether the goals apply (the goal speed)."""
        return math.isclose(self.speed_mps, GOAL_SPEED)

    def verdicts(self) -> list[Verdict]:
        if not self.judged:
            return []
        verdicts = judge(self.fig, goals_for(self.friction), self.time_ratio)
        if self.failure is not None:
            reached = Verdict("finished", len(self.run.legs), len(self.run.planned) - 1, False)
            verdicts.insert(0, reached)
        return verdicts

    @property
    def label(self) -> str:
        floor = "" if self.friction is None else f" mu {self.friction:g}"
        return f"{self.mission} {self.speed_mps:g} m/s {self.physics}{floor}"


def bench_params(speed_mps: float, friction: float | None,
                 overrides: Sequence[tuple[str, float]] = ()) -> Params:
    """The parameters of one run (module docstring), then ``overrides`` in order; on the
    MuJoCo chassis (a ``friction``) ``MOT_DZ`` follows ``SIM_ESC_DZ`` as overridden,
    ``MOT_DZ_TYPE`` is 1 (jump) and ``WHL_STRAFE_EFF`` is :data:`MUJOCO_STRAFE_EFF`, unless an
    override sets them.

    Raises:
        ParamError: an override the store refuses.
    """
    params = Params()
    params.update({"WHL_MAX_SPD": WHEEL_MAX_MPS, "GUID_SPD_MAX": speed_mps + SPEED_MARGIN_MPS,
                   "WP_SPEED": speed_mps})
    if friction is not None and "SIM_FRICTION" in params:
        params.set("SIM_FRICTION", friction)
    for name, value in overrides:
        params.set(name, value)
    if friction is None:
        return params
    chassis = {"WHL_STRAFE_EFF": MUJOCO_STRAFE_EFF, "MOT_DZ_TYPE": 1.0}
    if "SIM_ESC_DZ" in params and "MOT_DZ" in params:
        chassis["MOT_DZ"] = min(params["SIM_ESC_DZ"] + DEAD_BAND_MARGIN,
                                SPECS["MOT_DZ"].maximum)
    for name, value in chassis.items():
        if name in params and name not in dict(overrides):
            params.set(name, value)
    return params


def run_mission(name: str, speed_mps: float, physics: str = "kinematic",
                friction: float | None = None, overrides: Sequence[tuple[str, float]] = (),
                dt_s: float = DT_S) -> Row:
    """Fly mission ``name`` at ``speed_mps`` on the chassis ``physics`` and floor
    ``friction`` (None: the kinematic chassis's own) in the lockstep harness.

    A mission that does not run to its end (the rover stops short, or takes more than
    :func:`time_allowed_s`) is a row with its :attr:`Row.failure`.

    Raises:
        PhysicsUnavailableError: the chassis needs a package that is not installed.
    """
    mission = MISSIONS[name]()
    items, waypoints = waypoint_mission(mission.points, mission.yaws_deg,
                                        heading_deg=mission.heading_deg)
    harness = Lockstep(bench_params(speed_mps, friction, overrides), dt_s=dt_s,
                       physics=physics)
    run = MissionRun([], [])
    failure = None
    try:
        fly(harness.gcs, harness.truth, items, waypoints,
            time_allowed_s(((0.0, 0.0), *mission.points), speed_mps), into=run)
    except RuntimeError as exc:
        failure = f"{exc}{_where(run)}"
    return Row(name, speed_mps, physics, friction, run, figures(run), failure=failure)


def time_allowed_s(points: Sequence[Vec], speed_mps: float) -> float:
    """How long a mission through ``points`` at ``speed_mps`` may take: 10 s plus three
    times its length at that speed (the kinematic chassis takes under twice)."""
    return 10.0 + 3.0 * path_length_m(points) / speed_mps


def _where(run: MissionRun) -> str:
    """Where a run that did not finish ended: the true distance to its next waypoint."""
    k = len(run.legs)
    if not run.true_path or k + 1 >= len(run.planned):
        return ""
    gap = math.dist(run.true_path[-1][:2], run.planned[k + 1])
    return f" ({gap * 100:.1f} cm from waypoint {k + 1} of {len(run.planned) - 1})"


# ---------------------------------------------------------------------------- the twin

TWIN_ODOM_CMD_TAU = 0.12
"""``ODOM_CMD_TAU`` on the twin (no WHEEL_DISTANCE from ArduPilot: the odometry takes the
commanded speeds): the motors' 0.08 s and the firmware's pass-through (measured at 1 m/s,
friction 0.8: strafe-rotate drift 7.9 % with 0, 2-3 % with 0.12); a ``--set`` wins."""
TWIN_ODOM_CMD_GAIN = 0.9975
TWIN_STRAFE_EFF = 0.983
"""``ODOM_CMD_GAIN`` and ``WHL_STRAFE_EFF`` on the twin, calibrated as a user without encoders
does: its AUTO driving 3 m and back at 1 m/s, friction 0.8, read 0.15-0.35 % long forward and
0.6-0.8 % long strafing (under load the MuJoCo motors run below their command, and the strafe
slips beyond :data:`MUJOCO_STRAFE_EFF`; the chassis alone through the same PWM edge: 0.25 %
and 0.9 %); a ``--set`` wins."""
TWIN_GUID_YAW_LEAD = 0.15
"""``GUID_YAW_LEAD`` on the twin: the body velocity is turned for the heading the rover will
have when the wheels deliver it, and on the twin they deliver it later than on the companion's
own simulator (0.09 s there: the motors' 0.08 s and half a control period): the firmware's
pass-through and its loop come on top. Measured at 1 m/s, friction 0.8, the strafe-rotate's
worst offset of the true track from its line (it turns 60 degrees/s while it strafes, and a
lead too short bends the track clockwise): 2.95 cm at 0.09, 1.39 cm at 0.15; a ``--set``
wins."""
TWIN_FLOORS = (0.8,)
"""The twin's default floor (real time: one floor)."""
SITL_BESIDE = Path(__file__).resolve().parent.parent.parent / "shared" / "ardupilot-sitl" / \
    "ardurover"
"""Where the firmware is when the checkout sits beside ``shared/`` (as on this machine)."""


def default_sitl() -> Path:
    """``$MECANUM_SITL``, else :data:`SITL_BESIDE`."""
    return sitl_from_env() or SITL_BESIDE


ANCHOR_TIME_FACTOR = 2.0
"""ArduPilot's AUTO may take this many times :func:`time_allowed_s` (it pivots at corners)."""


def twin_row(name: str, speed_mps: float, friction: float, driver: str,
             fly_on: Callable[..., tuple[MissionRun, str | None]], twin: Any,
             time_factor: float = 1.0) -> Row:
    """Mission ``name`` flown on ``twin`` by ``fly_on`` (the companion's or the firmware's
    :mod:`~mecanum_mav.sim.twinmission` flight) within ``time_factor`` times
    :func:`time_allowed_s`, as a row of chassis ``driver``."""
    mission = MISSIONS[name]()
    allowed = time_factor * time_allowed_s(((0.0, 0.0), *mission.points), speed_mps)
    run, failure = fly_on(twin, mission.points, mission.yaws_deg, mission.heading_deg, allowed)
    if failure is not None:
        failure = f"{failure}{_where(run)}"
    return Row(name, speed_mps, driver, friction, run, figures(run), failure=failure)


def twin_params(speed_mps: float, friction: float,
                overrides: Sequence[tuple[str, float]] = ()) -> Params:
    """:func:`bench_params` on the MuJoCo chassis with ``ODOM_CMD_TAU``, ``ODOM_CMD_GAIN``,
    ``WHL_STRAFE_EFF`` and ``GUID_YAW_LEAD`` at :data:`TWIN_ODOM_CMD_TAU`,
    :data:`TWIN_ODOM_CMD_GAIN`, :data:`TWIN_STRAFE_EFF` and :data:`TWIN_GUID_YAW_LEAD` (unless
    overridden)."""
    return bench_params(speed_mps, friction, [
        ("ODOM_CMD_TAU", TWIN_ODOM_CMD_TAU), ("ODOM_CMD_GAIN", TWIN_ODOM_CMD_GAIN),
        ("WHL_STRAFE_EFF", TWIN_STRAFE_EFF), ("GUID_YAW_LEAD", TWIN_GUID_YAW_LEAD),
        *overrides])


def run_twin(sitl: Path, missions: Sequence[str], speeds: Sequence[float],
             floors: Sequence[float], overrides: Sequence[tuple[str, float]] = (), *,
             anchor: bool = True, on_row: Callable[[Row], None] = lambda row: None,
             say: Callable[[str], None] = print,
             firmware: Sequence[tuple[str, float]] = ()) -> list[Row]:
    """Every mission x speed x floor on the twin with the companion, then (``anchor``) with
    ArduPilot's own omni frame, and its MANUAL probe once; ``say`` gets each twin's figures.

    Raises:
        PhysicsUnavailableError: no mujoco. FileNotFoundError: no firmware at ``sitl``.
        TwinError: a twin did not come up.
    """
    from mecanum_mav.sim import twinmission as tm
    from mecanum_mav.sim.groundstation import udp_ground_station
    from mecanum_mav.sim.twin import Twin, describe

    rows: list[Row] = []
    probed = not anchor
    for friction in floors:
        for speed in speeds:
            params = twin_params(speed, friction, overrides)
            twin = tm.SettledTwin(sitl, friction=friction, params=params,
                                  firmware_params=dict(firmware))
            with twin:
                say(f"twin (companion) mu {friction:g} at {speed:g} m/s: the firmware's heading "
                    f"settled {twin.settle_s:.1f} s after setup-fc, "
                    f"{twin.heading_error_deg:+.2f} deg from the truth")
                gcs, port = udp_ground_station(twin.gcs_url)
                try:
                    for name in missions:
                        rows.append(twin_row(name, speed, friction, "twin",
                                             partial(tm.fly_companion, gcs=gcs), twin))
                        on_row(rows[-1])
                finally:
                    port.close()
                say(f"  twin (companion): {describe(twin.stats())}")
            if not anchor:
                continue
            with Twin(sitl, friction=friction, params=params, frame="ardupilot-omni",
                      wheel_map=tm.OMNI_WHEEL_MAP,
                      firmware_params=tm.omni_firmware_params(speed, dict(firmware))) as omni:
                settle_s, error_deg = tm.wait_heading_settled(omni)
                say(f"twin (ArduPilot omni) mu {friction:g} at {speed:g} m/s: its heading "
                    f"settled {settle_s:.1f} s after start, {error_deg:+.2f} deg from the truth")
                for name in missions:
                    rows.append(twin_row(name, speed, friction, "ardupilot", tm.fly_firmware,
                                         omni, ANCHOR_TIME_FACTOR))
                    on_row(rows[-1])
                if not probed:
                    probed = True
                    say("  ArduPilot's MANUAL, a ground station's MANUAL_CONTROL held "
                        f"{tm.MANUAL_HOLD_S:g} s each (what the chassis truly did):")
                    for step in tm.manual_probe(omni):
                        say("    " + step.describe())
                say(f"  twin (ArduPilot omni): {describe(omni.stats())}")
    return rows


def chassis_and_floors(physics: str, floors: Sequence[float]) -> list[tuple[str, float | None]]:
    """What to run: the kinematic chassis once (it ignores friction); with ``mujoco`` also
    the MuJoCo chassis on each floor."""
    runs: list[tuple[str, float | None]] = [("kinematic", None)]
    if physics == "mujoco":
        runs += [("mujoco", f) for f in floors]
    return runs


def run_all(missions: Sequence[str], speeds: Sequence[float], physics: str,
            floors: Sequence[float], overrides: Sequence[tuple[str, float]] = (),
            on_row: Callable[[Row], None] = lambda row: None) -> list[Row]:
    """Every mission x speed x chassis x floor; finished MuJoCo rows get their time ratio to
    the finished kinematic row of the same mission and speed."""
    rows: list[Row] = []
    base: dict[tuple[str, float], float] = {}
    for chassis, friction in chassis_and_floors(physics, floors):
        for mission in missions:
            for speed in speeds:
                row = run_mission(mission, speed, chassis, friction, overrides)
                if row.failure is None and chassis == "kinematic":
                    base[mission, speed] = row.fig.time_s
                elif row.failure is None and (mission, speed) in base:
                    row.time_ratio = row.fig.time_s / base[mission, speed]
                rows.append(row)
                on_row(row)
    return rows


# ---------------------------------------------------------------------------- output

HEADER = (f"{'mission':<14}{'m/s':>4} {'chassis':<10}{'mu':>4}{'time s':>8}{'ratio':>6}"
          f"{'xt max cm':>10}{'xt rms cm':>10}{'arr cm':>8}{'hdg deg':>8}{'drift %':>8}"
          f"{'dist m':>7}  goals")


def table_row(row: Row) -> str:
    """``row`` as a line under :data:`HEADER`."""
    f = row.fig
    mu = "-" if row.friction is None else f"{row.friction:g}"
    ratio = "-" if row.time_ratio is None else f"{row.time_ratio:.2f}"
    verdicts = row.verdicts()
    missed = [v.name.split()[0] for v in verdicts if not v.met]
    goals = "-" if not verdicts else "met" if not missed else "NOT MET: " + ", ".join(missed)
    if row.failure is not None:
        goals = f"DID NOT FINISH: {row.failure}"
    return (f"{row.mission:<14}{row.speed_mps:>4.1f} {row.physics:<10}{mu:>4}{f.time_s:8.2f}"
            f"{ratio:>6}{f.worst_cross_track_m * 100:10.2f}{f.rms_cross_track_m * 100:10.2f}"
            f"{f.worst_arrival_m * 100:8.2f}{_number(f.worst_heading_deg):>8}"
            f"{f.drift_pct:8.2f}{f.distance_m:7.2f}  {goals}")


def _number(x: float) -> str:
    return "-" if math.isnan(x) else f"{x:.2f}"


def arrivals_line(row: Row) -> str:
    """Every waypoint's true arrival error of ``row``: cm, and deg where it has a heading."""
    cm = " ".join(f"{a * 100:.1f}" for a in row.fig.arrivals_m)
    line = f"{row.label}: arrival cm [{cm}]"
    if any(not math.isnan(h) for h in row.fig.headings_deg):
        line += " heading deg [" + " ".join(_number(h) for h in row.fig.headings_deg) + "]"
    return line


def summary(rows: Sequence[Row]) -> list[str]:
    """Each judged run's goals, one line per run, and a count."""
    lines: list[str] = []
    judged = [r for r in rows if r.judged]
    met = 0
    for row in judged:
        verdicts = row.verdicts()
        met += all(v.met for v in verdicts)
        lines.append(f"{row.label}: " + "; ".join(v.describe() for v in verdicts))
    lines.append(f"goals met in {met} of {len(judged)} runs at {GOAL_SPEED:g} m/s")
    return lines


def plot(rows: Sequence[Row], path: Path) -> Path:
    """Planned, true and estimated paths, one panel per mission (at the goal speed if it was
    run, else the first speed), every chassis and floor in it; north up, east right. A
    straight mission's panel stretches east (its errors are centimetres on metres)."""
    from mecanum_mav.app.plots import _pyplot

    plt = _pyplot()
    missions = list(dict.fromkeys(r.mission for r in rows))
    fig, axes = plt.subplots(1, len(missions), figsize=(5.0 * len(missions), 6.0),
                             squeeze=False)
    for ax, mission in zip(axes[0], missions, strict=True):
        these = [r for r in rows if r.mission == mission]
        speeds = sorted({r.speed_mps for r in these})
        speed = GOAL_SPEED if GOAL_SPEED in speeds else speeds[0]
        _panel(ax, [r for r in these if r.speed_mps == speed])
        ax.set_title(f"{mission} at {speed:g} m/s")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 4), fontsize=8)
    fig.tight_layout(rect=(0.0, 0.08, 1.0, 1.0))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


COLOURS = ("tab:blue", "tab:red", "tab:green", "tab:purple", "tab:brown")


def _panel(ax: Any, rows: Sequence[Row]) -> None:
    pn, pe = zip(*rows[0].run.planned, strict=True)
    ax.plot(pe, pn, "o--", color="0.6", markersize=3, label="planned")
    for row, colour in zip(rows, COLOURS, strict=False):
        name = row.physics + ("" if row.friction is None else f" mu {row.friction:g}")
        tn, te = zip(*[(p[0], p[1]) for p in row.run.true_path], strict=True)
        ax.plot(te, tn, "-", color=colour, linewidth=1.2, label=f"true, {name}")
        if row.run.odometry_path:
            on, oe = zip(*row.run.odometry_path, strict=True)
            ax.plot(oe, on, ":", color=colour, linewidth=1.4, label=f"estimated, {name}")
    ax.set_ylabel("north (m)")
    ax.grid(True, alpha=0.3)
    if max(pe) - min(pe) < 0.2 * (max(pn) - min(pn)):  # a straight line north
        east = [abs(p[1]) for r in rows for p in (*r.run.true_path, *r.run.odometry_path)]
        half = max(0.1, 1.2 * max(east, default=0.0))
        ax.set_xlim(-half, half)
        ax.set_xlabel("east (m, stretched)")
    else:
        ax.set_aspect("equal")
        ax.set_xlabel("east (m)")


# ---------------------------------------------------------------------------- CLI

def _numbers(text: str) -> list[float]:
    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a list of numbers: {text!r}") from None


def _names(text: str) -> list[str]:
    names = [x.strip() for x in text.split(",") if x.strip()]
    unknown = [n for n in names if n not in MISSIONS]
    if unknown:
        raise argparse.ArgumentTypeError(
            f"unknown mission {', '.join(unknown)}: one of {', '.join(MISSIONS)}")
    return names


def _assignment(text: str) -> tuple[str, float]:
    try:
        name, value = parse_assignment(text)
    except ParamError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return name, float(value)


def _firmware_assignment(text: str) -> tuple[str, float]:
    name, _, value = text.partition("=")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not NAME=VALUE: {text!r}") from None


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--physics", choices=PHYSICS, default="kinematic",
                   help="mujoco runs the kinematic chassis too, for the time ratio")
    p.add_argument("--friction", type=_numbers, default=list(FLOORS),
                   help="floors for the MuJoCo chassis (SIM_FRICTION), comma-separated")
    p.add_argument("--speeds", type=_numbers, default=None,
                   help="WP_SPEED values, m/s, comma-separated (default 0.5,1.0,1.5)")
    p.add_argument("--missions", type=_names, default=list(MISSIONS),
                   help=f"comma-separated, of {', '.join(MISSIONS)}")
    p.add_argument("--quick", action="store_true",
                   help=f"only {GOAL_SPEED:g} m/s (unless --speeds is given)")
    p.add_argument("--plot", type=Path, default=None, help="draw the paths to this PNG")
    p.add_argument("--set", dest="overrides", type=_assignment, action="append", default=[],
                   metavar="NAME=VALUE", help="a parameter for every run (repeatable)")
    p.add_argument("--twin", action="store_true",
                   help="on the twin: real ArduPilot firmware (SITL) on the MuJoCo chassis, "
                   "in real time (default 1.0 m/s, friction 0.8)")
    p.add_argument("--sitl", type=Path, default=None,
                   help="the ardurover binary (default $MECANUM_SITL, else "
                   "../shared/ardupilot-sitl/ardurover)")
    p.add_argument("--firmware-set", dest="firmware", type=_firmware_assignment,
                   action="append", default=[], metavar="NAME=VALUE",
                   help="with --twin: an ArduPilot parameter for the firmware (repeatable)")
    p.add_argument("--no-anchor", dest="anchor", action="store_false",
                   help="with --twin: not ArduPilot's own omni frame beside the companion")
    return p


def report(rows: Sequence[Row], picture: Path | None, started: float) -> None:
    """After the table: every waypoint's arrival, the goals, the picture, the wall time since
    ``started`` (monotonic s)."""
    print("\nper waypoint (true, at MISSION_ITEM_REACHED; passed at speed: where it crossed the "
          "line, if first):")
    for row in rows:
        print(arrivals_line(row))
        if row.failure is not None:
            print(f"  did not finish: {row.failure}")
    print(f"\ngoals at {GOAL_SPEED:g} m/s (friction {HIGH_FRICTION:g}; below it twice the "
          "errors):")
    for line in summary(rows):
        print(line)
    if picture is not None:
        try:
            print(f"wrote {plot(rows, picture)}")
        except RuntimeError as exc:  # no matplotlib
            print(f"bench_control: no picture: {exc}", file=sys.stderr)
    print(f"wall time {time.monotonic() - started:.1f} s")


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    if args.twin:
        return main_twin(args)
    speeds = args.speeds or ([GOAL_SPEED] if args.quick else list(SPEEDS))
    started = time.monotonic()
    sets = ", ".join(f"{n}={v:g}" for n, v in args.overrides)
    print(f"bench_control: missions {', '.join(args.missions)}; speeds "
          f"{', '.join(f'{s:g}' for s in speeds)} m/s; WHL_MAX_SPD {WHEEL_MAX_MPS:g}, "
          f"GUID_SPD_MAX speed + {SPEED_MARGIN_MPS:g}" + (f"; --set {sets}" if sets else ""))
    shown = bench_params(GOAL_SPEED, args.friction[0] if args.physics == "mujoco" else None,
                         args.overrides)
    print("with " + ", ".join(f"{n} {shown[n]:g}" for n in SHOWN if n in shown)
          + (" (MOT_DZ, MOT_DZ_TYPE and WHL_STRAFE_EFF on the MuJoCo chassis; the kinematic "
             "one has 0, 0 and 1)"
             if args.physics == "mujoco" and "MOT_DZ" in shown else ""))
    if args.physics == "mujoco":
        print(f"MuJoCo chassis on friction {', '.join(f'{f:g}' for f in args.friction)}; "
              "the kinematic chassis ignores friction: run once, for the time ratio")
    else:
        print("kinematic chassis (it ignores friction: run once)")
    if args.physics == "mujoco" and "SIM_FRICTION" not in Params():
        print("bench_control: SIM_FRICTION is not a parameter of this build: the floors "
              "cannot be set", file=sys.stderr)
        return 2
    print(HEADER, flush=True)
    try:
        rows = run_all(args.missions, speeds, args.physics, args.friction, args.overrides,
                       on_row=lambda row: print(table_row(row), flush=True))
    except (PhysicsUnavailableError, ParamError) as exc:
        print(f"bench_control: {exc}", file=sys.stderr)
        return 1
    report(rows, args.plot, started)
    return 0


def main_twin(args: argparse.Namespace) -> int:
    """``--twin``: the missions on the twin, ours and (unless ``--no-anchor``) ArduPilot's."""
    from mecanum_mav.sim.twin import TwinError

    sitl = args.sitl or default_sitl()
    if not (sitl.is_file() and os.access(sitl, os.X_OK)):
        print(f"bench_control: no ArduPilot SITL firmware at {sitl} (give --sitl PATH or set "
              "$MECANUM_SITL)", file=sys.stderr)
        return 2
    speeds = args.speeds or [GOAL_SPEED]
    floors = args.friction if args.friction != list(FLOORS) else list(TWIN_FLOORS)
    started = time.monotonic()
    shown = twin_params(GOAL_SPEED, floors[0], args.overrides)
    print(f"bench_control --twin: {sitl}; missions {', '.join(args.missions)}; speeds "
          f"{', '.join(f'{s:g}' for s in speeds)} m/s; friction "
          f"{', '.join(f'{f:g}' for f in floors)}; real time")
    print("companion with " + ", ".join(f"{n} {shown[n]:g}" for n in (*SHOWN, "ODOM_SRC",
                                                                         "ODOM_CMD_TAU",
                                                                         "ODOM_CMD_GAIN",
                                                                         "GUID_YAW_LEAD",
                                                                         "ODOM_YAW_BIAS",
                                                                         "ODOM_POS_TAU")
                                      if n in shown))
    if args.firmware:
        print("firmware with " + ", ".join(f"{n} {v:g}" for n, v in args.firmware))
    if args.anchor:
        print("ardupilot: its own omni frame (params/ardupilot_omni.parm), its own AUTO")
    print(HEADER, flush=True)
    try:
        rows = run_twin(sitl, args.missions, speeds, floors, args.overrides,
                        anchor=args.anchor, on_row=lambda row: print(table_row(row), flush=True),
                        say=lambda line: print(line, flush=True), firmware=args.firmware)
    except (PhysicsUnavailableError, ParamError, TwinError, FileNotFoundError) as exc:
        print(f"bench_control: {exc}", file=sys.stderr)
        return 1
    report(rows, args.plot, started)
    return 0


if __name__ == "__main__":
    sys.exit(main())
