"""The control chain: from what a pilot or a controller asks to four pulse widths.

Two chains, each one function that the rover core, the tests and the tools all call:

- :func:`manual_output`: stick (x forward, y right, r clockwise, normalized) -> input shaping
  -> the mixing algorithm with its desaturation -> PWM.
- :func:`autonomous_output`: mission executor (AUTO only) -> GUIDED controller (body velocity
  m/s FRD, yaw rate rad/s clockwise) -> inverse kinematics (wheel speeds m/s) -> normalized by
  the wheel speed at full command -> prioritized desaturation -> PWM.

Both return ``(wheels, pulses_us)``: the normalized wheel commands FL, FR, RL, RR in [-1, 1]
and the pulse widths in microseconds for the same wheels.
"""

from __future__ import annotations

from functools import partial

from mecanum_mav.config.views import InputConfig
from mecanum_mav.control.executor import MissionExecutor
from mecanum_mav.control.guided import GuidedController
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.mecanum.kinematics import MecanumKinematics
from mecanum_mav.mecanum.mixing import (
    Desaturation,
    desaturate_prioritized_scalar,
    wheels_from_stick,
)
from mecanum_mav.mecanum.shaping import shape_stick
from mecanum_mav.mecanum.wheels import WheelQuad

__all__ = ["Output", "autonomous_output", "manual_output"]

_wheel_quad = partial(tuple.__new__, WheelQuad)
"""``WheelQuad(*values)`` without the generated ``__new__``'s Python frame (a 50 Hz path)."""

Output = tuple[tuple[float, float, float, float], tuple[int, int, int, int]]
"""(normalized wheel commands FL, FR, RL, RR; pulse widths in us, same order)."""


def manual_output(x: float, y: float, r: float, config: InputConfig, pwm: PwmMap) -> Output:
    """A pilot's stick -> wheel commands and pulse widths.

    Args:
        x, y, r: the stick, forward, right and clockwise, each normalized to [-1, 1].
        config: shaping (deadband, expo, circle) and mixing (algorithm, desaturation).
        pwm: the PWM edge.
    """
    x, y, r = shape_stick(x, y, r, deadband_width=config.deadband, expo_weight=config.expo,
                          circle=config.circle)
    wheels = wheels_from_stick(x, y, r, config.algorithm, priority=config.desaturation)
    return wheels, pwm.pulses_us(wheels)


def autonomous_output(guided: GuidedController, executor: MissionExecutor | None, pose: Pose2d,
                      now_s: float, kinematics: MecanumKinematics, wheel_speed_max_mps: float,
                      priority: Desaturation | int, pwm: PwmMap) -> Output:
    """One GUIDED (``executor`` None) or AUTO control tick -> wheel commands and pulse widths.

    Args:
        guided: the velocity and heading controller (its setpoint is replaced by the
            executor's in AUTO).
        executor: the mission executor in AUTO, else None.
        pose: the rover's pose, local NED (m, m, rad clockwise from north).
        now_s: the time of this tick, monotonic seconds.
        kinematics: the wheel geometry (body FRD, metres).
        wheel_speed_max_mps: wheel surface speed at full command (``WHL_MAX_SPD``), m/s.
        priority: how translation and rotation share the wheels when they saturate; both
            proportional and rotation priority keep the direction of travel.
        pwm: the PWM edge.
    """
    if executor is not None:
        guided.setpoint = executor.update(pose, guided.velocity_ned, now_s)
    speeds = guided.update(pose, now_s)
    # Plain floats throughout (no numpy): this runs at CTL_RATE, with caches cold.
    t0, t1, t2, t3 = kinematics.wheel_speeds(speeds.vx_mps, speeds.vy_mps, 0.0)
    r0, r1, r2, r3 = kinematics.wheel_speeds(0.0, 0.0, speeds.yaw_rate)
    top = wheel_speed_max_mps
    wheels = _wheel_quad(desaturate_prioritized_scalar(
        (t0 / top, t1 / top, t2 / top, t3 / top), (r0 / top, r1 / top, r2 / top, r3 / top),
        priority))
    return wheels, pwm.pulses_us(wheels)
