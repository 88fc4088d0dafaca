"""The twin's sensors (mecanum_mav.sim.twinbridge.ChassisSensors) in the frames ArduPilot's
SITL JSON backend documents (mecanum_mav.sim.sitljson; ArduPilot's libraries/SITL/SIM_JSON):
``velocity`` in NED, ``imu.accel_body`` and ``imu.gyro`` in the body frame FRD, ``attitude``
yaw clockwise from north. At heading 0 body and NED axes coincide, so a rotation applied the
wrong way round (or not at all) reads the same there; these tests turn the chassis to east
(90 degrees) and to south-west (225 degrees, where north and east both carry every body
axis).

What is expected comes from the chassis itself (its pose and body velocity,
MujocoChassis.pose / velocity_body) and from the frames' definitions: with heading psi,
forward is (cos psi, sin psi) in NED and right (-sin psi, cos psi).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mujoco", reason="the MuJoCo chassis needs the physics extra")

from mecanum_mav.config.params import Params
from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.sim.mujocochassis import MujocoChassis
from mecanum_mav.sim.sitljson import PhysicsState
from mecanum_mav.sim.twinbridge import ChassisSensors

RATE = 1200
"""Frames per second, as the firmware asks for them."""
G = 9.81
HEADINGS_DEG = [90.0, 225.0]
FORWARD = (1.0, 1.0, 1.0, 1.0)
RIGHT = (1.0, -1.0, -1.0, 1.0)  # the X rollers: FL = x + y, FR = x - y, RL = x - y, RR = x + y


def to_ned(heading_rad: float, forward: float, right: float) -> tuple[float, float]:
    """Body (forward, right) -> (north, east) at ``heading_rad`` (clockwise from north)."""
    c, s = math.cos(heading_rad), math.sin(heading_rad)
    return c * forward - s * right, s * forward + c * right


def settled(heading_deg: float) -> tuple[MujocoChassis, ChassisSensors]:
    """A chassis at rest facing ``heading_deg``, and its sensors."""
    chassis = MujocoChassis.from_params(Params(), Pose2d(0.0, 0.0, math.radians(heading_deg)))
    sensors = ChassisSensors(chassis)
    for _ in range(10):
        chassis.step(1 / RATE, (0.0, 0.0, 0.0, 0.0))
        sensors.read()
    return chassis, sensors


def launch(chassis: MujocoChassis, sensors: ChassisSensors, commands: tuple[float, ...],
           frames: int = 60) -> tuple[np.ndarray, PhysicsState]:
    """Drive ``commands`` for ``frames`` frames: the mean specific force (body) over them
    and the last state."""
    forces = []
    for _ in range(frames):
        chassis.step(1 / RATE, commands)
        state = sensors.read()
        forces.append(state.accel_body)
    return np.mean(forces, axis=0), state


@pytest.mark.parametrize("heading_deg", HEADINGS_DEG)
def test_at_rest_facing_away_from_north_gravity_is_still_minus_g_on_body_z_and_yaw_is_the_heading(
        heading_deg: float) -> None:
    _, sensors = settled(heading_deg)
    state = sensors.read()
    assert state.accel_body == pytest.approx((0.0, 0.0, -G), abs=0.05)
    assert state.velocity_ned == pytest.approx((0.0, 0.0, 0.0), abs=1e-3)
    assert math.cos(state.attitude[2] - math.radians(heading_deg)) == pytest.approx(1.0)


@pytest.mark.parametrize("heading_deg", HEADINGS_DEG)
@pytest.mark.parametrize(("commands", "axis"), [(FORWARD, 0), (RIGHT, 1)])
def test_a_launch_reads_as_body_acceleration_along_its_axis_and_ned_velocity_along_the_heading(
        heading_deg: float, commands: tuple[float, ...], axis: int) -> None:
    """Forward (x) or right (y): the accelerometer reads the launch on that body axis only,
    whatever the heading; the velocity is the body velocity turned by the heading."""
    chassis, sensors = settled(heading_deg)
    seconds = 60 / RATE
    mean, state = launch(chassis, sensors, commands)
    body = chassis.velocity_body
    assert abs(body[axis]) > 0.15  # it did move that way (0.22-0.24 m/s)
    assert mean[axis] == pytest.approx(body[axis] / seconds, rel=0.1)
    assert mean[axis] > 2.0
    assert abs(mean[1 - axis]) < 0.05 * mean[axis]  # nothing on the other horizontal axis
    assert mean[2] == pytest.approx(-G, abs=1.0)
    heading = chassis.pose.yaw_rad
    north, east = to_ned(heading, *body)
    assert state.velocity_ned[:2] == pytest.approx((north, east), abs=0.01)
    # and so the velocity points along the body axis turned by the heading
    direction = heading + (0.0 if axis == 0 else math.pi / 2)
    speed = math.hypot(north, east)
    assert state.velocity_ned[:2] == pytest.approx(
        (speed * math.cos(direction), speed * math.sin(direction)), abs=0.01)


@pytest.mark.parametrize("heading_deg", HEADINGS_DEG)
def test_a_shove_forward_and_right_is_ned_velocity_turned_by_the_heading(
        heading_deg: float) -> None:
    chassis, sensors = settled(heading_deg)
    chassis.push(0.5, 0.3, 0.0)  # 0.5 m/s forward, 0.3 m/s right, read at that instant
    state = sensors.read()
    expected = to_ned(math.radians(heading_deg), 0.5, 0.3)
    assert state.velocity_ned[:2] == pytest.approx(expected, abs=1e-6)
    if heading_deg == 90.0:  # facing east: forward is east, right is south
        assert state.velocity_ned[:2] == pytest.approx((-0.3, 0.5), abs=1e-6)


@pytest.mark.parametrize("heading_deg", HEADINGS_DEG)
def test_the_gyro_reads_body_rates_frd_whatever_the_heading(heading_deg: float) -> None:
    """Roll right side down, pitch nose up and yaw clockwise are positive (FRD), about the
    body's own axes: a roll rate facing east is not a rate about north."""
    chassis, sensors = settled(heading_deg)
    chassis.push(0.0, 0.0, 0.4)  # clockwise at 0.4 rad/s
    # MuJoCo's free joint keeps its angular velocity in the body frame FLU (x forward,
    # y left, z up): FRD's (p, q, r) is (x, -y, -z).
    chassis.data.qvel[3] = 0.2  # roll, right side down
    chassis.data.qvel[4] = -0.1  # about y left, nose up: pitch up
    state = sensors.read()
    assert state.gyro == pytest.approx((0.2, 0.1, 0.4), abs=1e-9)


# ------------------------------------------------------------ tilted: roll and pitch as well
# ArduPilot builds the body's rotation from the ``attitude`` it is sent (Euler 3-2-1, as its
# Matrix3::from_euler) and reads ``accel_body`` in that body frame: the two must agree when
# the body is tilted too. Level, the body's x and y never carry the vertical, so only a tilt
# shows a rotation with its roll/pitch terms wrong.

TILTS_RAD = [(0.15, -0.25), (-0.3, 0.2)]
"""(roll, pitch): right side down and nose down, then left side down and nose up."""


def dcm_from_euler(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Body FRD -> NED rotation for Euler 3-2-1 angles (ArduPilot's Matrix3::from_euler)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array([[cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
                     [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
                     [-sp, sr * cp, cr * cp]])


def tilt(chassis: MujocoChassis, roll: float, pitch: float, yaw: float) -> None:
    """Put the chassis at this attitude (NED/FRD), where it stands. MuJoCo's state holds the
    body FLU in the world x north, y west, z up: the same rotation as a quaternion with y and
    z negated."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    w = cr * cp * cy + sr * sp * sy
    x = sr * cp * cy - cr * sp * sy
    y = cr * sp * cy + sr * cp * sy
    z = cr * cp * sy - sr * sp * cy
    chassis.data.qpos[3:7] = (w, x, -y, -z)


def wrapped(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


@pytest.mark.parametrize("heading_deg", HEADINGS_DEG)
@pytest.mark.parametrize(("roll", "pitch"), TILTS_RAD)
def test_held_still_tilted_the_accelerometer_reads_gravity_on_the_tilted_body_axes(
        heading_deg: float, roll: float, pitch: float) -> None:
    """Specific force at rest is -g up the NED z axis: in the body, (g sin(pitch),
    -g sin(roll) cos(pitch), -g cos(roll) cos(pitch)) whatever the heading."""
    chassis, sensors = settled(heading_deg)
    tilt(chassis, roll, pitch, math.radians(heading_deg))
    state = sensors.read()
    assert state.attitude[:2] == pytest.approx((roll, pitch), abs=1e-9)
    assert wrapped(state.attitude[2] - math.radians(heading_deg)) == pytest.approx(0.0, abs=1e-9)
    assert state.accel_body == pytest.approx(
        (G * math.sin(pitch), -G * math.sin(roll) * math.cos(pitch),
         -G * math.cos(roll) * math.cos(pitch)), abs=0.05)


@pytest.mark.parametrize("heading_deg", HEADINGS_DEG)
@pytest.mark.parametrize(("roll", "pitch"), TILTS_RAD)
def test_accelerating_tilted_the_accelerometer_reads_the_specific_force_in_the_attitude_it_reports(
        heading_deg: float, roll: float, pitch: float) -> None:
    """A velocity change of (0.02, -0.03, 0.01) m/s NED over 10 ms of physics, the body
    tilted: accel_body is (a - g) turned into the body by the attitude sent with it."""
    chassis, sensors = settled(heading_deg)
    before = sensors.read()
    tilt(chassis, roll, pitch, math.radians(heading_deg))
    gained_ned = np.array([0.02, -0.03, 0.01])
    velocity_ned = np.array(before.velocity_ned) + gained_ned
    chassis.data.qvel[0:3] = velocity_ned * (1.0, -1.0, -1.0)  # (MuJoCo's world: z up, y west)
    chassis.data.time += 0.01
    state = sensors.read()
    assert state.velocity_ned == pytest.approx(tuple(velocity_ned), abs=1e-12)
    specific_force_ned = gained_ned / 0.01 - (0.0, 0.0, G)
    expected = dcm_from_euler(*state.attitude).T @ specific_force_ned
    assert state.accel_body == pytest.approx(tuple(expected), abs=1e-6)


def test_a_chassis_above_where_it_started_is_at_a_negative_down() -> None:
    """``position`` is NED: up is negative down."""
    chassis, sensors = settled(0.0)
    chassis.data.qpos[2] += 0.05
    assert sensors.read().position_ned == pytest.approx((0.0, 0.0, -0.05), abs=1e-6)


def test_the_sensors_time_is_the_physics_time_counted_from_the_epoch_given() -> None:
    """``read()`` counts from physics time 0; ``read(epoch_s)`` from where the firmware last
    started (the bridge's restarts)."""
    chassis, sensors = settled(0.0)
    assert chassis.time_s == pytest.approx(10 / RATE)
    assert sensors.read().time_s == pytest.approx(chassis.time_s, abs=1e-12)
    assert sensors.read(2 / RATE).time_s == pytest.approx(8 / RATE, abs=1e-12)
