"""The MuJoCo model of the mecanum chassis, generated as MJCF text from the parameters.

One source: the geometry (``GEO_HALF_LEN``/``GEO_HALF_WID``), the wheels (``SIM_WHL_RAD``,
``WHL_MAX_SPD``), the motors (``SIM_MOTOR_TAU``, ``SIM_MOT_TORQUE``), the mass
(``SIM_MASS``) and the floor (``SIM_FRICTION``) come from :class:`~mecanum_mav.config.params.
Params`; no model file is kept in the repository. Pure text generation: nothing here imports
MuJoCo (:mod:`mecanum_mav.sim.mujocochassis` loads the text).

Frames: MuJoCo's world is z up, so the model is built in body FLU (x forward, y left, z up)
and the chassis converts to NED/FRD at its edge. Units SI (m, kg, s, rad, N.m).

The model:

- a free-floating box (the chassis: ``SIM_MASS`` minus the wheels, the inertia of a box of
  the wheelbase by the track by :data:`BODY_HALF_HEIGHT_M` * 2), its centre at axle height;
- four wheel bodies at (+-L, +-W) on hinges about the body's y axis (positive = rolls the
  robot forward), each carrying :data:`ROLLERS` passive rollers on hinges whose axes are at
  45 degrees to the wheel axis, the sense per wheel from the "X" roller signs
  (:data:`~mecanum_mav.mecanum.wheels.LATERAL_SIGNS`): at the contact point a roller's axis
  is along ``(1, s_i)`` in body FRD, so the wheel rolls at ``v_x + s_i * v_y`` of the ground
  velocity there, as :mod:`mecanum_mav.mecanum.kinematics` assumes;
- each roller an ellipsoid whose long semi-axis ``c = sqrt(r^2 + 2 * rho * r)`` makes the
  wheel's lowest point stay at the wheel radius to second order in the wheel angle (rho: the
  roller centre's distance from the wheel axis, r: its short semi-axis), so the wheel rolls
  smoothly; only rollers and the floor plane collide (contype/conaffinity);
- per wheel, a velocity servo behind a first-order filter (``dyntype="filterexact"``, time
  constant ``SIM_MOTOR_TAU``), gain :attr:`ChassisSpec.servo_gain` and torque limited to
  ``SIM_MOT_TORQUE``: the motor and its ESC. Its control is the target wheel speed in rad/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from mecanum_mav.mecanum.wheels import CORNER_SIGNS, LATERAL_SIGNS, WHEEL_KEYS

if TYPE_CHECKING:
    from mecanum_mav.config.params import Params

__all__ = ["ROLLERS", "ChassisSpec", "mjcf", "roller_frames"]

ROLLERS = 12
"""Passive rollers per wheel."""
TIMESTEP_S = 0.001
"""MuJoCo's integration step, seconds, unless the wheels are fast (:attr:`ChassisSpec.
timestep_s`); short enough for a stiff roller contact (:data:`CONTACT_STEPS`)."""
STEPS_PER_ROLLER = 1.5
"""At least this many integration steps while one roller passes the floor at top wheel
speed (a faster wheel gets a shorter step)."""
CONTACT_STEPS = 2.0
"""Time constant of the roller-floor contact (MuJoCo solref), in integration steps: 2, the
stiffest MuJoCo allows. The stiffer the contact, the less the wheels sink (rolling radius
closer to ``SIM_WHL_RAD``) and the less the wheels lag the ground: a soft contact lets each
wheel's rolling follow the ground's motion under it about a time constant late, so a rover
translating while it turns measures its body-frame velocity rotated by yaw rate x that lag
(at 1 m/s and 1 rad/s on friction 0.8 the wheels' odometry, with the true yaw, ended 1.65 cm
to the side per 2.6 m with 5 ms at a 2 ms step, 0.38 cm with 2 ms at 1 ms)."""
WHEEL_MASS_FRACTION = 0.06
"""Each wheel's share of ``SIM_MASS`` (hub, motor rotor and rollers)."""
ROLLER_MASS_FRACTION = 0.4
"""The rollers' share of a wheel's mass."""
ROLLER_SHORT_FRACTION = 0.3
"""A roller's short semi-axis as a fraction of the wheel radius."""
BODY_HALF_HEIGHT_M = 0.04
"""Half the chassis box's height, metres."""
GRAVITY_MPS2 = 9.81
"""MuJoCo's default gravity, m/s^2."""
GEARBOX_FRICTION_FRACTION = 1.0 / 60.0
"""Dry friction of each wheel's gearbox, as a fraction of ``SIM_MOT_TORQUE``."""
ROLLER_RESISTANCE = 0.015
"""Dry friction of each roller's bearing, as the force it takes at the roller's surface over
the wheel's share of the robot's weight (what makes a mecanum robot strafe slower than it
drives; scaled so a light robot or a small wheel behaves alike)."""
SERVO_SATURATION_FRACTION = 0.05
"""The speed error, as a fraction of top wheel speed, at which a motor reaches its torque
limit (sets :attr:`ChassisSpec.servo_gain`)."""

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class ChassisSpec:
    """What the model is built from (SI units, body FLU for positions).

    Attributes:
        half_length_m: centre to each wheel centre along x (``GEO_HALF_LEN``).
        half_width_m: centre to each wheel centre along y (``GEO_HALF_WID``).
        wheel_radius_m: wheel radius to the rollers' outer surface (``SIM_WHL_RAD``).
        mass_kg: the whole robot, wheels included (``SIM_MASS``).
        friction: roller-floor Coulomb coefficient (``SIM_FRICTION``).
        max_wheel_speed_mps: wheel surface speed at full command (``WHL_MAX_SPD``).
        motor_tau_s: motor lag time constant (``SIM_MOTOR_TAU``).
        motor_torque_nm: each motor's torque limit (``SIM_MOT_TORQUE``).
        esc_dead_band: ESC dead band, fraction of full command (``SIM_ESC_DZ``).
    """

    half_length_m: float
    half_width_m: float
    wheel_radius_m: float
    mass_kg: float
    friction: float
    max_wheel_speed_mps: float
    motor_tau_s: float
    motor_torque_nm: float
    esc_dead_band: float

    @classmethod
    def from_params(cls, params: Params) -> ChassisSpec:
        """The spec the parameters give."""
        return cls(
            half_length_m=params["GEO_HALF_LEN"], half_width_m=params["GEO_HALF_WID"],
            wheel_radius_m=params["SIM_WHL_RAD"], mass_kg=params["SIM_MASS"],
            friction=params["SIM_FRICTION"], max_wheel_speed_mps=params["WHL_MAX_SPD"],
            motor_tau_s=params["SIM_MOTOR_TAU"], motor_torque_nm=params["SIM_MOT_TORQUE"],
            esc_dead_band=params["SIM_ESC_DZ"],
        )

    @property
    def max_wheel_rate(self) -> float:
        """Top wheel angular speed, rad/s."""
        return self.max_wheel_speed_mps / self.wheel_radius_m

    @property
    def servo_gain(self) -> float:
        """Velocity servo gain, N.m per rad/s of speed error."""
        return self.motor_torque_nm / (SERVO_SATURATION_FRACTION * self.max_wheel_rate)

    @property
    def timestep_s(self) -> float:
        """MuJoCo's integration step, seconds: :data:`TIMESTEP_S`, shorter if the wheels' top
        speed would pass a roller over the floor in under :data:`STEPS_PER_ROLLER` steps."""
        pitch = 2.0 * math.pi * self.wheel_radius_m * (1.0 - ROLLER_SHORT_FRACTION) / ROLLERS
        return min(TIMESTEP_S, pitch / (STEPS_PER_ROLLER * self.max_wheel_speed_mps))

    @property
    def contact_timeconst_s(self) -> float:
        """Time constant of the roller-floor contact (MuJoCo solref), seconds:
        :data:`CONTACT_STEPS` integration steps."""
        return CONTACT_STEPS * self.timestep_s

    @property
    def gearbox_friction_nm(self) -> float:
        """Dry friction of each wheel's gearbox, N.m."""
        return GEARBOX_FRICTION_FRACTION * self.motor_torque_nm

    @property
    def wheel_mass_kg(self) -> float:
        """One wheel's mass, kg."""
        return WHEEL_MASS_FRACTION * self.mass_kg


def roller_frames(radius_m: float, lateral_sign: float, rollers: int = ROLLERS,
                  ) -> list[tuple[Vec3, Vec3]]:
    """Each roller's centre and unit axis in its wheel's frame (FLU, wheel axis y), roller 0
    at the bottom, then every ``2 pi / rollers`` about +y.

    At the bottom the axis is ``(1, -s) / sqrt(2)`` in FLU, i.e. ``(1, s)`` in FRD with ``s``
    the wheel's ``lateral_sign``; a roller at wheel angle ``t`` is that frame turned by ``t``
    about +y."""
    rho = radius_m * (1.0 - ROLLER_SHORT_FRACTION)
    ax, ay = 1.0 / math.sqrt(2.0), -lateral_sign / math.sqrt(2.0)
    frames = []
    for k in range(rollers):
        t = 2.0 * math.pi * k / rollers
        c, s = math.cos(t), math.sin(t)
        frames.append(((-rho * s, 0.0, -rho * c), (ax * c, ay, -ax * s)))
    return frames


def _v(values: Vec3 | tuple[float, ...]) -> str:
    """Numbers as MJCF text (space separated, full precision)."""
    return " ".join(repr(float(v)) for v in values)


def _box_inertia(mass: float, half: Vec3) -> Vec3:
    """Diagonal inertia of a solid box of this mass and half extents, kg.m^2."""
    hx, hy, hz = half
    return (mass * (hy * hy + hz * hz) / 3.0, mass * (hx * hx + hz * hz) / 3.0,
            mass * (hx * hx + hy * hy) / 3.0)


def _wheel_xml(spec: ChassisSpec, index: int) -> str:
    """One wheel body with its rollers (FLU; wheel ``index`` in FL, FR, RL, RR order)."""
    key = WHEEL_KEYS[index].lower()
    sx, sy_right = CORNER_SIGNS[index]
    pos = (sx * spec.half_length_m, -sy_right * spec.half_width_m, 0.0)
    r = spec.wheel_radius_m
    hub_mass = spec.wheel_mass_kg * (1.0 - ROLLER_MASS_FRACTION)
    roller_mass = spec.wheel_mass_kg * ROLLER_MASS_FRACTION / ROLLERS
    short = ROLLER_SHORT_FRACTION * r
    rho = r - short
    long = math.sqrt(short * short + 2.0 * rho * short)
    hub_axial = 0.5 * hub_mass * (0.5 * r) ** 2
    hub_radial = 0.25 * hub_mass * (0.5 * r) ** 2
    roller_radial = roller_mass * (short * short + long * long) / 5.0
    roller_axial = 2.0 * roller_mass * short * short / 5.0
    roller_friction = ROLLER_RESISTANCE * spec.mass_kg * GRAVITY_MPS2 / 4.0 * short
    lines = [
        f'    <body name="wheel_{key}" pos="{_v(pos)}">',
        f'      <joint name="wheel_{key}" type="hinge" axis="0 1 0" '
        f'frictionloss="{spec.gearbox_friction_nm!r}"/>',
        f'      <inertial pos="0 0 0" mass="{hub_mass!r}" '
        f'diaginertia="{_v((hub_radial, hub_axial, hub_radial))}"/>',
    ]
    for k, (centre, axis) in enumerate(roller_frames(r, LATERAL_SIGNS[index])):
        lines += [
            f'      <body name="roller_{key}{k}" pos="{_v(centre)}" zaxis="{_v(axis)}">',
            f'        <joint name="roller_{key}{k}" type="hinge" axis="0 0 1" '
            f'frictionloss="{roller_friction!r}"/>',
            f'        <inertial pos="0 0 0" mass="{roller_mass!r}" '
            f'diaginertia="{_v((roller_radial, roller_radial, roller_axial))}"/>',
            f'        <geom class="roller" size="{_v((short, short, long))}"/>',
            "      </body>",
        ]
    lines.append("    </body>")
    return "\n".join(lines)


def _actuator_xml(spec: ChassisSpec, index: int) -> str:
    """The motor of wheel ``index``: a filtered velocity servo, torque limited."""
    key = WHEEL_KEYS[index].lower()
    kv, torque = spec.servo_gain, spec.motor_torque_nm
    return (f'    <general name="motor_{key}" joint="wheel_{key}" dyntype="filterexact" '
            f'dynprm="{spec.motor_tau_s!r}" gaintype="fixed" gainprm="{kv!r}" '
            f'biastype="affine" biasprm="0 0 {-kv!r}" forcelimited="true" '
            f'forcerange="{-torque!r} {torque!r}"/>')


def mjcf(spec: ChassisSpec) -> str:
    """The MJCF text of the chassis on a flat floor: body ``chassis`` (free joint), wheels
    ``wheel_fl`` .. ``wheel_rr`` (hinge joints of the same names), actuators ``motor_fl`` ..
    ``motor_rr`` (control: target wheel rate, rad/s)."""
    wheels_mass = 4.0 * spec.wheel_mass_kg
    body_half = (spec.half_length_m, spec.half_width_m, BODY_HALF_HEIGHT_M)
    body_mass = spec.mass_kg - wheels_mass
    mu = spec.friction
    wheels = "\n".join(_wheel_xml(spec, i) for i in range(4))
    motors = "\n".join(_actuator_xml(spec, i) for i in range(4))
    return f"""<mujoco model="mecanum_chassis">
  <compiler angle="radian" inertiafromgeom="false"/>
  <option timestep="{spec.timestep_s!r}" integrator="implicitfast" cone="elliptic">
    <flag energy="enable"/>
  </option>
  <default>
    <geom contype="0" conaffinity="0" condim="3" solref="{spec.contact_timeconst_s!r} 1"
          friction="{mu!r} 0.005 0.0001"/>
    <default class="roller">
      <geom type="ellipsoid" contype="1" conaffinity="0"/>
    </default>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1" contype="0" conaffinity="1"/>
    <body name="chassis" pos="0 0 {spec.wheel_radius_m!r}">
    <freejoint name="chassis"/>
    <inertial pos="0 0 0" mass="{body_mass!r}" diaginertia="{_v(_box_inertia(body_mass,
                                                                                body_half))}"/>
    <geom type="box" size="{_v(body_half)}" mass="0"/>
{wheels}
    </body>
  </worldbody>
  <actuator>
{motors}
  </actuator>
</mujoco>
"""
