"""GUIDED's limits (control/guided.py): a setpoint asking for more than ``GUID_SPD_MAX`` or
``GUID_YAW_RATE`` gets exactly that much ("largest translation speed / yaw rate, whatever the
setpoint asks": the parameter reference), in the controller itself (time passed in) and on the
simulated rover in the lockstep harness."""

from __future__ import annotations

import math

import pytest
from conftest import lockstep

from mecanum_mav.config.params import Params
from mecanum_mav.control.guided import GuidedController, Setpoint
from mecanum_mav.io.links import mavlink
from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.lockstep import Lockstep

ORIGIN = Pose2d(0.0, 0.0, 0.0)
FAST = {"GUID_ACC_MAX": 10.0}
"""A slew limit that is not what a test is about (reached in a few steps)."""


def controller(**values: float) -> GuidedController:
    params = Params()
    params.update({**FAST, **values})
    c = GuidedController(params)
    c.start(ORIGIN, 0.0)
    return c


def settle(c: GuidedController, setpoint: Setpoint, pose: Pose2d = ORIGIN,
           seconds: float = 1.0) -> tuple[float, float, float]:
    """Accept ``setpoint`` and update at 50 Hz for ``seconds``; the last command (forward,
    right m/s, yaw rate rad/s clockwise)."""
    c.accept(setpoint, pose)
    out = (0.0, 0.0, 0.0)
    for k in range(1, round(seconds * 50) + 1):
        out = tuple(c.update(pose, k / 50))
    return out


# ------------------------------------------------------------------------------ speed

def test_a_velocity_faster_than_guid_spd_max_is_driven_at_guid_spd_max_in_its_direction():
    c = controller(GUID_SPD_MAX=0.5)
    forward, right, _ = settle(c, Setpoint(None, (1.2, 1.6), None, None, 0.0))  # 2 m/s
    assert (forward, right) == pytest.approx((0.3, 0.4), abs=1e-12)  # 0.5 m/s, same way
    assert c.velocity_ned == pytest.approx((0.3, 0.4), abs=1e-12)


def test_a_far_position_target_with_a_fast_feed_forward_is_driven_at_guid_spd_max():
    """Position (P controller) plus velocity feed-forward: the sum is limited, not only the
    P term (10 m away at GUID_POS_P 1.5 asks for 15 m/s, the feed-forward 3 m/s more)."""
    c = controller(GUID_SPD_MAX=0.5)
    forward, right, _ = settle(c, Setpoint((10.0, 0.0), (0.0, 3.0), None, None, 0.0))
    assert math.hypot(forward, right) == pytest.approx(0.5, abs=1e-12)
    assert forward > 0.0 and right > 0.0


def test_a_far_position_target_alone_is_driven_at_guid_spd_max():
    c = controller(GUID_SPD_MAX=0.4)
    forward, right, _ = settle(c, Setpoint((-20.0, 0.0), None, None, None, 0.0))
    assert (forward, right) == pytest.approx((-0.4, 0.0), abs=1e-12)


# --------------------------------------------------------------------------- yaw rate

@pytest.mark.parametrize("asked", [3.0, -3.0])
def test_a_yaw_rate_beyond_guid_yaw_rate_turns_at_guid_yaw_rate(asked):
    c = controller(GUID_YAW_RATE=45.0)  # deg/s
    _, _, rate = settle(c, Setpoint(None, None, None, asked, 0.0), seconds=0.1)
    assert rate == pytest.approx(math.copysign(math.radians(45.0), asked), rel=1e-12)


@pytest.mark.parametrize("target_deg", [90.0, -90.0])
def test_a_yaw_target_far_off_is_turned_to_at_guid_yaw_rate(target_deg):
    """GUID_YAW_P 20 /s asks 31 rad/s for a quarter turn: GUID_YAW_RATE (30 deg/s) is what
    the rover turns at."""
    c = controller(GUID_YAW_RATE=30.0, GUID_YAW_P=20.0)
    _, _, rate = settle(c, Setpoint(None, None, math.radians(target_deg), None, 0.0),
                        seconds=0.1)
    assert rate == pytest.approx(math.copysign(math.radians(30.0), target_deg), rel=1e-12)


def test_a_setpoints_own_yaw_rate_limit_only_lowers_guid_yaw_rate():
    """A setpoint's ``yaw_rate_max`` is "a lower yaw-rate limit than GUID_YAW_RATE" (AUTO's
    CONDITION_YAW rate): a higher one leaves GUID_YAW_RATE in force."""
    c = controller(GUID_YAW_RATE=30.0, GUID_YAW_P=20.0)
    turn = math.radians(90.0)
    _, _, rate = settle(c, Setpoint(None, None, turn, None, 0.0, yaw_rate_max=10.0),
                        seconds=0.1)
    assert rate == pytest.approx(math.radians(30.0), rel=1e-12)
    _, _, rate = settle(c, Setpoint(None, None, turn, None, 0.0, yaw_rate_max=0.2),
                        seconds=0.1)
    assert rate == pytest.approx(0.2, rel=1e-12)


# ---------------------------------------------------------------- on the simulated rover

VELOCITY_ONLY = 1 | 2 | 4 | 64 | 128 | 256 | 1024 | 2048
RATE_ONLY = 1 | 2 | 4 | 8 | 16 | 32 | 64 | 128 | 256 | 1024


def streaming(h: Lockstep, mask: int, vx: float = 0.0, rate: float = 0.0) -> None:
    """A ground station sending one SET_POSITION_TARGET_LOCAL_NED (LOCAL_NED) at 20 Hz."""
    h.every(0.05, lambda now_s: h.gcs.mav.set_position_target_local_ned_send(
        0, 1, 1, mavlink.MAV_FRAME_LOCAL_NED, mask, 0.0, 0.0, 0.0, vx, 0.0, 0.0, 0.0, 0.0,
        0.0, 0.0, rate))


def guided(values: dict[str, float]) -> Lockstep:
    h = lockstep(values)
    h.gcs.arm()
    assert h.gcs.set_mode(Mode.GUIDED) == mavlink.MAV_RESULT_ACCEPTED
    return h


def test_the_rover_asked_for_0_9_m_s_drives_at_guid_spd_max_and_follows_a_new_value_at_once():
    h = guided({"GUID_SPD_MAX": 0.3})
    streaming(h, VELOCITY_ONLY, vx=0.9)
    h.run_for(2.0)
    assert h.truth().velocity_body == pytest.approx((0.3, 0.0), abs=0.005)
    h.gcs.mav.param_set_send(1, 1, b"GUID_SPD_MAX", 0.6, mavlink.MAV_PARAM_TYPE_REAL32)
    h.run_for(2.0)
    assert h.truth().velocity_body == pytest.approx((0.6, 0.0), abs=0.005)


def test_the_rover_asked_to_turn_at_2_rad_s_turns_at_guid_yaw_rate():
    h = guided({"GUID_YAW_RATE": 30.0})
    streaming(h, RATE_ONLY, rate=2.0)
    h.run_for(1.5)
    assert h.truth().yaw_rate == pytest.approx(math.radians(30.0), rel=0.01)
