"""Simulated mecanum chassis: motors with lag, wheel encoders, slip and the true pose.

Pure physics, no I/O. Frames and units (see CONVENTIONS.md): the pose is in the local NED
frame (x north, y east, metres; yaw radians clockwise from north); velocities are in the body
FRD frame (vx forward, vy right, m/s; yaw rate rad/s clockwise); wheel arrays are ordered
FL, FR, RL, RR and a positive wheel speed rolls the robot forward.

Model, per :meth:`SimChassis.step` of ``dt`` seconds:

- Motor: each wheel's surface speed ``w`` follows a first-order lag towards
  ``command * max_wheel_speed`` with time constant ``tau``, discretized exactly:
  ``w += (target - w) * (1 - exp(-dt / tau))``. Splitting a step in two changes nothing.
- Encoders: each wheel's cumulative distance grows by the exact integral of ``w`` over the
  step (the lag's closed form), so it too is independent of how time is split into steps.
- Slip: the ground moves under each wheel at ``w * (1 + n)``, ``n ~ N(0, slip)`` drawn per
  wheel per step from a seeded generator (``slip = 0``: exactly ``w``, nothing is drawn).
  Encoders measure the wheel, not the ground, so slip shows only in the true pose.
- Body: the true body velocity is the least-squares mecanum forward kinematics of the ground
  speeds, and the pose moves along its exact arc (:func:`geometry.pose_exp`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from mecanum_mav.mecanum.geometry import Pose2d, Twist2d, pose_exp
from mecanum_mav.mecanum.kinematics import MecanumKinematics

if TYPE_CHECKING:
    from mecanum_mav.config.params import Params

__all__ = ["ORIGIN_POSE", "SimChassis"]

Wheels = tuple[float, float, float, float]

ORIGIN_POSE = Pose2d(0.0, 0.0, 0.0)
"""Where a chassis starts unless told otherwise: the local origin, facing north."""


def _wheels(values: Sequence[float]) -> Wheels:
    """Four floats FL, FR, RL, RR."""
    fl, fr, rl, rr = values
    return (fl, fr, rl, rr)


def step_needed(dt_s: float, wheel_commands: Sequence[float]) -> bool:
    """Whether a chassis step of ``dt_s`` seconds has anything to do (``dt_s > 0``).

    Raises:
        ValueError: a negative or non-finite ``dt_s``, or not four wheel commands.
    """
    if not (math.isfinite(dt_s) and dt_s >= 0.0):
        raise ValueError(f"time step must be finite and >= 0 s, got {dt_s}")
    if len(wheel_commands) != 4:
        raise ValueError("need 4 wheel commands (FL, FR, RL, RR)")
    return dt_s > 0.0


def _clean_command(command: float) -> float:
    """A normalized wheel command limited to [-1, 1]; non-finite reads as 0 (stop)."""
    c = float(command)
    if not math.isfinite(c):
        return 0.0
    return -1.0 if c < -1.0 else (1.0 if c > 1.0 else c)


class SimChassis:
    """The true motion of a four-wheel mecanum robot driven by normalized wheel commands.

    Args:
        kinematics: wheel positions (metres, body FRD) and forward kinematics.
        max_wheel_speed_mps: wheel surface speed at a command of 1, m/s.
        motor_tau_s: first-order time constant of every motor, seconds (> 0).
        slip: standard deviation of each wheel's traction error, a fraction of its speed.
        seed: seed of the slip noise generator, for repeatable runs.
        pose: starting true pose, local NED (m, m, rad clockwise from north).
    """

    def __init__(
        self,
        kinematics: MecanumKinematics,
        *,
        max_wheel_speed_mps: float,
        motor_tau_s: float,
        slip: float = 0.0,
        seed: int = 0,
        pose: Pose2d = ORIGIN_POSE,
    ) -> None:
        if not (math.isfinite(max_wheel_speed_mps) and max_wheel_speed_mps > 0.0):
            raise ValueError(f"max wheel speed must be > 0 m/s, got {max_wheel_speed_mps}")
        if not (math.isfinite(motor_tau_s) and motor_tau_s > 0.0):
            raise ValueError(f"motor time constant must be > 0 s, got {motor_tau_s}")
        if not (math.isfinite(slip) and slip >= 0.0):
            raise ValueError(f"slip must be >= 0, got {slip}")
        self._kinematics = kinematics
        self._max_speed = float(max_wheel_speed_mps)
        self._tau = float(motor_tau_s)
        self._slip = float(slip)
        self._rng = np.random.default_rng(seed)
        self._pose = Pose2d(*(float(v) for v in pose))
        self._speeds: Wheels = (0.0, 0.0, 0.0, 0.0)
        self._distances: Wheels = (0.0, 0.0, 0.0, 0.0)
        self._velocity = (0.0, 0.0)
        self._yaw_rate = 0.0
        self._time = 0.0

    @classmethod
    def from_params(cls, params: Params, pose: Pose2d = ORIGIN_POSE) -> SimChassis:
        """Build from ``GEO_HALF_LEN/WID``, ``WHL_MAX_SPD``, ``SIM_MOTOR_TAU/SLIP/SEED``."""
        return cls(
            MecanumKinematics.from_half_extents(params["GEO_HALF_LEN"], params["GEO_HALF_WID"]),
            max_wheel_speed_mps=params["WHL_MAX_SPD"],
            motor_tau_s=params["SIM_MOTOR_TAU"],
            slip=params["SIM_SLIP"],
            seed=int(params["SIM_SEED"]),
            pose=pose,
        )

    @property
    def pose(self) -> Pose2d:
        """True pose, local NED: north m, east m, yaw rad clockwise from north in [-pi, pi)."""
        return self._pose

    @property
    def velocity_body(self) -> tuple[float, float]:
        """True velocity of the robot centre, body FRD: (forward m/s, right m/s)."""
        return self._velocity

    @property
    def yaw_rate(self) -> float:
        """True yaw rate, rad/s, clockwise seen from above."""
        return self._yaw_rate

    @property
    def roll_pitch(self) -> tuple[float, float]:
        """True roll and pitch, radians: always level (a kinematic chassis has no tilt)."""
        return (0.0, 0.0)

    @property
    def wheel_speeds_mps(self) -> Wheels:
        """Wheel surface speeds FL, FR, RL, RR, m/s (positive rolls the robot forward)."""
        return self._speeds

    @property
    def wheel_distances_m(self) -> Wheels:
        """Cumulative encoder distances FL, FR, RL, RR, metres rolled (wheel, not ground)."""
        return self._distances

    @property
    def time_s(self) -> float:
        """Simulated time, seconds: the sum of every step's ``dt_s``."""
        return self._time

    def step(self, dt_s: float, wheel_commands: Sequence[float]) -> None:
        """Advance ``dt_s`` seconds with four normalized wheel commands FL, FR, RL, RR held.

        Commands are limited to [-1, 1]; a non-finite command is 0. ``dt_s = 0`` does
        nothing; a negative or non-finite ``dt_s`` raises ``ValueError``.
        """
        if not step_needed(dt_s, wheel_commands):
            return
        targets = [_clean_command(c) * self._max_speed for c in wheel_commands]
        gain = -math.expm1(-dt_s / self._tau)  # 1 - exp(-dt/tau), accurate for small dt
        mean_weight = self._tau * gain / dt_s  # step mean = target + (w0 - target) * this
        start = self._speeds
        means = [t + (w - t) * mean_weight for w, t in zip(start, targets, strict=True)]
        self._speeds = _wheels([w + (t - w) * gain for w, t in zip(start, targets, strict=True)])
        self._distances = _wheels(
            [d + m * dt_s for d, m in zip(self._distances, means, strict=True)]
        )
        traction = self._traction()
        self._move(dt_s, [m * k for m, k in zip(means, traction, strict=True)])
        end = [w * k for w, k in zip(self._speeds, traction, strict=True)]
        vx, vy, yaw_rate = self._kinematics.to_chassis_speeds(end).tolist()
        self._velocity = (vx, vy)
        self._yaw_rate = yaw_rate
        self._time += dt_s

    def _traction(self) -> list[float]:
        """This step's ground-speed factor of each wheel, ``1 + N(0, slip)``."""
        if self._slip == 0.0:
            return [1.0, 1.0, 1.0, 1.0]
        factors: list[float] = (1.0 + self._rng.normal(0.0, self._slip, 4)).tolist()
        return factors

    def _move(self, dt_s: float, ground_mps: list[float]) -> None:
        """Move the true pose along the exact arc of these mean ground speeds (m/s)."""
        vx, vy, yaw_rate = self._kinematics.to_chassis_speeds(ground_mps).tolist()
        self._pose = pose_exp(self._pose, Twist2d(vx * dt_s, vy * dt_s, yaw_rate * dt_s))
