"""``mecanum-mav demo``: the whole product in one command.

It starts the simulated flight controller and chassis, the companion, and a scripted ground
station (:class:`~mecanum_mav.sim.groundstation.ScriptedGroundStation`), all in this process
on UDP loopback, in real time. The ground station uploads a mission over the MAVLink mission
protocol (a square with a diagonal, the rover facing north all the way), arms, switches to AUTO
and watches MISSION_ITEM_REACHED and the odometry until the rover holds at the end. It
reports each leg as it ends (``on_leg``; the CLI prints it as one row of the table: time,
largest cross-track error, arrival error; from the simulator's true pose) and draws the
planned path, the true path and the odometry to a PNG.

``run_demo(..., virtual=True)`` runs the same script in the lockstep harness
(:class:`~mecanum_mav.sim.lockstep.Lockstep`: the rover core, the simulated board and the same
ground station in virtual time, no sockets): the same mission in a fraction of a second, with
the same figures every run.

Errors are measured against the simulator's ground truth: cross-track is the distance from the
true position to the leg (a segment) while that leg is current; arrival is the distance to the
waypoint when its MISSION_ITEM_REACHED arrives. Times are the ground station's: wall-clock
seconds in real time, simulated seconds in virtual time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.control.pathfollow import Leg
from mecanum_mav.io.links import mavlink
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.board import SimState
from mecanum_mav.sim.groundstation import ScriptedGroundStation, udp_ground_station
from mecanum_mav.sim.lockstep import Lockstep
from mecanum_mav.sim.simfc import SimFlightController

__all__ = ["TABLE_HEADER", "DemoResult", "LegReport", "OnLeg", "demo_mission", "leg_row",
           "plot_demo", "run_demo"]

Vec = tuple[float, float]
WATCH_PERIOD_S = 0.02
"""The ground station looks at the rover at least this often while the mission runs."""


def demo_mission(side_m: float) -> tuple[list[MissionItem], list[Vec]]:
    """The demo's mission and its waypoints (north, east): a square of ``side_m`` metres
    driven clockwise from the start, then the diagonal; CONDITION_YAW 0 keeps the rover facing
    north, so it strafes and reverses along the legs instead of turning."""
    points = [(side_m, 0.0), (side_m, side_m), (0.0, side_m), (0.0, 0.0), (side_m, side_m)]
    items = [
        MissionItem(0, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_CMD_NAV_WAYPOINT),  # home
        MissionItem(1, mavlink.MAV_FRAME_MISSION, mavlink.MAV_CMD_CONDITION_YAW),  # north
    ]
    for n, e in points:
        items.append(MissionItem(len(items), mavlink.MAV_FRAME_LOCAL_NED,
                                 mavlink.MAV_CMD_NAV_WAYPOINT, param4=math.nan,
                                 x=round(n * 1e4), y=round(e * 1e4)))
    return items, points


@dataclass
class LegReport:
    """One leg of the demo: from the previous waypoint to ``goal``."""

    seq: int
    start: Vec
    goal: Vec
    time_s: float
    max_cross_track_m: float
    arrival_error_m: float


@dataclass
class DemoResult:
    """What the demo measured."""

    legs: list[LegReport]
    planned: list[Vec]
    true_path: list[tuple[float, float, float]] = field(default_factory=list)
    odometry_path: list[Vec] = field(default_factory=list)
    total_s: float = 0.0
    max_yaw_deg: float = 0.0

    def table(self) -> str:
        """The per-leg table as text: :data:`TABLE_HEADER`, :func:`leg_row` per leg, then
        :meth:`summary`."""
        rows = [TABLE_HEADER, *(leg_row(k, leg) for k, leg in enumerate(self.legs, start=1))]
        return "\n".join([*rows, self.summary()])

    def summary(self) -> str:
        """The table's last line: mission time, worst errors, heading."""
        worst_xt = max(leg.max_cross_track_m for leg in self.legs) * 100
        worst_arr = max(leg.arrival_error_m for leg in self.legs) * 100
        return (f"mission {self.total_s:.1f} s; worst cross-track {worst_xt:.2f} cm, worst "
                f"arrival {worst_arr:.2f} cm; heading within {self.max_yaw_deg:.2f} deg of "
                f"north")


TABLE_HEADER = (f"{'leg':<4}{'item':>5}  {'from':>13} -> {'to':<13}{'time s':>8}"
                f"{'max cross-track cm':>20}{'arrival error cm':>18}")
"""The first line of :meth:`DemoResult.table`."""


def leg_row(k: int, leg: LegReport) -> str:
    """Leg number ``k`` (from 1) as a row of :meth:`DemoResult.table`."""
    return (f"{k:<4}{leg.seq:>5}  ({leg.start[0]:5.2f},{leg.start[1]:5.2f}) -> "
            f"({leg.goal[0]:5.2f},{leg.goal[1]:5.2f}){leg.time_s:8.2f}"
            f"{leg.max_cross_track_m * 100:20.2f}{leg.arrival_error_m * 100:18.2f}")


OnLeg = Callable[[int, LegReport], None]
"""Called with each leg's number (from 1) and report as soon as the leg ends."""


def _ignore_leg(k: int, leg: LegReport) -> None:
    pass


def run_demo(params: Params | None = None, side_m: float = 2.0, timeout_s: float = 120.0,
             *, virtual: bool = False, dt_s: float = 0.002,
             on_leg: OnLeg = _ignore_leg) -> DemoResult:
    """Run the demo mission in the simulator; returns the measurements.

    Args:
        params: parameters for the companion and the simulator (defaults if None).
        side_m: side of the square, metres.
        timeout_s: the mission must end within this long (the ground station's time).
        virtual: run in the lockstep harness (virtual time, no sockets) instead of real time
            on UDP loopback.
        dt_s: the harness's time step with ``virtual``.
        on_leg: told each leg as soon as it ends (to print it while the rover drives on).

    Raises:
        RuntimeError: a step failed (upload refused, arming refused, mission not finished).
    """
    params = params or Params()
    items, points = demo_mission(side_m)
    if virtual:
        harness = Lockstep(params, dt_s=dt_s)
        return _fly(harness.gcs, harness.truth, items, points, timeout_s, on_leg)
    sim = SimFlightController("udpin:127.0.0.1:0", params)
    sim.start()
    gcs, port = udp_ground_station()
    companion = Companion(params, port.url, f"udpout:127.0.0.1:{sim.local_port}")
    companion.start()
    try:
        return _fly(gcs, sim.snapshot, items, points, timeout_s, on_leg)
    finally:
        companion.close()
        sim.stop()
        port.close()


def _fly(gcs: ScriptedGroundStation, truth: Callable[[], SimState], items: list[MissionItem],
         points: list[Vec], timeout_s: float, on_leg: OnLeg) -> DemoResult:
    """The ground station's script: upload, arm, AUTO, watch until HOLD."""
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
    return _watch(gcs, truth, points, timeout_s, on_leg)


def _watch(gcs: ScriptedGroundStation, truth: Callable[[], SimState], points: list[Vec],
           timeout_s: float, on_leg: OnLeg) -> DemoResult:
    planned = [(0.0, 0.0), *points]
    out = DemoResult([], planned)
    first_leg_seq = 2  # item 1 is the CONDITION_YAW
    clock = gcs.port.now
    start_s = clock()
    leg_start_s, leg_cross = start_s, 0.0
    deadline = start_s + timeout_s
    while clock() < deadline:
        messages = gcs.pump(WATCH_PERIOD_S)
        pose = truth().pose
        here = (pose.x_m, pose.y_m)
        out.true_path.append((pose.x_m, pose.y_m, pose.yaw_rad))
        out.max_yaw_deg = max(out.max_yaw_deg, abs(math.degrees(pose.yaw_rad)))
        k = len(out.legs)
        if k < len(points):
            leg_cross = max(leg_cross, Leg(planned[k], planned[k + 1]).distance_m(here))
        for msg in messages:
            kind = msg.get_type()
            if kind == "LOCAL_POSITION_NED":
                out.odometry_path.append((msg.x, msg.y))
            elif kind == "MISSION_ITEM_REACHED" and msg.seq >= first_leg_seq:
                k = len(out.legs)
                now = clock()
                out.legs.append(LegReport(msg.seq, planned[k], planned[k + 1], now - leg_start_s,
                                          leg_cross, math.dist(here, planned[k + 1])))
                on_leg(len(out.legs), out.legs[-1])
                leg_start_s, leg_cross = now, 0.0
            elif kind == "HEARTBEAT" and msg.get_srcSystem() == 1 and msg.custom_mode == Mode.HOLD:
                if len(out.legs) == len(points):
                    out.total_s = clock() - start_s
                    return out
                raise RuntimeError(f"the rover stopped after {len(out.legs)} legs")
    raise RuntimeError("the mission did not finish in time")


def plot_demo(result: DemoResult, path: Path) -> Path:
    """Draw planned, true and odometry paths (north up, east right) to ``path`` (PNG)."""
    from mecanum_mav.app.plots import _pyplot

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 6.4))
    pn, pe = zip(*result.planned, strict=True)
    ax.plot(pe, pn, "o--", color="0.6", label="planned")
    tn, te = zip(*[(p[0], p[1]) for p in result.true_path], strict=True)
    ax.plot(te, tn, "-", color="tab:blue", label="true (simulator)")
    if result.odometry_path:
        on, oe = zip(*result.odometry_path, strict=True)
        ax.plot(oe, on, ":", color="tab:orange", label="odometry (LOCAL_POSITION_NED)")
    for k, (n, e) in enumerate(result.planned[1:], start=1):
        ax.annotate(str(k), (e, n), textcoords="offset points", xytext=(6, 6))
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    worst = max(leg.max_cross_track_m for leg in result.legs) * 100
    ax.set_title(f"AUTO mission, facing north: worst cross-track {worst:.1f} cm")
    ax.legend(loc="center")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
