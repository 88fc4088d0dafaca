"""The twin's record: the bridge's counters (:class:`BridgeStats`) and the truth
(:class:`TruthSample`, one per frame) in one float64 array, written by the bridge and read by
whoever holds the twin, in another process if need be (the array may be a file both map),
and the wheels' contacts with the floor, read every :data:`CONTACTS_PERIOD_S` of physics.

Layout: the counters at the indices below, the contacts (:data:`CONTACTS`: physics time of
the reading, NaN before any, then normal force N, slip m/s and slipping 0/1 per wheel FL, FR,
RL, RR), :data:`HEADER` floats in all, then ``capacity`` rows of :data:`ROW` floats, a ring
of the last frames' truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mecanum_mav.sim.physics import CONTACTS_PERIOD_S, WheelContact

__all__ = ["BUSY_S", "COMMANDS", "CONTACTS", "CONTACTS_PERIOD_S", "COUNT", "DROPPED",
           "FIRST_WALL", "FRAMES", "FRAME_RATE", "HEADER", "LAST_WALL", "MALFORMED", "PHYSICS_S",
           "PULSES", "REPEATED", "RESTARTS", "ROW", "TRUTH_CAPACITY", "BridgeStats",
           "TruthSample", "TwinRecord", "blank", "sample_row"]

TRUTH_CAPACITY = 720_000
"""Frames of truth a twin keeps (the last 10 minutes at the firmware's 1200 Hz; 40 MB)."""

# The counters' indices (BridgeStats' fields; FIRST_WALL and LAST_WALL: the monotonic time of
# the first and the last frame answered, NaN before any; COUNT: frames of truth recorded):
(FRAMES, REPEATED, DROPPED, RESTARTS, MALFORMED, PHYSICS_S, FIRST_WALL, LAST_WALL,
 BUSY_S, FRAME_RATE) = range(10)
COMMANDS, PULSES, COUNT, CONTACTS = 10, 14, 18, 19
HEADER = CONTACTS + 13
ROW = 7


@dataclass(frozen=True)
class TruthSample:
    """Where the chassis really was when the bridge answered a frame.

    Attributes:
        wall_s: ``time.monotonic()`` when the frame was answered.
        time_s: physics time, seconds.
        north_m, east_m: true position, local NED from the start, metres.
        yaw_rad: true heading, radians clockwise from north, [-pi, pi).
        forward_mps, right_mps: true velocity, body FRD, m/s.
    """

    wall_s: float
    time_s: float
    north_m: float
    east_m: float
    yaw_rad: float
    forward_mps: float
    right_mps: float


@dataclass(frozen=True)
class BridgeStats:
    """What the bridge has done so far.

    Attributes:
        frames: frames stepped (new frame counts answered).
        repeated: packets with the frame count just answered (answered again, no step).
        dropped: frame counts skipped (a count ahead of the next one: the gap's size).
        restarts: times the count went back (the firmware restarted).
        malformed: packets that were not servo packets (ignored).
        physics_s: physics seconds stepped.
        wall_s: wall seconds from the first frame answered to the last.
        busy_s: wall seconds spent answering (decode, step, read, encode).
        frame_rate: the firmware's last frame rate, Hz (0 before any).
        commands: the wheel commands FL, FR, RL, RR of the last frame.
        wheel_pulses: the pulse widths (us) the firmware put out for FL, FR, RL, RR in the
            last frame (0: no output).
    """

    frames: int
    repeated: int
    dropped: int
    restarts: int
    malformed: int
    physics_s: float
    wall_s: float
    busy_s: float
    frame_rate: int
    commands: tuple[float, float, float, float]
    wheel_pulses: tuple[int, int, int, int]

    @property
    def real_time_factor(self) -> float:
        """Physics seconds per wall second while stepping (NaN before two frames)."""
        return self.physics_s / self.wall_s if self.wall_s > 0.0 else math.nan

    @property
    def busy_fraction(self) -> float:
        """Mean busy time per frame over the frame period: the bridge's load at real time
        (1 / this is how much faster than real time it could go; NaN before any frame)."""
        if self.frames == 0 or self.frame_rate == 0:
            return math.nan
        return self.busy_s / self.frames * self.frame_rate


class TwinRecord:
    """The bridge's counters and truth in one float64 array, so that another process can read
    them (the array may live in shared memory: :class:`BridgeProcess`).

    The truth is a ring of the last ``capacity`` frames (:data:`TRUTH_CAPACITY`: 10 minutes
    at 1200 Hz, 40 MB), oldest first when read. One writer; readers may run at any time (a
    read never waits; the counters are each written whole).
    """

    def __init__(self, array: np.ndarray) -> None:
        self.array = array
        self.capacity = (len(array) - HEADER) // ROW
        if self.capacity < 1:
            raise ValueError("a record needs room for at least one frame")
        self._rows = array[HEADER:HEADER + self.capacity * ROW].reshape(self.capacity, ROW)

    @staticmethod
    def size(capacity: int) -> int:
        """The array's length (float64 items) for ``capacity`` frames."""
        return HEADER + capacity * ROW

    @classmethod
    def local(cls, capacity: int = TRUTH_CAPACITY) -> TwinRecord:
        """A record in this process's memory."""
        return cls(blank(np.zeros(cls.size(capacity))))

    def add(self, sample: TruthSample) -> None:
        """Record one frame's truth (the oldest goes once the ring is full)."""
        count = int(self.array[COUNT])
        self._rows[count % self.capacity] = sample_row(sample)
        self.array[COUNT] = count + 1

    def truth_array(self) -> np.ndarray:
        """The truth so far as rows of :class:`TruthSample`'s fields, oldest first (a copy)."""
        count = int(self.array[COUNT])
        if count <= self.capacity:
            return np.array(self._rows[:count])
        cut = count % self.capacity
        return np.concatenate((self._rows[cut:], self._rows[:cut]))

    @property
    def count(self) -> int:
        """Frames of truth recorded so far (the ring keeps the last :attr:`capacity`)."""
        return int(self.array[COUNT])

    def latest(self, frames: int) -> np.ndarray:
        """The last ``frames`` rows of :meth:`truth_array` (fewer if fewer were recorded),
        oldest first, without copying the rest of the ring (a copy)."""
        count = int(self.array[COUNT])
        rows = np.arange(max(count - min(frames, self.capacity), 0), count) % self.capacity
        return self._rows[rows]

    def set_contacts(self, time_s: float,
                     contacts: tuple[WheelContact, WheelContact, WheelContact,
                                     WheelContact]) -> None:
        """Record the wheels' contacts read at physics time ``time_s``."""
        self.array[CONTACTS + 1:HEADER] = [v for c in contacts for v in c]
        self.array[CONTACTS] = time_s  # (last: a reader that sees the time sees the values)

    def contacts(self) -> tuple[float, tuple[WheelContact, ...]] | None:
        """The physics time of the last contacts read and the contacts FL, FR, RL, RR; None
        before any."""
        a = self.array[CONTACTS:HEADER].tolist()
        if math.isnan(a[0]):
            return None
        return a[0], tuple(WheelContact(n, s, bool(f)) for n, s, f in
                           zip(a[1::3], a[2::3], a[3::3], strict=True))

    def truth(self) -> list[TruthSample]:
        """The truth so far, oldest first (a copy)."""
        return [TruthSample(*row) for row in self.truth_array().tolist()]

    def truth_now(self) -> TruthSample:
        """The latest truth.

        Raises:
            LookupError: nothing recorded yet.
        """
        count = int(self.array[COUNT])
        if count == 0:
            raise LookupError("no truth recorded yet")
        return TruthSample(*self._rows[(count - 1) % self.capacity].tolist())

    def stats(self) -> BridgeStats:
        """The counters now."""
        a = self.array[:HEADER].tolist()
        first, last = a[FIRST_WALL], a[LAST_WALL]
        wall = 0.0 if math.isnan(first) else last - first
        c, p = a[COMMANDS:COMMANDS + 4], [int(v) for v in a[PULSES:PULSES + 4]]
        return BridgeStats(int(a[FRAMES]), int(a[REPEATED]), int(a[DROPPED]),
                           int(a[RESTARTS]), int(a[MALFORMED]), a[PHYSICS_S], wall,
                           a[BUSY_S], int(a[FRAME_RATE]), (c[0], c[1], c[2], c[3]),
                           (p[0], p[1], p[2], p[3]))


def blank(array: np.ndarray) -> np.ndarray:
    """``array`` (zeros) made an empty record: no frame answered, no contacts read yet."""
    array[FIRST_WALL:LAST_WALL + 1] = math.nan
    array[CONTACTS] = math.nan
    return array


def sample_row(sample: TruthSample) -> tuple[float, ...]:
    """A truth sample as one row of :meth:`TwinRecord.truth_array`."""
    return (sample.wall_s, sample.time_s, sample.north_m, sample.east_m, sample.yaw_rad,
            sample.forward_mps, sample.right_mps)
