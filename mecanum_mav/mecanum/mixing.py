"""Normalized mecanum mixing: chassis commands in [-1, 1] -> four wheel commands in [-1, 1].

Frame and signs (see docs/index.md, "Conventions"): x forward, y right, rotation positive clockwise
seen from above; a polar ``direction_deg`` is degrees clockwise from the robot's nose (0 forward,
90 right). Every mixing function takes floats or numpy arrays, broadcasts its arguments, and
returns an ``ndarray`` whose last axis is the four wheels in the order FL, FR, RL, RR. A positive
wheel command rolls the robot forward; mirrored motors are handled at the PWM edge, never here.

With rollers in the usual "X" arrangement a wheel command is ``x + s*y + q*r`` with lateral signs
``s = (+1, -1, -1, +1)`` and rotation signs ``q = (+1, -1, +1, -1)`` (defined in
:mod:`mecanum_mav.mecanum.wheels`; tests/test_wheels.py holds the closed forms here to them).
The translation part of the FL/RR pair is ``a = x + y`` and of the FR/RL pair ``b = x - y``, so
the largest wheel magnitude is exactly ``max(|a|, |b|) + |r|``: every desaturation strategy has
a closed form, which is what keeps the scalar path in single-digit microseconds.

Bad input: a command with any non-finite component (NaN, +/-inf) is read as a stop: that
command's four wheels are 0.0. Magnitudes, stick axes and rotations outside [-1, 1] are limited
to it. Nothing here ever returns NaN wheel commands. Forward kinematics
(:func:`chassis_from_wheels`) raises ``ValueError`` on non-finite wheels: a corrupt measurement
is the caller's decision, not a silent zero.

Input shaping for the drive path (deadband, expo, square stick to circle) lives in
:mod:`mecanum_mav.mecanum.shaping` and is re-exported here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from enum import IntEnum
from typing import Any, TypeGuard

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mecanum_mav.mecanum.shaping import deadband, expo, shape_stick, square_to_circle
from mecanum_mav.mecanum.wheels import LATERAL_SIGNS as _LATERAL_SIGNS
from mecanum_mav.mecanum.wheels import ROTATION_SIGNS as _ROTATION_SIGNS

__all__ = [
    "ALGORITHMS",
    "ALGORITHM_NAMES",
    "LATERAL_SIGNS",
    "ROTATION_SIGNS",
    "Desaturation",
    "cartesian",
    "chassis_from_wheels",
    "deadband",
    "desaturate",
    "desaturate_prioritized",
    "desaturate_prioritized_scalar",
    "expo",
    "holonomic_2010",
    "max_speed_scaled",
    "mix_pairs",
    "mix_stick",
    "normalize",
    "polar_2011",
    "shape_stick",
    "square_to_circle",
    "wheels_from_stick",
]

Wheels = NDArray[np.float64]
"""Wheel commands, shape ``[..., 4]`` in the order FL, FR, RL, RR."""
WheelTuple = tuple[float, float, float, float]
"""One set of wheel commands FL, FR, RL, RR as plain floats (the control loop's path)."""

LATERAL_SIGNS: NDArray[np.float64] = np.array(_LATERAL_SIGNS)
"""Sign of the y (right) command in each wheel, FL, FR, RL, RR (an array of
:data:`mecanum_mav.mecanum.wheels.LATERAL_SIGNS`)."""
ROTATION_SIGNS: NDArray[np.float64] = np.array(_ROTATION_SIGNS)
"""Sign of the clockwise rotation command in each wheel, FL, FR, RL, RR (an array of
:data:`mecanum_mav.mecanum.wheels.ROTATION_SIGNS`)."""

_INV_SQRT2 = 1.0 / math.sqrt(2.0)
_SCALAR_TYPES = frozenset({float, int, np.float64, np.float32, np.int64, np.int32})


class Desaturation(IntEnum):
    """How a mixer brings wheel commands back inside the limit (parameter ``MIX_DESAT``).

    PROPORTIONAL
        Scale all four wheels down together (WPILib ``desaturate``, the seeds' "normalize").
        Keeps every ratio between wheels, so direction *and* the translation:rotation ratio
        hold; the robot just goes slower.
    ROTATION_PRIORITY
        Keep the commanded rotation and shrink the translation along its own direction until
        the wheels fit (PX4 rover / multicopter mixers keep yaw). Direction of travel holds,
        speed of travel gives way to turning.
    TRANSLATION_PRIORITY
        Keep the commanded translation (limited to what the wheels can do) and shrink the
        rotation. Good for line following where the path matters more than the heading.
    """

    PROPORTIONAL = 0
    ROTATION_PRIORITY = 1
    TRANSLATION_PRIORITY = 2


# --------------------------------------------------------------------------- desaturation


def _zero_nonfinite_rows(wheels: Wheels) -> Wheels:
    """Rows (last axis) containing any non-finite value become all zeros."""
    finite = np.isfinite(wheels).all(axis=-1, keepdims=True)
    if finite.all():
        return wheels
    return np.where(finite, wheels, 0.0)


def _check_limit(limit: float) -> float:
    limit = float(limit)
    if not (math.isfinite(limit) and limit > 0.0):
        raise ValueError(f"limit must be a finite number > 0, got {limit!r}")
    return limit


def desaturate(wheels: ArrayLike, limit: float = 1.0) -> Wheels:
    """Scale all four wheels down together, only when one exceeds ``limit``.

    Args:
        wheels: wheel commands ``[..., 4]`` (FL, FR, RL, RR), any unit (normalized or m/s).
        limit: largest allowed magnitude, same unit as ``wheels``, > 0.

    Returns:
        ``[..., 4]``: unchanged where ``max|w| <= limit``, else ``w * limit / max|w|``, so the
        ratios between wheels (direction and translation:rotation) are kept. A row with a
        non-finite wheel becomes all zeros.
    """
    limit = _check_limit(limit)
    w = _zero_nonfinite_rows(np.asarray(wheels, dtype=np.float64))
    peak = np.abs(w).max(axis=-1, keepdims=True)
    scaled: Wheels = w * (limit / np.maximum(peak, limit))
    return scaled


def normalize(wheels: ArrayLike, always: bool = False) -> Wheels:
    """Normalize wheel commands to [-1, 1].

    Args:
        wheels: wheel commands ``[..., 4]`` (FL, FR, RL, RR).
        always: False (default) is :func:`desaturate` with limit 1. True is the "Simplistic
            control of Mecanum drive" variant (seed 002): scale *up or down* so the largest
            wheel is exactly 1, i.e. always full power in the commanded pattern.

    Returns:
        ``[..., 4]``. All-zero rows (and rows with a non-finite wheel) give zeros, never NaN
        (seed 002's sample code divides by zero there).
    """
    if not always:
        return desaturate(wheels, 1.0)
    w = _zero_nonfinite_rows(np.asarray(wheels, dtype=np.float64))
    peak = np.abs(w).max(axis=-1, keepdims=True)
    normalized: Wheels = np.divide(w, peak, out=np.zeros_like(w), where=peak > 0.0)
    return normalized


def desaturate_prioritized(
    translation: ArrayLike,
    rotation: ArrayLike,
    priority: Desaturation | int = Desaturation.ROTATION_PRIORITY,
    limit: float = 1.0,
) -> Wheels:
    """Combine a translation part and a rotation part of the wheel commands within ``limit``.

    Args:
        translation: the wheels' translation parts ``[..., 4]`` (any unit).
        rotation: the wheels' rotation parts ``[..., 4]`` (same unit).
        priority: a :class:`Desaturation`. The kept part is first limited on its own (scaled
            down together); the other part is then scaled by the largest ``s`` in [0, 1] with
            ``|kept + s * other| <= limit`` on every wheel, so it shrinks along its own
            direction. PROPORTIONAL is :func:`desaturate` of the sum.
        limit: largest allowed magnitude, > 0.

    Returns:
        ``[..., 4]`` wheel commands with ``max|w| <= limit``. Rows with a non-finite value give
        zeros (in PROPORTIONAL, also a sum that overflows, as the scalar version). Works for
        any wheel pattern (an off-centre centre of rotation included).
    """
    limit = _check_limit(limit)
    t = np.asarray(translation, dtype=np.float64)
    r = np.asarray(rotation, dtype=np.float64)
    priority = Desaturation(priority)
    if priority is Desaturation.PROPORTIONAL:
        with np.errstate(over="ignore"):  # a sum that overflows is not finite: zeros
            return desaturate(t + r, limit)
    kept, other = (r, t) if priority is Desaturation.ROTATION_PRIORITY else (t, r)
    kept, other = np.broadcast_arrays(kept, other)
    finite = np.isfinite(kept).all(axis=-1, keepdims=True) & np.isfinite(other).all(
        axis=-1, keepdims=True
    )
    kept = desaturate(np.where(finite, kept, 0.0), limit)
    other = np.where(finite, other, 0.0)
    magnitude = np.abs(other)
    # Per wheel, |kept + s*other| <= limit holds for s <= (limit - sign(other)*kept) / |other|.
    room = limit - np.sign(other) * kept
    with np.errstate(over="ignore"):  # a subnormal |other| gives an infinite bound: fine
        bound = np.divide(room, magnitude, out=np.full_like(room, np.inf), where=magnitude > 0)
    s = np.clip(bound.min(axis=-1, keepdims=True), 0.0, 1.0)
    result: Wheels = kept + s * other
    return result


def desaturate_prioritized_scalar(
    translation: Sequence[float],
    rotation: Sequence[float],
    priority: Desaturation | int = Desaturation.ROTATION_PRIORITY,
    limit: float = 1.0,
) -> WheelTuple:
    """:func:`desaturate_prioritized` for one set of plain floats (FL, FR, RL, RR), as a tuple:
    the same numbers without numpy (the control loop's path; numpy's fixed cost per call is
    most of the work for four wheels, several times more with cold caches).

    Args:
        translation, rotation: the wheels' two parts (4 each, any unit, the same for both).
        priority: a :class:`Desaturation` (see :func:`desaturate_prioritized`).
        limit: largest allowed magnitude, > 0.

    Returns:
        Wheel commands with ``max|w| <= limit``; four 0.0 if any value is not finite.
    """
    if limit != 1.0:
        limit = _check_limit(limit)
    t0, t1, t2, t3 = translation
    r0, r1, r2, r3 = rotation
    # x - x is 0.0 for finite x and NaN for NaN or inf (unrolled: this runs every tick).
    if (t0 - t0) + (t1 - t1) + (t2 - t2) + (t3 - t3) + (r0 - r0) + (r1 - r1) + (r2 - r2) + (
            r3 - r3) != 0.0:
        return _STOP
    if priority == 0:  # Desaturation.PROPORTIONAL
        w0, w1, w2, w3 = t0 + r0, t1 + r1, t2 + r2, t3 + r3
        if (w0 - w0) + (w1 - w1) + (w2 - w2) + (w3 - w3) != 0.0:  # a sum that overflowed
            return _STOP
        k = limit / max(abs(w0), abs(w1), abs(w2), abs(w3), limit)
        return w0 * k, w1 * k, w2 * k, w3 * k
    if priority == 1:  # Desaturation.ROTATION_PRIORITY: rotation kept
        k0, k1, k2, k3, o0, o1, o2, o3 = r0, r1, r2, r3, t0, t1, t2, t3
    else:
        k0, k1, k2, k3, o0, o1, o2, o3 = t0, t1, t2, t3, r0, r1, r2, r3
    k = limit / max(abs(k0), abs(k1), abs(k2), abs(k3), limit)
    k0, k1, k2, k3 = k0 * k, k1 * k, k2 * k, k3 * k
    # Per wheel, |kept + s*other| <= limit holds for s <= (limit - sign(other)*kept) / |other|.
    s = 1.0
    for held, part in ((k0, o0), (k1, o1), (k2, o2), (k3, o3)):
        if part > 0.0:
            bound = (limit - held) / part
        elif part < 0.0:
            bound = (limit + held) / -part
        else:
            continue
        if bound < s:
            s = bound
    if s < 0.0:
        s = 0.0
    return k0 + s * o0, k1 + s * o1, k2 + s * o2, k3 + s * o3


# --------------------------------------------------------------------------- scalar core


def _clamp1(v: float) -> float:
    return -1.0 if v < -1.0 else (1.0 if v > 1.0 else v)


def mix_pairs(a: float, b: float, r: float, priority: Desaturation | int) -> WheelTuple:
    """Desaturated wheel commands from the pair translations and the rotation, plain floats.

    Args:
        a: the FL/RR pair's translation, ``x + y`` (normalized, x forward, y right).
        b: the FR/RL pair's translation, ``x - y``.
        r: rotation, normalized, clockwise seen from above, in [-1, 1].
        priority: how translation and rotation share the wheels when they saturate.

    Returns:
        ``(FL, FR, RL, RR)``, each in [-1, 1] for ``|a|, |b|, |r| <= 1``. Closed forms of
        :func:`desaturate` and :func:`desaturate_prioritized` for the mecanum pattern, where
        every wheel's rotation part has magnitude ``|r|``; no checks (finite input expected).
    """
    t = max(abs(a), abs(b))
    ar = abs(r)
    if t + ar > 1.0:
        if priority == 0:  # proportional
            k = 1.0 / (t + ar)
            a, b, r = a * k, b * k, r * k
        elif priority == 1:  # rotation priority (|r| <= 1 already)
            k = (1.0 - ar) / t
            a, b = a * k, b * k
        else:  # translation priority
            if t > 1.0:
                a, b, t = a / t, b / t, 1.0
            r = math.copysign(1.0 - t, r) if ar > 0.0 else 0.0
    return (a + r, b - r, b + r, a - r)


_Scalar = float | int | np.floating[Any] | np.integer[Any]
"""What :data:`_SCALAR_TYPES` admits (exact types; ``float()`` takes each of them)."""


def _is_scalar(values: tuple[object, ...]) -> TypeGuard[tuple[_Scalar, ...]]:
    """True when every value's exact type is one of :data:`_SCALAR_TYPES` (plain numbers)."""
    return all(type(v) in _SCALAR_TYPES for v in values)


def _finite(a: float, b: float, c: float, d: float = 0.0) -> bool:
    isfinite = math.isfinite
    return isfinite(a) and isfinite(b) and isfinite(c) and isfinite(d)


_STOP: WheelTuple = (0.0, 0.0, 0.0, 0.0)


# --------------------------------------------------------------------------- scalar algorithms
# Plain floats in, a tuple out, no numpy: one command costs a few microseconds even with cold
# caches, which is what the 50 Hz control loop sees (numpy's per-call overhead is ~80 us cold).


def _cartesian_scalar(x: float, y: float, r: float, heading_deg: float, priority: int
                      ) -> WheelTuple:
    if not _finite(x, y, r, heading_deg):
        return _STOP
    xs, ys = _clamp1(x), _clamp1(y)
    if heading_deg:
        c, s = math.cos(math.radians(heading_deg)), math.sin(math.radians(heading_deg))
        xs, ys = xs * c + ys * s, ys * c - xs * s
    return mix_pairs(xs + ys, xs - ys, _clamp1(r), priority)


def _polar_2011_scalar(magnitude: float, direction_deg: float, r: float, priority: int
                       ) -> WheelTuple:
    if not _finite(magnitude, direction_deg, r):
        return _STOP
    m, d = _clamp1(magnitude), math.radians(direction_deg)
    x, y = m * math.cos(d), m * math.sin(d)
    return mix_pairs(x + y, x - y, _clamp1(r), priority)


def _max_speed_scaled_scalar(magnitude: float, direction_deg: float, r: float, priority: int
                             ) -> WheelTuple:
    if not _finite(magnitude, direction_deg, r):
        return _STOP
    d = math.radians(direction_deg)
    c, s = math.cos(d), math.sin(d)
    a, b = c + s, c - s  # max(|a|, |b|) >= 1 since a^2 + b^2 = 2
    k = _clamp1(magnitude) / max(abs(a), abs(b))
    return mix_pairs(a * k, b * k, _clamp1(r), priority)


def _holonomic_2010_scalar(magnitude: float, direction_deg: float, r: float) -> WheelTuple:
    if not _finite(magnitude, direction_deg, r):
        return _STOP
    m, d, r = _clamp1(magnitude) * _INV_SQRT2, math.radians(direction_deg), _clamp1(r)
    c, s = math.cos(d), math.sin(d)
    a, b = m * (c + s), m * (c - s)
    return (_clamp1(a + r), _clamp1(b - r), _clamp1(b + r), _clamp1(a - r))


# --------------------------------------------------------------------------- vector core


def _as_float(*values: ArrayLike) -> tuple[NDArray[np.float64], ...]:
    return tuple(np.asarray(v, dtype=np.float64) for v in values)


def _finite_mask(*values: NDArray[np.float64]) -> NDArray[np.bool_]:
    mask = np.isfinite(values[0])
    for v in values[1:]:
        mask = mask & np.isfinite(v)
    return mask


def _mix_vector(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    r: NDArray[np.float64],
    ok: NDArray[np.bool_],
    priority: Desaturation | int,
) -> Wheels:
    """Vector twin of :func:`mix_pairs`; rows where ``ok`` is False become zeros."""
    a, b, r, ok = np.broadcast_arrays(a, b, r, ok)
    a = np.where(ok, a, 0.0)
    b = np.where(ok, b, 0.0)
    r = np.where(ok, r, 0.0)
    translation = np.stack((a, b, b, a), axis=-1)
    rotation = r[..., None] * ROTATION_SIGNS
    return desaturate_prioritized(translation, rotation, priority)


def _clip1(v: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.clip(v, -1.0, 1.0)


# --------------------------------------------------------------------------- algorithms


def cartesian(
    x: ArrayLike,
    y: ArrayLike,
    rotation: ArrayLike,
    heading_deg: ArrayLike = 0.0,
    *,
    priority: Desaturation | int = Desaturation.PROPORTIONAL,
) -> Wheels:
    """Cartesian mixing (WPILib ``driveCartesian``), optionally field-oriented.

    Args:
        x: forward command in [-1, 1] (limited to it).
        y: right command in [-1, 1] (limited to it).
        rotation: clockwise rotation command in [-1, 1] (limited to it).
        heading_deg: the robot's heading in degrees clockwise from north. When non-zero,
            ``(x, y)`` is a field-frame command (x north, y east) and is rotated into the body
            frame: field-oriented driving. 0 means ``(x, y)`` is already body-frame FRD.
        priority: desaturation strategy (:class:`Desaturation`), default proportional.

    Returns:
        ``[..., 4]`` wheel commands FL, FR, RL, RR in [-1, 1], desaturated. Before
        desaturation FL = x + y + r, FR = x - y - r, RL = x - y + r, RR = x + y - r, so
        :func:`chassis_from_wheels` inverts it exactly where nothing saturated.
    """
    args = (x, y, rotation, heading_deg)
    if _is_scalar(args):
        xs, ys, rs, hs = args
        return np.array(_cartesian_scalar(float(xs), float(ys), float(rs), float(hs), priority))
    xa, ya, ra, ha = _as_float(x, y, rotation, heading_deg)
    ok = _finite_mask(xa, ya, ra, ha)
    xa, ya = _clip1(xa), _clip1(ya)
    h = np.radians(np.where(ok, ha, 0.0))
    c, s = np.cos(h), np.sin(h)
    xb, yb = xa * c + ya * s, ya * c - xa * s
    return _mix_vector(xb + yb, xb - yb, _clip1(ra), ok, priority)


def polar_2011(
    magnitude: ArrayLike,
    direction_deg: ArrayLike,
    rotation: ArrayLike,
    *,
    priority: Desaturation | int = Desaturation.PROPORTIONAL,
) -> Wheels:
    """The 2011 WPILib algorithm (``MecanumDrive_Polar``, seed 000).

    ``wheel = magnitude * sqrt(2) * sin(direction + 45 deg +/- ...) +/- rotation``, then
    normalized only when a wheel exceeds 1. The sqrt(2) factor gives full speed (1.0) along the
    four cardinal directions and sqrt(2)/2 on the diagonals; normalizing keeps the
    translation:rotation ratio.

    Args:
        magnitude: translation command in [-1, 1] (limited to it; negative reverses).
        direction_deg: direction of travel, degrees clockwise from the nose (0 forward,
            90 right).
        rotation: clockwise rotation command in [-1, 1] (limited to it).
        priority: desaturation strategy; WPILib's own is PROPORTIONAL (the default).

    Returns:
        ``[..., 4]`` wheel commands FL, FR, RL, RR in [-1, 1].
    """
    args = (magnitude, direction_deg, rotation)
    if _is_scalar(args):
        ms, ds, rs = args
        m, d, r = float(ms), float(ds), float(rs)
        return np.array(_polar_2011_scalar(m, d, r, priority))
    ma, da, ra = _as_float(magnitude, direction_deg, rotation)
    ok = _finite_mask(ma, da, ra)
    ma, dr = _clip1(ma), np.radians(np.where(ok, da, 0.0))
    x, y = ma * np.cos(dr), ma * np.sin(dr)
    return _mix_vector(x + y, x - y, _clip1(ra), ok, priority)


def max_speed_scaled(
    magnitude: ArrayLike,
    direction_deg: ArrayLike,
    rotation: ArrayLike,
    *,
    priority: Desaturation | int = Desaturation.PROPORTIONAL,
) -> Wheels:
    """Seed 004's direction-dependent scaling: the larger wheel pair reaches ``magnitude``.

    The pair commands ``A = sin(direction + 45)``, ``B = cos(direction + 45)`` (up to a common
    factor) are scaled by ``1 / max(|A|, |B|)`` (seed 004's cosecant "sawtooth"), so the faster
    pair always runs at ``magnitude`` whatever the direction; rotation is then added and the
    result desaturated. Compared with :func:`polar_2011`, wheel power is linear in magnitude in
    every direction (2011 reaches full power on the diagonals at magnitude 0.71).

    Args:
        magnitude: translation command in [-1, 1] (limited to it; negative reverses).
        direction_deg: degrees clockwise from the nose.
        rotation: clockwise rotation command in [-1, 1] (limited to it).
        priority: desaturation strategy (:class:`Desaturation`).

    Returns:
        ``[..., 4]`` wheel commands FL, FR, RL, RR in [-1, 1].
    """
    args = (magnitude, direction_deg, rotation)
    if _is_scalar(args):
        ms, ds, rs = args
        m, d, r = float(ms), float(ds), float(rs)
        return np.array(_max_speed_scaled_scalar(m, d, r, priority))
    ma, da, ra = _as_float(magnitude, direction_deg, rotation)
    ok = _finite_mask(ma, da, ra)
    dr = np.radians(np.where(ok, da, 0.0))
    c, s = np.cos(dr), np.sin(dr)
    a, b = c + s, c - s
    k = _clip1(ma) / np.maximum(np.abs(a), np.abs(b))
    return _mix_vector(a * k, b * k, _clip1(ra), ok, priority)


def holonomic_2010(magnitude: ArrayLike, direction_deg: ArrayLike, rotation: ArrayLike) -> Wheels:
    """The 2010 WPILib algorithm (``HolonomicDrive``, seed 000), kept for comparison.

    ``wheel = magnitude * cos(direction -/+ 45 deg) +/- rotation``, each wheel clipped to
    [-1, 1] on its own. Top speed is sqrt(2)/2 in every direction, and once a wheel clips (above
    magnitude ``1 - |rotation|`` on the diagonals) the translation:rotation relationship
    distorts: the robot is no longer strictly holonomic. Prefer :func:`polar_2011` or
    :func:`cartesian`.

    Args:
        magnitude: translation command in [-1, 1] (limited to it).
        direction_deg: degrees clockwise from the nose.
        rotation: clockwise rotation command in [-1, 1] (limited to it).

    Returns:
        ``[..., 4]`` wheel commands FL, FR, RL, RR, each clipped to [-1, 1].
    """
    args = (magnitude, direction_deg, rotation)
    if _is_scalar(args):
        ms, ds, rs = args
        m, d, r = float(ms), float(ds), float(rs)
        return np.array(_holonomic_2010_scalar(m, d, r))
    ma, da, ra = _as_float(magnitude, direction_deg, rotation)
    ok = _finite_mask(ma, da, ra)
    mv = np.where(ok, _clip1(ma), 0.0) * _INV_SQRT2
    dr = np.radians(np.where(ok, da, 0.0))
    rv = np.where(ok, _clip1(ra), 0.0)
    a, b = mv * (np.cos(dr) + np.sin(dr)), mv * (np.cos(dr) - np.sin(dr))
    return _clip1(np.stack((a + rv, b - rv, b + rv, a - rv), axis=-1))


def chassis_from_wheels(wheels: ArrayLike) -> NDArray[np.float64]:
    """Normalized forward kinematics: wheel commands -> chassis command.

    Args:
        wheels: ``[..., 4]`` wheel commands FL, FR, RL, RR (normalized, or any unit).

    Returns:
        ``[..., 3]`` = (x forward, y right, rotation clockwise) in the wheels' unit, the least
        squares solution ``x = mean(w)``, ``y = (FL - FR - RL + RR) / 4``,
        ``r = (FL - FR + RL - RR) / 4``. It is the exact inverse of :func:`cartesian` (heading
        0) where nothing saturated. The robot's speed as a fraction of full wheel speed is
        ``hypot(x, y)``.

    Raises:
        ValueError: a wheel value is not finite.
    """
    w = np.asarray(wheels, dtype=np.float64)
    if w.shape[-1:] != (4,):
        raise ValueError(f"wheels must have 4 values on the last axis, got shape {w.shape}")
    if not np.isfinite(w).all():
        raise ValueError("chassis_from_wheels: wheel values must be finite")
    fl, fr, rl, rr = w[..., 0], w[..., 1], w[..., 2], w[..., 3]
    return np.stack(
        ((fl + fr + rl + rr) * 0.25, (fl - fr - rl + rr) * 0.25, (fl - fr + rl - rr) * 0.25),
        axis=-1,
    )


PolarMixer = Callable[..., Wheels]

ALGORITHMS: dict[str, PolarMixer] = {
    "cartesian": cartesian,
    "polar_2011": polar_2011,
    "max_speed_scaled": max_speed_scaled,
    "holonomic_2010": holonomic_2010,
}
"""Mixing algorithms by name, in the order of the ``MIX_ALGO`` parameter (0, 1, 2, 3).

``cartesian`` takes (x, y, rotation[, heading_deg]); the others (magnitude, direction_deg,
rotation).
"""

ALGORITHM_NAMES: tuple[str, ...] = tuple(ALGORITHMS)
"""Algorithm names indexed by the ``MIX_ALGO`` parameter value."""


def wheels_from_stick(
    x: float,
    y: float,
    rotation: float,
    algorithm: str = "cartesian",
    *,
    heading_deg: float = 0.0,
    priority: Desaturation | int = Desaturation.PROPORTIONAL,
) -> WheelTuple:
    """The control loop's path: plain-float stick -> wheel commands as a tuple, no numpy.

    Same numbers as :func:`mix_stick` (which wraps it in an ndarray); see there for the
    arguments. Returns ``(FL, FR, RL, RR)`` in [-1, 1]; a stop for non-finite input.

    Raises:
        KeyError: unknown algorithm name.
    """
    if algorithm == "cartesian":
        return _cartesian_scalar(x, y, rotation, heading_deg, priority)
    scalar = _POLAR_SCALAR[algorithm]
    if not _finite(x, y, rotation, heading_deg):
        return _STOP
    magnitude = math.hypot(x, y)
    direction_deg = math.degrees(math.atan2(y, x)) - heading_deg
    if scalar is _holonomic_2010_scalar:
        return _holonomic_2010_scalar(magnitude, direction_deg, rotation)
    return scalar(magnitude, direction_deg, rotation, priority)


_POLAR_SCALAR: dict[str, Callable[..., WheelTuple]] = {
    "polar_2011": _polar_2011_scalar,
    "max_speed_scaled": _max_speed_scaled_scalar,
    "holonomic_2010": _holonomic_2010_scalar,
}


def mix_stick(
    x: float,
    y: float,
    rotation: float,
    algorithm: str = "cartesian",
    *,
    heading_deg: float = 0.0,
    priority: Desaturation | int = Desaturation.PROPORTIONAL,
) -> Wheels:
    """Stick axes -> wheel commands with a named algorithm (the drive path's entry point).

    Args:
        x: forward stick, normalized [-1, 1].
        y: right stick, normalized [-1, 1].
        rotation: clockwise rotation stick, normalized [-1, 1].
        algorithm: a key of :data:`ALGORITHMS`. The polar algorithms get
            ``magnitude = hypot(x, y)`` (limited to 1) and
            ``direction_deg = degrees(atan2(y, x))`` (seed 001's joystick conversion).
        heading_deg: robot heading, degrees clockwise from north, for field-oriented driving
            (0: the stick is in the body frame). Polar algorithms subtract it from the
            direction; ``cartesian`` rotates (x, y).
        priority: desaturation strategy (ignored by ``holonomic_2010``, which clips).

    Returns:
        ``[4]`` wheel commands FL, FR, RL, RR in [-1, 1]; a stop for non-finite input.
        :func:`wheels_from_stick` gives the same as a tuple without numpy.

    Raises:
        KeyError: unknown algorithm name.
    """
    return np.array(wheels_from_stick(x, y, rotation, algorithm, heading_deg=heading_deg,
                                      priority=priority))
