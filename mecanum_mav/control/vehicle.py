"""The vehicle's state machine: arming, modes and failsafes. Pure logic; time is passed in.

This is what a ground station sees as the rover's state, in the ArduPilot Rover dialect:
modes use Rover's ``custom_mode`` numbering (MANUAL 0, HOLD 4, AUTO 10, GUIDED 15). The
companion loop feeds it events (heartbeats, stick input, commands) with a monotonic time in
seconds, calls :meth:`Vehicle.update` regularly, and asks :meth:`Vehicle.driving` whether the
sticks may move the wheels. Every way out of normal driving (disarm, HOLD, any failsafe, stale
input) makes :meth:`Vehicle.driving` False, which the loop turns into neutral PWM.

Failsafes (each a parameter):

- Stale stick input (``FS_INPUT_TMO``): while armed in MANUAL, no stick input for the timeout
  brings the wheels to neutral; driving resumes with the next input. Reported once each way.
- Ground-station loss (``FS_GCS_TMO``, ``FS_GCS_ACTION``): once a ground station has been
  seen, no HEARTBEAT from it for the timeout while armed switches to HOLD (default) or
  disarms. Like ArduPilot, the rover stays in HOLD when the link returns: the pilot chooses.
- Flight-controller loss (``FS_FC_TMO``): no flight-controller HEARTBEAT for the timeout (or
  never one) reports CRITICAL, disarms, and refuses to arm until it is back.

- Receiver failsafe (``RCIN_ENABLE`` and ``FS_THR_ENABLE``, ``FS_RC_ACTION``): the receiver
  read through the flight controller gave no valid RC_CHANNELS for ``FS_INPUT_TMO`` or said it
  lost its transmitter (:meth:`Vehicle.on_receiver`): reports CRITICAL, switches to HOLD
  (default) or disarms while armed, and refuses to arm until the receiver is back. It starts
  active (no receiver heard yet). Like ArduPilot, the rover stays in HOLD when it returns.

A link that breaks (the shell saw its device vanish or its connection close) needs no
timeout: nothing can arrive on it, so :meth:`Vehicle.on_fc_link_down` and
:meth:`Vehicle.on_gcs_link_down` fire its failsafe at once.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple, Protocol

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import FailsafeConfig
from mecanum_mav.control.refusals import Refusal
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.statustext import Severity

__all__ = ["Decision", "Event", "Mode", "ModeHooks", "Severity", "Vehicle"]

_AUTONOMOUS = (Mode.GUIDED, Mode.AUTO)


@dataclass(frozen=True)
class Decision:
    """The answer to a command: accepted or not, and why (for COMMAND_ACK and STATUSTEXT)."""

    accepted: bool
    reason: str = ""


class Event(NamedTuple):
    """A state change or a refusal a pilot must know about (a STATUSTEXT)."""

    severity: Severity
    text: str
    refusal: Refusal | None = None
    """The kind of refused input, or None for a state change."""


class ModeHooks(Protocol):
    """What a mode change does beyond the mode itself (the controllers behind GUIDED and AUTO)."""

    def refuse_entry(self, mode: Mode, now_s: float) -> str | None:
        """Why ``mode`` cannot be entered now, or None to allow it."""

    def on_mode_change(self, before: Mode, after: Mode, now_s: float) -> None:
        """The mode changed from ``before`` to ``after`` at ``now_s``."""


class Vehicle:
    """Arming, mode and failsafe state of the rover.

    Args:
        params: the parameter store; the failsafe timeouts and action are read from it here
            and by :meth:`reconfigure` (after a parameter changed).
        hooks: the side effects of mode changes (see :class:`ModeHooks`), or None.
    """

    def __init__(self, params: Params, hooks: ModeHooks | None = None) -> None:
        self.config = FailsafeConfig.from_params(params)
        self.hooks = hooks
        self.armed = False
        self.mode = Mode.MANUAL
        self.gcs_seen_s: float | None = None
        self.fc_seen_s: float | None = None
        self.input_s: float | None = None
        self.gcs_failsafe = False
        self.fc_lost = True
        self.input_stale = True
        self.rc_seen_s: float | None = None
        """When the receiver last gave valid input (monotonic s), None before."""
        self.rc_failsafe = self.config.receiver_failsafe
        """The receiver failsafe is active (see the module docstring)."""
        self.events: list[Event] = []
        """The state changes since :meth:`take_events`, oldest first (empty: none)."""

    def reconfigure(self, params: Params) -> None:
        """Take the failsafe parameters from ``params`` (after a parameter changed)."""
        self.config = FailsafeConfig.from_params(params)
        if not self.config.receiver_failsafe:
            self.rc_failsafe = False
        elif self.rc_seen_s is None:
            self.rc_failsafe = True

    # ----------------------------------------------------------------- inputs

    def on_gcs_heartbeat(self, now_s: float) -> None:
        """A HEARTBEAT from the (permitted) ground station arrived."""
        self.gcs_seen_s = now_s
        if self.gcs_failsafe:
            self.gcs_failsafe = False
            self._say(Severity.NOTICE, f"GCS link regained, mode {self.mode.name}")

    def on_fc_heartbeat(self, now_s: float) -> None:
        """A HEARTBEAT from the flight controller arrived."""
        self.fc_seen_s = now_s
        if self.fc_lost:
            self.fc_lost = False
            self._say(Severity.NOTICE, "Flight controller link up")

    def on_stick_input(self, now_s: float) -> None:
        """Valid stick input (MANUAL_CONTROL or ground-station RC override) arrived."""
        self.input_s = now_s
        if self.input_stale:
            self.input_stale = False
            if self.armed and self.mode is Mode.MANUAL:
                self._say(Severity.INFO, "Manual input resumed")

    def on_receiver(self, problem: str | None, now_s: float) -> None:
        """The receiver's RC_CHANNELS arrived: valid (``problem`` None) or its failsafe
        (``problem`` says which: no channels, RSSI 0, throttle below FS_THR_VALUE)."""
        if problem is None:
            self.rc_seen_s = now_s
            if self.rc_failsafe:
                self.rc_failsafe = False
                self._say(Severity.NOTICE, f"Radio receiver OK, mode {self.mode.name}")
        elif self.config.receiver_failsafe:
            self._receiver_failsafe(problem, now_s)

    def _receiver_failsafe(self, problem: str, now_s: float) -> None:
        self.rc_seen_s = None
        if self.rc_failsafe:
            return
        self.rc_failsafe = True
        self._say(Severity.CRITICAL, f"Radio failsafe: {problem}")
        if self.armed:
            if self.config.receiver_action_disarm:
                self.request_disarm("radio failsafe")
            else:
                self.request_mode(Mode.HOLD, now_s)

    def on_fc_link_down(self, now_s: float) -> None:
        """The flight controller's link broke (device gone, connection closed): no HEARTBEAT
        can arrive, so the flight controller is lost now, not at the timeout (disarm; arming
        is refused until its HEARTBEAT is back)."""
        self.fc_seen_s = None
        self.update(now_s)

    def on_gcs_link_down(self, now_s: float) -> None:
        """The ground station's link broke: no stick and no HEARTBEAT can arrive, so the stick
        input is stale now (wheels neutral) and, once a ground station was seen, its failsafe
        fires now (``FS_GCS_ACTION``)."""
        self.input_s = None
        if self.gcs_seen_s is not None:
            self.gcs_seen_s = -math.inf
        self.update(now_s)

    # ----------------------------------------------------------------- commands

    def request_arm(self, now_s: float, problems: Sequence[str] = (), *,
                    force: bool = False) -> Decision:
        """Arm, unless a pre-arm check fails: the flight controller link is down (always
        checked: without it the rover would be disarmed again at once), or one of
        ``problems`` (the caller's checks, e.g. deflected sticks), which ``ARMING_CHECK`` 0
        and ``force`` (ArduPilot's forced arming) skip. Refusals are worded as ArduPilot's
        ("PreArm: ..."). Arming when armed is accepted."""
        self.update(now_s)
        if self.armed:
            return Decision(True)
        if self.fc_lost:
            return self._refuse("PreArm: flight controller link down", Refusal.ARM)
        if self.rc_failsafe:
            return self._refuse("PreArm: radio failsafe (receiver)", Refusal.ARM)
        if problems and not force and self.config.arming_check:
            return self._refuse(f"PreArm: {problems[0]}", Refusal.ARM)
        self.armed = True
        self.input_stale = True  # the wheels wait for fresh sticks after arming
        self._say(Severity.INFO, f"Armed, mode {self.mode.name}")
        return Decision(True)

    def request_disarm(self, reason: str) -> Decision:
        """Disarm (always allowed), saying why ("Disarmed: by command"). Disarming when
        disarmed is accepted."""
        if self.armed:
            self.armed = False
            self._say(Severity.INFO, f"Disarmed: {reason}")
        return Decision(True)

    def request_mode(self, mode_number: int, now_s: float) -> Decision:
        """Switch to a Rover mode number; a number that is not one of :class:`Mode` (each of
        which it can enter) is refused, and so is a mode whose controller cannot start
        (:meth:`ModeHooks.refuse_entry`, e.g. AUTO without a mission). The hooks see every
        change, failsafe switches included."""
        try:
            mode = Mode(mode_number)
        except ValueError:
            return self._refuse(f"Mode {mode_number} unknown", Refusal.MODE)
        if mode is self.mode:
            return Decision(True)
        if self.hooks is not None:
            reason = self.hooks.refuse_entry(mode, now_s)
            if reason is not None:
                self._refuse(f"{mode.name} refused: {reason}", Refusal.MODE)
                return Decision(False, reason)
        before, self.mode = self.mode, mode
        self._say(Severity.INFO, f"Mode {mode.name}")
        if self.hooks is not None:
            self.hooks.on_mode_change(before, mode, now_s)
        return Decision(True)

    # ----------------------------------------------------------------- time

    def update(self, now_s: float) -> None:
        """Check every timeout at time ``now_s`` (monotonic seconds); queue the events."""
        c = self.config
        fc_down = self.fc_seen_s is None or now_s - self.fc_seen_s > c.fc_timeout_s
        if fc_down and not self.fc_lost:
            self.fc_lost = True
            self._say(Severity.CRITICAL, "Flight controller link lost")
        if self.fc_lost and self.armed:
            self.request_disarm("flight controller link lost")
        gcs_late = self.gcs_seen_s is not None and now_s - self.gcs_seen_s > c.gcs_timeout_s
        if gcs_late and not self.gcs_failsafe:
            self.gcs_failsafe = True
            self._say(Severity.CRITICAL, "GCS link lost: failsafe")
            if self.armed:
                if c.gcs_action_disarm:
                    self.request_disarm("GCS failsafe")
                else:
                    self.request_mode(Mode.HOLD, now_s)
        rc_s = self.rc_seen_s
        if rc_s is not None and now_s - rc_s > c.input_timeout_s and c.receiver_failsafe:
            self._receiver_failsafe("no RC_CHANNELS", now_s)
        stale = self.input_s is None or now_s - self.input_s > c.input_timeout_s
        if stale and not self.input_stale:
            self.input_stale = True
            if self.armed and self.mode is Mode.MANUAL:
                self._say(Severity.WARNING, "Manual input lost: wheels neutral")

    def next_due_s(self) -> float:
        """When the next timeout can fire if nothing arrives first (monotonic s; inf if none):
        the flight controller's and the ground station's heartbeat deadlines and the stick
        input's. :meth:`update` must run then for the failsafe to fire on time."""
        c = self.config
        due = math.inf
        if not self.fc_lost and self.fc_seen_s is not None:
            due = self.fc_seen_s + c.fc_timeout_s
        if not self.gcs_failsafe and self.gcs_seen_s is not None:
            due = min(due, self.gcs_seen_s + c.gcs_timeout_s)
        if not self.input_stale and self.input_s is not None:
            due = min(due, self.input_s + c.input_timeout_s)
        if self.rc_seen_s is not None and c.receiver_failsafe:
            due = min(due, self.rc_seen_s + c.input_timeout_s)
        return due

    # ----------------------------------------------------------------- outputs

    def driving(self) -> bool:
        """True when the sticks may move the wheels: armed, MANUAL, fresh input, no failsafe."""
        return (
            self.armed and self.mode is Mode.MANUAL and not self.input_stale
            and not self.fc_lost and not self.gcs_failsafe and not self.rc_failsafe
        )

    def autonomous(self) -> bool:
        """True when the controllers may move the wheels: armed, GUIDED or AUTO, no failsafe."""
        return self.armed and self.mode in _AUTONOMOUS and not (
            self.fc_lost or self.gcs_failsafe or self.rc_failsafe)  # (not failsafe)

    def guided(self) -> bool:
        """True when GUIDED setpoints may move the wheels: armed, GUIDED, no failsafe."""
        return self.mode is Mode.GUIDED and self.autonomous()

    def auto(self) -> bool:
        """True when the mission may move the wheels: armed, AUTO, no failsafe."""
        return self.mode is Mode.AUTO and self.autonomous()

    @property
    def failsafe(self) -> bool:
        """Any link or receiver failsafe is active (the heartbeat then reports CRITICAL)."""
        return self.fc_lost or self.gcs_failsafe or self.rc_failsafe

    def take_events(self) -> list[Event]:
        """The state changes since the last call, oldest first (for STATUSTEXT)."""
        events, self.events = self.events, []
        return events

    # ----------------------------------------------------------------- helpers

    def _say(self, severity: Severity, text: str) -> None:
        self.events.append(Event(severity, text))

    def _refuse(self, reason: str, kind: Refusal) -> Decision:
        self.events.append(Event(Severity.WARNING, reason, kind))
        return Decision(False, reason)
