"""The four wheels: their order, their names and the "X" roller sign pattern.

The one definition of these facts (see CONVENTIONS.md, "Wheels"); everything else imports
them. Plain tuples and no imports from the package, so that ``mecanum_mav/__init__.py`` can
re-export :data:`WHEEL_NAMES` without an import cycle.

- Order everywhere (the last axis of every wheel array, parameter groups, CSV columns):
  front left, front right, rear left, rear right (FL, FR, RL, RR).
- Rollers in the usual "X" arrangement, with x forward, y right and r clockwise (body FRD,
  normalized or m/s and rad/s scaled by the wheel's lever arm)::

      FL = x + y + r    FR = x - y - r    RL = x - y + r    RR = x + y - r

  :data:`LATERAL_SIGNS` and :data:`ROTATION_SIGNS` hold the signs of y and r in that order.
  A positive wheel command rolls the robot forward; mirrored motors are handled at the PWM
  edge (``MOT_x_REV``), never here.
"""

from __future__ import annotations

from typing import NamedTuple

__all__ = [
    "CORNER_SIGNS",
    "LATERAL_SIGNS",
    "ROTATION_SIGNS",
    "WHEEL_KEYS",
    "WHEEL_NAMES",
    "WheelQuad",
]


class WheelQuad(NamedTuple):
    """One number per wheel, in wheel order: a normalized command in [-1, 1], a surface speed
    in m/s or a distance in m, as the name of the value holding it says (``wheels``,
    ``wheel_speeds_mps``, ``wheel_distances_m``). A tuple, so it unpacks and compares as one."""

    fl: float
    fr: float
    rl: float
    rr: float

WHEEL_NAMES: tuple[str, str, str, str] = ("front_left", "front_right", "rear_left", "rear_right")
"""Wheel order used on the last axis of every wheel array."""

WHEEL_KEYS: tuple[str, str, str, str] = ("FL", "FR", "RL", "RR")
"""Abbreviations of :data:`WHEEL_NAMES`, same order: the infixes of the parameter names
(``MOT_FL_CH``) and the suffixes of the CLI's CSV columns."""

LATERAL_SIGNS: tuple[float, float, float, float] = (1.0, -1.0, -1.0, 1.0)
"""Sign of the y (right) command in each wheel, FL, FR, RL, RR: a wheel rolls at
``v_x + s_i * v_y`` (body FRD) of the velocity at its contact point (the roller signs)."""

ROTATION_SIGNS: tuple[float, float, float, float] = (1.0, -1.0, 1.0, -1.0)
"""Sign of the clockwise rotation command in each wheel, FL, FR, RL, RR."""

_Corner = tuple[float, float]

CORNER_SIGNS: tuple[_Corner, _Corner, _Corner, _Corner] = (
    (1.0, -1.0), (1.0, 1.0), (-1.0, -1.0), (-1.0, 1.0)
)
"""Where each wheel sits, FL, FR, RL, RR: the signs of its (x forward, y right) position from
the robot centre, body FRD. With these, ``ROTATION_SIGNS[i]`` is the sign of
``LATERAL_SIGNS[i] * x_i - y_i``, the rotation column of the kinematics."""
