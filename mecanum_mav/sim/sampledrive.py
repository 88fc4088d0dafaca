"""A sample drive in the lockstep harness, recorded to a tlog: something for ``mecanum-mav log``.

:func:`sample_drive` runs, in virtual time (a fraction of a minute of simulated driving in a
few seconds): a mission upload (a square of ``side_m`` metres from the origin), arming,
MANUAL driving with MANUAL_CONTROL (forward, then right, then turning clockwise), the sticks
stopping (the "Manual input lost" failsafe), AUTO, the ground station's heartbeats stopping
half-way through the mission (the "GCS link lost" failsafe: HOLD), heartbeats back and AUTO
again, the mission's end (HOLD) and disarming. Every packet on the harness's four wires goes
to ``tlog`` as ``--tlog`` records them. The returned :class:`SampleDrive` holds what the test
of the log viewer compares the log's analysis with: the true path and when each mode began, as
the harness saw them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, BinaryIO

from mecanum_mav.config.params import Params
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import LOCAL_XY_SCALE, MissionItem
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.lockstep import Lockstep

__all__ = ["SampleDrive", "sample_drive", "square_mission"]

STICK_PERIOD_S = 0.05
"""The scripted pilot sends MANUAL_CONTROL this often (seconds)."""
TRUTH_PERIOD_S = 0.02
"""The true pose is sampled this often (seconds)."""
MANUAL_SEGMENTS: tuple[tuple[int, int, int, float], ...] = (
    (500, 0, 0, 2.0), (0, 500, 0, 2.0), (0, 0, 300, 1.0))
"""(x, y, r) MANUAL_CONTROL and how long (s): forward, right, turn clockwise."""


def square_mission(side_m: float) -> list[MissionItem]:
    """Home, then a ``side_m`` metre square from the origin, clockwise (local NED): its
    corners are waypoints with no heading of their own (yaw NaN: the rover's heading mode)."""
    corners = [(side_m, 0.0), (side_m, side_m), (0.0, side_m), (0.0, 0.0)]
    items = [MissionItem(0, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_CMD_NAV_WAYPOINT)]
    for n, e in corners:
        items.append(MissionItem(len(items), mavlink.MAV_FRAME_LOCAL_NED,
                                 mavlink.MAV_CMD_NAV_WAYPOINT, param4=float("nan"),
                                 x=round(n * LOCAL_XY_SCALE), y=round(e * LOCAL_XY_SCALE)))
    return items


@dataclass
class SampleDrive:
    """What the harness saw during :func:`sample_drive` (virtual seconds from its start).

    Attributes:
        harness: the harness, after the drive.
        items: the mission uploaded.
        true_path: (time, north m, east m) every :data:`TRUTH_PERIOD_S`.
        mode_starts: (time, mode) when each mode was accepted (its COMMAND_ACK, or the
            failsafe's STATUSTEXT, or the HEARTBEAT that first showed the mission's end).
        end_s: when the drive ended.
    """

    harness: Lockstep
    items: list[MissionItem]
    true_path: list[tuple[float, float, float]] = field(default_factory=list)
    mode_starts: list[tuple[float, Mode]] = field(default_factory=list)
    end_s: float = 0.0


def _need(value: Any, what: str) -> Any:
    if not value:
        raise RuntimeError(f"sample drive: {what}")
    return value


def sample_drive(tlog: BinaryIO | None, params: Params | None = None, *,
                 side_m: float = 1.5, dt_s: float = 0.002) -> SampleDrive:
    """Run the sample drive (see the module docstring), recording to ``tlog``.

    Raises:
        RuntimeError: a step failed (the rover refused something or never got there).
    """
    h = Lockstep(params, dt_s=dt_s, tlog=tlog)
    gcs = h.gcs
    items = square_mission(side_m)
    out = SampleDrive(h, items)
    next_truth = [0.0]

    def sample_truth(now_s: float) -> None:
        if now_s >= next_truth[0]:
            pose = h.truth().pose
            out.true_path.append((now_s, pose.x_m, pose.y_m))
            next_truth[0] += TRUTH_PERIOD_S

    h.on_step.append(sample_truth)
    _need(gcs.upload(items).type == mavlink.MAV_MISSION_ACCEPTED, "upload refused")
    _need(gcs.wait("STATUSTEXT", lambda m: m.text == "Flight controller link up", 5.0, since=0),
          "no flight controller")
    gcs.arm()
    out.mode_starts.append((h.now_s, Mode.MANUAL))
    stick = [0, 0, 0]
    stop = h.every(STICK_PERIOD_S,
                   lambda _t: gcs.mav.manual_control_send(1, stick[0], stick[1], 500, stick[2], 0))
    for x, y, r, seconds in MANUAL_SEGMENTS:
        stick[:] = [x, y, r]
        h.run_for(seconds)
    stick[:] = [0, 0, 0]
    h.run_for(0.5)
    stop()
    _need(gcs.wait("STATUSTEXT", lambda m: m.text.startswith("Manual input lost"), 2.0),
          "no input failsafe")
    h.run_for(0.5)

    def mode(to: Mode) -> None:
        _need(gcs.set_mode(to) == mavlink.MAV_RESULT_ACCEPTED, f"{to.name} refused")
        out.mode_starts.append((h.now_s, to))

    mode(Mode.AUTO)
    last = items[-1].seq
    _need(gcs.wait("MISSION_ITEM_REACHED", lambda m: m.seq == 2, 30.0), "item 2 not reached")
    h.run_for(1.0)
    gcs.beating = False
    _need(gcs.wait("STATUSTEXT", lambda m: m.text == "GCS link lost: failsafe", 10.0),
          "no GCS failsafe")
    out.mode_starts.append((h.now_s, Mode.HOLD))
    h.run_for(1.0)
    gcs.beating = True
    h.run_for(1.5)
    mode(Mode.AUTO)
    _need(gcs.wait("MISSION_ITEM_REACHED", lambda m: m.seq == last, 30.0), "mission unfinished")
    holding: Callable[[Any], bool] = lambda m: (  # noqa: E731
        m.get_srcSystem() == 1 and m.custom_mode == Mode.HOLD)
    _need(gcs.wait("HEARTBEAT", holding, 3.0), "no HOLD at the mission's end")
    out.mode_starts.append((h.now_s, Mode.HOLD))
    h.run_for(1.0)
    ack = gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    _need(ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED, "disarm refused")
    h.run_for(1.0)
    out.end_s = h.now_s
    h.on_step.remove(sample_truth)
    return out
