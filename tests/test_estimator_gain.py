"""The commanded-speed odometry's gain (ODOM_CMD_GAIN): the fraction of its commanded speed a
wheel really rolls, in virtual time (time passed in); on the MuJoCo chassis, whose motors run
below their command under load, it takes the odometry's over-reading away."""

from __future__ import annotations

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.mecanum.geometry import ned_to_body


def commanded(**values: float) -> WheelOdometryEstimator:
    params = Params()
    params.update({"ODOM_SRC": 2, **values})
    return WheelOdometryEstimator(params)


@pytest.mark.parametrize("tau", [0.0, 0.08])
def test_a_commanded_gain_scales_the_distance_every_wheel_is_counted_to_roll(tau: float):
    est = commanded(ODOM_CMD_TAU=tau, ODOM_CMD_GAIN=0.95)  # WHL_MAX_SPD 1 m/s
    plain = commanded(ODOM_CMD_TAU=tau)
    t = 0.0
    for _ in range(100):
        t += 0.02
        est.on_commanded([0.5, 0.5, 0.5, 0.5], 0.02, t)
        plain.on_commanded([0.5, 0.5, 0.5, 0.5], 0.02, t)
    assert est.pose.x_m == pytest.approx(0.95 * plain.pose.x_m, rel=1e-9)
    assert est.wheel_distances_m == pytest.approx([0.95 * d for d in plain.wheel_distances_m])
    assert plain.pose.x_m > 0.9  # (1 s at 0.5 m/s, less the lag's)


def drive(params: Params, forward: float, right: float, seconds: float) -> tuple[float, float]:
    """Drive the MuJoCo chassis with the kinematic wheel commands of (``forward``, ``right``)
    m/s ramped up at 0.5 m/s/s (``WP_ACCEL``), held for ``seconds``, then ramped down, each
    command through the PWM edge (dead band, whole microseconds) to the ESCs as on the twin;
    the distance truly driven and the commanded odometry's (m)."""
    from mecanum_mav.control.pwm import PwmMap
    from mecanum_mav.mecanum.kinematics import MecanumKinematics
    from mecanum_mav.sim.mujocochassis import MujocoChassis

    pytest.importorskip("mujoco")
    chassis = MujocoChassis.from_params(params)
    pwm = PwmMap.from_params(params)
    est = WheelOdometryEstimator(params)
    kinematics = MecanumKinematics.from_half_extents(
        float(params["GEO_HALF_LEN"]), float(params["GEO_HALF_WID"]),
        strafe_efficiency=float(params["WHL_STRAFE_EFF"]))
    speed = max(abs(forward), abs(right))
    ramp_s, dt, t = speed / 0.5, 0.002, 0.0
    while t < seconds + 2 * ramp_s + 1.0:
        scale = min(t / ramp_s, 1.0, max((seconds + 2 * ramp_s - t) / ramp_s, 0.0))
        wheels = [w / float(params["WHL_MAX_SPD"]) for w in
                  kinematics.wheel_speeds(forward * scale, right * scale, 0.0)]
        pulses = pwm.pulses_us(wheels)
        chassis.step(dt, [out.command_from_pulse(p)
                          for out, p in zip(pwm.wheels, pulses, strict=True)])
        t += dt
        est.on_commanded(wheels, dt, t)
    true = ned_to_body(chassis.pose.x_m, chassis.pose.y_m, 0.0)
    return abs(true[0] + true[1]), abs(est.pose.x_m + est.pose.y_m)


TWIN_CHASSIS = {"WHL_MAX_SPD": 3.0, "SIM_MOTOR_TAU": 0.08, "SIM_ESC_DZ": 0.02, "MOT_DZ": 0.022,
                "MOT_DZ_TYPE": 1, "ODOM_SRC": 2, "ODOM_CMD_TAU": 0.08}
"""The twin bench's chassis and PWM edge (tools/bench_control.py), odometry from commands."""


@pytest.mark.parametrize(("gain", "over_reads"), [(1.0, True), (0.9975, False)])
def test_on_the_mujoco_chassis_the_measured_gain_takes_the_odometrys_over_reading_away(
        gain: float, over_reads: bool):
    """Its motors run below their command under load: driving forward at 1 m/s the odometry
    read 0.25 % long (issue 26's twin in AUTO: 0.15-0.35 %), and with ODOM_CMD_GAIN 0.9975
    within 0.1 %."""
    params = Params()
    params.update({**TWIN_CHASSIS, "ODOM_CMD_GAIN": gain})
    true_m, odometry_m = drive(params, 1.0, 0.0, 3.0)
    error = odometry_m / true_m - 1.0
    assert (error > 0.0015) is over_reads
    assert abs(error) < 0.004
