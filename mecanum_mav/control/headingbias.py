"""The flight controller's heading bias, from its own position track (I/O-free, time passed in).

The odometry turns the rover's body-frame motion into the local NED frame with the flight
controller's ATTITUDE yaw. A compass heading that is off by ``b`` (ArduPilot's EKF3 settles
about 2 degrees off in SITL once it fuses GPS; a few degrees is normal on a real rover) rotates
every step of that track by ``b``: the rover arrives centimetres off and faces ``b`` off. The
flight controller's own position (LOCAL_POSITION_NED: GPS-fused, so its direction of travel is
true) shows it: over a stretch of travel, the direction of the odometry's displacement minus
the direction of the flight controller's is ``b``.

:class:`HeadingBias` takes one sample per flight-controller position message: that position
(north, east m) and the odometry's position at the same moment together with the correction the
odometry was using. It keeps the *raw* odometry track (each step rotated back by the correction
in force when it was made), so its measurement does not depend on its own estimate. A
measurement is made over the latest window whose raw path is at least :data:`BASELINE_M` long
(position noise of 1 cm over 0.5 m is 1.1 degrees; the filter averages many; a longer one
leaves the rover further off before it is corrected: 2.5 degrees over 1 m is 4.4 cm), and only
when:

- both paths are straight (chord at least :data:`STRAIGHT_RATIO` of its length): on a curve a
  few centimetres of lag between the two tracks (GPS delay, the motors' lag in commanded
  odometry) turns into degrees; on a straight line it only slides along it (an EKF's track
  that swings past a corner the odometry turned exactly is not straight);
- the raw path kept its direction (within :data:`TURN_GUARD_RAD`, its two halves' chords) from
  :data:`TURN_GUARD_S` before the window to its end: the flight controller's fixes come late
  (ArduPilot SITL's GPS about 0.15 s, 15 cm at 1 m/s), so while the track bends (the rover
  steering back onto its line after a correction) the fixes' chord points where the track
  went a moment before: measured on the twin, the first estimate overshot by 0.8 degrees for a
  second (a track that keeps its direction within a degree leaves the window's error under a
  third of that; the twin's cross-track corrections bend it by about that much);
- against the flight controller's EKF position (``follows_yaw``), the rover moved steadily: no
  step of the raw path in the window is under :data:`STEADY_RATIO` of its mean step (starting
  and stopping, an EKF's position follows its own heading until GPS pulls it back: measured on
  ArduPilot SITL, degrees toward its bias). GPS fixes do not follow the yaw: they are measured
  against from a standing start on (they come late, which on a straight line only slides
  them along it), so the first correction comes after about :data:`BASELINE_M` of a mission's
  first leg, not after the rover has reached its speed (on the twin, 2 degrees of bias had put
  the square's first leg 4.3 cm off by then);
- the two chords agree in length within :data:`SCALE_TOLERANCE` (a GPS glitch, an EKF reset or
  wheels slipping are not a heading), and within what the positions' lateness explains
  besides: :data:`FIX_LAG_S` times the change of speed over the window (a late track is short
  of a window that speeds up: on the twin the GPS's chord was 0.74-0.77 of the odometry's for
  the first 1.1 m of a start from rest, and the first correction waited until then);
- the angle is within :data:`MAX_BIAS_RAD` (10 degrees): beyond that it is not a compass bias
  to correct quietly; after :data:`REFUSE_AFTER` such windows in a row (and none accepted) it
  is said once, the correction left as it is;
- once the estimate has settled, the angle is within :data:`OUTLIER_RAD` of it (a GPS glitch a
  few centimetres sideways is degrees over half a metre); :data:`REFUSE_AFTER` outliers in a
  row, none accepted between, mean the bias itself has moved: the filter starts again from
  the next measurement (a plain mean first, as at the start).

Rotation in place has no baseline (the raw path does not grow), a flight controller without
a position sends nothing: no estimate, the odometry works exactly as without this. A gap in
the positions longer than :data:`GAP_S`, or an odometry reset, restarts the window (the bias,
a property of the flight controller's heading, is kept).

The estimate is the mean of the first measurements, then an exponential filter with gain
:data:`GAIN_MIN` per measurement; it counts as settled after
:data:`SETTLED_COUNT` measurements (said once). Angles are radians, clockwise positive (NED).
"""

from __future__ import annotations

import math
from collections import deque
from itertools import chain, dropwhile
from typing import NamedTuple

from mecanum_mav.mecanum.geometry import body_to_ned, wrap_pi

__all__ = ["BASELINE_M", "MAX_BIAS_RAD", "BiasUpdate", "HeadingBias"]

BASELINE_M = 0.5
"""Shortest raw odometry path a measurement is made over (m)."""
WINDOW_S = 20.0
"""Samples older than this (s) are dropped: a baseline needs at least 5 cm/s."""
STRAIGHT_RATIO = 0.99
"""A window counts as straight when its chord is at least this fraction of its path."""
STEADY_RATIO = 0.8
"""Each step of a window's raw path is at least this fraction of the window's mean step."""
TURN_GUARD_S = 0.5
"""How long before a window its raw path must already keep its direction (s): longer than a
flight controller's position is late."""
TURN_GUARD_RAD = math.radians(1.0)
"""The most the directions of the two halves of the guarded raw path may differ (rad)."""
SCALE_TOLERANCE = 0.2
"""The flight controller's chord over the odometry's must be within 1 +- this (and
:data:`FIX_LAG_S` times the window's change of speed)."""
FIX_LAG_S = 0.4
"""How late a flight controller's position may be (s): ArduPilot SITL's GPS fixes (5 Hz, 0.15
s of delay) reach the companion 0.15-0.35 s after they were true."""
MAX_BIAS_RAD = math.radians(10.0)
"""The largest heading bias corrected (rad)."""
REFUSE_AFTER = 20
"""Measurements beyond :data:`MAX_BIAS_RAD` in a row, none accepted between, before it is said."""
OUTLIER_RAD = math.radians(3.0)
"""Once settled, a measurement further than this from the estimate (rad) is an outlier."""
GAP_S = 1.0
"""Positions further apart than this (s) restart the window."""
GAIN_MIN = 0.05
"""The filter's gain per measurement once past the first ``1 / GAIN_MIN`` (a plain mean).
Windows are rare on a mission (straight half-metres: on the twin 29 in 51 s of the square and
strafe-rotate, when they also had to be driven steadily) while ArduPilot's EKF3 heading error
on SITL drifts (2.1 degrees at rest, 0.9 a minute of driving later): replayed, 0.05 followed
it 0.27 degrees behind on average, 0.2 0.19; but 0.2 let a GPS fix sliding 6 cm sideways over
0.6 s walk the settled estimate 2.5 degrees away (its windows each within
:data:`OUTLIER_RAD` of the last), 0.05 0.4."""
SETTLED_COUNT = 10
"""Measurements before the estimate is said."""


class _Sample(NamedTuple):
    time_s: float
    raw: tuple[float, float]
    """The raw odometry position (m, NED, the track rotated back by its corrections)."""
    path_m: float
    """The raw path's length from the window's start (m)."""
    fc: tuple[float, float]
    """The flight controller's position (m, NED)."""
    fc_path_m: float
    """The flight controller's path's length from the window's start (m)."""


def _speed(first: _Sample, second: _Sample) -> float:
    """The raw path's speed between two samples (m/s; 0 if no time passed)."""
    dt = second.time_s - first.time_s
    return (second.path_m - first.path_m) / dt if dt > 0.0 else 0.0


class BiasUpdate(NamedTuple):
    """What one position sample changed."""

    bias_rad: float
    """The estimate now (rad, clockwise): the flight controller's yaw minus the true one."""
    notice: str | None
    """Something to say once (settled, or beyond the bound), else None."""


class HeadingBias:
    """Estimates the flight controller's yaw bias (see the module docstring)."""

    def __init__(self) -> None:
        self.bias_rad = 0.0
        """The estimate (rad, clockwise; 0 until the first measurement)."""
        self.measurements = 0
        """Accepted measurements so far."""
        self.rejected = 0
        """Windows turned down for the bound, in a row."""
        self.outliers = 0
        """Windows turned down as outliers of the settled estimate, in a row."""
        self._samples: deque[_Sample] = deque()
        self._odometry: tuple[float, float] | None = None  # the last odometry position seen
        self._said_settled = False
        self._said_refused = False

    def restart(self) -> None:
        """Forget the window (an odometry reset, a gap): the estimate stays."""
        self._samples.clear()
        self._odometry = None

    def follow(self, odom_north_m: float, odom_east_m: float) -> None:
        """The odometry's position was moved (its track turned by a new correction): steps
        are measured from here. (Before the first position, or after a restart, it changes
        nothing: the next position starts the window.)"""
        self._odometry = (odom_north_m, odom_east_m)

    @property
    def settled(self) -> bool:
        """Whether the estimate has :data:`SETTLED_COUNT` measurements behind it."""
        return self.measurements >= SETTLED_COUNT

    def shifted(self, north_m: float, east_m: float) -> None:
        """The odometry's position was shifted by (``north_m``, ``east_m``) m (a fused
        position's pull): not a step it drove."""
        if self._odometry is not None:
            self._odometry = (self._odometry[0] + north_m, self._odometry[1] + east_m)

    def on_position(self, fc_north_m: float, fc_east_m: float, odom_north_m: float,
                    odom_east_m: float, correction_rad: float, now_s: float, *,
                    follows_yaw: bool = True) -> BiasUpdate:
        """One flight-controller position (m, NED) with the odometry's position at the same
        moment and the correction (rad) it has used since the previous call; ``follows_yaw``:
        the position is the flight controller's EKF's (measured over steady driving only),
        not a GPS fix."""
        samples = self._samples
        if samples and now_s - samples[-1].time_s > GAP_S:
            self.restart()
        last = self._odometry
        self._odometry = (odom_north_m, odom_east_m)
        if last is None or not samples:
            samples.append(_Sample(now_s, (0.0, 0.0), 0.0, (fc_north_m, fc_east_m), 0.0))
            return BiasUpdate(self.bias_rad, None)
        # The odometry's step, rotated back by the correction it was made with: raw.
        dn, de = odom_north_m - last[0], odom_east_m - last[1]
        rn, re_ = body_to_ned(dn, de, correction_rad)  # (turned clockwise by the correction)
        prev = samples[-1]
        raw = (prev.raw[0] + rn, prev.raw[1] + re_)
        fc_step = math.hypot(fc_north_m - prev.fc[0], fc_east_m - prev.fc[1])
        sample = _Sample(now_s, raw, prev.path_m + math.hypot(dn, de), (fc_north_m, fc_east_m),
                         prev.fc_path_m + fc_step)
        samples.append(sample)
        while now_s - samples[0].time_s > WINDOW_S:
            samples.popleft()
        notice = self._measure(sample, follows_yaw)
        return BiasUpdate(self.bias_rad, notice)

    def _bends(self, start: _Sample, now: _Sample) -> bool:
        """Whether the raw path from :data:`TURN_GUARD_S` before ``start`` (or the oldest
        sample) to ``now`` turns: its two halves' chords more than :data:`TURN_GUARD_RAD`
        apart. ``now`` is the newest sample (so the path has a first sample and a middle one,
        ``now`` at the latest: the path only grows)."""
        guard_s = start.time_s - TURN_GUARD_S
        recent = dropwhile(lambda sample: sample.time_s < guard_s, self._samples)
        first = next(recent)
        half = (first.path_m + now.path_m) / 2.0
        mid = next(sample for sample in chain((first,), recent) if sample.path_m >= half)
        if mid is first or mid is now:
            return False
        before = math.atan2(mid.raw[1] - first.raw[1], mid.raw[0] - first.raw[0])
        after = math.atan2(now.raw[1] - mid.raw[1], now.raw[0] - mid.raw[0])
        return abs(wrap_pi(before - after)) > TURN_GUARD_RAD

    def _measure(self, now: _Sample, steady_only: bool) -> str | None:
        """Measure over the latest window of :data:`BASELINE_M`, if any (``steady_only``: if
        the rover drove it steadily); a notice or None."""
        start = None
        least_step, later, after, steps = math.inf, now, now, 0
        for sample in reversed(self._samples):
            if sample is not now:
                least_step = min(least_step, later.path_m - sample.path_m)
                after, later, steps = later, sample, steps + 1
            if now.path_m - sample.path_m >= BASELINE_M:
                start = sample
                break
        if start is None:
            return None
        path = now.path_m - start.path_m
        if steady_only and least_step < STEADY_RATIO * path / steps:
            return None
        if self._bends(start, now):
            return None
        rn, re_ = now.raw[0] - start.raw[0], now.raw[1] - start.raw[1]
        fn, fe = now.fc[0] - start.fc[0], now.fc[1] - start.fc[1]
        chord, fc_chord = math.hypot(rn, re_), math.hypot(fn, fe)
        # (start is not now, the window being BASELINE_M long: the samples are two or more)
        late_m = FIX_LAG_S * abs(_speed(self._samples[-2], now) - _speed(start, after))
        if chord < STRAIGHT_RATIO * path or fc_chord < STRAIGHT_RATIO * (
                now.fc_path_m - start.fc_path_m) or abs(
                fc_chord - chord) > SCALE_TOLERANCE * chord + late_m:
            return None
        angle = wrap_pi(math.atan2(re_, rn) - math.atan2(fe, fn))
        if not abs(angle) <= MAX_BIAS_RAD:
            self.rejected += 1
            if self.rejected >= REFUSE_AFTER and not self._said_refused:
                self._said_refused = True
                return (f"Heading: FC yaw {math.degrees(angle):+.1f} deg off its track, beyond "
                        f"{math.degrees(MAX_BIAS_RAD):.0f}: not corrected")
            return None
        self.rejected = 0
        if self.measurements >= SETTLED_COUNT and abs(angle - self.bias_rad) > OUTLIER_RAD:
            self.outliers += 1
            if self.outliers >= REFUSE_AFTER:  # not an outlier: the bias moved
                self.measurements = self.outliers = 0
            return None
        self.outliers = 0
        self.measurements += 1
        gain = max(1.0 / self.measurements, GAIN_MIN)
        self.bias_rad += gain * (angle - self.bias_rad)
        if self.measurements >= SETTLED_COUNT and not self._said_settled:
            self._said_settled = True
            return (f"Heading: FC yaw {math.degrees(self.bias_rad):+.1f} deg off its track: "
                    "corrected")
        return None
