"""Stick input shaping for the drive path: deadband, expo, square stick to circle.

All inputs are normalized stick axes in [-1, 1] (x forward, y right, r clockwise). Each function
takes a float (and returns a float) or a numpy array (and returns an array of the same shape).
Non-finite input is propagated by :func:`deadband` and :func:`expo` (the mixers then read the
whole command as a stop); :func:`shape_stick`, the one the drive path calls, returns an
all-zero command when any axis is non-finite.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["deadband", "expo", "shape_stick", "square_to_circle"]

FloatOrArray = float | NDArray[np.float64]
_SCALAR_TYPES = frozenset({float, int, np.float64, np.float32})


def deadband(value: ArrayLike, deadband: float, max_magnitude: float = 1.0) -> FloatOrArray:
    """Zero ``value`` inside ``[-deadband, deadband]`` and rescale the rest (WPILib style).

    Outside the band the output is ``sign(v) * max_magnitude * (|v| - deadband) /
    (max_magnitude - deadband)``, so it starts at 0 at the edge of the band (no jump) and still
    reaches ``max_magnitude`` at full stick. Unit: that of ``value`` (normalized stick).

    Args:
        value: stick value(s).
        deadband: half-width of the dead zone, ``0 <= deadband < max_magnitude``.
        max_magnitude: the stick's full scale (1 for a normalized axis).

    Raises:
        ValueError: the band is negative, non-finite or not below ``max_magnitude``.
    """
    if not (0.0 <= deadband < max_magnitude and math.isfinite(max_magnitude)):
        raise ValueError(f"deadband must be in [0, {max_magnitude}), got {deadband!r}")
    gain = max_magnitude / (max_magnitude - deadband)
    if type(value) in _SCALAR_TYPES:
        v = float(value)  # type: ignore[arg-type]  # type() checked
        if abs(v) <= deadband:
            return 0.0
        return math.copysign((abs(v) - deadband) * gain, v)
    a = np.asarray(value, dtype=np.float64)
    magnitude = np.abs(a)
    return np.where(magnitude <= deadband, 0.0, np.sign(a) * (magnitude - deadband) * gain)


def expo(value: ArrayLike, expo: float) -> FloatOrArray:
    """Cubic expo curve ``(1 - e) * v + e * v**3`` (PX4 ``math::expo``).

    ``e = 0`` is linear; ``e = 1`` is a pure cubic. Fine control near centre, full output at
    full stick: ``expo(+/-1) = +/-1`` for every ``e``. Unit: normalized stick, [-1, 1].

    Args:
        value: stick value(s) in [-1, 1].
        expo: curvature ``e`` in [0, 1].

    Raises:
        ValueError: ``expo`` outside [0, 1].
    """
    if not 0.0 <= expo <= 1.0:
        raise ValueError(f"expo must be in [0, 1], got {expo!r}")
    if type(value) in _SCALAR_TYPES:
        v = float(value)  # type: ignore[arg-type]  # type() checked
        return (1.0 - expo) * v + expo * v * v * v
    a = np.asarray(value, dtype=np.float64)
    return (1.0 - expo) * a + expo * a**3


def square_to_circle(x: ArrayLike, y: ArrayLike) -> tuple[FloatOrArray, FloatOrArray]:
    """Clamp a square stick's (x, y) onto the unit disc (seed 001).

    A stick that moves in a square reaches magnitude sqrt(2) in its corners; this scales any
    vector longer than 1 back to length 1, keeping its direction, so a corner becomes a
    full-speed diagonal instead of an over-range command. Shorter vectors are unchanged.

    Returns:
        ``(x, y)`` as floats for float input, arrays for array input. Normalized, FRD.
    """
    if type(x) in _SCALAR_TYPES and type(y) in _SCALAR_TYPES:
        fx, fy = float(x), float(y)  # type: ignore[arg-type]  # type() checked
        length = math.hypot(fx, fy)
        return (fx / length, fy / length) if length > 1.0 else (fx, fy)
    xa, ya = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    scale = 1.0 / np.maximum(np.hypot(xa, ya), 1.0)
    return xa * scale, ya * scale


def shape_stick(
    x: float,
    y: float,
    r: float,
    *,
    deadband_width: float = 0.0,
    expo_weight: float = 0.0,
    circle: bool = True,
) -> tuple[float, float, float]:
    """The drive path's stick shaping: per-axis deadband and expo, then the circle clamp.

    Plain floats only (it runs once per stick message, so it avoids numpy and per-axis
    re-validation); same numbers as :func:`deadband`, :func:`expo` and
    :func:`square_to_circle` applied in that order.

    Args:
        x, y, r: stick axes, normalized, x forward, y right, r clockwise (limited to [-1, 1]).
        deadband_width: per-axis dead zone in [0, 1) (parameter ``INP_DEADBAND``).
        expo_weight: cubic expo weight in [0, 1] (parameter ``INP_EXPO``).
        circle: clamp the (x, y) magnitude to 1 (parameter ``INP_CIRCLE``).

    Returns:
        ``(x, y, r)`` normalized. Any non-finite input gives ``(0.0, 0.0, 0.0)``: a stop.

    Raises:
        ValueError: ``deadband_width`` or ``expo_weight`` out of range.
    """
    isfinite = math.isfinite
    if not (isfinite(x) and isfinite(y) and isfinite(r)):
        return 0.0, 0.0, 0.0
    if not (0.0 <= deadband_width < 1.0 and 0.0 <= expo_weight <= 1.0):
        raise ValueError(f"deadband {deadband_width!r} or expo {expo_weight!r} out of range")
    gain = 1.0 / (1.0 - deadband_width)
    sx = _shape_axis(x, deadband_width, gain, expo_weight)
    sy = _shape_axis(y, deadband_width, gain, expo_weight)
    sr = _shape_axis(r, deadband_width, gain, expo_weight)
    if circle:
        length_sq = sx * sx + sy * sy
        if length_sq > 1.0:
            length = math.sqrt(length_sq)
            sx, sy = sx / length, sy / length
    return sx, sy, sr


def _shape_axis(v: float, band: float, gain: float, weight: float) -> float:
    """One axis: limit to [-1, 1], rescaled deadband, cubic expo."""
    magnitude = -v if v < 0.0 else v
    if magnitude <= band:
        return 0.0
    magnitude = ((1.0 if magnitude > 1.0 else magnitude) - band) * gain
    magnitude = (1.0 - weight) * magnitude + weight * magnitude * magnitude * magnitude
    return -magnitude if v < 0.0 else magnitude
