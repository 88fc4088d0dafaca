"""How far the wheel odometry is from the truth on the MuJoCo chassis, per direction (issue 25).

The companion's wheel odometry is the kinematics' forward fit of the encoders (WHEEL_DISTANCE:
what each wheel rolled, not the ground). This drives the MuJoCo chassis directly (no
companion) with the kinematic wheel speeds of one direction and compares the true motion with
the odometry's, as true / odometry (1.0: exact; under 1: the odometry over-reads):

- steady: forward, strafe (right) and rotate (clockwise) at each speed (m/s at the wheels), the
  second and third second of driving (the launch left out);
- ramps: forward and strafe from rest to 1.5 m/s and back to rest at each acceleration
  (``WP_ACCEL`` 0.5 and ``GUID_ACC_MAX`` 1.0 m/s/s, the autonomous limits, and 2.0): whether
  the wheels keep traction;
- launch: a step from rest to the speed's full command (what MANUAL does with a full stick),
  the first second.

The strafe ratio is ``WHL_STRAFE_EFF`` (the mean of the steady strafe rows is printed); the
rotation ratio matters only when the heading comes from the wheels (``ODOM_YAW_SRC`` 1).

Usage::

    python tools/odometry_calibration.py [--friction 0.8,0.4] [--speeds 0.5,1.0,1.5]
        [--accels 0.5,1.0,2.0]
"""

from __future__ import annotations

import argparse
import math
import statistics
from collections.abc import Sequence

from mecanum_mav.config.params import Params
from mecanum_mav.mecanum.kinematics import MecanumKinematics
from mecanum_mav.sim.mujocochassis import MujocoChassis

DT_S = 0.002
"""The chassis's step, seconds."""
WHEEL_MAX_MPS = 3.0
"""``WHL_MAX_SPD``, as bench_control sets it."""
DIRECTIONS = {"forward": (1.0, 0.0, 0.0), "strafe": (0.0, 1.0, 0.0), "rotate": (0.0, 0.0, 1.0)}
"""Unit twists (forward m/s, right m/s, clockwise rad/s per m/s at the wheels)."""


class Drive:
    """A MuJoCo chassis on a floor, its kinematics, and the true heading unwrapped."""

    def __init__(self, friction: float) -> None:
        params = Params()
        params.update({"WHL_MAX_SPD": WHEEL_MAX_MPS, "SIM_FRICTION": friction})
        self.kinematics = MecanumKinematics.from_half_extents(params["GEO_HALF_LEN"],
                                                              params["GEO_HALF_WID"])
        self.chassis = MujocoChassis.from_params(params)
        self.turned_rad = 0.0
        self._yaw = self.chassis.pose.yaw_rad
        half_length, half_width = params["GEO_HALF_LEN"], params["GEO_HALF_WID"]
        self.rate_per_wheel_mps = 1.0 / (half_length + half_width)
        """Yaw rate (rad/s) with every wheel at 1 m/s."""

    def twist(self, direction: str, wheel_mps: float) -> tuple[float, float, float]:
        """The body twist of ``direction`` with its wheels at ``wheel_mps``."""
        vx, vy, r = DIRECTIONS[direction]
        return vx * wheel_mps, vy * wheel_mps, r * wheel_mps * self.rate_per_wheel_mps

    def step(self, twist: tuple[float, float, float]) -> None:
        """One step with the wheel commands of ``twist``."""
        wheels = self.kinematics.wheel_speeds(*twist)
        self.chassis.step(DT_S, [w / WHEEL_MAX_MPS for w in wheels])
        yaw = self.chassis.pose.yaw_rad
        self.turned_rad += math.remainder(yaw - self._yaw, 2.0 * math.pi)
        self._yaw = yaw

    def mark(self) -> tuple[tuple[float, ...], tuple[float, float], float]:
        """Encoders, true position and unwrapped heading now."""
        pose = self.chassis.pose
        return tuple(self.chassis.wheel_distances_m), (pose.x_m, pose.y_m), self.turned_rad

    def ratio(self, direction: str, start: tuple[tuple[float, ...], tuple[float, float], float]
              ) -> float:
        """True over odometry motion in ``direction`` since ``start`` (a :meth:`mark`)."""
        wheels, xy, yaw = self.mark()
        rolled = [b - a for a, b in zip(start[0], wheels, strict=True)]
        fit = self.kinematics.to_chassis_speeds(rolled)
        if direction == "rotate":
            return (yaw - start[2]) / float(fit[2])
        axis = 0 if direction == "forward" else 1
        return math.dist(start[1], xy) / abs(float(fit[axis]))


def steady(friction: float, direction: str, wheel_mps: float) -> float:
    """True / odometry over the second and third second at ``wheel_mps``."""
    drive = Drive(friction)
    twist = drive.twist(direction, wheel_mps)
    for _ in range(round(1.0 / DT_S)):
        drive.step(twist)
    start = drive.mark()
    for _ in range(round(2.0 / DT_S)):
        drive.step(twist)
    return drive.ratio(direction, start)


def ramp(friction: float, direction: str, accel: float, top_mps: float = 1.5) -> float:
    """True / odometry from rest to ``top_mps`` at ``accel`` m/s/s, 0.5 s there, back to rest
    at ``accel``, 0.5 s at rest."""
    drive = Drive(friction)
    start = drive.mark()
    step = accel * DT_S
    up = [min(top_mps, step * (k + 1)) for k in range(math.ceil(top_mps / step))]
    hold = round(0.5 / DT_S)
    for speed in [*up, *[top_mps] * hold, *reversed(up[:-1]), *[0.0] * (hold + 1)]:
        drive.step(drive.twist(direction, speed))
    return drive.ratio(direction, start)


def launch(friction: float, direction: str, wheel_mps: float) -> float:
    """True / odometry over the first second of a step from rest to ``wheel_mps``."""
    drive = Drive(friction)
    start = drive.mark()
    twist = drive.twist(direction, wheel_mps)
    for _ in range(round(1.0 / DT_S)):
        drive.step(twist)
    return drive.ratio(direction, start)


def _numbers(text: str) -> list[float]:
    return [float(x) for x in text.split(",") if x.strip()]


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--friction", type=_numbers, default=[0.8, 0.4])
    p.add_argument("--speeds", type=_numbers, default=[0.5, 1.0, 1.5])
    p.add_argument("--accels", type=_numbers, default=[0.5, 1.0, 2.0])
    args = p.parse_args(argv)
    print("true / odometry on the MuJoCo chassis (1: exact; < 1: the odometry over-reads)")
    print(f"{'mu':>4} {'direction':<9} {'test':<20} {'ratio':>7}")
    strafes = []
    for mu in args.friction:
        for direction in DIRECTIONS:
            for speed in args.speeds:
                value = steady(mu, direction, speed)
                strafes += [value] if direction == "strafe" else []
                print(f"{mu:>4g} {direction:<9} {f'steady {speed:g} m/s':<20} {value:>7.4f}")
        for direction in ("forward", "strafe"):
            for accel in args.accels:
                value = ramp(mu, direction, accel)
                print(f"{mu:>4g} {direction:<9} {f'ramp {accel:g} m/s/s':<20} {value:>7.4f}")
            for speed in args.speeds:
                value = launch(mu, direction, speed)
                print(f"{mu:>4g} {direction:<9} {f'launch {speed:g} m/s':<20} {value:>7.4f}")
    if strafes:
        print(f"strafe efficiency (mean of the steady strafes): WHL_STRAFE_EFF "
              f"{statistics.fmean(strafes):.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
