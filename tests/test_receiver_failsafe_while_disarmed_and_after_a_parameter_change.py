"""The receiver failsafe (RCIN_ENABLE, FS_THR_ENABLE) where the rover is disarmed, and across a
parameter change (mecanum_mav.control.vehicle's module docstring: it reports CRITICAL,
switches to HOLD or disarms while armed, refuses to arm until the receiver is back; it starts
active only until a receiver is heard). The companion, the board and its simulated receiver in
the lockstep harness (virtual time)."""

from __future__ import annotations

from conftest import lockstep

from mecanum_mav.io.links import mavlink
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.lockstep import Lockstep

RECEIVER = {"RCIN_ENABLE": 1, "MOT_FL_CH": 9, "MOT_FR_CH": 10, "MOT_RL_CH": 11,
            "MOT_RR_CH": 12}
"""The receiver read, the wheels on channels it does not use."""
CENTRE = (1500, 1500, 1500, 1500, 1500, 1500, 1000, 1100)
ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM


def with_receiver() -> Lockstep:
    h = lockstep(RECEIVER)
    h.board.receiver = CENTRE
    assert h.run_until(lambda: not h.core.vehicle.rc_failsafe, 1.0), "receiver never OK"
    return h


def arm_result(h: Lockstep) -> int:
    ack = h.gcs.command(ARM, 1)
    assert ack is not None
    return int(ack.result)


def test_a_receiver_failing_while_disarmed_is_reported_and_blocks_arming_but_keeps_the_mode():
    h = with_receiver()
    since = h.gcs.mark()
    h.board.rssi = 0  # the receiver lost its transmitter
    assert h.run_until(lambda: h.core.vehicle.rc_failsafe, 0.5)
    failsafe = h.gcs.wait("STATUSTEXT", lambda m: m.text.startswith("Radio failsafe"), 0.5,
                          since)
    assert failsafe is not None and failsafe.severity == mavlink.MAV_SEVERITY_CRITICAL
    assert h.core.vehicle.mode is Mode.MANUAL and not h.core.vehicle.armed
    assert arm_result(h) == mavlink.MAV_RESULT_DENIED
    assert "PreArm: radio failsafe (receiver)" in h.gcs.texts(since)
    h.board.rssi = 255
    assert h.run_until(lambda: not h.core.vehicle.rc_failsafe, 0.5)
    assert arm_result(h) == mavlink.MAV_RESULT_ACCEPTED


def test_a_parameter_change_with_the_receiver_heard_does_not_start_its_failsafe():
    """Only a receiver never heard starts in failsafe: with one heard, a new failsafe setting
    (here FS_RC_ACTION) leaves it healthy and the rover arms."""
    h = with_receiver()
    since = h.gcs.mark()
    h.gcs.mav.param_set_send(1, 1, b"FS_RC_ACTION", 1.0, mavlink.MAV_PARAM_TYPE_INT32)
    assert h.gcs.wait("PARAM_VALUE", lambda m: m.param_id == "FS_RC_ACTION", 0.5, since)
    assert h.core.params["FS_RC_ACTION"] == 1
    assert not h.core.vehicle.rc_failsafe
    assert arm_result(h) == mavlink.MAV_RESULT_ACCEPTED
    assert not any(t.startswith(("Radio failsafe", "Radio receiver OK"))
                   for t in h.gcs.texts(since))
