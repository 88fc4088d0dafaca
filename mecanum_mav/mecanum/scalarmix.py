"""The mixing algorithms on plain floats: the control loop's path (no numpy).

One command in, a tuple ``(FL, FR, RL, RR)`` out, in a few microseconds even with cold caches,
which is what the 50 Hz control loop sees (numpy's per-call overhead is ~80 us cold). The same
numbers as the array algorithms of :mod:`mecanum_mav.mecanum.mixing` (which call these for
plain-number arguments); frames, signs and bad input as described there: x forward, y right,
rotation clockwise, a polar ``direction_deg`` clockwise from the nose; a non-finite input gives
four 0.0, inputs outside [-1, 1] are limited to it.

:func:`wheels_from_stick` is the entry point: stick axes and an algorithm's name.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from mecanum_mav.mecanum.desaturation import STOP as _STOP
from mecanum_mav.mecanum.desaturation import Desaturation, WheelTuple, mix_pairs

__all__ = [
    "INV_SQRT2",
    "cartesian_scalar",
    "holonomic_2010_scalar",
    "max_speed_scaled_scalar",
    "polar_2011_scalar",
    "wheels_from_stick",
]

INV_SQRT2 = 1.0 / math.sqrt(2.0)
"""1 / sqrt(2): the 2010 algorithm's top speed in every direction."""


def _clamp1(v: float) -> float:
    return -1.0 if v < -1.0 else (1.0 if v > 1.0 else v)


def _finite(a: float, b: float, c: float, d: float = 0.0) -> bool:
    isfinite = math.isfinite
    return isfinite(a) and isfinite(b) and isfinite(c) and isfinite(d)


# --------------------------------------------------------------------------- the algorithms


def cartesian_scalar(x: float, y: float, r: float, heading_deg: float, priority: int
                     ) -> WheelTuple:
    """:func:`~mecanum_mav.mecanum.mixing.cartesian` for plain floats: x forward, y right,
    r clockwise (normalized), ``heading_deg`` clockwise from north (0: body frame)."""
    if not _finite(x, y, r, heading_deg):
        return _STOP
    xs, ys = _clamp1(x), _clamp1(y)
    if heading_deg:
        c, s = math.cos(math.radians(heading_deg)), math.sin(math.radians(heading_deg))
        xs, ys = xs * c + ys * s, ys * c - xs * s
    return mix_pairs(xs + ys, xs - ys, _clamp1(r), priority)


def polar_2011_scalar(magnitude: float, direction_deg: float, r: float, priority: int
                      ) -> WheelTuple:
    """:func:`~mecanum_mav.mecanum.mixing.polar_2011` for plain floats (``direction_deg``
    clockwise from the nose)."""
    if not _finite(magnitude, direction_deg, r):
        return _STOP
    m, d = _clamp1(magnitude), math.radians(direction_deg)
    x, y = m * math.cos(d), m * math.sin(d)
    return mix_pairs(x + y, x - y, _clamp1(r), priority)


def max_speed_scaled_scalar(magnitude: float, direction_deg: float, r: float, priority: int
                            ) -> WheelTuple:
    """:func:`~mecanum_mav.mecanum.mixing.max_speed_scaled` for plain floats."""
    if not _finite(magnitude, direction_deg, r):
        return _STOP
    d = math.radians(direction_deg)
    c, s = math.cos(d), math.sin(d)
    a, b = c + s, c - s  # max(|a|, |b|) >= 1 since a^2 + b^2 = 2
    k = _clamp1(magnitude) / max(abs(a), abs(b))
    return mix_pairs(a * k, b * k, _clamp1(r), priority)


def holonomic_2010_scalar(magnitude: float, direction_deg: float, r: float) -> WheelTuple:
    """:func:`~mecanum_mav.mecanum.mixing.holonomic_2010` for plain floats (each wheel
    clipped; no desaturation strategy)."""
    if not _finite(magnitude, direction_deg, r):
        return _STOP
    m, d, r = _clamp1(magnitude) * INV_SQRT2, math.radians(direction_deg), _clamp1(r)
    c, s = math.cos(d), math.sin(d)
    a, b = m * (c + s), m * (c - s)
    return (_clamp1(a + r), _clamp1(b - r), _clamp1(b + r), _clamp1(a - r))


_POLAR_SCALAR: dict[str, Callable[..., WheelTuple]] = {
    "polar_2011": polar_2011_scalar,
    "max_speed_scaled": max_speed_scaled_scalar,
    "holonomic_2010": holonomic_2010_scalar,
}


# --------------------------------------------------------------------------- by name


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

    Same numbers as :func:`~mecanum_mav.mecanum.mixing.mix_stick` (which wraps it in an
    ndarray); see there for the arguments. Returns ``(FL, FR, RL, RR)`` in [-1, 1]; a stop
    for non-finite input.

    Raises:
        KeyError: unknown algorithm name.
    """
    if algorithm == "cartesian":
        return cartesian_scalar(x, y, rotation, heading_deg, priority)
    scalar = _POLAR_SCALAR[algorithm]
    # (no check here: a non-finite x or y makes the magnitude or the direction non-finite, a
    # non-finite heading the direction, and each polar function stops on its own arguments)
    magnitude = math.hypot(x, y)
    direction_deg = math.degrees(math.atan2(y, x)) - heading_deg
    if scalar is holonomic_2010_scalar:
        return holonomic_2010_scalar(magnitude, direction_deg, rotation)
    return scalar(magnitude, direction_deg, rotation, priority)
