"""How well a mission was driven, from what :func:`~mecanum_mav.sim.missionrun.fly` recorded.

Pure functions of the recorded true path (local NED metres, yaw radians) and the companion's
odometry; :func:`figures` gathers them for one run (:class:`RunFigures`):

- cross-track: the true position's distance to the leg current then (worst, and the RMS over
  time: each look weighs as long as it stood, up to the next look);
- arrival: at each waypoint's MISSION_ITEM_REACHED, the true distance to it (m) and the true
  heading's difference to the waypoint's heading (degrees, where it has one);
- drift: the odometry's last estimate minus the truth then, as a percentage of the distance
  truly driven (the true path's length).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

from mecanum_mav.sim.missionrun import MissionRun

__all__ = ["RunFigures", "drift_percent", "figures", "path_length_m", "time_weighted_rms"]

Vec = tuple[float, float]


def time_weighted_rms(times_s: Sequence[float], values: Sequence[float]) -> float:
    """RMS of ``values`` over time: each value holds from its time to the next one's (the
    last has no weight). NaN values (and their intervals) are left out; NaN if no interval
    counts."""
    total = weight = 0.0
    for k in range(len(values) - 1):
        value, dt = values[k], times_s[k + 1] - times_s[k]
        if math.isnan(value) or dt <= 0.0:
            continue
        total += value * value * dt
        weight += dt
    return math.sqrt(total / weight) if weight > 0.0 else math.nan


def path_length_m(points: Sequence[Sequence[float]]) -> float:
    """Length of the polyline through ``points`` ((north, east, ...) metres; extra items such
    as yaw are ignored), metres."""
    return sum(math.dist(a[:2], b[:2]) for a, b in itertools.pairwise(points))


def drift_percent(estimate: Vec, truth: Vec, distance_m: float) -> float:
    """The distance between ``estimate`` and ``truth`` (north, east metres) as a percentage
    of ``distance_m``; infinite if nothing was driven but they differ (0 if they agree)."""
    error = math.dist(estimate, truth)
    if distance_m <= 0.0:
        return 0.0 if error == 0.0 else math.inf
    return 100.0 * error / distance_m


@dataclass(frozen=True)
class RunFigures:
    """One run's figures (see the module docstring). Lengths metres, angles degrees."""

    time_s: float
    """From AUTO to the end (a run that did not finish: to its last look)."""
    worst_cross_track_m: float
    rms_cross_track_m: float
    arrivals_m: tuple[float, ...]
    """True distance to each waypoint at its MISSION_ITEM_REACHED, in mission order."""
    headings_deg: tuple[float, ...]
    """True heading minus each waypoint's heading then (NaN: the waypoint has none)."""
    distance_m: float
    """The true path's length."""
    drift_pct: float
    """Odometry minus truth at the end, % of :attr:`distance_m` (NaN: no odometry came)."""

    @property
    def worst_arrival_m(self) -> float:
        """The largest of :attr:`arrivals_m` (NaN: no waypoint)."""
        return max(self.arrivals_m, default=math.nan)

    @property
    def worst_heading_deg(self) -> float:
        """The largest size of :attr:`headings_deg` among waypoints with a heading (NaN:
        none has one)."""
        return max((abs(h) for h in self.headings_deg if not math.isnan(h)), default=math.nan)


def figures(run: MissionRun) -> RunFigures:
    """The figures of a finished run."""
    crossing = [x for x in run.cross_track_m if not math.isnan(x)]
    distance = path_length_m(run.true_path)
    drift = math.nan
    if run.final_estimate is not None and run.final_truth is not None:
        drift = drift_percent(run.final_estimate, run.final_truth, distance)
    time_s = run.total_s or (run.times_s[-1] if run.times_s else 0.0)  # unfinished: so far
    return RunFigures(time_s, max(crossing, default=math.nan),
                      time_weighted_rms(run.times_s, run.cross_track_m),
                      tuple(leg.arrival_error_m for leg in run.legs),
                      tuple(leg.arrival_heading_deg for leg in run.legs), distance, drift)
