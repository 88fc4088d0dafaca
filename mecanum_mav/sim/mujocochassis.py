"""The physics-grade mecanum chassis: MuJoCo simulates the model of
:mod:`mecanum_mav.sim.mujocomodel` (a rigid body on four wheels with passive rollers in
contact with the floor); this module drives its motors and reads it in the project's frames.

Motors, as PWM -> ESC -> motor, per wheel (normalized command ``c``, already limited by the
board; non-finite reads 0):

- ESC dead band ``SIM_ESC_DZ``: ``|c| < dz`` drives nothing; the ESC leaves the motor
  unpowered with its windings shorted (the usual "brake" neutral): the servo holds zero wheel
  speed at once, no lag, within the torque limit.
- Otherwise the target wheel surface speed is ``c * WHL_MAX_SPD`` (angular speed: over
  ``SIM_WHL_RAD``), followed by a first-order lag ``SIM_MOTOR_TAU`` (MuJoCo's exact filter),
  and a velocity servo whose torque is limited to ``SIM_MOT_TORQUE``.

:meth:`MujocoChassis.step` sub-steps MuJoCo at its fixed timestep and carries the remainder,
so splitting a step changes nothing beyond rounding. Outputs are converted at the edge from
MuJoCo's z-up world (x north, y west) to NED/FRD (see CONVENTIONS.md): pose x north, y east,
yaw clockwise from north; velocities body forward/right; yaw rate clockwise; wheels FL, FR,
RL, RR, read from the wheel joints as encoders read them (joint angle * radius: the wheel,
not the ground).

Wheel contacts (:meth:`MujocoChassis.wheel_contacts`, only when asked: nothing is added to a
step): per wheel, the normal force summed over its rollers touching the floor
(``mj_contactForce``) and its slip, the contact point's speed over the floor (the roller
surface's velocity there, along the floor; the largest of the wheel's contacts). A wheel slips
when that speed exceeds :data:`SLIP_MPS` (chosen over "the friction force at the cone's edge":
MuJoCo's soft contacts let a sliding contact's friction sit inside the cone, and a speed is
what a user can judge).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.mecanum.wheels import WHEEL_KEYS
from mecanum_mav.sim.chassis import ORIGIN_POSE, Wheels, _clean_command, step_needed
from mecanum_mav.sim.mujocomodel import ChassisSpec, mjcf
from mecanum_mav.sim.physics import WheelContact

if TYPE_CHECKING:
    from mecanum_mav.config.params import Params

__all__ = ["SETTLE_S", "SLIP_MPS", "MujocoChassis", "real_time_factor"]

SETTLE_S = 0.3
"""Simulated seconds the chassis settles onto the floor (braked) before its time 0."""
SLIP_MPS = 0.05
"""A wheel slips when a contact point of its rollers moves over the floor faster than this
(m/s): a rolling contact stays well under it, a spinning or sliding wheel far over."""


def _wrap(angle: float) -> float:
    """An angle in [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class MujocoChassis:
    """A MuJoCo mecanum chassis; the :class:`~mecanum_mav.sim.physics.Chassis` interface.

    Args:
        spec: what the model is built from (:class:`~mecanum_mav.sim.mujocomodel.ChassisSpec`).
        pose: starting true pose, local NED (m, m, rad clockwise from north); the chassis
            starts there at rest on the floor.
    """

    def __init__(self, spec: ChassisSpec, pose: Pose2d = ORIGIN_POSE) -> None:
        self.spec = spec
        self.model = mujoco.MjModel.from_xml_string(mjcf(spec))
        self.data = mujoco.MjData(self.model)
        joints = [self.model.joint(f"wheel_{key.lower()}").id for key in WHEEL_KEYS]
        self._wheel_q = [int(self.model.jnt_qposadr[j]) for j in joints]
        self._wheel_v = [int(self.model.jnt_dofadr[j]) for j in joints]
        self._timestep = float(self.model.opt.timestep)
        self._pending = 0.0
        self._time = 0.0
        # Contact reading, allocated once: each geom's wheel (-1: not a roller), buffers.
        self._geom_wheel = np.full(self.model.ngeom, -1, dtype=np.int64)
        for wheel, key in enumerate(WHEEL_KEYS):
            for k in range(self.model.nbody):
                if self.model.body(k).name.startswith(f"roller_{key.lower()}"):
                    self._geom_wheel[self.model.body_geomadr[k]] = wheel
        self._floor = self.model.geom("floor").id
        self._force6 = np.zeros(6)
        self._vel6 = np.zeros(6)
        self._normal = np.zeros(4)
        self._slip = np.zeros(4)
        self._settle(pose)
        self._wheel_zero = [float(self.data.qpos[i]) for i in self._wheel_q]

    @classmethod
    def from_params(cls, params: Params, pose: Pose2d = ORIGIN_POSE) -> MujocoChassis:
        """Build from ``GEO_HALF_LEN/WID``, ``WHL_MAX_SPD``, ``SIM_MOTOR_TAU``, ``SIM_FRICTION``,
        ``SIM_MASS``, ``SIM_WHL_RAD``, ``SIM_MOT_TORQUE`` and ``SIM_ESC_DZ``."""
        return cls(ChassisSpec.from_params(params), pose)

    def _settle(self, pose: Pose2d) -> None:
        """Let the chassis come to rest on the floor (braked), then put it at ``pose``."""
        mujoco.mj_step(self.model, self.data, round(SETTLE_S / self._timestep))
        qpos = self.data.qpos
        qpos[0], qpos[1] = float(pose.x_m), -float(pose.y_m)
        half = -pose.yaw_rad / 2.0
        turn = np.array([math.cos(half), 0.0, 0.0, math.sin(half)])
        quat = np.empty(4)
        mujoco.mju_mulQuat(quat, turn, qpos[3:7].copy())
        qpos[3:7] = quat
        self.data.qvel[:6] = 0.0
        self.data.time = 0.0
        mujoco.mj_forward(self.model, self.data)

    def _rotation(self) -> np.ndarray:
        """The body's rotation matrix (body FLU -> world z-up), from the state's quaternion:
        the same instant as the position and the wheel angles (MuJoCo's ``xmat`` is from the
        start of its last step, one timestep older)."""
        matrix = np.empty(9)
        mujoco.mju_quat2Mat(matrix, self.data.qpos[3:7])
        return matrix.reshape(3, 3)

    def _velocity_world(self) -> np.ndarray:
        """The body origin's (rotation, linear) velocity, world frame (z up), from the state
        (the free joint's linear velocity is in the world frame, its angular one body-local;
        MuJoCo's ``cvel`` is one timestep older)."""
        spin = self._rotation() @ self.data.qvel[3:6]
        return np.concatenate((spin, self.data.qvel[0:3]))

    @property
    def pose(self) -> Pose2d:
        """True pose, local NED: north m, east m, yaw rad clockwise from north in [-pi, pi)."""
        rot = self._rotation()
        yaw_up = math.atan2(rot[1, 0], rot[0, 0])
        x, y = self.data.qpos[0], self.data.qpos[1]
        return Pose2d(float(x), -float(y), _wrap(-yaw_up))

    @property
    def velocity_body(self) -> tuple[float, float]:
        """True velocity of the robot centre, body FRD: (forward m/s, right m/s) (the
        horizontal velocity in the heading frame)."""
        vel = self._velocity_world()
        yaw_up = -self.pose.yaw_rad
        c, s = math.cos(yaw_up), math.sin(yaw_up)
        forward = c * vel[3] + s * vel[4]
        left = -s * vel[3] + c * vel[4]
        return (float(forward), float(-left))

    @property
    def yaw_rate(self) -> float:
        """True yaw rate, rad/s, clockwise seen from above."""
        return float(-self._velocity_world()[2])

    @property
    def roll_pitch(self) -> tuple[float, float]:
        """True roll and pitch, radians, FRD (roll right side down, pitch nose up)."""
        rot = self._rotation()
        roll = math.atan2(rot[2, 1], rot[2, 2])
        pitch_up = math.asin(max(-1.0, min(1.0, -rot[2, 0])))
        return (roll, -pitch_up)

    @property
    def wheel_speeds_mps(self) -> Wheels:
        """Wheel surface speeds FL, FR, RL, RR, m/s (joint rate * radius; positive rolls the
        robot forward)."""
        r = self.spec.wheel_radius_m
        fl, fr, rl, rr = (float(self.data.qvel[i]) * r for i in self._wheel_v)
        return (fl, fr, rl, rr)

    @property
    def wheel_distances_m(self) -> Wheels:
        """Cumulative encoder distances FL, FR, RL, RR, metres rolled (joint angle since time
        0 * radius: the wheel, not the ground)."""
        r = self.spec.wheel_radius_m
        fl, fr, rl, rr = ((float(self.data.qpos[i]) - zero) * r
                          for i, zero in zip(self._wheel_q, self._wheel_zero, strict=True))
        return (fl, fr, rl, rr)

    @property
    def time_s(self) -> float:
        """Simulated time, seconds: the sum of every step's ``dt_s`` (MuJoCo runs up to one
        of its timesteps behind, carried to the next step)."""
        return self._time

    @property
    def kinetic_energy_j(self) -> float:
        """Kinetic energy of the whole robot (body, wheels, rollers), joules, as MuJoCo
        computed it at the start of its last timestep."""
        return float(self.data.energy[1])

    def wheel_contacts(self) -> tuple[WheelContact, WheelContact, WheelContact, WheelContact]:
        """Each wheel's contact with the floor now, FL, FR, RL, RR: normal force (N) summed
        over its rollers touching the floor, slip speed (m/s, the fastest of its contact
        points over the floor) and whether it slips (above :data:`SLIP_MPS`); from MuJoCo's
        contacts of its last timestep. A wheel off the floor: 0 N, no slip."""
        model, data = self.model, self.data
        normal, slip, force, vel = self._normal, self._slip, self._force6, self._vel6
        normal[:] = 0.0
        slip[:] = 0.0
        for i in range(data.ncon):
            contact = data.contact[i]
            g1, g2 = int(contact.geom1), int(contact.geom2)
            roller = g2 if g1 == self._floor else g1
            wheel = int(self._geom_wheel[roller])
            if wheel < 0 or self._floor not in (g1, g2):
                continue
            mujoco.mj_contactForce(model, data, i, force)
            normal[wheel] += force[0]
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_GEOM, roller, vel, 0)
            # the roller surface at the contact point: v + w x r (world frame, z up)
            rx, ry, rz = contact.pos - data.geom_xpos[roller]
            wx, wy, wz = vel[0], vel[1], vel[2]
            vx = vel[3] + wy * rz - wz * ry
            vy = vel[4] + wz * rx - wx * rz
            slip[wheel] = max(slip[wheel], math.hypot(vx, vy))
        fl, fr, rl, rr = (WheelContact(float(n), float(s), bool(s > SLIP_MPS))
                          for n, s in zip(normal, slip, strict=True))
        return (fl, fr, rl, rr)

    def push(self, forward_mps: float, right_mps: float, yaw_rate: float) -> None:
        """Set the body's velocity at once (a shove), body FRD and clockwise rad/s; the
        wheels and rollers keep theirs."""
        yaw_up = -self.pose.yaw_rad
        c, s = math.cos(yaw_up), math.sin(yaw_up)
        left = -right_mps
        self.data.qvel[0] = c * forward_mps - s * left
        self.data.qvel[1] = s * forward_mps + c * left
        self.data.qvel[5] = -yaw_rate  # (the free joint's angular velocity is body-local)
        mujoco.mj_forward(self.model, self.data)

    def step(self, dt_s: float, wheel_commands: Sequence[float]) -> None:
        """Advance ``dt_s`` seconds with four normalized wheel commands FL, FR, RL, RR held.

        Commands are limited to [-1, 1]; a non-finite command is 0. ``dt_s = 0`` does
        nothing; a negative or non-finite ``dt_s`` raises ``ValueError``.
        """
        if not step_needed(dt_s, wheel_commands):
            return
        self._command([_clean_command(c) for c in wheel_commands])
        self._pending += dt_s
        steps = math.floor(self._pending / self._timestep + 1e-9)
        self._pending = max(0.0, self._pending - steps * self._timestep)
        if steps > 0:
            mujoco.mj_step(self.model, self.data, steps)
        self._time += dt_s

    def _command(self, commands: list[float]) -> None:
        """Set each motor's target (rad/s) from its command: the ESC's dead band brakes."""
        rate = self.spec.max_wheel_rate
        for i, c in enumerate(commands):
            if abs(c) < self.spec.esc_dead_band:
                self.data.ctrl[i] = 0.0
                self.data.act[i] = 0.0
            else:
                self.data.ctrl[i] = c * rate


def real_time_factor(params: Params, seconds: float = 2.0,
                     clock: Callable[[], float] = time.perf_counter) -> float:
    """Simulated seconds per second of ``clock`` of a MuJoCo chassis stepped at ``SIM_RATE``
    through a typical command mix (forward, strafe, rotate, all three at once, half a second
    each). The default clock is the wall's: what a simulator on this machine, as busy as it is
    now, can keep up with; ``time.thread_time`` gives the chassis's own cost, whatever else
    runs."""
    chassis = MujocoChassis.from_params(params)
    dt = 1.0 / params["SIM_RATE"]
    mix = ((0.6, 0.6, 0.6, 0.6), (0.6, -0.6, -0.6, 0.6), (0.6, -0.6, 0.6, -0.6),
           (0.9, -0.3, 0.3, 0.3))
    ticks = max(1, round(seconds / dt))
    start = clock()
    for tick in range(ticks):
        chassis.step(dt, mix[int(tick * dt / 0.5) % len(mix)])
    spent = clock() - start
    return ticks * dt / spent if spent > 0.0 else math.inf
