"""Speed envelopes of the mixing algorithms: the numbers behind seed 000's illustrations.

"Robot speed" is the translation speed that the wheels' forward kinematics give, as a fraction
of full wheel speed: ``hypot(x, y)`` of
:func:`mecanum_mav.mecanum.mixing.chassis_from_wheels`. It is
what Anderson's comparison of the 2010 and 2011 WPILib algorithms plots against the commanded
velocity (magnitude) and heading (direction, degrees clockwise from the nose).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mecanum_mav.mecanum.mixing import ALGORITHMS, cartesian, chassis_from_wheels

__all__ = [
    "ENVELOPE_ALGORITHMS",
    "non_clipping_limit_2010",
    "robot_speed",
    "speed_grid",
    "square_stick",
]

ENVELOPE_ALGORITHMS: tuple[str, ...] = tuple(ALGORITHMS)
"""Names accepted by :func:`robot_speed`: those of :data:`mecanum_mav.mecanum.mixing.ALGORITHMS`."""


def square_stick(
    velocity: ArrayLike, heading_deg: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Stick (x, y) of a square-travel joystick deflected ``velocity`` of the way to its edge.

    For the Cartesian mixer the natural domain is the square ``|x|, |y| <= 1``: at velocity 1
    the stick touches the square's edge in the given heading (length up to sqrt(2) on the
    diagonals). Normalized, x forward, y right.
    """
    h = np.radians(np.asarray(heading_deg, dtype=np.float64))
    c, s = np.cos(h), np.sin(h)
    reach = np.asarray(velocity, dtype=np.float64) / np.maximum(np.abs(c), np.abs(s))
    return reach * c, reach * s


def robot_speed(
    algorithm: str, velocity: ArrayLike, heading_deg: ArrayLike, rotation: ArrayLike = 0.0
) -> NDArray[np.float64]:
    """Translation speed (fraction of full wheel speed) an algorithm gives for a command.

    Args:
        algorithm: a key of :data:`mecanum_mav.mecanum.mixing.ALGORITHMS`. The polar algorithms take
            ``velocity`` as magnitude; ``cartesian`` takes the square stick of
            :func:`square_stick`.
        velocity: commanded velocity (magnitude), [0, 1].
        heading_deg: commanded heading, degrees clockwise from the nose.
        rotation: commanded clockwise rotation, [-1, 1].

    Returns:
        Speed, broadcast shape of the inputs. Not a velocity: the direction is dropped.
    """
    if algorithm == "cartesian":
        x, y = square_stick(velocity, heading_deg)
        wheels = cartesian(x, y, np.asarray(rotation, dtype=np.float64))
    else:
        mixer = ALGORITHMS[algorithm]
        wheels = mixer(
            np.asarray(velocity, dtype=np.float64), np.asarray(heading_deg, dtype=np.float64),
            np.asarray(rotation, dtype=np.float64),
        )
    chassis = chassis_from_wheels(wheels)
    return np.hypot(chassis[..., 0], chassis[..., 1])


def non_clipping_limit_2010(heading_deg: ArrayLike, rotation: ArrayLike) -> NDArray[np.float64]:
    """Largest velocity at which no wheel of the 2010 algorithm clips (seed 000, Illust. 3).

    A 2010 wheel is ``v * cos(heading -/+ 45 deg) +/- rotation``; it clips once the largest
    translation part ``v * max(|cos(h - 45)|, |cos(h + 45)|)`` exceeds ``1 - |rotation|``.
    Returns that velocity, capped at 1 (the magnitude limit): 0.71 on the diagonals for
    rotation 0.29, and 1.0 on the cardinals.
    """
    h = np.radians(np.asarray(heading_deg, dtype=np.float64))
    pair = np.maximum(np.abs(np.cos(h - np.pi / 4)), np.abs(np.cos(h + np.pi / 4)))
    room = 1.0 - np.abs(np.asarray(rotation, dtype=np.float64))
    return np.minimum(room / pair, 1.0)


def speed_grid(
    algorithm: str, rotation: float, n_velocity: int = 41, n_heading: int = 181
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Velocity x heading grid of :func:`robot_speed` for one rotation.

    Returns:
        ``(velocity, heading_deg, speed)``, each ``[n_velocity, n_heading]``; velocity spans
        [0, 1] and heading [0, 360] degrees.
    """
    velocity, heading = np.meshgrid(
        np.linspace(0.0, 1.0, n_velocity), np.linspace(0.0, 360.0, n_heading), indexing="ij"
    )
    return velocity, heading, robot_speed(algorithm, velocity, heading, rotation)
