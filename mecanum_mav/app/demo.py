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
seconds in real time, simulated seconds in virtual time. The script and the watch are
:func:`mecanum_mav.sim.missionrun.fly`'s (``tools/bench_control.py`` flies its missions with
them too).
"""

from __future__ import annotations

from pathlib import Path

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.sim.groundstation import udp_ground_station
from mecanum_mav.sim.lockstep import Lockstep
from mecanum_mav.sim.missionrun import (
    LegReport,
    MissionRun,
    OnLeg,
    fly,
    waypoint_mission,
)
from mecanum_mav.sim.missionrun import ignore_leg as _ignore_leg
from mecanum_mav.sim.simfc import SimFlightController

__all__ = ["TABLE_HEADER", "DemoResult", "LegReport", "OnLeg", "demo_mission", "leg_row",
           "plot_demo", "run_demo"]

Vec = tuple[float, float]


def demo_mission(side_m: float) -> tuple[list[MissionItem], list[Vec]]:
    """The demo's mission and its waypoints (north, east): a square of ``side_m`` metres
    driven clockwise from the start, then the diagonal; CONDITION_YAW 0 keeps the rover facing
    north, so it strafes and reverses along the legs instead of turning."""
    points = _square_and_diagonal(side_m)
    items, _ = waypoint_mission(points)
    return items, points


def _square_and_diagonal(side_m: float) -> list[Vec]:
    return [(side_m, 0.0), (side_m, side_m), (0.0, side_m), (0.0, 0.0), (side_m, side_m)]


class DemoResult(MissionRun):
    """What the demo measured (:class:`~mecanum_mav.sim.missionrun.MissionRun`), as a table."""

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
    items, waypoints = waypoint_mission(_square_and_diagonal(side_m))
    into = DemoResult([], [])
    if virtual:
        harness = Lockstep(params, dt_s=dt_s)
        fly(harness.gcs, harness.truth, items, waypoints, timeout_s, on_leg, into)
        return into
    sim = SimFlightController("udpin:127.0.0.1:0", params)
    sim.start()
    gcs, port = udp_ground_station()
    companion = Companion(params, port.url, f"udpout:127.0.0.1:{sim.local_port}")
    companion.start()
    try:
        fly(gcs, sim.snapshot, items, waypoints, timeout_s, on_leg, into)
        return into
    finally:
        companion.close()
        sim.stop()
        port.close()


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
