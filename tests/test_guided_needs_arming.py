"""GUIDED moves the wheels only while armed: a disarmed rover in GUIDED takes setpoints but
stays at neutral (control/vehicle.py ``autonomous``), in the lockstep harness."""

from __future__ import annotations

from conftest import lockstep

from mecanum_mav.io.links import mavlink
from mecanum_mav.protocol.modes import Mode

VELOCITY_ONLY = 1 | 2 | 4 | 64 | 128 | 256 | 1024 | 2048
NEUTRAL = [1500] * 4


def test_a_disarmed_rover_in_guided_stays_at_neutral_under_a_velocity_setpoint():
    h = lockstep()
    assert h.gcs.set_mode(Mode.GUIDED) == mavlink.MAV_RESULT_ACCEPTED
    assert not h.core.vehicle.armed
    start_s = h.now_s
    stop = h.every(0.05, lambda now_s: h.gcs.mav.set_position_target_local_ned_send(
        0, 1, 1, mavlink.MAV_FRAME_BODY_FRD, VELOCITY_ONLY, 0, 0, 0, 0.5, 0.3, 0, 0, 0, 0, 0, 0))
    h.run_for(1.0)
    stop()
    sent = h.overrides_since(start_s)
    assert sent and all(o.channels[:4] == NEUTRAL for o in sent)
    pose = h.truth().pose
    assert abs(pose.x_m) < 1e-9 and abs(pose.y_m) < 1e-9
