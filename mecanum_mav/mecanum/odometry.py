"""Dead reckoning from cumulative wheel distances, optionally steered by an external yaw.

Frames (see CONVENTIONS.md): the pose is in the local NED frame (x north, y east, metres;
yaw radians clockwise from north); wheel distances are cumulative metres rolled by each
wheel (FL, FR, RL, RR; positive = the robot went forward), as the flight controller's
WHEEL_DISTANCE message reports them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from mecanum_mav.mecanum.geometry import Pose2d, Twist2d, body_to_ned, pose_exp, wrap_pi
from mecanum_mav.mecanum.kinematics import MecanumKinematics

__all__ = ["MecanumOdometry"]

_ORIGIN = Pose2d(0.0, 0.0, 0.0)


def _checked_distances(wheel_distances_m: Sequence[float]) -> tuple[float, ...]:
    """Four finite cumulative wheel distances (m) as floats; ValueError otherwise."""
    if isinstance(wheel_distances_m, (list, tuple)) and len(wheel_distances_m) == 4:
        # the control loop's path: plain floats, no numpy, no generator frames
        a, b, c, d = wheel_distances_m
        if type(a) is float and type(b) is float and type(c) is float and type(d) is float:
            if (a - a) + (b - b) + (c - c) + (d - d) == 0.0:  # (x - x is NaN for NaN, inf)
                return a, b, c, d
            raise ValueError(f"non-finite wheel distances: {(a, b, c, d)}")
    values = tuple(float(v) for v in np.asarray(wheel_distances_m, dtype=np.float64).ravel())
    if len(values) != 4 or np.ndim(wheel_distances_m) != 1:
        raise ValueError("wheel distances need exactly 4 values (FL, FR, RL, RR), metres")
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"non-finite wheel distances: {values}")
    return values


def _checked_yaw(yaw_rad: float | None) -> float | None:
    """A finite external yaw in radians (or None); ValueError if NaN or inf."""
    if yaw_rad is None:
        return None
    yaw = float(yaw_rad)
    if not math.isfinite(yaw):
        raise ValueError(f"non-finite yaw: {yaw}")
    return yaw


def _checked_pose(pose: Pose2d) -> Pose2d:
    """A finite pose with float fields and its yaw wrapped to [-pi, pi); ValueError otherwise."""
    x, y, yaw = (float(v) for v in pose)
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(yaw)):
        raise ValueError(f"non-finite pose: {pose}")
    return Pose2d(x, y, wrap_pi(yaw))


class MecanumOdometry:
    """Track the robot's NED pose from cumulative wheel distances, like WPILib's
    ``MecanumDriveOdometry``.

    Each :meth:`update` takes the wheel distances since the previous call, turns them into
    a body-frame twist by least squares (:meth:`MecanumKinematics.to_twist`) and moves the
    pose along that twist's exact arc (:func:`geometry.pose_exp`).

    Heading. An external yaw (gyro or flight-controller attitude; radians clockwise from
    north) is optional on every call. When given, it replaces the wheel-derived heading
    change: the heading becomes ``wrap_pi(yaw_rad + offset)``, where ``offset`` = pose yaw
    minus external yaw at the last :meth:`reset` (or construction), and the step's arc
    turns by ``wrap_pi(new heading - previous heading)``; while the external yaw keeps
    coming that is ``wrap_pi(yaw_now - yaw_prev)``. When a call gives no yaw, the wheels'
    own heading change is used, so the pose stays continuous when the gyro drops out;
    when it comes back, the heading returns to ``yaw_rad + offset`` (wheel-derived
    heading drifts; the external yaw is trusted). If the offset was never fixed (reset
    without a yaw), the first external yaw seen fixes it so that the heading stays
    continuous at that step.
    """

    __slots__ = ("_distances", "_kinematics", "_pose", "_yaw_offset", "reset_counter")

    def __init__(
        self,
        kinematics: MecanumKinematics,
        wheel_distances_m: Sequence[float] = (0.0, 0.0, 0.0, 0.0),
        pose: Pose2d = _ORIGIN,
        yaw_rad: float | None = None,
    ) -> None:
        """Start at ``pose`` (NED, m, rad) with the wheels at ``wheel_distances_m`` (m).

        ``yaw_rad`` is the external yaw (radians clockwise from north) read at the same
        moment, or None if there is none yet. ``reset_counter`` starts at 0. Raises
        ValueError on non-finite inputs or a wheel array that is not 4 long.
        """
        self._kinematics = kinematics
        self.reset_counter: int = 0
        """Number of :meth:`reset` calls so far (for MAVLink ODOMETRY ``reset_counter``)."""
        self._distances: tuple[float, ...]
        self._pose: Pose2d
        self._yaw_offset: float | None
        self._set_state(pose, wheel_distances_m, yaw_rad)  # (sets all three, or raises)

    @property
    def pose(self) -> Pose2d:
        """Current pose: NED (x north m, y east m), yaw radians clockwise from north."""
        return self._pose

    @property
    def kinematics(self) -> MecanumKinematics:
        """The kinematics used to turn wheel deltas into body twists."""
        return self._kinematics

    def reset(
        self,
        pose: Pose2d = _ORIGIN,
        wheel_distances_m: Sequence[float] | None = None,
        yaw_rad: float | None = None,
    ) -> None:
        """Jump to ``pose`` (NED, m, rad) and increment :attr:`reset_counter`.

        ``wheel_distances_m``: the cumulative wheel distances (m) at this moment; None
        keeps the last ones seen (the next update measures from them). ``yaw_rad``: the
        external yaw (radians clockwise from north) now, fixing the heading offset; None
        leaves the offset unfixed until the next update that brings a yaw. Raises
        ValueError (state unchanged) on non-finite inputs.
        """
        distances = self._distances if wheel_distances_m is None else wheel_distances_m
        self._set_state(pose, distances, yaw_rad)
        self.reset_counter += 1

    def rotate(self, angle_rad: float, about: tuple[float, float]) -> None:
        """Turn the track so far by ``angle_rad`` (clockwise) about ``about`` (north, east
        m): the position moves about that point and the heading turns by as much (a heading
        bias found late, corrected as if the track had been driven with it all along). The
        external yaw's offset is kept: the caller turns the yaw it passes in by as much.
        Not a reset (:attr:`reset_counter` stays)."""
        n, e = body_to_ned(self._pose.x_m - about[0], self._pose.y_m - about[1],
                           angle_rad)  # (turned clockwise by the angle)
        self._pose = _checked_pose(Pose2d(about[0] + n, about[1] + e,
                                          self._pose.yaw_rad + angle_rad))

    def shift(self, north_m: float, east_m: float) -> None:
        """Move the position by (``north_m``, ``east_m``) m, the heading kept (a fused
        position's pull). Not a reset (:attr:`reset_counter` stays)."""
        self._pose = _checked_pose(self._pose._replace(x_m=self._pose.x_m + north_m,
                                                       y_m=self._pose.y_m + east_m))

    def _set_state(
        self, pose: Pose2d, wheel_distances_m: Sequence[float], yaw_rad: float | None
    ) -> None:
        """Validate everything first, then set pose, distances and the heading offset."""
        new_pose = _checked_pose(pose)
        distances = _checked_distances(wheel_distances_m)
        yaw = _checked_yaw(yaw_rad)
        self._pose = new_pose
        self._distances = distances
        self._yaw_offset = None if yaw is None else wrap_pi(new_pose.yaw_rad - yaw)

    def update(self, wheel_distances_m: Sequence[float], yaw_rad: float | None = None) -> Pose2d:
        """Advance the pose with the wheels' cumulative distances (m, FL, FR, RL, RR).

        ``yaw_rad``: optional external yaw, radians clockwise from north (see the class
        docstring for how it replaces the wheel-derived heading change). Returns the new
        pose (NED, m, rad). Raises ValueError, leaving the state unchanged, if a distance
        or the yaw is NaN or inf or the wheel array is not 4 long.
        """
        distances = _checked_distances(wheel_distances_m)
        yaw = _checked_yaw(yaw_rad)
        (a, b, c, d), (e, f, g, h) = distances, self._distances
        deltas = (a - e, b - f, c - g, d - h)
        dx, dy, dyaw = self._kinematics.to_twist(deltas)
        if yaw is None:
            self._pose = pose_exp(self._pose, Twist2d(dx, dy, dyaw))
        else:
            if self._yaw_offset is None:
                # First external yaw since a reset without one: keep the wheel heading
                # change for this step and anchor the offset to the resulting heading.
                self._yaw_offset = wrap_pi(self._pose.yaw_rad + dyaw - yaw)
            heading = wrap_pi(yaw + self._yaw_offset)
            moved = pose_exp(self._pose, Twist2d(dx, dy, wrap_pi(heading - self._pose.yaw_rad)))
            self._pose = moved._replace(yaw_rad=heading)
        self._distances = distances
        return self._pose
