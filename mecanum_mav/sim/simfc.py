"""A simulated ArduPilot Rover flight controller on a MAVLink link, driving a :class:`SimChassis`.

What it models: an ArduPilot Rover board whose servo outputs pass RC input straight through
to four ESCs (``SERVOn_FUNCTION = RCINn``). RC passthrough works armed or disarmed, so the
board has no arming of its own. Its RC input is ``RC_CHANNELS_OVERRIDE`` only (there is no
radio), handled as ArduPilot's ``GCS_MAVLINK::handle_rc_channels_override`` does:

- Only messages from the ground station's system id (``SIM_GCS_SYSID``, ArduPilot
  ``SYSID_MYGCS``) count, and only those addressed to this board (``target_system`` =
  ``FC_SYSID`` or 0 and ``target_component`` = ``FC_COMPID`` or 0), as ArduPilot's routing
  decides what it processes itself.
- Channels 1-8: 65535 leaves the channel alone, 0 releases it, anything else overrides it.
  Channels 9-18: 0 and 65535 leave it alone, 65534 releases it, anything else overrides it.
- Each channel keeps its own timestamp; an override not refreshed for ``SIM_RC_TMO`` seconds
  (``RC_OVERRIDE_TIME``) lapses.

Wheel ``W`` is driven by channel ``MOT_W_CH``; its pulse width becomes a normalized command
through :meth:`pwm.WheelOutput.command_from_pulse` (the inverse of the companion's PWM edge,
limits and ``MOT_W_REV`` included), so one parameter file configures the companion and the
simulated robot alike. A channel without an active override outputs its wheel's trim (a
stopped wheel).

Telemetry, as ArduPilot Rover sends it, to every peer heard: HEARTBEAT 1 Hz, ATTITUDE 20 Hz
(true yaw, radians clockwise from north), WHEEL_DISTANCE 10 Hz (cumulative encoder metres FL,
FR, RL, RR) and SERVO_OUTPUT_RAW 10 Hz (the pulse width on each output).

The loop blocks in a selector on the link until a message arrives or the next physics tick
(``SIM_RATE``) or telemetry message is due; physics is stepped with the real elapsed time.
"""

from __future__ import annotations

import selectors
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import TracebackType
from typing import Any

from mecanum_mav.app.shutdown import on_termination
from mecanum_mav.config.params import Params
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.io.links import Link, mavlink, open_link
from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.sim.chassis import SimChassis

__all__ = ["RcOverrides", "SimFlightController", "SimState", "main"]

RC_CHANNELS = 18
"""Channels RC_CHANNELS_OVERRIDE carries."""
SERVO_OUTPUTS = 16
"""Outputs SERVO_OUTPUT_RAW reports."""

_UINT16_MAX = 65535
_RELEASE_HIGH = _UINT16_MAX - 1
"""On channels 9-18: give the channel back to the radio."""
_MAX_STEP_S = 0.1
"""Longest physics step: a stalled loop loses simulated time rather than jumping."""

_HEARTBEAT_PERIOD_S = 1.0
_ATTITUDE_PERIOD_S = 0.05
_WHEEL_DISTANCE_PERIOD_S = 0.1
_SERVO_OUTPUT_PERIOD_S = 0.1
_MANUAL_MODE = 0
"""ArduPilot Rover custom_mode of MANUAL."""


def _override_pulse(channel: int, raw: int) -> int | None:
    """What one RC_CHANNELS_OVERRIDE field does: None = leave alone, 0 = release, else us."""
    if raw == _UINT16_MAX:
        return None
    if channel <= 8:
        return raw
    if raw == 0:
        return None
    return 0 if raw == _RELEASE_HIGH else raw


class RcOverrides:
    """ArduPilot's per-channel RC override state (``RC_Channel::set_override/has_override``).

    Args:
        timeout_s: an override not refreshed for this many seconds lapses (RC_OVERRIDE_TIME).
    """

    def __init__(self, timeout_s: float) -> None:
        self._timeout_s = timeout_s
        self._pulses: dict[int, tuple[int, float]] = {}

    def apply(self, raw_channels: Sequence[int], now_s: float) -> None:
        """Apply the 18 raw fields of one accepted message (channel 1 first) at ``now_s``."""
        for channel, raw in enumerate(raw_channels, start=1):
            pulse = _override_pulse(channel, raw)
            if pulse is not None:
                self._pulses[channel] = (pulse, now_s)

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


class SimFlightController:
    """A simulated ArduPilot Rover board on ``url``, obeying RC overrides and sending telemetry.

    Args:
        url: pymavlink connection string to serve on, e.g. ``udpin:127.0.0.1:0``.
        params: read once here: ``FC_SYSID``/``FC_COMPID`` (its own ids), ``SIM_GCS_SYSID``,
            ``SIM_RC_TMO``, ``SIM_RATE``, the ``MOT_*`` channel map and the chassis
            parameters (see :meth:`SimChassis.from_params`).

    Raises ``OSError``/``ValueError`` when the link cannot be opened. Use :meth:`start` /
    :meth:`stop` (or ``with``, which stops on exit) or run :meth:`run` in your own thread.
    """

    def __init__(self, url: str, params: Params) -> None:
        self._sysid = int(params["FC_SYSID"])
        self._compid = int(params["FC_COMPID"])
        self._gcs_sysid = int(params["SIM_GCS_SYSID"])
        self._physics_period_s = 1.0 / float(params["SIM_RATE"])
        self._outputs = PwmMap.from_params(params)
        self._trims = {w.channel: w.trim for w in self._outputs.wheels}
        self._chassis = SimChassis.from_params(params)
        self._overrides = RcOverrides(float(params["SIM_RC_TMO"]))
        self._channel_pwm: dict[int, int] = {}
        self._commands = (0.0, 0.0, 0.0, 0.0)
        self._received = 0
        self._ignored = 0
        self._boot_s = time.monotonic()
        self._last_step_s = self._boot_s
        self._cond = threading.Condition()
        self._state = self._build_state()
        self._stop_event = threading.Event()
        self._thread: threading.Thread | None = None
        self._link: Link = open_link(
            url, source_system=self._sysid, source_component=self._compid, name="simfc"
        )
        self._telemetry: list[tuple[_Every, Callable[[float], Any]]] = [
            (_Every(_HEARTBEAT_PERIOD_S, self._boot_s), self._heartbeat),
            (_Every(_ATTITUDE_PERIOD_S, self._boot_s), self._attitude),
            (_Every(_WHEEL_DISTANCE_PERIOD_S, self._boot_s), self._wheel_distance),
            (_Every(_SERVO_OUTPUT_PERIOD_S, self._boot_s), self._servo_output_raw),
        ]

    # ------------------------------------------------------------------ lifecycle

    @property
    def local_port(self) -> int | None:
        """The bound local UDP/TCP port (after listening on port 0), else None."""
        return self._link.local_port

    def start(self) -> None:
        """Run the loop in a daemon thread; does nothing if it is already running."""
        if self._thread is not None:
            return
        self._thread = threading.Thread(
            target=self.run, args=(self._stop_event,), name=f"simfc:{self.local_port}", daemon=True
        )
        self._thread.start()

    def stop(self) -> None:
        """Stop the loop, wait for its thread and close the link; idempotent."""
        self._stop_event.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join()
        self._link.close()

    def __enter__(self) -> SimFlightController:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    # ------------------------------------------------------------------ state

    def snapshot(self) -> SimState:
        """The latest consistent state (thread-safe; the channel map is the caller's copy)."""
        with self._cond:
            state = self._state
        return _copy_state(state)

    def wait_for(self, predicate: Callable[[SimState], bool], timeout_s: float) -> SimState | None:
        """Wait until ``predicate(state)`` holds, re-checked at every published state
        (each physics tick and each batch of messages); the state, or None after
        ``timeout_s`` seconds."""
        with self._cond:
            if self._cond.wait_for(lambda: predicate(self._state), timeout_s):
                return _copy_state(self._state)
        return None

    def _build_state(self) -> SimState:
        c = self._chassis
        return SimState(
            time_s=c.time_s,
            pose=c.pose,
            velocity_body=c.velocity_body,
            yaw_rate=c.yaw_rate,
            wheel_speeds_mps=c.wheel_speeds_mps,
            wheel_distances_m=c.wheel_distances_m,
            wheel_commands=self._commands,
            channel_pwm=dict(self._channel_pwm),
            overrides_received=self._received,
            overrides_ignored=self._ignored,
        )

    def _publish(self) -> None:
        """Make the current state visible to :meth:`snapshot` and wake :meth:`wait_for`."""
        state = self._build_state()
        with self._cond:
            self._state = state
            self._cond.notify_all()

    # ------------------------------------------------------------------ loop

    def run(self, stop: threading.Event) -> None:
        """Serve until ``stop`` is set or :meth:`stop` is called (noticed within one physics
        period). Never raises on bad input: unparseable bytes are counted by the link and
        dropped."""
        with selectors.DefaultSelector() as selector:
            fd = self._link.fileno()
            selector.register(fd, selectors.EVENT_READ)
            while not (stop.is_set() or self._stop_event.is_set()):
                timeout = max(0.0, self._next_deadline() - time.monotonic())
                if selector.select(timeout):
                    self._receive(time.monotonic())
                self._on_time(time.monotonic())
                fd = self._follow_fd(selector, fd)

    def _follow_fd(self, selector: selectors.BaseSelector, fd: int) -> int:
        """Re-register when the link's descriptor changed (``tcpin`` after a connect)."""
        new_fd = self._link.fileno()
        if new_fd != fd:
            selector.unregister(fd)
            selector.register(new_fd, selectors.EVENT_READ)
        return new_fd

    def _next_deadline(self) -> float:
        """Monotonic time (s) of the next physics tick or telemetry message."""
        physics = self._last_step_s + self._physics_period_s
        return min(physics, *(every.next_s for every, _ in self._telemetry))

    def _on_time(self, now_s: float) -> None:
        """Step physics and send every telemetry message that is due."""
        if now_s >= self._last_step_s + self._physics_period_s:
            self._step_to(now_s)
            self._refresh(now_s)
            self._publish()
        for every, send in self._telemetry:
            if every.due(now_s):
                send(now_s)

    def _step_to(self, now_s: float) -> None:
        """Step the chassis to ``now_s`` (monotonic s) with the commands held since the last
        step (a zero-order hold; at most ``_MAX_STEP_S`` at once)."""
        dt = min(now_s - self._last_step_s, _MAX_STEP_S)
        if dt > 0.0:
            self._chassis.step(dt, self._commands)
        self._last_step_s = now_s

    def _refresh(self, now_s: float) -> None:
        """Let lapsed overrides go and work out the wheel commands from ``now_s`` on."""
        self._channel_pwm = self._overrides.active(now_s)
        fl, fr, rl, rr = (
            w.command_from_pulse(self._channel_pwm[w.channel])
            if w.channel in self._channel_pwm
            else 0.0
            for w in self._outputs.wheels
        )
        self._commands = (fl, fr, rl, rr)

    def _receive(self, now_s: float) -> None:
        """Handle every message waiting. Physics catches up first, so new overrides take
        effect from the moment they arrived."""
        overrides = [m for m in self._link.read() if m.get_type() == "RC_CHANNELS_OVERRIDE"]
        if not overrides:
            return
        self._step_to(now_s)
        for msg in overrides:
            self._handle_override(msg, now_s)
        self._refresh(now_s)
        self._publish()

    def _handle_override(self, msg: Any, now_s: float) -> None:
        """Obey or drop one RC_CHANNELS_OVERRIDE (ArduPilot's sender and target rules)."""
        if not self._accepts(msg):
            self._ignored += 1
            return
        raw = [getattr(msg, f"chan{i}_raw", 0) for i in range(1, RC_CHANNELS + 1)]
        self._overrides.apply(raw, now_s)
        self._received += 1

    def _accepts(self, msg: Any) -> bool:
        """From our ground station and addressed to this board (or broadcast)."""
        return (
            msg.get_srcSystem() == self._gcs_sysid
            and msg.target_system in (0, self._sysid)
            and msg.target_component in (0, self._compid)
        )

    # ------------------------------------------------------------------ telemetry

    def _boot_us(self, now_s: float) -> int:
        """Microseconds since this board booted."""
        return int((now_s - self._boot_s) * 1e6)

    def _heartbeat(self, now_s: float) -> None:
        """HEARTBEAT of a disarmed ArduPilot Rover in MANUAL: base_mode as Rover's
        ``GCS_MAVLINK_Rover::base_mode()`` gives it (custom mode + manual input, not armed)."""
        base_mode = (
            mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
        )
        self._link.send(
            self._link.mav.heartbeat_encode(
                mavlink.MAV_TYPE_GROUND_ROVER,
                mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                base_mode,
                _MANUAL_MODE,
                mavlink.MAV_STATE_STANDBY,
            )
        )

    def _attitude(self, now_s: float) -> None:
        """ATTITUDE: level, true yaw (rad clockwise from north; the pose keeps it in [-pi, pi))
        and true yaw rate (rad/s clockwise)."""
        c = self._chassis
        time_boot_ms = (self._boot_us(now_s) // 1000) & 0xFFFFFFFF
        self._link.send(
            self._link.mav.attitude_encode(
                time_boot_ms, 0.0, 0.0, c.pose.yaw_rad, 0.0, 0.0, c.yaw_rate
            )
        )

    def _wheel_distance(self, now_s: float) -> None:
        """WHEEL_DISTANCE: cumulative encoder metres FL, FR, RL, RR, then zeros."""
        distances = [*self._chassis.wheel_distances_m, *([0.0] * 12)]
        self._link.send(self._link.mav.wheel_distance_encode(self._boot_us(now_s), 4, distances))

    def _servo_output_raw(self, now_s: float) -> None:
        """SERVO_OUTPUT_RAW: active override, else the wheel's trim, else 0 (port 0)."""
        time_usec = self._boot_us(now_s) & 0xFFFFFFFF
        pulses = self._servo_pulses()
        self._link.send(self._link.mav.servo_output_raw_encode(time_usec, 0, *pulses))

    def _servo_pulses(self) -> list[int]:
        """Pulse width (us) on outputs 1-16: an active override, else the trim of a wheel
        mapped to that channel, else 0 (no pulse)."""
        return [
            self._channel_pwm.get(ch, self._trims.get(ch, 0)) for ch in range(1, SERVO_OUTPUTS + 1)
        ]


def _copy_state(state: SimState) -> SimState:
    """``state`` with its own channel map, so a caller cannot change the published one."""
    return SimState(**{**state.__dict__, "channel_pwm": dict(state.channel_pwm)})


def main(url: str, params: Params) -> int:
    """``mecanum-mav simfc --listen URL``: serve in the foreground until SIGINT or SIGTERM.

    Prints one line saying where it listens; returns 0, or 1 (message on stderr) when the
    link cannot be opened. Call from the main thread (it installs signal handlers).
    """
    try:
        sim = SimFlightController(url, params)
    except (OSError, ValueError) as exc:
        print(f"simfc: {exc}", file=sys.stderr)
        return 1
    stop = threading.Event()
    with sim, on_termination(stop.set):
        port = sim.local_port
        where = f"{url} (port {port})" if port is not None else url
        print(
            f"simfc: simulated ArduPilot Rover, system {params['FC_SYSID']} component "
            f"{params['FC_COMPID']}, listening on {where}",
            flush=True,
        )
        sim.run(stop)
    return 0
