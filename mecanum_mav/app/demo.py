"""``mecanum-mav demo``: the whole product in one command.

It starts the simulated flight controller and chassis, the companion, and a scripted ground
station, all in this process on UDP loopback. The ground station uploads a mission over the
MAVLink mission protocol (a square with a diagonal, the rover facing north all the way), arms,
switches to AUTO and watches MISSION_ITEM_REACHED and the odometry until the rover holds at the
end. Then it prints one row per leg (time, largest cross-track error, arrival error; from the
simulator's true pose) and draws the planned path, the true path and the odometry to a PNG.

Errors are measured against the simulator's ground truth: cross-track is the distance from the
true position to the leg (a segment) while that leg is current; arrival is the distance to the
waypoint when its MISSION_ITEM_REACHED arrives.
"""

from __future__ import annotations

import math
import selectors
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.control.pathfollow import Leg
from mecanum_mav.io.links import Link, mavlink, open_link
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.simfc import SimFlightController

__all__ = ["DemoResult", "LegReport", "ScriptedGroundStation", "demo_mission", "run_demo"]

Vec = tuple[float, float]


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


class ScriptedGroundStation:
    """A minimal ground station on a pymavlink link: mission upload, arming, modes.

    The client side of the mission protocol: it answers each request the vehicle sends (also
    re-requests) and, when the vehicle falls silent for the protocol's 1.5 s, starts again
    with MISSION_COUNT.
    """

    def __init__(self, url: str = "udpin:127.0.0.1:0") -> None:
        self.link: Link = open_link(url, source_system=255, source_component=190, name="gcs")
        self._selector = selectors.DefaultSelector()
        self._selector.register(self.link.fileno(), selectors.EVENT_READ)
        self.inbox: list[Any] = []
        self._next_beat = 0.0

    @property
    def url(self) -> str:
        """The URL a vehicle uses to reach this ground station."""
        return f"udpout:127.0.0.1:{self.link.local_port}"

    def pump(self, timeout_s: float) -> list[Any]:
        """Receive for up to ``timeout_s``; sends its own HEARTBEAT at 1 Hz."""
        now = time.monotonic()
        if now >= self._next_beat:
            self.link.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID,
                                         0, 0, mavlink.MAV_STATE_ACTIVE)
            self._next_beat = now + 1.0
        got = self.link.read() if self._selector.select(timeout_s) else []
        self.inbox.extend(got)
        return got

    def wait(self, kind: str, timeout_s: float, predicate: Any = None) -> Any | None:
        """The next message of ``kind`` (matching ``predicate``) within ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            for msg in self.pump(min(0.05, max(0.0, deadline - time.monotonic()))):
                if msg.get_type() == kind and (predicate is None or predicate(msg)):
                    return msg
        return None

    def upload(self, items: Sequence[MissionItem], timeout_s: float = 10.0) -> int:
        """Upload a mission; returns the MISSION_ACK type (MAV_MISSION_ACCEPTED = 0)."""
        mav = self.link.mav
        mav.mission_count_send(1, 1, len(items), 0)
        deadline = time.monotonic() + timeout_s
        quiet_since = time.monotonic()
        while time.monotonic() < deadline:
            for msg in self.pump(0.05):
                kind = msg.get_type()
                if kind == "MISSION_ACK":
                    return int(msg.type)
                if kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST") and msg.seq < len(items):
                    it = items[msg.seq]
                    mav.mission_item_int_send(1, 1, it.seq, it.frame, it.command, it.current,
                                              it.autocontinue, it.param1, it.param2,
                                              it.param3, it.param4, it.x, it.y, it.z, 0)
                    quiet_since = time.monotonic()
            if time.monotonic() - quiet_since > 1.5:  # the protocol's default timeout
                mav.mission_count_send(1, 1, len(items), 0)
                quiet_since = time.monotonic()
        raise TimeoutError("mission upload: no MISSION_ACK")

    def command(self, command: int, *params: float, timeout_s: float = 1.0) -> int | None:
        """COMMAND_LONG to system 1; the COMMAND_ACK result, or None."""
        p = [*params, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0][:7]
        self.link.mav.command_long_send(1, 1, command, 0, *p)
        ack = self.wait("COMMAND_ACK", timeout_s, lambda m: m.command == command)
        return None if ack is None else int(ack.result)

    def close(self) -> None:
        """Close the link."""
        self._selector.close()
        self.link.close()


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
        """The per-leg table as text."""
        rows = [f"{'leg':<4}{'item':>5}  {'from':>13} -> {'to':<13}{'time s':>8}"
                f"{'max cross-track cm':>20}{'arrival error cm':>18}"]
        for k, leg in enumerate(self.legs, start=1):
            rows.append(f"{k:<4}{leg.seq:>5}  ({leg.start[0]:5.2f},{leg.start[1]:5.2f}) -> "
                        f"({leg.goal[0]:5.2f},{leg.goal[1]:5.2f}){leg.time_s:8.2f}"
                        f"{leg.max_cross_track_m * 100:20.2f}{leg.arrival_error_m * 100:18.2f}")
        worst_xt = max(leg.max_cross_track_m for leg in self.legs) * 100
        worst_arr = max(leg.arrival_error_m for leg in self.legs) * 100
        rows.append(f"mission {self.total_s:.1f} s; worst cross-track {worst_xt:.2f} cm, worst "
                    f"arrival {worst_arr:.2f} cm; heading within {self.max_yaw_deg:.2f} deg of "
                    f"north")
        return "\n".join(rows)


def run_demo(params: Params | None = None, side_m: float = 2.0,
             timeout_s: float = 120.0) -> DemoResult:
    """Run the demo mission in the simulator; returns the measurements.

    Raises:
        RuntimeError: a step failed (upload refused, arming refused, mission not finished).
    """
    params = params or Params()
    items, points = demo_mission(side_m)
    sim = SimFlightController("udpin:127.0.0.1:0", params)
    sim.start()
    gcs = ScriptedGroundStation()
    companion = Companion(params, gcs.url, f"udpout:127.0.0.1:{sim.local_port}")
    companion.start()
    try:
        if gcs.wait("HEARTBEAT", 5.0, lambda m: m.get_srcSystem() == 1) is None:
            raise RuntimeError("no heartbeat from the companion")
        result = gcs.upload(items)
        if result != mavlink.MAV_MISSION_ACCEPTED:
            raise RuntimeError(f"mission upload refused (MISSION_ACK {result})")
        deadline = time.monotonic() + 5.0
        while gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) != 0:
            if time.monotonic() > deadline:
                raise RuntimeError("arming refused")
            gcs.pump(0.25)  # the flight controller's first heartbeat may be on its way
        if gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 1, Mode.AUTO) != 0:
            raise RuntimeError("AUTO refused")
        return _watch(sim, gcs, points, timeout_s)
    finally:
        companion.close()
        sim.stop()
        gcs.close()


def _watch(sim: SimFlightController, gcs: ScriptedGroundStation, points: list[Vec],
           timeout_s: float) -> DemoResult:
    planned = [(0.0, 0.0), *points]
    out = DemoResult([], planned)
    first_leg_seq = 2  # item 1 is the CONDITION_YAW
    start_s = time.monotonic()
    leg_start_s, leg_cross = start_s, 0.0
    deadline = start_s + timeout_s
    while time.monotonic() < deadline:
        messages = gcs.pump(0.02)
        pose = sim.snapshot().pose
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
                now = time.monotonic()
                out.legs.append(LegReport(msg.seq, planned[k], planned[k + 1], now - leg_start_s,
                                          leg_cross, math.dist(here, planned[k + 1])))
                leg_start_s, leg_cross = now, 0.0
            elif kind == "HEARTBEAT" and msg.get_srcSystem() == 1 and msg.custom_mode == Mode.HOLD:
                if len(out.legs) == len(points):
                    out.total_s = time.monotonic() - start_s
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
