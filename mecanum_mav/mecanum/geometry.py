"""Planar poses and twists (SE(2)) in the project's frames.

Frames and signs (see CONVENTIONS.md):

- A :class:`Pose2d` lives in the local NED frame: ``x_m`` north, ``y_m`` east (metres) and
  ``yaw_rad`` the heading, radians clockwise from north seen from above.
- A :class:`Twist2d` is a body-frame (FRD) displacement: ``dx_m`` forward, ``dy_m`` right
  (metres) and ``dyaw_rad`` the heading change, radians, clockwise positive.

With x north, y east and yaw measured from x towards y, the body-to-NED rotation is the
ordinary 2-D rotation ``[[cos, -sin], [sin, cos]]``: a robot facing east (yaw = pi/2)
moving forward moves east, and its right-hand side points south.
"""

from __future__ import annotations

import math
from typing import NamedTuple, overload

import numpy as np
import numpy.typing as npt

__all__ = [
    "ChassisSpeeds",
    "Pose2d",
    "Twist2d",
    "pose_exp",
    "pose_exp_array",
    "pose_log",
    "wrap_pi",
]

FloatArray = npt.NDArray[np.float64]

_TAU = 2.0 * math.pi
_SMALL_ANGLE_RAD = 1e-6
"""Below this |dyaw| the arc coefficients use their Taylor series (no division by ~0)."""


class Pose2d(NamedTuple):
    """A planar pose in the local NED frame.

    ``x_m``: north (m); ``y_m``: east (m); ``yaw_rad``: heading, radians clockwise from
    north seen from above (0 = facing north, pi/2 = facing east).
    """

    x_m: float
    y_m: float
    yaw_rad: float


class ChassisSpeeds(NamedTuple):
    """A body velocity, FRD: ``vx_mps`` forward, ``vy_mps`` right (m/s), ``yaw_rate``
    clockwise seen from above (rad/s). WPILib's ChassisSpeeds, in this product's frame."""

    vx_mps: float
    vy_mps: float
    yaw_rate: float


class Twist2d(NamedTuple):
    """A body-frame (FRD) displacement along a constant-curvature arc.

    ``dx_m``: forward (m); ``dy_m``: right (m); ``dyaw_rad``: heading change, radians,
    clockwise positive seen from above. Divided by a time step it is a body velocity.
    """

    dx_m: float
    dy_m: float
    dyaw_rad: float


@overload
def wrap_pi(angle: float) -> float: ...
@overload
def wrap_pi(angle: npt.ArrayLike) -> FloatArray: ...
def wrap_pi(angle: float | npt.ArrayLike) -> float | FloatArray:
    """Wrap an angle in radians to the half-open interval [-pi, pi).

    Works on python floats/ints (returns a float) and on array-likes (returns a float64
    ndarray of the same shape). Angles already inside the interval are returned unchanged
    (bit for bit), so small angles keep their full precision; +pi maps to -pi. A
    non-finite angle gives NaN. Frame-independent.
    """
    if isinstance(angle, (float, int)):
        a = float(angle)
        if -math.pi <= a < math.pi:
            return a
        if not math.isfinite(a):
            return math.nan
        w = math.fmod(a + math.pi, _TAU)
        if w < 0.0:
            w += _TAU
        w -= math.pi
        # Rounding can land exactly on +pi (e.g. a tiny negative w plus tau); fold it.
        return w - _TAU if w >= math.pi else w
    a_arr = np.asarray(angle, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        w_arr = np.mod(a_arr + math.pi, _TAU) - math.pi
        w_arr = np.where(w_arr >= math.pi, w_arr - _TAU, w_arr)
        inside = (a_arr >= -math.pi) & (a_arr < math.pi)
    return np.where(inside, a_arr, w_arr)


def _arc_coefficients(dyaw: float) -> tuple[float, float]:
    """(sin(t)/t, (1 - cos(t))/t) for a heading change t in radians, accurate near t = 0."""
    if abs(dyaw) < _SMALL_ANGLE_RAD:
        t2 = dyaw * dyaw
        return 1.0 - t2 / 6.0, dyaw * (0.5 - t2 / 24.0)
    half_sin = math.sin(0.5 * dyaw)
    # 1 - cos(t) = 2 sin^2(t/2) avoids the cancellation of 1 - cos(t) for small t.
    return math.sin(dyaw) / dyaw, 2.0 * half_sin * half_sin / dyaw


def body_to_ned(forward: float, right: float, yaw_rad: float) -> tuple[float, float]:
    """A body FRD vector (forward, right) as (north, east) for a heading ``yaw_rad``
    (radians clockwise from north). Any unit; the length is kept."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    return c * forward - s * right, s * forward + c * right


def ned_to_body(north: float, east: float, yaw_rad: float) -> tuple[float, float]:
    """A (north, east) vector as body FRD (forward, right) for a heading ``yaw_rad``
    (radians clockwise from north); the inverse of :func:`body_to_ned`."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    return c * north + s * east, -s * north + c * east


def pose_exp(pose: Pose2d, twist: Twist2d) -> Pose2d:
    """Move ``pose`` by the body-frame ``twist`` along its exact constant-curvature arc.

    ``pose`` is in the local NED frame (m, m, rad clockwise from north); ``twist`` is in
    the robot's body FRD frame at ``pose`` (m forward, m right, rad clockwise). This is the
    SE(2) exponential: driving with a constant body velocity (vx, vy, yaw_rate) for a time
    dt is ``pose_exp(pose, Twist2d(vx*dt, vy*dt, yaw_rate*dt))``. The returned yaw is
    wrapped to [-pi, pi). Non-finite inputs propagate (NaN/inf in the result).
    """
    x, y, yaw = pose
    dx, dy, dyaw = twist
    a, b = _arc_coefficients(dyaw)
    # Displacement in the start pose's body frame: V(dyaw) @ (dx, dy).
    fwd = a * dx - b * dy
    right = b * dx + a * dy
    north, east = body_to_ned(fwd, right, yaw)
    return Pose2d(x + north, y + east, wrap_pi(yaw + dyaw))


def pose_exp_array(poses: npt.ArrayLike, twists: npt.ArrayLike) -> FloatArray:
    """Vectorized :func:`pose_exp`: poses [..., 3] and twists [..., 3] broadcast together.

    ``poses[..., :]`` = (north m, east m, yaw rad clockwise from north), local NED frame;
    ``twists[..., :]`` = (forward m, right m, dyaw rad clockwise), body FRD frame of each
    pose. Returns float64 [..., 3] poses in NED with yaw wrapped to [-pi, pi). Small
    |dyaw| (< 1e-6 rad) uses the same Taylor series as the scalar function. Non-finite
    inputs propagate to the rows they touch.
    """
    p = np.asarray(poses, dtype=np.float64)
    t = np.asarray(twists, dtype=np.float64)
    if p.shape[-1:] != (3,) or t.shape[-1:] != (3,):
        raise ValueError("poses and twists need a last axis of length 3")
    x, y, yaw = p[..., 0], p[..., 1], p[..., 2]
    dx, dy, dyaw = t[..., 0], t[..., 1], t[..., 2]
    with np.errstate(invalid="ignore", over="ignore"):
        small = np.abs(dyaw) < _SMALL_ANGLE_RAD
        t_safe = np.where(small, 1.0, dyaw)
        half_sin = np.sin(0.5 * t_safe)
        t2 = dyaw * dyaw
        a = np.where(small, 1.0 - t2 / 6.0, np.sin(t_safe) / t_safe)
        b = np.where(small, dyaw * (0.5 - t2 / 24.0), 2.0 * half_sin * half_sin / t_safe)
        fwd = a * dx - b * dy
        right = b * dx + a * dy
        c, s = np.cos(yaw), np.sin(yaw)
        return np.stack(
            (x + c * fwd - s * right, y + s * fwd + c * right, wrap_pi(yaw + dyaw)), axis=-1
        )


def pose_log(start: Pose2d, end: Pose2d) -> Twist2d:
    """The body-frame twist that :func:`pose_exp` turns ``start`` into ``end``.

    Both poses in the local NED frame (m, m, rad clockwise from north). The result is in
    ``start``'s body FRD frame (m forward, m right, rad clockwise) and takes the shorter
    way round: its ``dyaw_rad`` is ``wrap_pi(end.yaw_rad - start.yaw_rad)`` in [-pi, pi),
    so ``pose_exp(start, pose_log(start, end)) == end`` (up to rounding) always, and
    ``pose_log(start, pose_exp(start, twist)) == twist`` when |twist.dyaw_rad| < pi.
    """
    dyaw = wrap_pi(end.yaw_rad - start.yaw_rad)
    north, east = end.x_m - start.x_m, end.y_m - start.y_m
    fwd, right = ned_to_body(north, east, start.yaw_rad)
    # Inverse of V(t) = [[a, -b], [b, a]] is [[h cot h, h], [-h, h cot h]] with h = t/2.
    half = 0.5 * dyaw
    if abs(dyaw) < _SMALL_ANGLE_RAD:
        h_cot_h = 1.0 - dyaw * dyaw / 12.0
    else:
        h_cot_h = half * math.cos(half) / math.sin(half)
    return Twist2d(h_cot_h * fwd + half * right, -half * fwd + h_cot_h * right, dyaw)
