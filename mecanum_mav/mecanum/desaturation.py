"""Desaturation: bringing four wheel commands back inside their limit, and how translation and
rotation share the wheels when they do not fit (parameter ``MIX_DESAT``).

Three forms of the same numbers:

- :func:`desaturate`, :func:`normalize` and :func:`desaturate_prioritized` take numpy arrays
  (``[..., 4]``, FL, FR, RL, RR) and work for any wheel pattern;
- :func:`desaturate_prioritized_scalar` takes plain floats (the control loop's path, no numpy);
- :func:`mix_pairs` is the closed form for the mecanum pattern, where the largest wheel
  magnitude is exactly ``max(|x + y|, |x - y|) + |r|`` (see :mod:`mecanum_mav.mecanum.mixing`),
  called by every scalar mixer (:mod:`mecanum_mav.mecanum.scalarmix`).

Bad input: a row (or set of floats) with any non-finite value gives zeros, never NaN.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from enum import IntEnum

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "STOP",
    "Desaturation",
    "WheelTuple",
    "Wheels",
    "desaturate",
    "desaturate_prioritized",
    "desaturate_prioritized_scalar",
    "mix_pairs",
    "normalize",
]

Wheels = NDArray[np.float64]
"""Wheel commands, shape ``[..., 4]`` in the order FL, FR, RL, RR."""
WheelTuple = tuple[float, float, float, float]
"""One set of wheel commands FL, FR, RL, RR as plain floats (the control loop's path)."""
STOP: WheelTuple = (0.0, 0.0, 0.0, 0.0)
"""The wheel commands of a command that cannot be mixed (a non-finite value): stopped."""


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


# ------------------------------------------------------------------ numpy arrays, any pattern


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


# --------------------------------------------------------------------------- plain floats


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
    if limit != 1.0 or type(limit) is not float:  # (a float32 1.0 would make float32 wheels)
        limit = _check_limit(limit)
    t0, t1, t2, t3 = translation
    r0, r1, r2, r3 = rotation
    # x - x is 0.0 for finite x and NaN for NaN or inf (unrolled: this runs every tick).
    if (t0 - t0) + (t1 - t1) + (t2 - t2) + (t3 - t3) + (r0 - r0) + (r1 - r1) + (r2 - r2) + (
            r3 - r3) != 0.0:
        return STOP
    if priority == 0:  # Desaturation.PROPORTIONAL
        w0, w1, w2, w3 = t0 + r0, t1 + r1, t2 + r2, t3 + r3
        if (w0 - w0) + (w1 - w1) + (w2 - w2) + (w3 - w3) != 0.0:  # a sum that overflowed
            return STOP
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
            r = math.copysign(1.0 - t, r)  # (|r| == 0 here only when t was > 1: 0.0 now)
    return (a + r, b - r, b + r, a - r)
