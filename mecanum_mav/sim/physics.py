"""Which chassis the simulated board drives: :data:`PHYSICS` names them, :func:`make_chassis`
builds one from the parameters.

``kinematic`` (the default) is :class:`~mecanum_mav.sim.chassis.SimChassis`: motors with lag,
encoders, slip as noise, the pose moved by the wheels' forward kinematics; fast and exact,
with no inertia or roller contact. ``mujoco`` is the physics-grade chassis
(:mod:`mecanum_mav.sim.mujocochassis`): a rigid body on four wheels with passive rollers in
contact with the floor, simulated by MuJoCo; it needs the optional extra
(``pip install 'mecanum-mav[physics]'``). Both have the interface :class:`Chassis` states,
so the board, its telemetry and every harness work with either.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.sim.chassis import ORIGIN_POSE, SimChassis

if TYPE_CHECKING:
    from mecanum_mav.config.params import Params

__all__ = [
    "CONTACTS_PERIOD_S",
    "DEFAULT_PHYSICS",
    "MIN_REAL_TIME_FACTOR",
    "PHYSICS",
    "Chassis",
    "PhysicsUnavailableError",
    "WheelContact",
    "contacts_of",
    "make_chassis",
    "mujoco_real_time_factor",
    "require_mujoco",
]

PHYSICS = ("kinematic", "mujoco")
"""The chassis models, by name (``sim --physics NAME``)."""
DEFAULT_PHYSICS = "kinematic"
MIN_REAL_TIME_FACTOR = 3.0
"""The MuJoCo chassis must run at least this many times faster than real time (room for the
tests and for a digital twin); ``sim --physics mujoco`` warns below it."""


class PhysicsUnavailableError(RuntimeError):
    """The chassis asked for needs a package that is not installed (the message says which
    and how to install it)."""


class WheelContact(NamedTuple):
    """One wheel's contact with the floor: ``normal_n`` the normal force (N) summed over its
    rollers touching the floor, ``slip_mps`` how fast its contact points move over the floor
    (m/s), ``slipping`` whether that is a slip (the chassis's threshold)."""

    normal_n: float
    slip_mps: float
    slipping: bool


CONTACTS_PERIOD_S = 0.1
"""How often a chassis's wheel contacts are read and sent (seconds; 10 Hz): the simulated
board's DEBUG_VECTs, the twin's bridge's record and its truth publisher alike."""

Contacts = Callable[[], tuple[WheelContact, WheelContact, WheelContact, WheelContact]]
"""A chassis's way to read its wheels' contacts now (FL, FR, RL, RR)."""


def contacts_of(chassis: Chassis) -> Contacts | None:
    """The chassis's ``wheel_contacts`` method where it has wheel contacts (the MuJoCo
    chassis), else None (the kinematic one); ask once, then call it only when needed: the
    step is not touched."""
    reader: Contacts | None = getattr(chassis, "wheel_contacts", None)
    return reader if callable(reader) else None


class Chassis(Protocol):
    """What the simulated board uses of a chassis. Frames and units as
    :class:`~mecanum_mav.sim.chassis.SimChassis`: pose local NED (m, yaw rad clockwise from
    north), velocities body FRD, wheels FL, FR, RL, RR, positive rolls the robot forward.
    Optional: ``wheel_contacts()``, read through :func:`contacts_of`."""

    @property
    def pose(self) -> Pose2d:
        """True pose, local NED."""

    @property
    def velocity_body(self) -> tuple[float, float]:
        """True velocity of the robot centre, body FRD (forward, right m/s)."""

    @property
    def yaw_rate(self) -> float:
        """True yaw rate, rad/s clockwise seen from above."""

    @property
    def roll_pitch(self) -> tuple[float, float]:
        """True roll and pitch, radians (FRD: roll right side down, pitch nose up)."""

    @property
    def wheel_speeds_mps(self) -> tuple[float, float, float, float]:
        """Wheel surface speeds, m/s (wheel, not ground)."""

    @property
    def wheel_distances_m(self) -> tuple[float, float, float, float]:
        """Cumulative encoder distances, metres rolled (wheel, not ground)."""

    @property
    def time_s(self) -> float:
        """Simulated time, seconds."""

    def step(self, dt_s: float, wheel_commands: Sequence[float]) -> None:
        """Advance ``dt_s`` seconds with four normalized wheel commands held (limited to
        [-1, 1]; non-finite reads 0)."""


def make_chassis(params: Params, pose: Pose2d = ORIGIN_POSE,
                 physics: str = DEFAULT_PHYSICS) -> Chassis:
    """The chassis named ``physics`` (:data:`PHYSICS`), built from ``params``, at ``pose``.

    Raises:
        ValueError: an unknown name.
        PhysicsUnavailableError: ``mujoco`` without the ``physics`` extra installed.
    """
    if physics == "kinematic":
        return SimChassis.from_params(params, pose)
    if physics == "mujoco":
        chassis: Chassis = _mujoco().MujocoChassis.from_params(params, pose)
        return chassis
    raise ValueError(f"unknown physics {physics!r}: one of {', '.join(PHYSICS)}")


def mujoco_real_time_factor(params: Params, seconds: float = 2.0) -> float:
    """Simulated seconds per wall second of the MuJoCo chassis stepped at ``SIM_RATE``
    (:func:`mecanum_mav.sim.mujocochassis.real_time_factor`).

    Raises:
        PhysicsUnavailableError: without the ``physics`` extra installed.
    """
    factor: float = _mujoco().real_time_factor(params, seconds)
    return factor


def require_mujoco() -> None:
    """Check that the MuJoCo chassis can be built here (before starting what needs it).

    Raises:
        PhysicsUnavailableError: without the ``physics`` extra installed (the install hint).
    """
    _mujoco()


def _mujoco() -> Any:
    """The module :mod:`mecanum_mav.sim.mujocochassis`, imported only when asked for (mujoco
    is an optional extra); PhysicsUnavailableError with the install hint without it."""
    try:
        return importlib.import_module("mecanum_mav.sim.mujocochassis")
    except ImportError as exc:  # (mujoco itself missing)
        raise PhysicsUnavailableError(
            f"the MuJoCo chassis needs the 'mujoco' package ({exc}): "
            "pip install 'mecanum-mav[physics]'") from exc
