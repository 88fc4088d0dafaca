"""What the rover core and its message handlers share: the configuration views, the two
outboxes, the pilot's drive input, and what every handler does (check an address, say,
refuse, ask the flight controller, the pre-arm checks).

:class:`~mecanum_mav.control.core.RoverCore` is a :class:`Context` (so the hot path reads
these as its own attributes); the handlers (:mod:`~mecanum_mav.control.gcsinput`,
:mod:`~mecanum_mav.control.commands`, :mod:`~mecanum_mav.control.paramlink`,
:mod:`~mecanum_mav.control.fclink`) are given it and never import the core. A handler can be
tested alone on a bare :class:`Context`. No sockets, no clock: times are passed in (s).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import IdentityConfig, InputConfig, RcInputConfig, ReceiverConfig
from mecanum_mav.control.fccheck import FcSetupCheck
from mecanum_mav.control.refusals import FC_SIGNATURE_REFUSED, Refusal, RefusalLog
from mecanum_mav.control.vehicle import Vehicle
from mecanum_mav.protocol.outbox import MessageOutbox
from mecanum_mav.protocol.signing import REFUSED_TEXTS, Check
from mecanum_mav.protocol.statustext import Severity, statustext_messages

__all__ = ["COMPANION_COMPID", "NEUTRAL_STICK", "Context", "Handler"]

log = logging.getLogger("mecanum_mav.control.core")
"""The rover's voice keeps the core's logger name (what its log lines always said)."""

COMPANION_COMPID = 1
"""The companion's component id on the ground-station link (MAVSDK talks to component 1 only)."""
NEUTRAL_STICK = (0.0, 0.0, 0.0)

Handler = Callable[[Any, float], None]
"""A message handler: (the message, its arrival time in s); each declares the fields it
reads with a protocol of :mod:`mecanum_mav.protocol.messages`."""


class Context:
    """The state the core and its handlers share (module docstring).

    Args:
        params: the parameter store.
        vehicle: arming, mode and failsafes.
        now_s: the time now, monotonic s.
    """

    identity: IdentityConfig
    """Who is who on the two links (:meth:`read_views`; the boot ``SYSID_THISMAV`` kept)."""
    input: InputConfig
    """How the pilot's sticks are shaped (:meth:`read_views`)."""
    rc_input: RcInputConfig
    """How RC channels become sticks (:meth:`read_views`)."""
    receiver_config: ReceiverConfig
    """The RC receiver read through the flight controller (:meth:`read_views`)."""

    def __init__(self, params: Params, vehicle: Vehicle, now_s: float) -> None:
        self.params = params
        self._boot_sysid = int(params["SYSID_THISMAV"])
        self.vehicle = vehicle
        self.boot_s = now_s
        """When the rover booted (monotonic s; telemetry's ``time_boot_ms``)."""
        self.now_s = now_s
        """The time of the message or wake being handled (monotonic s)."""
        self.to_gcs = MessageOutbox()
        self.to_fc = MessageOutbox()
        self.refusals = RefusalLog()
        """What was refused, per kind (:mod:`mecanum_mav.control.refusals`)."""
        self.fc_check = FcSetupCheck()
        """The read-only check of the flight controller's setup, run when it appears."""
        self.stick = NEUTRAL_STICK
        """The latest valid stick: forward, right, clockwise, normalized."""
        self.gcs_stick_s = -math.inf
        """When a ground station's stick last arrived (it takes over from the receiver)."""
        self.faulted = False
        """An exception forced neutral; cleared by the next valid input or a mode change."""
        self.new_input = False
        """A stick or setpoint arrived since the last override: send one at once."""
        self.read_views()

    def read_views(self) -> None:
        """Re-read the views the handlers use from the parameters (after one changed)."""
        p = self.params
        # SYSID_THISMAV is reboot_required: the links keep the id they were opened with.
        self.identity = replace(IdentityConfig.from_params(p), sysid=self._boot_sysid)
        self.input = InputConfig.from_params(p)
        self.rc_input = RcInputConfig.from_params(p)
        self.receiver_config = ReceiverConfig.from_params(p)

    # ------------------------------------------------------------------ addressing

    def for_us(self, target_system: int, target_component: int | None = None) -> bool:
        """Whether a message addressed to ``target_system`` (and ``target_component``, when
        the message has one) is for this vehicle: 0 is everyone."""
        if target_system != 0 and target_system != self.identity.sysid:
            return False
        return target_component is None or target_component in (0, COMPANION_COMPID)

    def from_pilot(self, msg: Any) -> bool:
        """Whether ``msg`` comes from the ground station allowed to command (``SYSID_MYGCS``,
        0 = any)."""
        gcs = self.identity.gcs_sysid
        return gcs == 0 or msg.get_srcSystem() == gcs

    # ------------------------------------------------------------------ the voice

    def say(self, severity: Severity, text: str) -> None:
        """A STATUSTEXT to the ground station (and the log); long texts go in chunks."""
        log.log(logging.WARNING if severity <= Severity.WARNING else logging.INFO, "%s", text)
        self.to_gcs.messages.extend(statustext_messages(severity, text))

    def refuse(self, kind: Refusal, text: str, count: int = 1) -> None:
        """Count ``count`` refused inputs of ``kind`` and say why (WARNING), at most once a
        second per kind (:class:`~mecanum_mav.control.refusals.RefusalLog`)."""
        if self.refusals.add(kind, self.now_s, count):
            self.say(Severity.WARNING, text)

    def tell_vehicle_events(self) -> None:
        """What the vehicle decided since (mode changes, failsafes, arming refused): each
        said, or refused (counted) when it turned an input down."""
        for event in self.vehicle.take_events():
            if event.refusal is None:
                self.say(event.severity, event.text)
            else:
                self.refuse(event.refusal, event.text)

    def refuse_unsigned(self, rejected: Mapping[Check, int], now_s: float, *,
                        from_fc: bool) -> None:
        """Packets a link's signature check dropped before they became messages (per kind,
        :meth:`~mecanum_mav.protocol.signing.SignatureCheck.take_rejections`): counted as
        :attr:`Refusal.SIGNATURE`; none of them reached the core's ``handle``, so none armed, drove
        or kept the ground-station failsafe from firing (or, ``from_fc``, brought the
        flight-controller link up)."""
        self.now_s = now_s
        texts = FC_SIGNATURE_REFUSED if from_fc else REFUSED_TEXTS
        for kind, count in rejected.items():
            self.refuse(Refusal.SIGNATURE, texts[kind], count)

    def ask_fc_params(self, names: Sequence[str]) -> None:
        """PARAM_REQUEST_READ to the flight controller for each of ``names``."""
        target = self.identity.fc_sysid, self.identity.fc_compid
        for name in names:
            self.to_fc.param_request_read_send(*target, name.encode("ascii"), -1)

    # ------------------------------------------------------------------ the drive input

    def take_stick(self, stick: tuple[float, float, float], now_s: float) -> None:
        """A ground station's valid ``stick`` at ``now_s``: it drives (the receiver waits),
        clears an exception's latch and is output at once."""
        self.stick = stick
        self.gcs_stick_s = now_s  # a ground station's stick: the receiver's wait
        self.faulted = False
        self.vehicle.on_stick_input(now_s)
        self.new_input = True

    def prearm_problems(self, stick: tuple[float, float, float] | None = None) -> list[str]:
        """The core's pre-arm checks: the flight controller's setup (when it was checked)
        must be safe, and a pilot's fresh stick (or ``stick``, the receiver's) must be
        centred (within the deadband), or arming would drive off at once."""
        problems = []
        fc_problem, ask = self.fc_check.arm_problem(self.now_s)
        self.ask_fc_params(ask)
        if fc_problem is not None:
            problems.append(fc_problem)
        if stick is None and not self.vehicle.input_stale:
            stick = self.stick
        if stick is not None:
            deflected = [f"{name} {value:+.2f}" for name, value in zip("xyr", stick,
                                                                        strict=True)
                         if abs(value) > self.input.deadband]
            if deflected:
                problems.append(f"sticks not centred ({', '.join(deflected)})")
        return problems
