"""What the flight controller tells the companion: its HEARTBEAT (the link is up; then the
battery stream, the receiver's channels and the setup check are asked for), SYS_STATUS (its
battery), RC_CHANNELS (the receiver, when ``RCIN_ENABLE``), PARAM_VALUE (answers for the setup
check, :mod:`mecanum_mav.control.fccheck`), WHEEL_DISTANCE, ATTITUDE, LOCAL_POSITION_NED and
GPS_RAW_INT (the estimator's: the positions are the heading bias's reference; GPS_RAW_INT's
RTK fixes are placed about the first one heard).

The core routes only messages from the flight controller's own system id here. Each handler
takes one message and its arrival time (s); what goes back to the board is queued in the
shared outbox.
"""

from __future__ import annotations

import math

from mecanum_mav.control.context import NEUTRAL_STICK, Context, Handler
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.control.fccheck import FcCheckState
from mecanum_mav.control.rcinput import RC_CHANNELS_INTERVAL_US, ReceiverInput
from mecanum_mav.control.refusals import Refusal
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.health import BATTERY_FRESH_S, UNKNOWN_BATTERY, Battery
from mecanum_mav.protocol.messages import (
    AttitudeMsg,
    FcGpsMsg,
    FcParamValueMsg,
    FcPositionMsg,
    FcSysStatusMsg,
    RcChannelsMsg,
    Received,
    WheelDistanceMsg,
)
from mecanum_mav.protocol.statustext import Severity

__all__ = ["FC_ATTITUDE_INTERVAL_US", "FC_POSITION_INTERVAL_US", "FC_SYS_STATUS_INTERVAL_US",
           "FcLink"]

FC_SYS_STATUS_INTERVAL_US = 1_000_000
"""The flight controller is asked for SYS_STATUS (its battery) at 1 Hz."""
FC_ATTITUDE_INTERVAL_US = 50_000
"""... and for ATTITUDE at 20 Hz: the odometry's heading (ArduPilot's own stream rate on a
serial port, SRn_EXTRA1, can be a few Hz: measured 2 Hz on SITL's, whose yaw then steered
the odometry half a second late)."""
FC_POSITION_INTERVAL_US = 100_000
"""... and for LOCAL_POSITION_NED at 10 Hz: the track the heading bias is measured against
(:mod:`mecanum_mav.control.headingbias`; a board without a position sends none)."""
GPS_RTK_FIX = 5
"""GPS_RAW_INT ``fix_type`` from which a fix is used for the heading bias: RTK (float or
fixed, GPS_FIX_TYPE_RTK_FLOAT and better). An ordinary 3D fix wanders by a metre or more,
which over the estimator's half-metre windows is tens of degrees; an RTK fix is good to
centimetres. (ArduPilot's SITL reports RTK fixed.)"""
_FC_CHECK_FINE = (FcCheckState.SAFE, FcCheckState.NOT_CHECKED)
"""Verdicts said as a NOTICE; the others as a WARNING."""


class FcLink:
    """The flight controller's observations for one rover.

    Args:
        ctx: what the core shares (identity, the outboxes, the vehicle, the setup check).
        estimator: takes the board's attitude and wheel distances.
    """

    def __init__(self, ctx: Context, estimator: WheelOdometryEstimator) -> None:
        self._ctx = ctx
        self.vehicle = ctx.vehicle
        self.estimator = estimator
        self.fc_check = ctx.fc_check
        self.receiver = ReceiverInput()
        """The RC receiver read through the flight controller (``RCIN_ENABLE``)."""
        self._battery = UNKNOWN_BATTERY
        self._battery_s = -math.inf
        self._fc_streams_asked = False
        self.rc_stream_asked = False
        """The receiver's RC_CHANNELS were asked for (again when the receiver is turned on)."""
        self.refuse = ctx.refuse
        self._gps_origin: GlobalOrigin | None = None  # the first RTK fix
        self._gps_fix_us = -1  # the last fix's time_usec (a repeated one is not a new fix)

    def routes(self) -> dict[str, Handler]:
        """The flight controller's messages handled here, by type."""
        return {"HEARTBEAT": self.on_heartbeat, "ATTITUDE": self.on_attitude,
                "WHEEL_DISTANCE": self.on_wheel_distance, "LOCAL_POSITION_NED": self.on_position,
                "GPS_RAW_INT": self.on_gps, "SYS_STATUS": self.on_sys_status,
                "PARAM_VALUE": self.on_param_value, "RC_CHANNELS": self.on_rc_channels}

    def battery(self, now_s: float) -> tuple[Battery, bool]:
        """The board's battery at ``now_s`` and whether it is fresh (else unknown)."""
        fresh = now_s - self._battery_s <= BATTERY_FRESH_S
        return (self._battery if fresh else UNKNOWN_BATTERY), fresh

    def housekeeping(self, now_s: float) -> None:
        """After the output: a board that was lost is asked again when it comes back, and the
        setup check's timers (asks again, says its verdict)."""
        if self.vehicle.fc_lost:
            self._fc_streams_asked = False  # ask a rebooted flight controller again
            self.rc_stream_asked = False
        fc_check = self.fc_check
        if now_s >= fc_check.next_due_s:
            ctx = self._ctx
            again, verdict = fc_check.tick(ctx.params, now_s)
            ctx.ask_fc_params(again)
            if verdict is not None:
                ctx.say(Severity.NOTICE if fc_check.state in _FC_CHECK_FINE
                        else Severity.WARNING, verdict)

    def on_heartbeat(self, msg: Received, now_s: float) -> None:
        """The board's HEARTBEAT: the link is up; the first asks for its battery and attitude
        streams and starts the setup check; with the receiver read, its channels are asked for."""
        ctx = self._ctx
        self.vehicle.on_fc_heartbeat(now_s)
        if not self._fc_streams_asked:  # the link came up: the battery and the setup check
            self._fc_streams_asked = True
            ctx.ask_fc_params(self.fc_check.start(ctx.params, now_s))
            for msg_id, interval_us in ((mavlink.MAVLINK_MSG_ID_SYS_STATUS,
                                         FC_SYS_STATUS_INTERVAL_US),
                                        (mavlink.MAVLINK_MSG_ID_ATTITUDE,
                                         FC_ATTITUDE_INTERVAL_US),
                                        (mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
                                         FC_POSITION_INTERVAL_US),
                                        (mavlink.MAVLINK_MSG_ID_GPS_RAW_INT,
                                         FC_POSITION_INTERVAL_US)):
                ctx.to_fc.command_long_send(
                    ctx.identity.fc_sysid, ctx.identity.fc_compid,
                    mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0, msg_id, interval_us, 0, 0, 0, 0, 0)
        if ctx.receiver_config.enabled and not self.rc_stream_asked:
            self.rc_stream_asked = True  # the receiver's channels, when it is read
            ctx.to_fc.command_long_send(
                ctx.identity.fc_sysid, ctx.identity.fc_compid,
                mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0, mavlink.MAVLINK_MSG_ID_RC_CHANNELS,
                RC_CHANNELS_INTERVAL_US, 0, 0, 0, 0, 0)

    def on_rc_channels(self, msg: RcChannelsMsg, now_s: float) -> None:
        """The receiver through the flight controller (:mod:`mecanum_mav.control.rcinput`):
        its sticks drive unless a ground station's are fresh; its switches set the mode and
        arm; its failsafe stops the wheels at once and takes ``FS_RC_ACTION``."""
        ctx = self._ctx
        config = ctx.receiver_config
        if not config.enabled:
            return
        pulses = [getattr(msg, f"chan{i}_raw") for i in range(1, 19)]
        frame = self.receiver.frame(msg.chancount, pulses, msg.rssi, config, ctx.rc_input,
                                    now_s)
        vehicle = self.vehicle
        vehicle.on_receiver(frame.problem, now_s)
        gcs_driving = now_s - ctx.gcs_stick_s <= vehicle.config.input_timeout_s
        # (A changed output goes out at once: every message makes the next tick look.)
        if frame.stick is None:
            if not gcs_driving:
                ctx.stick = NEUTRAL_STICK  # the wheels stop now, whatever the action
            return
        if frame.mode is not None:
            vehicle.request_mode(frame.mode, now_s)
        if frame.arm is True:
            vehicle.update(now_s)
            vehicle.request_arm(now_s, ctx.prearm_problems(frame.stick))
        elif frame.arm is False:
            vehicle.request_disarm("by RC switch")
        if not gcs_driving:
            ctx.stick = frame.stick
            ctx.faulted = False
            vehicle.on_stick_input(now_s)

    def on_param_value(self, msg: FcParamValueMsg, now_s: float) -> None:
        """The board's PARAM_VALUE: an answer for the setup check (which may ask again)."""
        self._ctx.ask_fc_params(self.fc_check.on_value(msg.param_id.rstrip("\x00"),
                                                       float(msg.param_value), now_s))

    def on_sys_status(self, msg: FcSysStatusMsg, now_s: float) -> None:
        """The board's SYS_STATUS: its battery (0 or unknown voltage: no monitor, ignored)."""
        if msg.voltage_battery not in (0, UNKNOWN_BATTERY.voltage_mv):  # 0: no monitor
            self._battery = Battery(msg.voltage_battery, msg.current_battery,
                                    msg.battery_remaining)
            self._battery_s = now_s

    def on_attitude(self, msg: AttitudeMsg, now_s: float) -> None:
        """The board's ATTITUDE: its yaw and yaw rate to the estimator."""
        problem = self.estimator.on_attitude(msg.yaw, msg.yawspeed, now_s)
        if problem is not None:
            self.refuse(Refusal.SENSOR, f"Ignored: {problem}")

    def on_position(self, msg: FcPositionMsg, now_s: float) -> None:
        """The board's LOCAL_POSITION_NED: to the estimator's heading bias (what it says once,
        its estimate or its refusal, as a NOTICE)."""
        self._notice(self.estimator.on_position(msg.x, msg.y, now_s))

    def on_gps(self, msg: FcGpsMsg, now_s: float) -> None:
        """The board's GPS_RAW_INT: each new RTK fix (:data:`GPS_RTK_FIX`), placed about the
        first (m, NED), to the estimator's heading bias (what it says once as a NOTICE)."""
        if msg.fix_type < GPS_RTK_FIX or msg.time_usec == self._gps_fix_us:
            return
        self._gps_fix_us = msg.time_usec
        try:
            if self._gps_origin is None:
                self._gps_origin = GlobalOrigin(msg.lat, msg.lon)
        except ValueError:  # not on earth
            return
        self._notice(self.estimator.on_gps(*self._gps_origin.to_local(msg.lat, msg.lon),
                                           now_s))

    def _notice(self, text: str | None) -> None:
        """What the estimator says once (its heading bias settled, or refused), as a NOTICE."""
        if text is not None:
            self._ctx.say(Severity.NOTICE, text)

    def on_wheel_distance(self, msg: WheelDistanceMsg, now_s: float) -> None:
        """The board's WHEEL_DISTANCE (at least four wheels): to the estimator."""
        if msg.count >= 4:
            problem = self.estimator.on_wheel_distance(msg.distance[:4], now_s)
            if problem is not None:
                self.refuse(Refusal.SENSOR, f"Ignored: {problem}")
