"""The MuJoCo mecanum chassis (sim/mujocomodel.py, sim/mujocochassis.py): the model generated
from the parameters, its motors, its frames, and how it drives on a grippy and a slippery
floor."""

from __future__ import annotations

import math
import time
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.mecanum.kinematics import MecanumKinematics
from mecanum_mav.mecanum.odometry import MecanumOdometry
from mecanum_mav.sim.chassis import ORIGIN_POSE
from mecanum_mav.sim.mujocomodel import ROLLER_SHORT_FRACTION, ROLLERS, ChassisSpec, mjcf

mujoco = pytest.importorskip("mujoco")
mujoco_chassis = pytest.importorskip("mecanum_mav.sim.mujocochassis")
MujocoChassis = mujoco_chassis.MujocoChassis

DT = 0.01  # the board's step at SIM_RATE 100 Hz
STOP = (0.0, 0.0, 0.0, 0.0)


def params(**values: float) -> Params:
    p = Params()
    p.update(values)
    return p


def wheel_commands(p: Params, vx: float, vy: float, yaw_rate: float) -> list[float]:
    """The project's inverse kinematics, as normalized commands (FRD, m/s, rad/s cw)."""
    kin = MecanumKinematics.from_half_extents(p["GEO_HALF_LEN"], p["GEO_HALF_WID"])
    return [w / p["WHL_MAX_SPD"] for w in kin.to_wheel_speeds(vx, vy, yaw_rate)]


def run(chassis, seconds: float, commands) -> None:
    for _ in range(round(seconds / DT)):
        chassis.step(DT, commands)


def driven(twist: tuple[float, float, float], seconds: float = 2.0, pose=ORIGIN_POSE,
           **values: float):
    p = params(**values)
    chassis = MujocoChassis.from_params(p, pose)
    run(chassis, seconds, wheel_commands(p, *twist))
    return chassis


# --------------------------------------------------------------------------- the model text


def test_the_model_has_four_wheels_of_twelve_rollers_at_45_degrees_in_the_x_pattern():
    p = Params()
    root = ET.fromstring(mjcf(ChassisSpec.from_params(p)))
    wheels = {b.get("name"): b for b in root.iter("body") if b.get("name", "").startswith("w")}
    assert list(wheels) == ["wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"]
    length, width = p["GEO_HALF_LEN"], p["GEO_HALF_WID"]
    # (MuJoCo's frame is FLU: y left; FL is forward and left)
    assert [tuple(map(float, w.get("pos").split()))[:2] for w in wheels.values()] == [
        (length, width), (length, -width), (-length, width), (-length, -width)]
    for name, wheel in wheels.items():
        assert wheel.find("joint").get("axis") == "0 1 0"
        rollers = wheel.findall("body")
        assert len(rollers) == ROLLERS == 12
        for roller in rollers:
            axis = np.array([float(v) for v in roller.get("zaxis").split()])
            # 45 degrees to the wheel axis (y)
            assert math.degrees(math.acos(abs(axis[1]))) == pytest.approx(45.0)
        bottom = np.array([float(v) for v in rollers[0].get("zaxis").split()])
        # at the contact point the roller axis is along (1, s) in FRD: (1, -s) in FLU, with
        # s = +1 for FL and RR (they roll at vx + vy), -1 for FR and RL
        s = 1.0 if name in ("wheel_fl", "wheel_rr") else -1.0
        assert bottom == pytest.approx([1 / math.sqrt(2), -s / math.sqrt(2), 0.0])


def test_the_floor_friction_is_sim_friction():
    root = ET.fromstring(mjcf(ChassisSpec.from_params(params(SIM_FRICTION=0.4))))
    friction = root.find("default/geom").get("friction")
    assert float(friction.split()[0]) == 0.4


@pytest.mark.parametrize("top_speed", [1.0, 3.0, 10.0, 20.0])
def test_a_roller_passes_the_floor_in_at_least_one_and_a_half_integration_steps(top_speed):
    spec = ChassisSpec.from_params(params(WHL_MAX_SPD=top_speed))
    step = float(ET.fromstring(mjcf(spec)).find("option").get("timestep"))
    assert step == spec.timestep_s <= 0.001
    rho = spec.wheel_radius_m * (1 - ROLLER_SHORT_FRACTION)  # where the rollers' centres are
    roller_pass_s = 2 * math.pi * rho / ROLLERS / top_speed
    assert roller_pass_s / step >= 1.5 - 1e-9
    if top_speed <= 3.0:
        assert step == 0.001  # (the common robots keep the common step)
    solref = ET.fromstring(mjcf(spec)).find("default/geom").get("solref").split()
    assert float(solref[0]) == pytest.approx(2 * step)  # the stiffest contact MuJoCo allows


# --------------------------------------------------------------------------- driving


def settled_twist(twist: tuple[float, float, float]) -> tuple[float, float, float]:
    """The mean true (forward, right m/s, clockwise rad/s) over the second after one second of
    the wheel speeds ``twist`` gives, from a robot at the origin facing north (on 0.8)."""
    p = Params()
    chassis = MujocoChassis.from_params(p)
    commands = wheel_commands(p, *twist)
    run(chassis, 1.0, commands)
    x0, y0, yaw0 = chassis.pose
    run(chassis, 1.0, commands)
    x1, y1, yaw1 = chassis.pose
    assert abs(yaw1) < 0.05 or twist[2] != 0.0  # (straight legs keep facing north)
    turned = math.remainder(yaw1 - yaw0, 2 * math.pi)
    return (x1 - x0, y1 - y0, turned)


def test_forward_wheel_speeds_give_the_kinematic_forward_speed_within_5_percent():
    forward, right, yaw_rate = settled_twist((0.5, 0.0, 0.0))
    error = forward / 0.5 - 1.0
    print(f"forward 0.5 m/s on friction 0.8: {forward:.4f} m/s ({error:+.1%})")
    assert abs(error) < 0.05
    assert abs(right) < 0.005 and abs(yaw_rate) < 0.01


def test_rotate_wheel_speeds_give_the_kinematic_yaw_rate_within_5_percent():
    forward, right, yaw_rate = settled_twist((0.0, 0.0, 1.0))
    error = yaw_rate / 1.0 - 1.0
    print(f"rotate 1 rad/s on friction 0.8: {yaw_rate:.4f} rad/s ({error:+.1%})")
    assert abs(error) < 0.05
    assert math.hypot(forward, right) < 0.005  # on the spot


def test_strafe_wheel_speeds_strafe_right_at_a_measured_efficiency():
    forward, right, yaw_rate = settled_twist((0.0, 0.5, 0.0))
    efficiency = right / 0.5
    print(f"strafe efficiency on friction 0.8: {efficiency:.3f} (achieved / commanded)")
    assert 0.6 < efficiency <= 1.01  # east: right of a robot facing north
    assert abs(forward) < 0.005 and abs(yaw_rate) < 0.01


def test_forward_moves_along_the_heading_in_ned():
    chassis = driven((0.5, 0.0, 0.0), seconds=1.0, pose=Pose2d(1.0, 2.0, math.pi / 2))
    assert chassis.pose.y_m > 2.3  # facing east, it went east
    assert chassis.pose.x_m == pytest.approx(1.0, abs=0.01)
    assert chassis.pose.yaw_rad == pytest.approx(math.pi / 2, abs=0.01)
    assert chassis.roll_pitch == pytest.approx((0.0, 0.0), abs=0.01)


@pytest.mark.parametrize("friction", [0.4, 0.8])
def test_a_hard_brake_from_1_m_s_slides_further_than_the_wheels_roll(friction):
    chassis = driven((1.0, 0.0, 0.0), seconds=1.5, SIM_FRICTION=friction)
    start, rolled = chassis.pose.x_m, chassis.wheel_distances_m
    run(chassis, 2.0, STOP)
    slid = chassis.pose.x_m - start
    wheels = max(d - r for d, r in zip(chassis.wheel_distances_m, rolled, strict=True))
    print(f"brake from 1 m/s on friction {friction}: the body slid {slid * 100:.1f} cm, "
          f"the wheels rolled {wheels * 100:.1f} cm")
    assert slid > wheels + 0.03  # the encoders count the wheel, not the ground
    # it stops no sooner than friction allows (v^2 / 2 mu g), and not much later
    assert 1.0 / (2 * friction * 9.81) < slid < 2.0 / (2 * friction * 9.81)
    assert abs(chassis.velocity_body[0]) < 0.001


def test_a_slippery_floor_slides_further_than_a_grippy_one():
    def slide(friction: float) -> float:
        chassis = driven((1.0, 0.0, 0.0), seconds=1.5, SIM_FRICTION=friction)
        start = chassis.pose.x_m
        run(chassis, 1.5, STOP)
        return chassis.pose.x_m - start

    assert slide(0.4) > 1.5 * slide(0.8)


def test_at_rest_with_zero_commands_nothing_creeps_in_10_s():
    chassis = MujocoChassis.from_params(Params(), Pose2d(3.0, -1.0, 0.5))
    run(chassis, 10.0, STOP)
    x, y, yaw = chassis.pose
    creep = math.hypot(x - 3.0, y + 1.0)
    print(f"creep in 10 s at rest: {creep * 1000:.4f} mm, {math.degrees(yaw - 0.5):.5f} deg")
    assert creep < 0.001
    assert abs(math.degrees(yaw - 0.5)) < 0.1
    assert max(map(abs, chassis.wheel_distances_m)) < 0.001


def test_energy_never_appears_from_nowhere_after_a_push_with_the_motors_off():
    chassis = MujocoChassis.from_params(Params())
    chassis.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_ACTUATION  # motors off
    chassis.push(1.0, 0.5, 1.5)
    chassis.step(0.002, STOP)  # (MuJoCo reports the energy of its last timestep's start)
    start = chassis.kinetic_energy_j
    energies = []
    for _ in range(500):
        chassis.step(0.002, STOP)
        energies.append(chassis.kinetic_energy_j)
    print(f"kinetic energy after a push, motors off: {start:.3f} J, at most "
          f"{max(energies):.3f} J after, {energies[-1]:.3f} J 1 s later")
    assert max(energies) <= start + 1e-6
    assert energies[-1] < 0.8 * start  # friction (gearboxes, rollers) takes it
    assert chassis.pose.x_m > 0.5  # it was pushed, and coasted


def test_a_command_inside_the_esc_dead_band_does_not_drive_the_wheels():
    idle = MujocoChassis.from_params(params(SIM_ESC_DZ=0.05))
    run(idle, 1.0, (0.04, 0.04, 0.04, 0.04))
    assert max(map(abs, idle.wheel_distances_m)) < 1e-4
    moving = MujocoChassis.from_params(params(SIM_ESC_DZ=0.05))
    run(moving, 1.0, (0.06, 0.06, 0.06, 0.06))
    assert min(moving.wheel_distances_m) > 0.03  # ~0.06 m/s for ~0.9 s


def test_the_wheels_follow_the_command_with_the_motor_lag():
    tau = 0.2
    chassis = MujocoChassis.from_params(params(SIM_MOTOR_TAU=tau))
    run(chassis, tau, (0.5, 0.5, 0.5, 0.5))
    # one time constant: 1 - 1/e of the 0.5 m/s target (the servo trails the filter a bit)
    assert np.mean(chassis.wheel_speeds_mps) == pytest.approx(0.5 * (1 - math.exp(-1)), rel=0.1)
    run(chassis, 5 * tau, (0.5, 0.5, 0.5, 0.5))
    assert np.mean(chassis.wheel_speeds_mps) == pytest.approx(0.5, rel=0.02)


def test_splitting_a_step_changes_nothing_beyond_rounding():
    whole, split = MujocoChassis.from_params(Params()), MujocoChassis.from_params(Params())
    commands = wheel_commands(Params(), 0.4, 0.2, 0.5)
    for _ in range(50):
        whole.step(0.02, commands)
        split.step(0.007, commands)
        split.step(0.013, commands)
    assert split.time_s == pytest.approx(whole.time_s)
    assert split.pose == pytest.approx(whole.pose, abs=1e-9)
    assert split.wheel_distances_m == pytest.approx(whole.wheel_distances_m, abs=1e-9)


def test_non_finite_commands_stop_and_out_of_range_ones_are_limited():
    def after(commands):
        chassis = MujocoChassis.from_params(Params())
        run(chassis, 0.5, commands)
        return chassis.pose

    assert after((math.nan, math.inf, -math.inf, math.nan)) == after(STOP)
    assert after((5.0, 5.0, 5.0, 5.0)) == after((1.0, 1.0, 1.0, 1.0))
    assert after((-7.0, 3.0, 3.0, -7.0)) == after((-1.0, 1.0, 1.0, -1.0))
    with pytest.raises(ValueError, match="4 wheel"):
        MujocoChassis.from_params(Params()).step(DT, (0.0, 0.0))
    with pytest.raises(ValueError, match="finite"):
        MujocoChassis.from_params(Params()).step(math.nan, STOP)


def test_the_chassis_costs_at_most_a_third_of_a_cpu_second_per_simulated_second():
    # its own thread's CPU time, not the wall's: the suite's other workers share the cores
    factor = mujoco_chassis.real_time_factor(Params(), seconds=2.0, clock=time.thread_time)
    print(f"MuJoCo chassis: {factor:.1f}x real time on one core")
    assert factor >= 3.0


def test_the_pose_and_rates_are_of_the_same_instant_as_the_wheel_distances():
    # MuJoCo's derived xmat/cvel are from the start of its last step: read from them, the
    # ATTITUDE yaw lags WHEEL_DISTANCE and the position by a timestep (0.1 degrees at 1 rad/s).
    p = params()
    chassis = MujocoChassis.from_params(p)
    run(chassis, 1.0, wheel_commands(p, 0.5, 0.3, 1.0))
    reported = (chassis.pose, chassis.yaw_rate, chassis.velocity_body, chassis.roll_pitch)
    mujoco_chassis.mujoco.mj_forward(chassis.model, chassis.data)  # derived from the state now
    pose, yaw_rate, velocity, roll_pitch = reported
    assert pose.yaw_rad == pytest.approx(chassis.pose.yaw_rad, abs=1e-9)
    assert yaw_rate == pytest.approx(chassis.yaw_rate, abs=1e-9)
    assert velocity == pytest.approx(chassis.velocity_body, abs=1e-9)
    assert roll_pitch == pytest.approx(chassis.roll_pitch, abs=1e-9)
    assert yaw_rate > 0.5  # (it was turning)


def test_translating_while_turning_the_wheels_odometry_stays_within_0_3_percent_sideways():
    # 1 m/s north (held in the world frame) while turning at 1 rad/s, 3 s; the wheels'
    # odometry with the true yaw (as the companion has from ATTITUDE). A soft roller contact
    # (5 ms at a 2 ms step) lets the wheels follow the ground late: 1.65 cm to the side.
    p = params(WHL_MAX_SPD=3.0)
    kin = MecanumKinematics.from_half_extents(p["GEO_HALF_LEN"], p["GEO_HALF_WID"])
    chassis = MujocoChassis.from_params(p)
    odometry = MecanumOdometry(kin, chassis.wheel_distances_m, chassis.pose,
                               chassis.pose.yaw_rad)
    dt, ramp = 0.002, 0.5
    for k in range(1, 1501):
        scale = min(1.0, k * dt / ramp)
        yaw = chassis.pose.yaw_rad
        forward, right = scale * math.cos(yaw), -scale * math.sin(yaw)
        wheels = kin.to_wheel_speeds(forward, right, scale * 1.0)
        chassis.step(dt, [w / p["WHL_MAX_SPD"] for w in wheels])
        if k % 50 == 0:  # WHEEL_DISTANCE at 10 Hz
            odometry.update(chassis.wheel_distances_m, chassis.pose.yaw_rad)
    truth, estimate = chassis.pose, odometry.pose
    sideways = estimate.y_m - truth.y_m
    print(f"1 m/s turning at 1 rad/s: {truth.x_m:.3f} m north; odometry {sideways * 100:+.2f} cm"
          f" east of the truth, {(estimate.x_m - truth.x_m) * 100:+.2f} cm north")
    assert truth.x_m > 2.5 and abs(truth.yaw_rad) > 2.0  # (it drove and turned)
    assert abs(sideways) < 0.003 * truth.x_m


# --------------------------------------------------------------------------- wheel contacts


def test_at_rest_the_wheels_normal_forces_sum_to_the_weight_and_are_about_equal():
    # Kills: a roller's contact force counted for the wrong wheel or not at all (the geom ->
    # wheel map), the friction component read as the normal one.
    p = Params()
    chassis = MujocoChassis.from_params(p)
    run(chassis, 0.2, STOP)
    contacts = chassis.wheel_contacts()
    forces = [c.normal_n for c in contacts]
    weight = p["SIM_MASS"] * 9.81
    assert sum(forces) == pytest.approx(weight, rel=0.02)
    assert forces == pytest.approx([weight / 4] * 4, rel=0.05)
    assert not any(c.slipping for c in contacts)


def test_a_full_command_launch_on_friction_0_4_slips_and_a_steady_cruise_does_not():
    # Kills: slip read from the roller's centre (its rolling motion, not the contact point's)
    # or never flagged; and a contact at the threshold flagged while it rolls.
    chassis = MujocoChassis.from_params(params(SIM_FRICTION=0.4))
    slipped = set()
    for _ in range(40):  # the first 0.4 s
        chassis.step(DT, (1.0, 1.0, 1.0, 1.0))
        slipped |= {k for k, c in enumerate(chassis.wheel_contacts()) if c.slipping}
    assert slipped  # the wheels spin up faster than the rover can follow
    run(chassis, 1.0, (0.5, 0.5, 0.5, 0.5))
    contacts = chassis.wheel_contacts()
    assert not any(c.slipping for c in contacts)
    assert max(c.slip_mps for c in contacts) < mujoco_chassis.SLIP_MPS


def contact_truth(chassis) -> tuple[list[float], list[float], list[int]]:
    """Each wheel's normal force (N) and fastest contact point over the floor (m/s), and its
    number of rollers touching, computed apart from the chassis: the force of every
    roller-floor contact, and the floor-plane speed of the roller's material point at the
    contact from its body Jacobian (MuJoCo's mj_jac)."""
    model, data = chassis.model, chassis.data
    floor = model.geom("floor").id
    normal, slip, touching = [0.0] * 4, [0.0] * 4, [0] * 4
    force = np.zeros(6)
    jacp = np.zeros((3, model.nv))
    for i in range(data.ncon):
        contact = data.contact[i]
        geoms = {int(contact.geom1), int(contact.geom2)}
        if floor not in geoms or len(geoms) != 2:
            continue
        (roller,) = geoms - {floor}
        body = int(model.geom_bodyid[roller])
        name = model.body(body).name  # a roller's body: roller_<wheel><k>
        wheel = next((k for k, w in enumerate(("fl", "fr", "rl", "rr"))
                      if name.lower().startswith(f"roller_{w}")), None)
        if wheel is None:
            continue
        mujoco.mj_contactForce(model, data, i, force)
        normal[wheel] += force[0]
        mujoco.mj_jac(model, data, jacp, None, contact.pos, body)
        v = jacp @ data.qvel
        slip[wheel] = max(slip[wheel], math.hypot(v[0], v[1]))
        touching[wheel] += 1
    return normal, slip, touching


def test_each_wheels_contact_is_the_sum_of_its_rollers_forces_and_their_fastest_point():
    # The docstring's rule (normal force summed over its rollers touching the floor, slip the
    # fastest of its contact points over the floor), against MuJoCo's own Jacobian, every
    # step of a drive that strafes, turns and brakes on a slippery floor.
    chassis = MujocoChassis.from_params(params(SIM_FRICTION=0.4))
    p = Params()
    legs = [wheel_commands(p, 0.6, 0.4, 0.8), (1.0, -1.0, -1.0, 1.0), STOP]
    two_rollers = slipped = 0
    for commands in legs:
        for _ in range(40):
            chassis.step(DT, commands)
            # (mj_step leaves velocities a step newer than the contacts and the Jacobian's
            # positions; mj_forward makes them of one instant, as after the step's start)
            mujoco.mj_forward(chassis.model, chassis.data)
            normal, slip, touching = contact_truth(chassis)
            contacts = chassis.wheel_contacts()
            assert [c.normal_n for c in contacts] == pytest.approx(normal, rel=1e-9, abs=1e-9)
            assert [c.slip_mps for c in contacts] == pytest.approx(slip, rel=1e-6, abs=1e-9)
            assert [c.slipping for c in contacts] == [s > mujoco_chassis.SLIP_MPS for s in slip]
            two_rollers += any(n > 1 for n in touching)
            slipped += any(c.slipping for c in contacts)
    assert two_rollers and slipped  # (the drive had the cases the rule is about)


def test_the_real_time_factor_is_simulated_seconds_over_the_clocks_seconds():
    ticks = iter([100.0, 100.5])  # the clock before and after: half a second
    assert mujoco_chassis.real_time_factor(Params(), seconds=2.0,
                                           clock=lambda: next(ticks)) == pytest.approx(4.0)
    frozen = iter([7.0, 7.0])  # a clock too coarse to see it: as fast as can be told
    assert mujoco_chassis.real_time_factor(Params(), seconds=0.1,
                                           clock=lambda: next(frozen)) == math.inf


def steps_taken(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """Each MuJoCo chassis step's dt from now on (the steps themselves skipped: quick)."""
    steps: list[float] = []
    monkeypatch.setattr(MujocoChassis, "step", lambda self, dt, commands: steps.append(dt))
    return steps


def test_the_real_time_factor_steps_the_chassis_at_sim_rate_for_the_seconds_asked(
        monkeypatch: pytest.MonkeyPatch):
    steps = steps_taken(monkeypatch)
    p = params(SIM_RATE=50.0)
    seconds = iter([10.0, 11.0, 20.0, 21.0])  # the clock: one second each time
    assert mujoco_chassis.real_time_factor(p, seconds=0.5,
                                           clock=lambda: next(seconds)) == pytest.approx(0.5)
    assert steps == [pytest.approx(1 / 50.0)] * 25
    steps.clear()
    assert mujoco_chassis.real_time_factor(p, seconds=1 / 50.0,  # a single step
                                           clock=lambda: next(seconds)) == pytest.approx(0.02)
    assert steps == [pytest.approx(1 / 50.0)]


def test_the_sim_commands_real_time_factor_measures_as_the_chassiss_own(
        monkeypatch: pytest.MonkeyPatch):
    # physics.mujoco_real_time_factor (what `sim --physics mujoco` prints) is
    # mujocochassis.real_time_factor on the wall's clock: the same steps, by default too
    from mecanum_mav.sim import physics

    steps = steps_taken(monkeypatch)
    p = params(SIM_RATE=50.0)
    assert physics.mujoco_real_time_factor(p, seconds=0.5) > 0.0
    assert steps == [pytest.approx(1 / 50.0)] * 25
    steps.clear()
    mujoco_chassis.real_time_factor(p)
    by_default = len(steps)
    steps.clear()
    assert physics.mujoco_real_time_factor(p) > 0.0
    assert len(steps) == by_default


def test_a_new_chassis_already_rests_on_its_wheels_at_its_pose():
    # The constructor lets it settle on the floor before the first step: the wheels carry its
    # weight and the first second at rest moves it by less than a millimetre.
    p = Params()
    start = Pose2d(2.0, -1.0, 3.0)
    chassis = MujocoChassis.from_params(p, start)
    assert sum(c.normal_n for c in chassis.wheel_contacts()) == pytest.approx(
        p["SIM_MASS"] * 9.81, rel=0.02)
    assert tuple(chassis.pose) == pytest.approx(tuple(start), abs=1e-9)
    run(chassis, 1.0, STOP)
    x, y, yaw = chassis.pose
    assert math.hypot(x - start.x_m, y - start.y_m) < 1e-3 and abs(yaw - 3.0) < 1e-3



@pytest.mark.parametrize("yaw", [math.pi, -math.pi, 3 * math.pi, 2.5])
def test_the_heading_is_reported_in_minus_pi_to_pi(yaw):
    chassis = MujocoChassis.from_params(Params(), Pose2d(0.0, 0.0, yaw))
    reported = chassis.pose.yaw_rad
    assert -math.pi <= reported < math.pi
    assert math.remainder(reported - yaw, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
