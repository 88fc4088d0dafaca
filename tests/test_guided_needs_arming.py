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


def test_disarming_in_guided_stops_the_wheels_and_arming_again_drives_without_a_mode_change():
    """Disarm and arm again while staying in GUIDED (as a pilot does with the arm switch):
    neutral while disarmed, and the rover obeys the setpoints again once armed."""
    h = lockstep()
    h.gcs.arm()
    assert h.gcs.set_mode(Mode.GUIDED) == mavlink.MAV_RESULT_ACCEPTED
    stop = h.every(0.05, lambda now_s: h.gcs.mav.set_position_target_local_ned_send(
        0, 1, 1, mavlink.MAV_FRAME_BODY_FRD, VELOCITY_ONLY, 0, 0, 0, 0.5, 0.0, 0, 0, 0, 0, 0, 0))
    h.run_for(1.0)
    assert h.truth().pose.x_m > 0.2  # driving
    disarm = h.gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    assert disarm is not None and disarm.result == mavlink.MAV_RESULT_ACCEPTED
    disarmed_s = h.now_s
    h.run_for(1.0)
    assert all(o.channels[:4] == NEUTRAL for o in h.overrides_since(disarmed_s + 0.1))
    stopped_at = h.truth().pose.x_m
    h.gcs.arm()
    assert h.core.vehicle.mode is Mode.GUIDED
    h.run_for(1.0)
    stop()
    assert h.truth().pose.x_m > stopped_at + 0.2  # driving again
