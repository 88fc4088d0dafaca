"""The ground station's commands and requests: COMMAND_LONG / COMMAND_INT (a table by command
id: arm and disarm, mode, message intervals, request message, mission current and start, set
home), SET_MODE, PING and FILE_TRANSFER_PROTOCOL (answered with a NAK: no files here).

Every command is answered with COMMAND_ACK (UNSUPPORTED for an id not in the table); SET_MODE
too, with SET_MODE's message id as the command, as ArduPilot does. Only the pilot's commands
for this vehicle count.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from mecanum_mav.control.context import Context, Handler
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.control.missions import MissionControl
from mecanum_mav.control.refusals import Refusal
from mecanum_mav.control.vehicle import Decision
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.messages import CommandMsg, FtpMsg, PingMsg, Result, SetModeMsg
from mecanum_mav.protocol.statustext import Severity
from mecanum_mav.protocol.telemetry import (
    REQUESTABLE,
    StreamSchedule,
    TelemetryState,
    build,
    ftp_nak,
)

__all__ = ["FORCE_ARM_MAGIC", "Command", "Commands"]

FORCE_ARM_MAGIC = 21196.0
"""MAV_CMD_COMPONENT_ARM_DISARM param2 that forces arming past the pre-arm checks (ArduPilot)."""

Command = Callable[[tuple[float, ...], float], Result]
"""A command: (param1..param4, the time s) -> the result to acknowledge."""


def _result(decision: Decision) -> Result:
    return Result.ACCEPTED if decision.accepted else Result.DENIED


class Commands:
    """The command table and the other requests of the ground station.

    Args:
        ctx: what the core shares (addressing, the voice, the vehicle, pre-arm checks).
        streams: the telemetry stream schedule (message intervals).
        estimator: the odometry (set home resets it).
        mission: the mission (set current, start).
        telemetry_state: the state telemetry is built from at a time (request message).
    """

    def __init__(self, ctx: Context, streams: StreamSchedule, estimator: WheelOdometryEstimator,
                 mission: MissionControl,
                 telemetry_state: Callable[[float], TelemetryState]) -> None:
        self._ctx = ctx
        self.vehicle = ctx.vehicle
        self.to_gcs = ctx.to_gcs
        self.streams = streams
        self.estimator = estimator
        self.telemetry_state = telemetry_state
        self._for_us = ctx.for_us
        self._from_pilot = ctx.from_pilot
        self.refuse = ctx.refuse
        self.table: dict[int, Command] = {
            mavlink.MAV_CMD_COMPONENT_ARM_DISARM: self._cmd_arm_disarm,
            mavlink.MAV_CMD_DO_SET_MODE: self._cmd_set_mode,
            mavlink.MAV_CMD_SET_MESSAGE_INTERVAL: self._cmd_set_message_interval,
            mavlink.MAV_CMD_GET_MESSAGE_INTERVAL: self._cmd_get_message_interval,
            mavlink.MAV_CMD_REQUEST_MESSAGE: self._cmd_request_message,
            mavlink.MAV_CMD_DO_SET_MISSION_CURRENT: mission.cmd_set_current,
            mavlink.MAV_CMD_MISSION_START: mission.cmd_start,
            mavlink.MAV_CMD_DO_SET_HOME: self._cmd_set_home,
        }
        """The commands answered, by MAV_CMD id."""

    def routes(self) -> dict[str, Handler]:
        """The messages handled here, by type."""
        return {"COMMAND_LONG": self.on_command, "COMMAND_INT": self.on_command,
                "SET_MODE": self.on_set_mode, "PING": self.on_ping,
                "FILE_TRANSFER_PROTOCOL": self.on_ftp}

    def on_command(self, msg: CommandMsg, now_s: float) -> None:
        """COMMAND_LONG or COMMAND_INT: run from the table, acknowledged."""
        if not (self._for_us(msg.target_system, msg.target_component) and self._from_pilot(msg)):
            return
        command = self.table.get(int(msg.command))
        params = (msg.param1, msg.param2, msg.param3, msg.param4)
        result = Result.UNSUPPORTED if command is None else command(params, now_s)
        self.to_gcs.command_ack_send(msg.command, result, 0, 0, msg.get_srcSystem(),
                                     msg.get_srcComponent())

    def on_set_mode(self, msg: SetModeMsg, now_s: float) -> None:
        """SET_MODE (the old way to change mode), acknowledged as ArduPilot does."""
        if not (self._for_us(msg.target_system) and self._from_pilot(msg)):
            return
        result = self._set_mode(float(msg.base_mode), float(msg.custom_mode), now_s)
        # ArduPilot acknowledges SET_MODE with COMMAND_ACK whose command is SET_MODE's id (11).
        self.to_gcs.command_ack_send(mavlink.MAVLINK_MSG_ID_SET_MODE, result, 0, 0,
                                     msg.get_srcSystem(), msg.get_srcComponent())

    def on_ping(self, msg: PingMsg, now_s: float) -> None:
        """PING: a request (target 0) is answered; an answer is not."""
        if msg.target_system == 0:  # a request (an answer names its target)
            self.to_gcs.ping_send(msg.time_usec, msg.seq, msg.get_srcSystem(),
                                  msg.get_srcComponent())

    def on_ftp(self, msg: FtpMsg, now_s: float) -> None:
        """FILE_TRANSFER_PROTOCOL: a NAK (no files), so a ground station stops asking."""
        if self._for_us(msg.target_system, msg.target_component):
            self.to_gcs.file_transfer_protocol_send(0, msg.get_srcSystem(),
                                                    msg.get_srcComponent(),
                                                    ftp_nak(msg.payload))

    # ------------------------------------------------------------------ the table

    def _cmd_arm_disarm(self, p: tuple[float, ...], now_s: float) -> Result:
        if p[0] == 1.0:
            self.vehicle.update(now_s)
            return _result(self.vehicle.request_arm(
                now_s, self._ctx.prearm_problems(), force=p[1] == FORCE_ARM_MAGIC))
        if p[0] == 0.0:
            return _result(self.vehicle.request_disarm("by command"))
        self.refuse(Refusal.COMMAND, f"Arm/disarm: param1 must be 0 or 1, got {p[0]}")
        return Result.DENIED

    def _cmd_set_mode(self, p: tuple[float, ...], now_s: float) -> Result:
        return self._set_mode(p[0], p[1], now_s)

    def _cmd_set_message_interval(self, p: tuple[float, ...], now_s: float) -> Result:
        ok = math.isfinite(p[0]) and self.streams.set_interval(int(p[0]), p[1])
        return Result.ACCEPTED if ok else Result.DENIED

    def _cmd_get_message_interval(self, p: tuple[float, ...], now_s: float) -> Result:
        interval = self.streams.get_interval_us(int(p[0])) if math.isfinite(p[0]) else None
        if interval is None:
            return Result.DENIED
        self.to_gcs.message_interval_send(int(p[0]), interval)
        return Result.ACCEPTED

    def _cmd_request_message(self, p: tuple[float, ...], now_s: float) -> Result:
        name = REQUESTABLE.get(int(p[0])) if math.isfinite(p[0]) else None
        if name is None:
            return Result.DENIED
        build(name, self.to_gcs, self.telemetry_state(now_s))
        return Result.ACCEPTED

    def _cmd_set_home(self, p: tuple[float, ...], now_s: float) -> Result:
        if p[0] != 1.0:
            self.refuse(Refusal.COMMAND, "Set home: only 'use current position' (param1=1)")
            return Result.DENIED
        self.estimator.reset(now_s)
        self._ctx.say(Severity.INFO, "Home and odometry origin set here")
        return Result.ACCEPTED

    def _set_mode(self, base_mode: float, custom_mode: float, now_s: float) -> Result:
        if not (math.isfinite(base_mode) and math.isfinite(custom_mode)):
            self.refuse(Refusal.COMMAND, "Set mode: base and custom mode must be numbers")
            return Result.DENIED
        if not int(base_mode) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            self.refuse(Refusal.COMMAND, "Set mode: only custom (Rover) modes are supported")
            return Result.UNSUPPORTED
        return _result(self.vehicle.request_mode(int(custom_mode), now_s))
