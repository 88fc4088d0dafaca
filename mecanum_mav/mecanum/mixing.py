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

The rooms of mixing, each re-exported here (import from this module):

- this module: the algorithms on numpy arrays (:func:`cartesian`, :func:`polar_2011`,
  :func:`max_speed_scaled`, :func:`holonomic_2010`), forward kinematics
  (:func:`chassis_from_wheels`), the algorithms by name (:data:`ALGORITHMS`, :func:`mix_stick`);
- :mod:`mecanum_mav.mecanum.scalarmix`: the same algorithms on plain floats, the control
  loop's path (:func:`wheels_from_stick`);
- :mod:`mecanum_mav.mecanum.desaturation`: :class:`Desaturation` and the desaturation
  functions, numpy and plain-float, and :func:`mix_pairs`, the mecanum pattern's closed form;
- :mod:`mecanum_mav.mecanum.shaping`: input shaping for the drive path (deadband, expo,
  square stick to circle).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeGuard

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mecanum_mav.mecanum.desaturation import (
    Desaturation,
    Wheels,
    desaturate,
    desaturate_prioritized,
    desaturate_prioritized_scalar,
    mix_pairs,
    normalize,
)
from mecanum_mav.mecanum.desaturation import (
    WheelTuple as WheelTuple,  # (re-exported: the control loop imports it from here)
)
from mecanum_mav.mecanum.scalarmix import (
    INV_SQRT2,
    cartesian_scalar,
    holonomic_2010_scalar,
    max_speed_scaled_scalar,
    polar_2011_scalar,
    wheels_from_stick,
)
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

LATERAL_SIGNS: NDArray[np.float64] = np.array(_LATERAL_SIGNS)
"""Sign of the y (right) command in each wheel, FL, FR, RL, RR (an array of
:data:`mecanum_mav.mecanum.wheels.LATERAL_SIGNS`)."""
ROTATION_SIGNS: NDArray[np.float64] = np.array(_ROTATION_SIGNS)
"""Sign of the clockwise rotation command in each wheel, FL, FR, RL, RR (an array of
:data:`mecanum_mav.mecanum.wheels.ROTATION_SIGNS`)."""

_SCALAR_TYPES = frozenset({float, int, np.float64, np.float32, np.int64, np.int32})

_Scalar = float | int | np.floating[Any] | np.integer[Any]
"""What :data:`_SCALAR_TYPES` admits (exact types; ``float()`` takes each of them)."""


def _is_scalar(values: tuple[object, ...]) -> TypeGuard[tuple[_Scalar, ...]]:
    """True when every value's exact type is one of :data:`_SCALAR_TYPES` (plain numbers)."""
    return all(type(v) in _SCALAR_TYPES for v in values)


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
        return np.array(cartesian_scalar(float(xs), float(ys), float(rs), float(hs), priority))
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
        return np.array(polar_2011_scalar(m, d, r, priority))
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
        return np.array(max_speed_scaled_scalar(m, d, r, priority))
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
        return np.array(holonomic_2010_scalar(m, d, r))
    ma, da, ra = _as_float(magnitude, direction_deg, rotation)
    ok = _finite_mask(ma, da, ra)
    mv = np.where(ok, _clip1(ma), 0.0) * INV_SQRT2
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
        ValueError: the last axis does not hold 4 values, or a wheel value is not finite.
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
