"""What a tlog's analysis returns (:class:`LogAnalysis`, filled by
:func:`mecanum_mav.app.loganalysis.analyse`) and its parts: mode spans, status events, mission
legs. Times are seconds from the log's first message; positions metres north and east of the
local origin."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from mecanum_mav.mecanum.geo import GlobalOrigin

__all__ = ["LegStat", "LogAnalysis", "ModeSpan", "PathPoint", "StatusEvent", "Vec"]

Vec = tuple[float, float]
"""(north m, east m)."""
PathPoint = tuple[float, float, float]
"""(time s from the log's start, north m, east m)."""


def _length(path: Sequence[PathPoint]) -> float:
    """Length of a path, metres."""
    return sum(math.dist(a[1:], b[1:]) for a, b in itertools.pairwise(path))


@dataclass(frozen=True)
class ModeSpan:
    """The vehicle in one mode from ``start_s`` to ``end_s`` (seconds from the log's start)."""

    start_s: float
    end_s: float
    mode: str
    armed: bool

    @property
    def duration_s(self) -> float:
        """Length of the span, seconds."""
        return self.end_s - self.start_s


@dataclass(frozen=True)
class StatusEvent:
    """A STATUSTEXT at ``time_s`` (seconds from the log's start)."""

    time_s: float
    severity: int
    text: str
    failsafe: bool


@dataclass(frozen=True)
class LegStat:
    """One mission leg as driven: to item ``seq`` at ``goal`` (north m, east m)."""

    seq: int
    start: Vec
    goal: Vec
    time_s: float
    max_cross_track_m: float
    samples: int


@dataclass
class LogAnalysis:
    """What :func:`~mecanum_mav.app.loganalysis.analyse` found; times are seconds from the
    log's first message.

    Attributes:
        start_unix_s: Unix time of the first message.
        duration_s: from the first message to the last.
        messages: messages analysed.
        vehicle: (system, component) of the vehicle, or None.
        path: the vehicle's position over time; ``path_source`` names the message.
        true_path: the simulator's true position over time (empty for a real vehicle).
        planned: the mission's positions by item (seq, north m, east m), seq 1 on.
        sticks: (time, x, y, r) of every MANUAL_CONTROL, normalized (NaN: axis invalid).
        pilot_overrides: sender ("255/230") -> (time, 18 channels) of the pilot's
            RC_CHANNELS_OVERRIDE (:func:`~mecanum_mav.app.logsenders.override_from_pilot`).
        pilot_sticks: sender -> (time, x, y, r), the pilot's overrides that set or release a
            stick channel read as sticks (:data:`~mecanum_mav.app.loganalysis.RC_STICKS`),
            x forward, y right, r clockwise, -1..1.
        overrides: sender and target ("255/190 -> 1/1") -> (time, 18 channels) of the
            companion's RC_CHANNELS_OVERRIDE (PWM to the flight controller).
        servo: (time, 16 pulses) of SERVO_OUTPUT_RAW (port 0 outputs 1-16).
        modes: the vehicle's modes, in order, without gaps.
        events: every STATUSTEXT, chunks joined, in time order (``failsafe`` marks the
            failsafes, :func:`~mecanum_mav.app.logstatus.is_failsafe`).
        mission_current: (time, seq) whenever the current item changed.
        reached: (time, seq) of every MISSION_ITEM_REACHED.
        legs: the mission legs driven in AUTO, in order.
        origin: the global origin used for global positions, or None.
    """

    start_unix_s: float = 0.0
    duration_s: float = 0.0
    messages: int = 0
    vehicle: tuple[int, int] | None = None
    path: list[PathPoint] = field(default_factory=list)
    path_source: str = ""
    true_path: list[PathPoint] = field(default_factory=list)
    planned: list[tuple[int, float, float]] = field(default_factory=list)
    sticks: list[tuple[float, float, float, float]] = field(default_factory=list)
    pilot_overrides: dict[str, list[tuple[float, list[int]]]] = field(default_factory=dict)
    pilot_sticks: dict[str, list[tuple[float, float, float, float]]] = field(
        default_factory=dict)
    overrides: dict[str, list[tuple[float, list[int]]]] = field(default_factory=dict)
    servo: list[tuple[float, list[int]]] = field(default_factory=list)
    modes: list[ModeSpan] = field(default_factory=list)
    events: list[StatusEvent] = field(default_factory=list)
    mission_current: list[tuple[float, int]] = field(default_factory=list)
    reached: list[tuple[float, int]] = field(default_factory=list)
    legs: list[LegStat] = field(default_factory=list)
    origin: GlobalOrigin | None = None

    @property
    def distance_m(self) -> float:
        """Length of :attr:`path`, metres."""
        return _length(self.path)

    @property
    def true_distance_m(self) -> float:
        """Length of :attr:`true_path`, metres."""
        return _length(self.true_path)

    @property
    def failsafes(self) -> list[StatusEvent]:
        """The failsafe events."""
        return [e for e in self.events if e.failsafe]

    def time_per_mode(self) -> dict[str, float]:
        """Seconds spent in each mode, in the order the modes first appear."""
        out: dict[str, float] = {}
        for span in self.modes:
            out[span.mode] = out.get(span.mode, 0.0) + span.duration_s
        return out

    def armed_s(self) -> float:
        """Seconds armed."""
        return sum(span.duration_s for span in self.modes if span.armed)
