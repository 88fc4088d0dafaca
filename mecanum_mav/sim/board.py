"""A simulated ArduPilot Rover board, stepped in time that is given: no sockets, no clock.

What it models: an ArduPilot Rover board whose servo outputs pass RC input straight through
to four ESCs (``SERVOn_FUNCTION = RCINn``). RC passthrough works armed or disarmed, so the
board has no arming of its own. Its RC input is ``RC_CHANNELS_OVERRIDE`` only (there is no
radio), handled as ArduPilot's ``GCS_MAVLINK::handle_rc_channels_override`` does:

- Only messages from the ground station's system id (``SIM_GCS_SYSID``, ArduPilot
  ``SYSID_MYGCS``) count, and only those addressed to this board (``target_system`` =
  ``FC_SYSID`` or 0 and ``target_component`` = ``FC_COMPID`` or 0), as ArduPilot's routing
  decides what it processes itself.
- Channels 1-8: 65535 leaves the channel alone, 0 releases it, anything else overrides it.
  Channels 9-18: 0 and 65535 leave it alone, 65534 releases it, anything else overrides it
  (the rules of :func:`mecanum_mav.protocol.rcoverride.field_action`).
- Each channel keeps its own timestamp; an override not refreshed for ``SIM_RC_TMO`` seconds
  (``RC_OVERRIDE_TIME``) lapses.

Wheel ``W`` is driven by channel ``MOT_W_CH``; its pulse width becomes a normalized command
through :meth:`~mecanum_mav.control.pwm.WheelOutput.command_from_pulse` (the inverse of the
companion's PWM edge, limits and ``MOT_W_REV`` included), so one parameter file configures the
companion and the simulated robot alike. A channel without an active override outputs its
wheel's trim (a stopped wheel).

Telemetry, as ArduPilot Rover sends it: HEARTBEAT 1 Hz, ATTITUDE 20 Hz (true yaw, radians
clockwise from north, plus ``SIM_YAW_BIAS``: a compass or EKF heading that is off),
LOCAL_POSITION_NED and GPS_RAW_INT at ``SIM_POS_RATE`` (the true position and velocity, as a
GPS-fused EKF gives them, and a 3D fix there; 0 Hz, the default: none, a board without GPS),
WHEEL_DISTANCE 10 Hz (cumulative
encoder metres FL, FR, RL, RR), SERVO_OUTPUT_RAW 10 Hz (the pulse width on each output) and
SYS_STATUS 1 Hz (a battery). As
ArduPilot's simulators do, it also reports its ground truth in SIM_STATE at 5 Hz: the true
pose (latitude and longitude about ``ORIGIN_LAT``/``ORIGIN_LON``, or about 0, 0 when no
origin is set; yaw in radians clockwise from north) and the true velocity (north, east m/s),
so a tlog shows where the chassis really went (``mecanum-mav log``). A chassis with wheel
contacts (the MuJoCo one) has them sent at 10 Hz, one DEBUG_VECT per wheel named
``CONTACT_FL`` .. ``CONTACT_RR``: x the normal force (N), y the slip speed (m/s), z 1 when
slipping else 0 (one message keeps a wheel's force and slip of one instant together;
ArduPilot sends no DEBUG_VECT, so no firmware name clashes, and ground stations show or
ignore it).

A simulated RC receiver (:attr:`SimBoard.receiver`, pulse widths of channels 1..N that a test
sets; None = no receiver, :attr:`SimBoard.rssi`) is reported as ArduPilot does in RC_CHANNELS,
sent only once asked for with MAV_CMD_SET_MESSAGE_INTERVAL (message 65): ``chancount`` N, each
channel the override in force or else the receiver's pulse (0 beyond N), RSSI 255 (unknown)
unless set. The wheels stay on the overrides (a wheel channel without one outputs trim).

It answers PARAM_REQUEST_READ (by name, addressed to it) for the ArduPilot settings the
companion checks (:mod:`mecanum_mav.protocol.fcsetup`), with what this board does: the scaled
pass-through the companion needs on its wheel channels, ``RC_OVERRIDE_TIME`` =
``SIM_RC_TMO``, ``MAV_GCS_SYSID`` = ``SIM_GCS_SYSID`` (:func:`board_parameters`); other names
are not answered, as ArduPilot does with names it does not have. It takes no PARAM_SET.

Physics is stepped at ``SIM_RATE`` with a zero-order hold of the wheel commands; an override
takes effect from the moment it arrives. The socket version is
:class:`mecanum_mav.sim.simfc.SimFlightController`; :class:`mecanum_mav.sim.lockstep.Lockstep`
steps the same board in virtual time.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from mecanum_mav.config.params import Params
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.mecanum.geometry import Pose2d, body_to_ned, wrap_pi
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.fcsetup import safe_settings
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.rcoverride import CHANNELS, LEAVE, RELEASE, field_action
from mecanum_mav.sim.chassis import ORIGIN_POSE
from mecanum_mav.sim.physics import (
    CONTACTS_PERIOD_S,
    DEFAULT_PHYSICS,
    Contacts,
    contacts_of,
    make_chassis,
)
from mecanum_mav.sim.truthsender import CONTACT_NAMES, send_contacts, send_sim_state

__all__ = ["CONTACT_NAMES", "ORIGIN", "RcOverrides", "SimBoard", "SimState", "board_parameters"]

ORIGIN = ORIGIN_POSE
"""Where the chassis starts unless told otherwise: the local origin, facing north."""
SERVO_OUTPUTS = 16
"""Outputs SERVO_OUTPUT_RAW reports."""
MAX_STEP_S = 0.1
"""Longest physics step: a stalled loop loses simulated time rather than jumping."""


def board_parameters(params: Params) -> dict[str, float]:
    """The ArduPilot parameters this simulated board answers with (what it does, in
    ArduPilot's words): the settings ``setup-fc --apply`` would give a real board, with its
    own override timeout and ground-station id."""
    values = safe_settings(params, {"RCMAP_THROTTLE": 3.0})
    values.update({"MAV_GCS_SYSID": int(params["SIM_GCS_SYSID"]),
                   "RC_OVERRIDE_TIME": float(params["SIM_RC_TMO"]),
                   "RCMAP_THROTTLE": values.get("RCMAP_THROTTLE", 3.0), "RC_PROTOCOLS": 0})
    return values

_HEARTBEAT_PERIOD_S = 1.0
_ATTITUDE_PERIOD_S = 0.05
_WHEEL_DISTANCE_PERIOD_S = 0.1
_SERVO_OUTPUT_PERIOD_S = 0.1
_SYS_STATUS_PERIOD_S = 1.0
SIM_STATE_PERIOD_S = 0.2
"""The simulator's ground truth (SIM_STATE) is sent this often (seconds)."""
BATTERY_V = 12.6
"""The simulated battery's voltage (V); it reports 100 % remaining."""
_IDLE_CURRENT_A, _WHEEL_CURRENT_A = 0.3, 2.0


class RcOverrides:
    """ArduPilot's per-channel RC override state (``RC_Channel::set_override/has_override``).

    Args:
        timeout_s: an override not refreshed for this many seconds lapses (RC_OVERRIDE_TIME).
    """

    def __init__(self, timeout_s: float) -> None:
        self._timeout_s = timeout_s
        self._pulses: dict[int, tuple[int, float]] = {}

    def apply(self, raw_channels: Sequence[int], now_s: float) -> None:
        """Apply the 18 raw fields of one accepted message (channel 1 first) at ``now_s``.

        A released channel is kept as pulse 0 (no override) with its time, as ArduPilot keeps
        a released channel's override value 0."""
        for channel, raw in enumerate(raw_channels, start=1):
            action = field_action(channel, raw)
            if action != LEAVE:
                self._pulses[channel] = (0 if action == RELEASE else action, now_s)

    def active(self, now_s: float) -> dict[int, int]:
        """Channel -> pulse width (us) of every override in force at ``now_s`` (monotonic s)."""
        return {
            channel: pulse
            for channel, (pulse, since) in self._pulses.items()
            if pulse != 0 and now_s - since < self._timeout_s
        }


@dataclass(frozen=True)
class SimState:
    """One consistent copy of the simulator's state.

    Attributes:
        time_s: simulated time, seconds since the loop started.
        pose: true pose, local NED (north m, east m, yaw rad clockwise from north).
        velocity_body: true velocity, body FRD (forward m/s, right m/s).
        yaw_rate: true yaw rate, rad/s clockwise.
        wheel_speeds_mps: wheel surface speeds FL, FR, RL, RR, m/s.
        wheel_distances_m: cumulative encoder distances FL, FR, RL, RR, metres.
        wheel_commands: normalized commands FL, FR, RL, RR the motors are following.
        channel_pwm: channel -> pulse width (us) of every active override.
        overrides_received: RC_CHANNELS_OVERRIDE messages obeyed.
        overrides_ignored: RC_CHANNELS_OVERRIDE messages dropped by the sender-id and
            target rules.
    """

    time_s: float
    pose: Pose2d
    velocity_body: tuple[float, float]
    yaw_rate: float
    wheel_speeds_mps: tuple[float, float, float, float]
    wheel_distances_m: tuple[float, float, float, float]
    wheel_commands: tuple[float, float, float, float]
    channel_pwm: dict[int, int]
    overrides_received: int
    overrides_ignored: int


class _Every:
    """A periodic deadline on the monotonic clock (seconds)."""

    def __init__(self, period_s: float, first_s: float) -> None:
        self.period_s = period_s
        self.next_s = first_s

    def due(self, now_s: float) -> bool:
        """True (and the deadline moves one period on) when ``now_s`` has reached it."""
        if now_s < self.next_s:
            return False
        self.next_s += self.period_s
        if self.next_s <= now_s:  # fell behind: no burst of catch-up sends
            self.next_s = now_s + self.period_s
        return True


class SimBoard:
    """The simulated board and chassis (see the module docstring); time is passed in.

    Args:
        params: read once here: ``FC_SYSID``/``FC_COMPID`` (its own ids), ``SIM_GCS_SYSID``,
            ``SIM_RC_TMO``, ``SIM_RATE``, the ``MOT_*`` channel map and the chassis
            parameters (see :func:`~mecanum_mav.sim.physics.make_chassis`).
        now_s: the time the board boots, seconds.
        pose: where the chassis starts (local NED, yaw clockwise from north).
        physics: the chassis model (:data:`~mecanum_mav.sim.physics.PHYSICS`).
    """

    def __init__(self, params: Params, now_s: float = 0.0, pose: Pose2d = ORIGIN,
                 physics: str = DEFAULT_PHYSICS) -> None:
        self.sysid = int(params["FC_SYSID"])
        self.compid = int(params["FC_COMPID"])
        self._gcs_sysid = int(params["SIM_GCS_SYSID"])
        self.physics_period_s = 1.0 / float(params["SIM_RATE"])
        self._outputs = PwmMap.from_params(params)
        self._trims = {w.channel: w.trim for w in self._outputs.wheels}
        self.chassis = make_chassis(params, pose, physics)
        self._origin = GlobalOrigin.from_degrees(float(params["ORIGIN_LAT"]),
                                                 float(params["ORIGIN_LON"]))
        self._overrides = RcOverrides(float(params["SIM_RC_TMO"]))
        self.channel_pwm: dict[int, int] = {}
        self.commands = (0.0, 0.0, 0.0, 0.0)
        self.received = 0
        self.ignored = 0
        self.receiver: tuple[int, ...] | None = None
        """The simulated receiver's pulse widths (us), channel 1 first; None: no receiver."""
        self.rssi = 255
        """The receiver's RSSI in RC_CHANNELS (0..254, 255 unknown)."""
        self._rc_channels = _Every(math.inf, math.inf)
        self.beating = True
        """Whether the board sends its HEARTBEAT (clear it to test link loss)."""
        self.boot_s = now_s
        self.last_step_s = now_s
        self.parameters = board_parameters(params)
        self._param_answers: list[str] = []
        self._telemetry: list[tuple[_Every, Callable[[Any, float], None]]] = [
            (_Every(_HEARTBEAT_PERIOD_S, now_s), self._heartbeat),
            (_Every(_ATTITUDE_PERIOD_S, now_s), self._attitude),
            (_Every(_WHEEL_DISTANCE_PERIOD_S, now_s), self._wheel_distance),
            (_Every(_SERVO_OUTPUT_PERIOD_S, now_s), self._servo_output_raw),
            (_Every(_SYS_STATUS_PERIOD_S, now_s), self._sys_status),
            (_Every(SIM_STATE_PERIOD_S, now_s), self._sim_state),
            (self._rc_channels, self._rc_channels_msg),
        ]
        self._yaw_bias_rad = math.radians(float(params["SIM_YAW_BIAS"]))
        position_hz = float(params["SIM_POS_RATE"])
        if position_hz > 0.0:
            self._telemetry.append((_Every(1.0 / position_hz, now_s), self._local_position))
        contacts = contacts_of(self.chassis)
        if contacts is not None:
            self._telemetry.append((_Every(CONTACTS_PERIOD_S, now_s),
                                    self._contacts_sender(contacts)))

    # ------------------------------------------------------------------ time

    def next_due_s(self) -> float:
        """Time (s) of the next physics step or telemetry message."""
        physics = self.last_step_s + self.physics_period_s
        if self._param_answers:
            return self.last_step_s
        return min(physics, *(every.next_s for every, _ in self._telemetry))

    def on_time(self, now_s: float, mav: Any) -> bool:
        """Step physics if a physics period has passed and send the telemetry that is due on
        ``mav`` (a pymavlink ``MAVLink`` or a message outbox); True if physics stepped."""
        stepped = now_s >= self.last_step_s + self.physics_period_s
        if stepped:
            self._step_to(now_s)
            self._refresh(now_s)
        for every, send in self._telemetry:
            if every.due(now_s):
                send(mav, now_s)
        for name in self._param_answers:
            mav.param_value_send(name.encode("ascii"), self.parameters[name],
                                 mavlink.MAV_PARAM_TYPE_REAL32, len(self.parameters), 65535)
        self._param_answers.clear()
        return stepped

    def receive(self, messages: Sequence[Any], now_s: float) -> bool:
        """Obey or drop the RC_CHANNELS_OVERRIDEs among ``messages`` received at ``now_s``
        (physics catches up first, so they take effect from that moment); True if any."""
        for msg in messages:
            if (msg.get_type() == "COMMAND_LONG"
                    and msg.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL
                    and int(msg.param1) == mavlink.MAVLINK_MSG_ID_RC_CHANNELS
                    and msg.target_system in (0, self.sysid)):
                period_s = msg.param2 / 1e6 if msg.param2 > 0 else math.inf
                self._rc_channels.period_s, self._rc_channels.next_s = period_s, now_s
            elif (msg.get_type() == "PARAM_REQUEST_READ" and msg.target_system == self.sysid
                    and msg.param_id.rstrip("\x00") in self.parameters):
                self._param_answers.append(msg.param_id.rstrip("\x00"))
        overrides = [m for m in messages if m.get_type() == "RC_CHANNELS_OVERRIDE"]
        if not overrides:
            return False
        self._step_to(now_s)
        for msg in overrides:
            if self._accepts(msg):
                raw = [getattr(msg, f"chan{i}_raw", 0) for i in range(1, CHANNELS + 1)]
                self._overrides.apply(raw, now_s)
                self.received += 1
            else:
                self.ignored += 1
        self._refresh(now_s)
        return True

    def state(self) -> SimState:
        """The board's state now (its own copy of the channel map)."""
        c = self.chassis
        return SimState(
            time_s=c.time_s,
            pose=c.pose,
            velocity_body=c.velocity_body,
            yaw_rate=c.yaw_rate,
            wheel_speeds_mps=c.wheel_speeds_mps,
            wheel_distances_m=c.wheel_distances_m,
            wheel_commands=self.commands,
            channel_pwm=dict(self.channel_pwm),
            overrides_received=self.received,
            overrides_ignored=self.ignored,
        )

    def _step_to(self, now_s: float) -> None:
        """Step the chassis to ``now_s`` with the commands held since the last step (a
        zero-order hold; at most :data:`MAX_STEP_S` at once)."""
        dt = min(now_s - self.last_step_s, MAX_STEP_S)
        if dt > 0.0:
            self.chassis.step(dt, self.commands)
        self.last_step_s = now_s

    def _refresh(self, now_s: float) -> None:
        """Let lapsed overrides go and work out the wheel commands from ``now_s`` on."""
        self.channel_pwm = self._overrides.active(now_s)
        fl, fr, rl, rr = (
            w.command_from_pulse(self.channel_pwm[w.channel])
            if w.channel in self.channel_pwm
            else 0.0
            for w in self._outputs.wheels
        )
        self.commands = (fl, fr, rl, rr)

    def _accepts(self, msg: Any) -> bool:
        """From our ground station and addressed to this board (or broadcast)."""
        return (
            msg.get_srcSystem() == self._gcs_sysid
            and msg.target_system in (0, self.sysid)
            and msg.target_component in (0, self.compid)
        )

    # ------------------------------------------------------------------ telemetry

    def _boot_us(self, now_s: float) -> int:
        """Microseconds since this board booted."""
        return int((now_s - self.boot_s) * 1e6)

    def _heartbeat(self, mav: Any, now_s: float) -> None:
        """HEARTBEAT of a disarmed ArduPilot Rover in MANUAL, as the real firmware sends it
        (measured with the SITL): base_mode custom mode + manual input, not armed; system
        status ACTIVE (Rover says STANDBY in HOLD only)."""
        if not self.beating:
            return
        base_mode = (
            mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
        )
        mav.heartbeat_send(mavlink.MAV_TYPE_GROUND_ROVER, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                           base_mode, int(Mode.MANUAL), mavlink.MAV_STATE_ACTIVE)

    def _attitude(self, mav: Any, now_s: float) -> None:
        """ATTITUDE: the chassis's true roll and pitch (level on the kinematic one), true yaw
        (rad clockwise from north; the pose keeps it in [-pi, pi)) and true yaw rate (rad/s
        clockwise)."""
        c = self.chassis
        time_boot_ms = (self._boot_us(now_s) // 1000) & 0xFFFFFFFF
        roll, pitch = c.roll_pitch
        yaw = c.pose.yaw_rad + self._yaw_bias_rad
        mav.attitude_send(time_boot_ms, roll, pitch, wrap_pi(yaw), 0.0, 0.0, c.yaw_rate)

    def _local_position(self, mav: Any, now_s: float) -> None:
        """LOCAL_POSITION_NED: the true position (m from the start's origin, NED) and
        velocity (m/s), as a GPS-fused EKF reports it; altitude 0."""
        c = self.chassis
        v_north, v_east = body_to_ned(*c.velocity_body, c.pose.yaw_rad)
        mav.local_position_ned_send((self._boot_us(now_s) // 1000) & 0xFFFFFFFF, c.pose.x_m,
                                    c.pose.y_m, 0.0, v_north, v_east, 0.0)
        lat_e7, lon_e7 = self._origin.to_global(c.pose.x_m, c.pose.y_m)
        mav.gps_raw_int_send(self._boot_us(now_s), mavlink.GPS_FIX_TYPE_RTK_FIXED, lat_e7,
                             lon_e7, 0, 100, 100, 65535, 65535, 12)  # (an RTK fix, as SITL's)

    def _wheel_distance(self, mav: Any, now_s: float) -> None:
        """WHEEL_DISTANCE: cumulative encoder metres FL, FR, RL, RR, then zeros."""
        distances = [*self.chassis.wheel_distances_m, *([0.0] * 12)]
        mav.wheel_distance_send(self._boot_us(now_s), 4, distances)

    def _sys_status(self, mav: Any, now_s: float) -> None:
        """SYS_STATUS: a battery monitor (voltage, a current that grows with the wheel
        commands, 100 % remaining); sensor bits of a healthy board."""
        current_a = _IDLE_CURRENT_A + _WHEEL_CURRENT_A * sum(abs(c) for c in self.commands)
        mav.sys_status_send(0, 0, 0xFFFFFFFF, 0, round(BATTERY_V * 1000), round(current_a * 100),
                            100, 0, 0, 0, 0, 0, 0)

    def _servo_output_raw(self, mav: Any, now_s: float) -> None:
        """SERVO_OUTPUT_RAW: active override, else the wheel's trim, else 0 (port 0)."""
        time_usec = self._boot_us(now_s) & 0xFFFFFFFF
        pulses = [self.channel_pwm.get(ch, self._trims.get(ch, 0))
                  for ch in range(1, SERVO_OUTPUTS + 1)]
        mav.servo_output_raw_send(time_usec, 0, *pulses)

    def _rc_channels_msg(self, mav: Any, now_s: float) -> None:
        """RC_CHANNELS: the receiver's pulses under the overrides in force (see the module
        docstring)."""
        receiver = self.receiver or ()
        pulses = [self.channel_pwm.get(ch, receiver[ch - 1] if ch <= len(receiver) else 0)
                  for ch in range(1, CHANNELS + 1)]
        mav.rc_channels_send((self._boot_us(now_s) // 1000) & 0xFFFFFFFF, len(receiver),
                             *pulses, self.rssi)

    def _contacts_sender(self, contacts: Contacts) -> Callable[[Any, float], None]:
        """The telemetry that sends DEBUG_VECT per wheel: its contact as ``contacts`` reads
        it (see the module docstring)."""

        def send(mav: Any, now_s: float) -> None:
            send_contacts(mav, self._boot_us(now_s), contacts())

        return send

    def _sim_state(self, mav: Any, now_s: float) -> None:
        """SIM_STATE: the true pose and velocity (see the module docstring); level, no
        accelerations, altitude 0."""
        pose = self.chassis.pose
        send_sim_state(mav, self._origin, pose.x_m, pose.y_m, pose.yaw_rad,
                       *self.chassis.velocity_body, self.chassis.yaw_rate)
