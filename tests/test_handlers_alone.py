"""The core's message handlers each work alone, on a bare Context: no RoverCore, no links,
no clock (what control/context.py promises a newcomer who changes one of them)."""

from __future__ import annotations

from types import SimpleNamespace

from mecanum_mav.config.params import Params
from mecanum_mav.control.commands import Commands
from mecanum_mav.control.context import Context
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.control.fclink import FcLink
from mecanum_mav.control.gcsinput import GcsInput
from mecanum_mav.control.paramlink import ParamLink
from mecanum_mav.control.vehicle import Vehicle
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.health import BATTERY_FRESH_S, UNKNOWN_BATTERY


def bare() -> Context:
    params = Params()
    return Context(params, Vehicle(params), now_s=0.0)


def packed(msg, system: int = 255):
    mav = mavlink.MAVLink(None, srcSystem=system, srcComponent=190)
    msg.pack(mav)
    return msg


ENCODE = mavlink.MAVLink(None)


def test_a_pilots_manual_control_becomes_the_drive_input_of_a_bare_context():
    ctx = bare()
    gcs = GcsInput(ctx, WheelOdometryEstimator(ctx.params), autopilot=None)
    gcs.on_manual_control(packed(ENCODE.manual_control_encode(1, 500, -1000, 0, 250, 0)), 2.0)
    assert ctx.stick == (0.5, -1.0, 0.25)
    assert ctx.new_input and ctx.gcs_stick_s == 2.0 and not ctx.faulted
    another = packed(ENCODE.manual_control_encode(7, 1000, 0, 0, 0, 0))
    gcs.on_manual_control(another, 3.0)  # for another vehicle: nothing changes
    assert ctx.stick == (0.5, -1.0, 0.25) and ctx.gcs_stick_s == 2.0


def test_a_command_alone_is_acknowledged_unsupported_when_not_in_its_table():
    ctx = bare()
    mission = SimpleNamespace(cmd_set_current=None, cmd_start=None)  # (not called here)
    commands = Commands(ctx, streams=None, estimator=None, mission=mission,
                        telemetry_state=None)
    reboot = mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN
    commands.on_command(packed(ENCODE.command_long_encode(1, 1, reboot, 0, 1, 0, 0, 0, 0, 0, 0)),
                        1.0)
    [ack] = ctx.to_gcs.take()
    assert (ack.command, ack.result) == (reboot, mavlink.MAV_RESULT_UNSUPPORTED)
    assert (ack.target_system, ack.target_component) == (255, 190)


def test_a_param_set_alone_answers_and_reconfigures_only_when_accepted():
    ctx = bare()
    reconfigured = []
    link = ParamLink(ctx, lambda: reconfigured.append(True), storage=None)
    link.on_param_set(packed(ENCODE.param_set_encode(
        1, 1, b"INP_EXPO", 0.3, mavlink.MAV_PARAM_TYPE_REAL32)), 1.0)
    assert [m.param_id for m in ctx.to_gcs.take()] == ["INP_EXPO"]
    assert reconfigured == [True] and ctx.params["INP_EXPO"] == 0.3
    link.on_param_set(packed(ENCODE.param_set_encode(
        1, 1, b"INP_EXPO", 7.0, mavlink.MAV_PARAM_TYPE_REAL32)), 2.0)
    assert reconfigured == [True] and ctx.params["INP_EXPO"] == 0.3  # refused: out of range


def test_the_boards_battery_alone_is_known_while_fresh_and_unknown_after():
    ctx = bare()
    fc = FcLink(ctx, WheelOdometryEstimator(ctx.params))
    fc.on_sys_status(packed(ENCODE.sys_status_encode(0, 0, 0, 0, 12_600, 30, 100, 0, 0, 0, 0, 0,
                                                     0), system=1), 1.0)
    battery, fresh = fc.battery(1.0 + BATTERY_FRESH_S)
    assert fresh and battery.voltage_mv == 12_600
    assert fc.battery(1.0 + BATTERY_FRESH_S + 0.01) == (UNKNOWN_BATTERY, False)
