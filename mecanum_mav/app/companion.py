"""The companion: the rover a ground station sees, driving four wheels through a flight controller.

One thread, one loop, top to bottom (:meth:`Companion.run`):

1. Wait until a link is readable or the next timer is due (``selectors``; it never polls, so
   an idle companion uses no CPU).
2. Read everything waiting on both links and handle each message: cheap state updates only.
   Under overload this drains the queue and acts on the newest stick, so latency stays bounded.
3. ``vehicle.update(now)``: timeouts and failsafes.
4. Output: if the vehicle is driving, mix the latest stick into four wheel commands and PWM,
   else neutral (each wheel's trim). Sent at once when new input arrived or the output changed,
   and re-sent at ``OUT_RATE`` so the flight controller's override timeout never lapses.
5. Timers: HEARTBEAT to both links at 1 Hz; STATUSTEXT for every state change.

Identity on the ground-station link: system ``SYSID_THISMAV``, component 1, ArduPilot Rover
dialect (see README). On the flight-controller link the companion is a ground station: it sends
from system ``FC_GCS_SYSID`` (255, ArduPilot's default SYSID_MYGCS), component 190.

Safety: disarmed, HOLD, any failsafe, stale input, an exception while handling a message or
computing the output, and shutdown all end at neutral PWM. On shutdown the wheels go to neutral
first, then the override channels are released to the flight controller.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import selectors
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, BinaryIO

from mecanum_mav.config.params import Params
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.control.executor import MissionExecutor
from mecanum_mav.control.guided import GuidedController, SetpointError, decode_setpoint
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.control.sticks import InputError, RcStickState, stick_from_manual_control
from mecanum_mav.control.vehicle import Decision, Mode, Severity, Vehicle
from mecanum_mav.io.links import Link, mavlink, open_link
from mecanum_mav.io.missionfile import (
    MissionFileError,
    load_mission,
    mission_path_for,
    save_mission,
)
from mecanum_mav.io.paramfile import save
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.mecanum.mixing import (
    ALGORITHM_NAMES,
    Desaturation,
    desaturate_prioritized,
    wheels_from_stick,
)
from mecanum_mav.mecanum.shaping import shape_stick
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.missionlink import MISSION_MESSAGES, MissionLink
from mecanum_mav.protocol.missionservice import MissionService
from mecanum_mav.protocol.paramservice import RESTART_REQUIRED, ParamService, ParamValue
from mecanum_mav.protocol.rcoverride import override_fields, release_fields
from mecanum_mav.protocol.telemetry import (
    REQUESTABLE,
    StreamSchedule,
    TelemetryState,
    build,
    ftp_nak,
)

log = logging.getLogger(__name__)

__all__ = ["Companion"]

COMPANION_COMPID = 1  # MAVSDK only talks to component 1 (the autopilot)
FC_LINK_COMPID = 190  # MAV_COMP_ID_MISSIONPLANNER: a ground station on the FC link
HEARTBEAT_PERIOD_S = 1.0
STATUSTEXT_REPEAT_S = 1.0  # the same rejection is reported at most once a second
MAX_STATUSTEXT = 50

Stick = tuple[float, float, float]


class Companion:
    """The companion process's state and loop.

    Args:
        params: the parameter store (read live; :meth:`reconfigure` after changing it).
        gcs_url: pymavlink URL of the ground-station link.
        fc_url: pymavlink URL of the flight-controller link.
        param_path: the parameter file the companion was started with; accepted PARAM_SETs
            are saved to it (atomically).
        tlog: an open binary file to record both links' traffic to, or None.
        clock: monotonic time source in seconds (tests may inject one).
    """

    def __init__(
        self,
        params: Params,
        gcs_url: str,
        fc_url: str,
        *,
        param_path: Path | None = None,
        tlog: BinaryIO | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.params = params
        self.param_path = param_path
        self.param_service = ParamService(params)
        self.clock = clock
        self.vehicle = Vehicle(params)
        self.sysid = int(params["SYSID_THISMAV"])
        self.gcs: Link = open_link(gcs_url, source_system=self.sysid,
                                   source_component=COMPANION_COMPID, name="gcs")
        self.fc: Link = open_link(fc_url, source_system=int(params["FC_GCS_SYSID"]),
                                  source_component=FC_LINK_COMPID, name="fc")
        if tlog is not None:
            self.gcs.record_to(tlog)
            self.fc.record_to(tlog)
        self.estimator = WheelOdometryEstimator(params)
        self.guided = GuidedController(params)
        self._guided_last: tuple[tuple[float, ...], tuple[int, ...]] | None = None
        self.kinematics = self.estimator.odometry.kinematics  # one geometry for both
        self._next_control_s = math.inf
        self.rc_sticks = RcStickState()
        self.stick: Stick = (0.0, 0.0, 0.0)
        self.pulses_us: tuple[int, ...] = ()
        self.wheels: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)  # commanded, normalized
        self._wheels_s: float | None = None
        self.streams = StreamSchedule(params)
        self._boot_s = clock()
        self._new_input = False
        self._next_output_s = 0.0
        self._next_heartbeat_s = 0.0
        self._said: dict[str, float] = {}
        self._handlers: dict[str, Callable[[Any, float], None]] = {
            "HEARTBEAT": self._on_gcs_heartbeat,
            "MANUAL_CONTROL": self._on_manual_control,
            "RC_CHANNELS_OVERRIDE": self._on_rc_override,
            "COMMAND_LONG": self._on_command,
            "COMMAND_INT": self._on_command,
            "SET_MODE": self._on_set_mode,
            "PARAM_REQUEST_LIST": self._on_param_request_list,
            "PARAM_REQUEST_READ": self._on_param_request_read,
            "PARAM_SET": self._on_param_set,
            "SET_POSITION_TARGET_LOCAL_NED": self._on_position_target,
            "PING": self._on_ping,
            "FILE_TRANSFER_PROTOCOL": self._on_ftp,
        }
        self.mission_path = None if param_path is None else mission_path_for(param_path)
        items = self._read_mission_file()
        self.mission = MissionService(items)
        self.mission_link = MissionLink(self.mission, self.gcs.mav, self._for_us)
        self.executor = MissionExecutor(params)
        self.executor.load(items)
        self._origin_set: GlobalOrigin | None = None  # from SET_GPS_GLOBAL_ORIGIN
        for name in MISSION_MESSAGES:
            self._handlers[name] = self._on_mission_message
        self._handlers["MISSION_SET_CURRENT"] = self._on_mission_set_current
        self._handlers["SET_GPS_GLOBAL_ORIGIN"] = self._on_set_origin
        self._stop = threading.Event()
        self._wake_r, self._wake_w = os.pipe()
        self._thread: threading.Thread | None = None
        self.reconfigure()

    # ================================================================== the loop

    def run(self) -> None:
        """Run until :meth:`stop`; always ends with neutral wheels and released channels."""
        selector = selectors.DefaultSelector()
        selector.register(self._wake_r, selectors.EVENT_READ, None)
        registered = {self.gcs: self.gcs.fileno(), self.fc: self.fc.fileno()}
        for link, fd in registered.items():
            selector.register(fd, selectors.EVENT_READ, link)
        try:
            while not self._stop.is_set():
                now = self.clock()
                due = min(self._next_output_s, self._next_heartbeat_s,
                          self.streams.next_due_s(), self._next_control_s,
                          self.mission.next_due_s())
                timeout = max(0.0, due - now)
                ready = selector.select(timeout)
                for key, _ in ready:
                    if key.data is None:
                        os.read(self._wake_r, 64)
                    else:
                        self._drain(key.data)
                self._tick(self.clock())
                for link, fd in registered.items():  # tcpin swaps its fd on accept
                    if link.fileno() != fd:
                        selector.unregister(fd)
                        registered[link] = link.fileno()
                        selector.register(registered[link], selectors.EVENT_READ, link)
        finally:
            selector.close()
            self._shutdown_outputs()

    def _drain(self, link: Link) -> None:
        now = self.clock()
        for msg in link.read():
            try:
                if link is self.gcs:
                    self._on_gcs_message(msg, now)
                else:
                    self._on_fc_message(msg, now)
            except Exception:  # never let one message take the control path down
                log.exception("error handling %s", msg.get_type())
                self._say(Severity.ERROR, f"Error handling {msg.get_type()}: neutral")
                self._send_output(self._neutral(), now)

    def _tick(self, now: float) -> None:
        """Steps 3-5 of the loop: failsafes, output, heartbeats, status texts."""
        self.vehicle.update(now)
        if self.executor.running or self.vehicle.mode is Mode.AUTO:
            self._sync_executor(now)
        try:
            wheels, pulses = self._compute_output(now)
        except Exception:
            log.exception("error computing the output")
            self._say(Severity.ERROR, "Error computing output: neutral")
            wheels, pulses = (0.0, 0.0, 0.0, 0.0), self._neutral()
        if self._new_input or pulses != self.pulses_us or now >= self._next_output_s:
            self._send_output(pulses, now)
        # Off the latency-critical path: everything below runs after the output went out.
        if self._wheels_s is not None:
            self.estimator.on_commanded(self.wheels, now - self._wheels_s, now)
        self.wheels, self._wheels_s = wheels, now
        # Telemetry rides the output refresh's wake-ups when it is due within half a period.
        due = self.streams.due(now, self.output_period_s / 2)
        if due:
            state = self._telemetry_state(now)
            for name in due:
                build(name, self.gcs.mav, state)
        if now >= self._next_heartbeat_s:
            self._send_heartbeats()
            self._send_mission_current()  # MISSION_CURRENT at 1 Hz, as ArduPilot
            self._next_heartbeat_s = now + HEARTBEAT_PERIOD_S
        if now >= self.mission.next_due_s():
            self.mission_link.tick(now)
            self._take_mission_events(now)
        if self.executor.has_events:
            self._take_executor_events(now)
        if self.vehicle.has_events:
            for severity, text in self.vehicle.take_events():
                self._say(severity, text)

    # ================================================================== output

    def reconfigure(self) -> None:
        """Re-read the parameters the loop caches (after a parameter changed)."""
        p = self.params
        self.pwm = PwmMap.from_params(p)
        self.algorithm = ALGORITHM_NAMES[int(p["MIX_ALGO"])]
        self.priority = Desaturation(int(p["MIX_DESAT"]))
        self.output_period_s = 1.0 / float(p["OUT_RATE"])
        self.fc_target = (int(p["FC_SYSID"]), int(p["FC_COMPID"]))
        self.fc.mav.srcSystem = int(p["FC_GCS_SYSID"])  # may change live
        # Read once here rather than per message: the input path runs at up to 1 kHz.
        self.gcs_id = int(p["SYSID_MYGCS"])
        self.shaping = (float(p["INP_DEADBAND"]), float(p["INP_EXPO"]), bool(p["INP_CIRCLE"]))
        self.z_scale = bool(p["MAN_Z_SCALE"])

    def _neutral(self) -> tuple[int, ...]:
        return self.pwm.neutral()

    def _compute_output(self, now: float) -> tuple[tuple[float, ...], tuple[int, ...]]:
        """(normalized wheel commands, pulse widths in us) for the current state."""
        if self.vehicle.autonomous():
            return self._guided_output(now)
        self._next_control_s = math.inf
        self._guided_last = None
        if not self.vehicle.driving():
            return (0.0, 0.0, 0.0, 0.0), self._neutral()
        band, weight, circle = self.shaping
        x, y, r = shape_stick(*self.stick, deadband_width=band, expo_weight=weight,
                              circle=circle)
        wheels = wheels_from_stick(x, y, r, self.algorithm, priority=self.priority)
        return wheels, self.pwm.pulses_us(wheels)

    def _guided_output(self, now: float) -> tuple[tuple[float, ...], tuple[int, ...]]:
        """GUIDED: setpoint -> body velocity and yaw rate -> wheel speeds (m/s) -> commands.

        The translation and rotation parts are desaturated with ``MIX_DESAT`` (proportional
        and rotation priority both keep the commanded direction of travel).
        """
        if now < self._next_control_s and self._guided_last is not None:
            return self._guided_last  # between control ticks (fixed CTL_RATE grid): hold
        period = 1.0 / float(self.params["CTL_RATE"])
        if self._guided_last is None:  # entering GUIDED: the grid starts now
            self._next_control_s = now
        self._next_control_s += period  # a fixed grid, so the rate does not drift
        if self._next_control_s <= now:  # fell behind: skip ahead
            self._next_control_s = now + period
        pose = self.estimator.pose
        if self.vehicle.mode is Mode.AUTO:
            self.guided.setpoint = self.executor.update(pose, self.guided.velocity_ned, now)
        vx, vy, yaw_rate = self.guided.update(pose, now)
        speed = float(self.params["WHL_MAX_SPD"])
        translation = self.kinematics.to_wheel_speeds(vx, vy, 0.0) / speed
        rotation = self.kinematics.to_wheel_speeds(0.0, 0.0, yaw_rate) / speed
        wheels = tuple(float(w) for w in desaturate_prioritized(translation, rotation,
                                                               self.priority))
        self._guided_last = (wheels, self.pwm.pulses_us(wheels))
        return self._guided_last

    def _on_position_target(self, msg: Any, now: float) -> None:
        if not (self._for_us(msg.target_system, msg.target_component)
                and self._from_permitted_gcs(msg)):
            return
        if self.vehicle.mode is not Mode.GUIDED:
            self._reject_input("setpoint: not in GUIDED")
            return
        try:
            setpoint = decode_setpoint(msg.coordinate_frame, msg.type_mask, msg.x, msg.y,
                                       msg.vx, msg.vy, msg.yaw, msg.yaw_rate,
                                       self.estimator.pose, now)
        except SetpointError as exc:
            self._reject_input(f"setpoint: {exc}")
            return
        self.guided.accept(setpoint, self.estimator.pose)
        self._new_input = True

    def _send_output(self, pulses: tuple[int, ...], now: float) -> None:
        self.fc.send_rc_override(*self.fc_target, override_fields(self.pwm.channels, pulses))
        self.pulses_us = pulses
        self._new_input = False
        self._next_output_s = now + self.output_period_s

    def _shutdown_outputs(self) -> None:
        """Neutral first (the wheels stop), then hand the channels back to the radio."""
        neutral = override_fields(self.pwm.channels, self._neutral())
        release = release_fields(self.pwm.channels)
        for fields in (neutral, neutral, release):
            self.fc.send_rc_override(*self.fc_target, fields)
        self.pulses_us = self._neutral()

    def _telemetry_state(self, now: float) -> TelemetryState:
        est = self.estimator
        return TelemetryState(now, self._boot_s, est.pose, est.velocity_body, est.yaw_rate,
                              est.reset_counter, est.wheel_distances_m, self.pwm.channels,
                              self.pulses_us, self.gcs.bad + self.fc.bad, self.origin)

    def _send_heartbeats(self) -> None:
        v = self.vehicle
        base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if v.armed:
            base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        base |= {
            Mode.MANUAL: mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED,
            Mode.GUIDED: mavlink.MAV_MODE_FLAG_GUIDED_ENABLED,
            Mode.AUTO: mavlink.MAV_MODE_FLAG_AUTO_ENABLED | mavlink.MAV_MODE_FLAG_GUIDED_ENABLED,
        }.get(v.mode, 0)
        if v.failsafe:
            status = mavlink.MAV_STATE_CRITICAL
        else:
            status = mavlink.MAV_STATE_ACTIVE if v.armed else mavlink.MAV_STATE_STANDBY
        self.gcs.mav.heartbeat_send(mavlink.MAV_TYPE_GROUND_ROVER,
                                    mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, base, int(v.mode), status)
        self.fc.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                   mavlink.MAV_STATE_ACTIVE)

    def _say(self, severity: Severity, text: str, *, repeat_s: float = 0.0) -> None:
        """STATUSTEXT to the ground station (and the log); long texts go in chunks."""
        now = self.clock()
        if repeat_s and now - self._said.get(text, -math.inf) < repeat_s:
            return
        self._said[text] = now
        log.log(logging.WARNING if severity <= Severity.WARNING else logging.INFO, "%s", text)
        data = text.encode("utf-8", "replace")
        if len(data) <= MAX_STATUSTEXT:
            self.gcs.mav.statustext_send(int(severity), data)
            return
        chunk_id = (hash(text) & 0x7FFF) or 1
        for seq, start in enumerate(range(0, len(data), MAX_STATUSTEXT)):
            self.gcs.mav.statustext_send(int(severity), data[start:start + MAX_STATUSTEXT],
                                         chunk_id, seq)

    # ================================================================== messages

    def _for_us(self, target_system: int, target_component: int | None = None) -> bool:
        if target_system != 0 and target_system != self.sysid:
            return False
        return target_component is None or target_component in (0, COMPANION_COMPID)

    def _from_permitted_gcs(self, msg: Any) -> bool:
        return self.gcs_id == 0 or msg.get_srcSystem() == self.gcs_id

    def _on_gcs_message(self, msg: Any, now: float) -> None:
        handler = self._handlers.get(msg.get_type())
        if handler is not None and msg.get_srcSystem() != self.sysid:
            handler(msg, now)

    def _on_fc_message(self, msg: Any, now: float) -> None:
        if msg.get_srcSystem() != self.fc_target[0]:
            return
        kind = msg.get_type()
        if kind == "HEARTBEAT":
            self.vehicle.on_fc_heartbeat(now)
        elif kind == "ATTITUDE":
            self.estimator.on_attitude(msg.yaw, msg.yawspeed, now)
        elif kind == "WHEEL_DISTANCE" and msg.count >= 4:
            self.estimator.on_wheel_distance(msg.distance[:4], now)

    def _on_gcs_heartbeat(self, msg: Any, now: float) -> None:
        if self._from_permitted_gcs(msg):
            self.vehicle.on_gcs_heartbeat(now)

    def _reject_input(self, reason: str) -> None:
        self._say(Severity.WARNING, f"Rejected: {reason}", repeat_s=STATUSTEXT_REPEAT_S)

    def _take_stick(self, stick: Stick, now: float) -> None:
        self.stick = stick
        self.vehicle.on_stick_input(now)
        self._new_input = True

    def _on_manual_control(self, msg: Any, now: float) -> None:
        if not (self._for_us(msg.target) and self._from_permitted_gcs(msg)):
            return
        try:
            stick = stick_from_manual_control(msg.x, msg.y, msg.r, msg.z, z_scale=self.z_scale)
        except InputError as exc:
            self._reject_input(str(exc))
            return
        self._take_stick(stick, now)

    def _on_rc_override(self, msg: Any, now: float) -> None:
        if not (self._for_us(msg.target_system, msg.target_component)
                and self._from_permitted_gcs(msg)):
            return
        channels = [getattr(msg, f"chan{i}_raw") for i in range(1, 19)]
        try:
            self.rc_sticks.apply(channels)
        except InputError as exc:
            self._reject_input(str(exc))
            return
        if self.rc_sticks.touches_sticks(channels, self.params):
            self._take_stick(self.rc_sticks.stick(self.params), now)

    # ------------------------------------------------------------------ commands

    def _on_command(self, msg: Any, now: float) -> None:
        if not (self._for_us(msg.target_system, msg.target_component)
                and self._from_permitted_gcs(msg)):
            return
        params = (msg.param1, msg.param2, msg.param3, msg.param4)
        result = self._command(int(msg.command), params, now)
        self.gcs.mav.command_ack_send(msg.command, result, 0, 0, msg.get_srcSystem(),
                                      msg.get_srcComponent())

    def _command(self, command: int, p: tuple[float, ...], now: float) -> int:
        """Carry out a COMMAND_LONG / COMMAND_INT; returns its MAV_RESULT."""
        if command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            if p[0] == 1.0:
                return self._result(self.vehicle.request_arm(now))
            if p[0] == 0.0:
                return self._result(self.vehicle.request_disarm(now, "by command"))
            self._say(Severity.WARNING, f"Arm/disarm: param1 must be 0 or 1, got {p[0]}")
            return mavlink.MAV_RESULT_DENIED
        if command == mavlink.MAV_CMD_DO_SET_MODE:
            return self._set_mode(p[0], p[1], now)
        if command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            ok = math.isfinite(p[0]) and self.streams.set_interval(int(p[0]), p[1])
            return mavlink.MAV_RESULT_ACCEPTED if ok else mavlink.MAV_RESULT_DENIED
        if command == mavlink.MAV_CMD_GET_MESSAGE_INTERVAL:
            interval = self.streams.get_interval_us(int(p[0])) if math.isfinite(p[0]) else None
            if interval is None:
                return mavlink.MAV_RESULT_DENIED
            self.gcs.mav.message_interval_send(int(p[0]), interval)
            return mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_REQUEST_MESSAGE:
            name = REQUESTABLE.get(int(p[0])) if math.isfinite(p[0]) else None
            if name is None:
                return mavlink.MAV_RESULT_DENIED
            build(name, self.gcs.mav, self._telemetry_state(now))
            return mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_DO_SET_MISSION_CURRENT:
            if p[1] == 1.0:  # param2 = 1: reset the mission (DO_JUMP counters, start over)
                self.executor.restart()
            if not (math.isfinite(p[0]) and p[0] >= -1):
                return mavlink.MAV_RESULT_DENIED
            seq = self.executor.current if p[0] == -1 else int(p[0])
            return self._set_mission_current(seq, now)
        if command == mavlink.MAV_CMD_MISSION_START:
            if math.isfinite(p[0]) and p[0] >= 1 and self._set_mission_current(
                    int(p[0]), now) != mavlink.MAV_RESULT_ACCEPTED:
                return mavlink.MAV_RESULT_DENIED
            return self._result(self._request_mode(Mode.AUTO, now))
        if command == mavlink.MAV_CMD_DO_SET_HOME:
            if p[0] != 1.0:
                self._say(Severity.WARNING, "Set home: only 'use current position' (param1=1)")
                return mavlink.MAV_RESULT_DENIED
            self.estimator.reset(now_s=now)
            self._say(Severity.INFO, "Home and odometry origin set here")
            return mavlink.MAV_RESULT_ACCEPTED
        return mavlink.MAV_RESULT_UNSUPPORTED

    def _request_mode(self, mode_number: int, now: float) -> Decision:
        before = self.vehicle.mode
        if mode_number == Mode.AUTO and before is not Mode.AUTO:
            reason = self.executor.prepare(self.origin)
            if reason is not None:
                self._say(Severity.WARNING, f"AUTO refused: {reason}")
                return Decision(False, reason)
            if self.executor.complete:
                self.executor.restart()
        decision = self.vehicle.request_mode(mode_number, now)
        mode = self.vehicle.mode
        if decision.accepted and mode in (Mode.GUIDED, Mode.AUTO) and before is not mode:
            self.guided.start(self.estimator.pose, now)
        return decision

    def _set_mode(self, base_mode: float, custom_mode: float, now: float) -> int:
        if not (math.isfinite(base_mode) and math.isfinite(custom_mode)):
            self._say(Severity.WARNING, "Set mode: base and custom mode must be numbers")
            return mavlink.MAV_RESULT_DENIED
        if not int(base_mode) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            self._say(Severity.WARNING, "Set mode: only custom (Rover) modes are supported")
            return mavlink.MAV_RESULT_UNSUPPORTED
        return self._result(self._request_mode(int(custom_mode), now))

    def _on_set_mode(self, msg: Any, now: float) -> None:
        if not (self._for_us(msg.target_system) and self._from_permitted_gcs(msg)):
            return
        result = self._set_mode(float(msg.base_mode), float(msg.custom_mode), now)
        # ArduPilot acknowledges SET_MODE with COMMAND_ACK whose command is SET_MODE's id (11).
        self.gcs.mav.command_ack_send(mavlink.MAVLINK_MSG_ID_SET_MODE, result, 0, 0,
                                      msg.get_srcSystem(), msg.get_srcComponent())

    def _on_ping(self, msg: Any, now: float) -> None:
        if msg.target_system == 0:  # a request (an answer names its target)
            self.gcs.mav.ping_send(msg.time_usec, msg.seq, msg.get_srcSystem(),
                                   msg.get_srcComponent())

    def _on_ftp(self, msg: Any, now: float) -> None:
        if self._for_us(msg.target_system, msg.target_component):
            self.gcs.mav.file_transfer_protocol_send(0, msg.get_srcSystem(),
                                                     msg.get_srcComponent(),
                                                     ftp_nak(msg.payload))

    # ------------------------------------------------------------------ missions

    @property
    def origin(self) -> GlobalOrigin | None:
        """Where local (0, 0) is on the earth: SET_GPS_GLOBAL_ORIGIN, else ORIGIN_LAT/LON."""
        if self._origin_set is not None:
            return self._origin_set
        lat, lon = float(self.params["ORIGIN_LAT"]), float(self.params["ORIGIN_LON"])
        if lat == 0.0 and lon == 0.0:
            return None
        return GlobalOrigin.from_degrees(lat, lon)

    def _read_mission_file(self) -> list[MissionItem]:
        path = self.mission_path
        if path is None or not path.exists():
            return []
        try:
            items = load_mission(path)
        except (MissionFileError, OSError) as exc:
            # The file is left as it is (nothing lost); the companion starts without a mission.
            log.error("mission not loaded: %s", exc)
            self._say(Severity.ERROR, f"Mission file unreadable: {path.name}")
            return []
        log.info("mission of %d items loaded from %s", len(items), path)
        return items

    def _on_mission_message(self, msg: Any, now: float) -> None:
        if self._from_permitted_gcs(msg):
            self.mission_link.handle(msg, now)
            self._take_mission_events(now)

    def _take_mission_events(self, now: float) -> None:
        for kind, text in self.mission.take_events():
            if kind == "error":
                self._say(Severity.WARNING, text)
                continue
            self._mission_replaced(now)

    def _mission_replaced(self, now: float) -> None:
        """A new mission was accepted (or the mission was cleared): run it, keep it."""
        items = self.mission.items
        was_running = self.executor.running
        self.executor.pause()
        self.executor.load(items)
        self._send_mission_current()
        if self.vehicle.mode is Mode.AUTO and not self.executor.has_mission:
            self._say(Severity.WARNING, "Mission cleared: HOLD")
            self._request_mode(Mode.HOLD, now)
        elif was_running:
            self._say(Severity.NOTICE, f"New mission: continuing at item {self.executor.current}")
        if self.mission_path is not None:
            try:
                save_mission(items, self.mission_path)
            except OSError as exc:
                self._say(Severity.ERROR, f"Mission save failed: {exc.strerror}")

    def _set_mission_current(self, seq: int, now: float) -> int:
        reason = self.executor.set_current(seq, self.estimator.pose, now)
        if reason is not None:
            self._say(Severity.WARNING, f"Set current item refused: {reason}")
            return mavlink.MAV_RESULT_DENIED
        self._take_executor_events(now)
        return mavlink.MAV_RESULT_ACCEPTED

    def _on_mission_set_current(self, msg: Any, now: float) -> None:
        if self._for_us(msg.target_system, msg.target_component) and self._from_permitted_gcs(
                msg):
            self._set_mission_current(msg.seq, now)  # answered by MISSION_CURRENT

    def _on_set_origin(self, msg: Any, now: float) -> None:
        if not (self._for_us(msg.target_system) and self._from_permitted_gcs(msg)):
            return
        try:
            origin = GlobalOrigin(msg.latitude, msg.longitude, msg.altitude)
        except ValueError as exc:
            self._reject_input(f"origin: {exc}")
            return
        self._origin_set = origin
        self.gcs.mav.gps_global_origin_send(origin.lat_e7, origin.lon_e7, origin.alt_mm,
                                            int((now - self._boot_s) * 1e6))
        self._say(Severity.INFO, f"Origin {origin.lat_e7 / 1e7:.7f} {origin.lon_e7 / 1e7:.7f}")

    def _sync_executor(self, now: float) -> None:
        """The mission runs while AUTO may drive (armed, no failsafe); otherwise it pauses."""
        ex, may_drive = self.executor, self.vehicle.auto()
        if ex.running and not may_drive:
            ex.pause()
        elif may_drive and not ex.running and not ex.complete:
            pose = self.estimator.pose
            reason = ex.start(pose, now, self.origin)
            if reason is not None:
                self._say(Severity.WARNING, f"AUTO: {reason}: HOLD")
                self._request_mode(Mode.HOLD, now)
                return
            self.guided.start(pose, now)
            self._guided_last = None
            self._take_executor_events(now)

    def _take_executor_events(self, now: float) -> None:
        for event in self.executor.take_events():
            if event.kind == "current":
                self._send_mission_current()
            elif event.kind == "reached":
                self.mission_link.reached_send(event.seq)
            elif event.kind == "say":
                self._say(event.severity, event.text)
            elif event.kind == "finished":
                self._request_mode(Mode.HOLD, now)

    def _send_mission_current(self) -> None:
        ex = self.executor
        total = len(ex.items) - 1 if ex.has_mission else 0xFFFF
        self.mission_link.current_send(ex.current, total, ex.state,
                                       self.vehicle.mode is Mode.AUTO)

    # ------------------------------------------------------------------ parameters

    def _send_param(self, value: ParamValue) -> None:
        self.gcs.mav.param_value_send(value.param_id, value.param_value, value.param_type,
                                      value.param_count, value.param_index)

    def _on_param_request_list(self, msg: Any, now: float) -> None:
        if self._for_us(msg.target_system, msg.target_component):
            for value in self.param_service.all_values():
                self._send_param(value)

    def _on_param_request_read(self, msg: Any, now: float) -> None:
        if self._for_us(msg.target_system, msg.target_component):
            value = self.param_service.read(msg.param_id, msg.param_index)
            if value is not None:
                self._send_param(value)

    def _on_param_set(self, msg: Any, now: float) -> None:
        if not (self._for_us(msg.target_system, msg.target_component)
                and self._from_permitted_gcs(msg)):
            return
        value, problem = self.param_service.set(msg.param_id, msg.param_value)
        if value is None:
            return  # unknown name: no answer, as the protocol specifies
        self._send_param(value)
        name = value.param_id.decode()
        if problem:
            self._say(Severity.WARNING, f"Param refused: {problem}")
            return
        self.reconfigure()
        if name in RESTART_REQUIRED:
            self._say(Severity.NOTICE, f"{name} takes effect after a restart")
        if self.param_path is not None:
            try:
                save(self.params, self.param_path)
            except OSError as exc:
                self._say(Severity.ERROR, f"Param save failed: {exc.strerror}")

    @staticmethod
    def _result(decision: Decision) -> int:
        return mavlink.MAV_RESULT_ACCEPTED if decision.accepted else mavlink.MAV_RESULT_DENIED

    # ================================================================== lifecycle

    def start(self) -> None:
        """Run the loop in a background thread (tests, ``--fc sim``)."""
        self._thread = threading.Thread(target=self.run, name="companion", daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 5.0) -> None:
        """Ask the loop to end (neutral, then release) and wait for it; idempotent."""
        self._stop.set()
        with contextlib.suppress(OSError):
            os.write(self._wake_w, b"x")
        if self._thread is not None:
            self._thread.join(timeout_s)
            self._thread = None

    def close(self) -> None:
        """Stop and close both links."""
        self.stop()
        self.gcs.close()
        self.fc.close()
        for fd in (self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)
