"""Arming over COMMAND_LONG (control/core.py): only ArduPilot's magic param2 (21196) forces an
arm past the pre-arm checks, and only the flight controller's own HEARTBEAT on its link counts
as the flight controller (lockstep harness and the core itself, virtual time)."""

from __future__ import annotations

from conftest import lockstep

from mecanum_mav.config.params import Params
from mecanum_mav.control.core import RoverCore
from mecanum_mav.io.links import mavlink

ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
DENIED, ACCEPTED = mavlink.MAV_RESULT_DENIED, mavlink.MAV_RESULT_ACCEPTED


def test_only_param2_21196_forces_an_arm_with_the_sticks_deflected():
    h = lockstep()
    stop = h.every(0.05, lambda now_s: h.gcs.mav.manual_control_send(1, 0, 800, 0, 0, 0))
    h.run_for(0.2)
    for param2 in (1.0, -1.0, 21195.0):
        ack = h.gcs.command(ARM, 1, param2)
        assert ack is not None and ack.result == DENIED, param2
        assert not h.core.vehicle.armed
    ack = h.gcs.command(ARM, 1, 21196.0)
    stop()
    assert ack is not None and ack.result == ACCEPTED and h.core.vehicle.armed


def heartbeat_from(system: int):
    mav = mavlink.MAVLink(None, srcSystem=system, srcComponent=1)
    msg = mav.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                               0, 0, mavlink.MAV_STATE_ACTIVE)
    msg.pack(mav)
    return msg


def test_a_heartbeat_from_another_system_on_the_flight_controllers_link_is_not_the_board():
    params = Params()
    core = RoverCore(params, now_s=0.0)
    fc = int(params["FC_SYSID"])
    core.handle(heartbeat_from(fc + 6), 0.1, from_fc=True)
    core.tick(0.1)
    assert core.vehicle.fc_lost
    core.handle(heartbeat_from(fc), 0.2, from_fc=True)
    core.tick(0.2)
    assert not core.vehicle.fc_lost
