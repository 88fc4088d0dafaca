"""The rover core: everything the companion decides, with messages and time in, messages out.

No sockets, no clock, no files. The companion process (:mod:`mecanum_mav.app.companion`) feeds
it what arrives on its two links and writes what it returns; the lockstep harness
(:mod:`mecanum_mav.sim`) does the same in virtual time. Per message and per wake-up:

1. :meth:`RoverCore.handle` (one received message, the time it arrived): cheap state updates
   only. Stick input is remembered, not yet mixed, so after a burst of messages the newest
   stick wins and nothing queues.
2. :meth:`RoverCore.tick` (the time now): failsafes; the mission; the output (the pilot's
   stick in MANUAL, the GUIDED/AUTO chain on its control grid, else neutral), returned as the
   RC_CHANNELS_OVERRIDE to send at once when new input arrived or the output changed, and
   re-sent every ``OUT_RATE`` so the flight controller's override timeout never lapses.
3. :meth:`RoverCore.housekeeping` (after the override went out, so none of this delays it):
   odometry, telemetry, heartbeats, mission protocol timeouts and status texts.
4. :meth:`RoverCore.next_due_s`: when to call :meth:`RoverCore.tick` again if nothing arrives.

When the shell finds a link broken (device gone, connection closed) it calls
:meth:`RoverCore.link_down` once, and :meth:`RoverCore.link_up` once it has reopened it.

All three return an :class:`Outbox`: pymavlink message objects for the ground station and for the
flight controller (packed by the link that sends them, with its own sequence numbers and ids),
and the override's 18 channel fields when one is due.

Identity on the ground-station link: system ``SYSID_THISMAV``, component 1, ArduPilot Rover
dialect. On the flight-controller link the companion is a ground station (system
``FC_GCS_SYSID``, 255 by default: ArduPilot obeys overrides only from its ``MAV_GCS_SYSID``).

Safety: disarmed, HOLD, any failsafe, stale input, and an exception while handling a message
or computing the output all end at neutral PWM (each wheel's trim). After an exception the
output stays neutral (latched) until the next valid stick or setpoint or a mode change.
:meth:`RoverCore.shutdown` gives the last overrides: neutral, then the channels released.

Where things are: this module routes each message by type to its concern's handler
(:mod:`~mecanum_mav.control.gcsinput`, :mod:`~mecanum_mav.control.commands`,
:mod:`~mecanum_mav.control.paramlink`, :mod:`~mecanum_mav.control.missions`,
:mod:`~mecanum_mav.control.fclink`), which changes the shared
:class:`~mecanum_mav.control.context.Context`, and decides what goes out when; the wheels'
output is :class:`~mecanum_mav.control.output.OutputStage`'s, telemetry
:mod:`~mecanum_mav.control.reports`'.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from typing import Protocol

from mecanum_mav.config.params import Params
from mecanum_mav.control.autopilot import TIMER_SLACK_S, Autopilot
from mecanum_mav.control.commands import Commands
from mecanum_mav.control.context import COMPANION_COMPID, Handler
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.control.fclink import FcLink
from mecanum_mav.control.gcsinput import GcsInput
from mecanum_mav.control.lane import LaneAnswer, StickLane, compile_stick_lane
from mecanum_mav.control.missions import MissionControl, MissionStore
from mecanum_mav.control.outbox import NOTHING, Outbox, RcOverride, new_outbox
from mecanum_mav.control.output import NEUTRAL_WHEELS, OutputStage
from mecanum_mav.control.paramlink import ParamLink, ParamStore
from mecanum_mav.control.reports import LinkCounts, Reports, no_link_counts
from mecanum_mav.control.vehicle import Vehicle
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.messages import Received
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.statustext import Severity
from mecanum_mav.protocol.telemetry import StreamSchedule, next_on_grid

log = logging.getLogger(__name__)

__all__ = ["COMPANION_COMPID", "FC_LINK_COMPID", "NOTHING", "LinkCounts", "Outbox", "RcOverride",
           "RoverCore", "Storage"]

FC_LINK_COMPID: int = mavlink.MAV_COMP_ID_MISSIONPLANNER
"""The companion's component id on the flight-controller link, where it is a ground station
(190, as Mission Planner)."""
HEARTBEAT_PERIOD_S = 1.0
_LINK_LABELS = {"fc": "FC", "gcs": "GCS"}


class Storage(ParamStore, MissionStore, Protocol):
    """Where accepted parameters and missions are kept (files, in the companion):
    ``save_params`` and ``save_mission``, each raising ``OSError`` when it fails."""


class RoverCore(OutputStage):
    """The rover's decisions (see the module docstring).

    Args:
        params: the parameter store; PARAM_SET changes it (and :meth:`reconfigure` re-reads it).
        now_s: the time the rover boots, monotonic seconds (telemetry's ``time_boot_ms``).
        mission: the mission to start with (item 0 is home), e.g. read from its file.
        storage: keeps accepted parameters and missions, or None.
        link_counts: what the links counted (:class:`LinkCounts`, over both links), for
            SYS_STATUS ``errors_comm`` and ``drop_rate_comm``.
    """

    def __init__(self, params: Params, *, now_s: float, mission: Sequence[MissionItem] = (),
                 storage: Storage | None = None,
                 link_counts: Callable[[], LinkCounts] = no_link_counts) -> None:
        estimator = WheelOdometryEstimator(params)
        autopilot = Autopilot(params, estimator, lambda: self.origin)
        super().__init__(params, Vehicle(params, hooks=self), estimator, autopilot, now_s)
        self.storage = storage
        self.link_counts = link_counts
        self.streams = StreamSchedule(params)
        self.mission = MissionControl(mission, self.to_gcs, self.for_us, self.from_pilot,
                                      self.vehicle, autopilot.executor,
                                      lambda: estimator.pose, self.say, self.refuse, storage)
        self._gcs = gcs = GcsInput(self, estimator, autopilot)
        self._fc = fc = FcLink(self, estimator)
        self._reports = Reports(self, fc, gcs.origin, link_counts)
        commands = Commands(self, self.streams, estimator, self.mission,
                            self._reports.telemetry_state)
        param_link = ParamLink(self, self.reconfigure, storage)
        self.param_service = param_link.service
        self.rc_sticks = gcs.rc_sticks
        self.receiver = fc.receiver
        """The RC receiver read through the flight controller (``RCIN_ENABLE``)."""
        self._next_heartbeat_s = now_s
        self._housekeeping_due_s = -math.inf
        """Before this no timer of :meth:`housekeeping` is due (-inf: look at them all)."""
        self._quiet_until_s = -math.inf
        """Before this nothing but the output refresh can be due (:meth:`tick`)."""
        self._lane_driving = False
        """The vehicle was driving (:meth:`Vehicle.driving`) when housekeeping settled."""
        self._lane_until_s = -math.inf
        """Before this no timeout that changes the output (the vehicle's) is due and nothing
        arrived since :meth:`housekeeping`: :meth:`stick_lane` may answer a stick (its own
        timers, telemetry and heartbeats, wait until after the override)."""
        self._housekeeping_timers_s = -math.inf
        """The earliest of the timers :meth:`housekeeping` keeps (heartbeat, streams, mission
        protocol, setup check), as it last left them; valid before :attr:`_housekeeping_due_s`
        (a message that may move one resets that)."""
        self._lane: StickLane
        """The stick lane compiled for the configuration (:meth:`reconfigure`)."""
        self._lane_answer: LaneAnswer | None = None
        self._lane_s = -math.inf
        self._gcs_handlers: dict[str, Handler] = {
            **gcs.routes(), **commands.routes(), **param_link.routes(), **self.mission.routes()}
        """The ground station's messages, by type, to their handlers."""
        self._fc_handlers: dict[str, Handler] = fc.routes()
        """The flight controller's messages, by type, to their handlers."""
        self.reconfigure()

    # ================================================================== the interface

    def handle(self, msg: Received, now_s: float, *, from_fc: bool = False) -> Outbox:
        """One message received on the ground-station link (or the flight controller's, with
        ``from_fc``) at ``now_s``; returns what to send in answer."""
        self.now_s = now_s
        self._unsettle()  # something arrived: the next tick looks at it all
        kind = msg.get_type()
        if kind != "MANUAL_CONTROL":  # every other message may set a housekeeping timer
            self._housekeeping_due_s = -math.inf
        try:
            if from_fc:
                if msg.get_srcSystem() == self.identity.fc_sysid:
                    fc_handler = self._fc_handlers.get(kind)
                    if fc_handler is not None:
                        fc_handler(msg, now_s)
            else:
                handler = self._gcs_handlers.get(kind)
                if handler is not None and msg.get_srcSystem() != self.identity.sysid:
                    handler(msg, now_s)
        except Exception:  # never let one message take the control path down
            return self._take(self._handler_failed(kind, now_s))
        if self.to_gcs.messages or self.to_fc.messages:
            return self._take(None)
        return NOTHING

    def tick(self, now_s: float) -> Outbox:
        """Failsafes and the output at ``now_s``: the RC override to send at once, if one is
        due. Call :meth:`housekeeping` after sending it.

        Before :attr:`_lane_until_s` (set by :meth:`housekeeping`: no message since, no
        timeout of the vehicle's due, not in GUIDED or AUTO) with nothing new to say, nothing
        can have changed the output: the tick only repeats the last override when its refresh
        is due, and after a stick answered by :meth:`stick_lane` it has nothing to do. An
        idle rover's wakes are mostly these (``OUT_RATE``)."""
        self.now_s = now_s
        if (now_s < self._lane_until_s and not self.new_input and not self.to_gcs.messages
                and not self.to_fc.messages and self._last_override is not None):
            if now_s < self._next_output_s:
                return NOTHING
            self._next_output_s = now_s + self.output.refresh_period_s - TIMER_SLACK_S
            return new_outbox(((), (), self._last_override))
        vehicle = self.vehicle
        vehicle.update(now_s)
        executor = self.autopilot.executor
        if executor.running or vehicle.mode is Mode.AUTO:
            reason = self.autopilot.sync(vehicle.auto(), now_s)
            if reason is not None:
                self.say(Severity.WARNING, f"AUTO: {reason}: HOLD")
                vehicle.request_mode(Mode.HOLD, now_s)
        try:
            wheels, pulses = self._compute_output(now_s)
        except Exception:
            log.exception("error computing the output")
            self.faulted = True
            self.say(Severity.ERROR, "Error computing output: neutral")
            wheels, pulses = NEUTRAL_WHEELS, self.pwm.neutral()
        self._output_wheels = wheels
        if self.new_input or pulses != self.pulses_us or now_s >= self._next_output_s:
            # (timers are set TIMER_SLACK_S early: a clock that adds in floating point,
            # like the lockstep harness's, must not miss a period by 1e-17 s)
            return self._take(self._override(pulses, now_s))
        return self._take(None)

    def housekeeping(self, now_s: float) -> Outbox:
        """After the output went out: odometry from the commanded wheels, telemetry,
        heartbeats, the mission protocol's timeouts and status texts; returns what to send.

        A wake that finds no timer due and nothing to report (a stick, a setpoint, a control
        tick) integrates the commanded wheels and stops there."""
        self.now_s = now_s
        self._wheels_held(self._output_wheels, now_s)
        executor = self.autopilot.executor
        if (now_s < self._housekeeping_due_s and not self.vehicle.events
                and not executor.events and not self.to_gcs.messages
                and not self.to_fc.messages):
            if not (self._lane_driving and now_s < self._lane_until_s):
                self._settle()  # (after a stick in its lane the lane's bounds still hold)
            return NOTHING
        if self.vehicle.fc_lost or now_s >= self.fc_check.next_due_s:
            self._fc.housekeeping(now_s)  # the board lost and back; the setup check's timers
        # Telemetry and heartbeats ride the output refresh's wake-ups: each goes on the first
        # wake within half a refresh period of its time, early or late (see _ride), on its grid.
        ride_s = self.output.refresh_period_s / 2
        due = self.streams.due(now_s, ride_s)
        if due:
            self._reports.send_streams(due, now_s)
        if now_s + ride_s >= self._next_heartbeat_s:
            self._reports.send_heartbeats()
            self.mission.send_current()  # MISSION_CURRENT at 1 Hz, as ArduPilot
            self._next_heartbeat_s = next_on_grid(self._next_heartbeat_s, HEARTBEAT_PERIOD_S,
                                                  now_s)
        self.mission.tick(now_s)
        if self.vehicle.events:
            self.tell_vehicle_events()
        timers_s = min(self.fc_check.next_due_s, self.mission.next_due_s())
        periodic_s = min(self._next_heartbeat_s, self.streams.next_due_s())
        self._housekeeping_timers_s = min(timers_s, self._ride(periodic_s, ride_s))
        self._housekeeping_due_s = min(timers_s, periodic_s - ride_s)
        self._settle()
        return self._take(None)

    def _ride(self, periodic_s: float, ride_s: float) -> float:
        """When the loop must wake for a periodic send due at ``periodic_s``: not at all when
        the output refresh's wake comes first or within ``ride_s`` after it (the send rides
        that wake, at most ``ride_s`` late, as it rides one up to ``ride_s`` early), so an
        idle rover wakes at the refresh rate only, not also at each stream's."""
        late_s = periodic_s + ride_s
        return late_s if self._next_output_s <= late_s else periodic_s

    def _settle(self) -> None:
        """After housekeeping: until when a tick may take its short way, and the lane answer
        (never while the controllers tick)."""
        if self.vehicle.autonomous() or self.autopilot.executor.running:
            self._unsettle()
            return
        self._lane_until_s = self.vehicle.next_due_s()
        self._quiet_until_s = min(self._housekeeping_due_s, self._lane_until_s)
        # Driving in MANUAL changes only with a message (which unsettles) or a vehicle
        # timeout (which ends the lane): what stick_lane needs, looked at once here.
        self._lane_driving = self.vehicle.driving()

    def _unsettle(self) -> None:
        """Something arrived or changed: the next tick and housekeeping look at everything,
        and no stick takes the lane before they have."""
        self._quiet_until_s = self._lane_until_s = -math.inf

    def stick_lane(self, datagram: bytes, now_s: float, seq: int) -> bytes | None:
        """The control path's lane: a datagram holding the pilot's MANUAL_CONTROL answered at
        once with the RC_CHANNELS_OVERRIDE packet to send, numbered ``seq``: exactly what
        :meth:`handle` then :meth:`tick` would answer, when nothing else can be involved:
        driving in MANUAL, no timeout that changes the output due and nothing else arrived
        since :meth:`housekeeping`, and a datagram the compiled lane answers
        (:mod:`mecanum_mav.control.lane`: one valid stick for us from the pilot). Else None,
        with nothing changed: parse the datagram and call :meth:`handle` and :meth:`tick`.

        Send the packet first, then call :meth:`stick_sent`: the stick is taken, the output
        recorded and the odometry of the wheels held until now taken there, after the send.
        A timer of housekeeping's own (telemetry, heartbeats) does not close the lane; call
        :meth:`tick` (nothing to send then) and :meth:`housekeeping` as after any message;
        :meth:`settled` says when a loop may skip them (after a stick in its lane, unless a
        timer is due). The packet is unsigned: a link that signs must not use the lane."""
        if now_s >= self._lane_until_s or self.faulted or not self._lane_driving:
            return None
        try:
            answer = self._lane(datagram, seq)
        except Exception:  # never seen; handle() and tick() take it the general way
            log.exception("error in the stick lane")
            return None
        if answer is None:
            return None
        self._lane_answer, self._lane_s = answer, now_s
        return answer[0]

    def stick_sent(self) -> None:
        """After the packet :meth:`stick_lane` returned went out: the stick taken, the output
        recorded (for the refresh and telemetry) and the odometry of the wheels held until
        then taken, at the lane's time."""
        answer, now_s = self._lane_answer, self._lane_s
        if answer is None:
            raise RuntimeError("stick_sent without a packet from stick_lane")
        self._lane_answer = None
        _, stick, wheels, pulses, fields = answer
        self.now_s = now_s
        self.take_stick(stick, now_s)
        self._override(pulses, now_s, fields)
        self._output_wheels = wheels
        self._wheels_held(wheels, now_s)  # (after the send: the odometry up to now)

    def settled(self, now_s: float) -> bool:
        """Whether :meth:`tick` and :meth:`housekeeping` have nothing to do at ``now_s``: no
        timer due (the output refresh's included), nothing arrived since housekeeping last
        looked, the odometry up to date with the wheels output, nothing waiting to be sent.
        A loop may then skip them (after a refresh, or a wake with nothing to read)."""
        return (now_s < self._quiet_until_s and now_s < self._next_output_s
                and self._output_wheels is self.wheels
                and not self.to_gcs.messages and not self.to_fc.messages)

    def _handler_failed(self, kind: str, now_s: float) -> RcOverride:
        """A message handler raised: logged, said, neutral at once and latched."""
        log.exception("error handling %s", kind)
        self.faulted = True
        self.say(Severity.ERROR, f"Error handling {kind}: neutral")
        return self._override(self.pwm.neutral(), now_s)

    def link_down(self, link: str, reason: str, now_s: float) -> Outbox:
        """The shell's ``link`` (``"fc"`` or ``"gcs"``) broke at ``now_s`` for ``reason``
        (device gone, closed by the peer) and is being reopened: said once (WARNING), and that
        link's failsafe fires now (:meth:`Vehicle.on_fc_link_down`,
        :meth:`Vehicle.on_gcs_link_down`); returns what to send (on the other link)."""
        self.now_s = now_s
        self._unsettle()
        self.say(Severity.WARNING, f"{_LINK_LABELS[link]} link down: {reason}; "
                                   f"reconnecting")
        if link == "fc":
            self.vehicle.on_fc_link_down(now_s)
        else:
            self.vehicle.on_gcs_link_down(now_s)
        self._next_output_s = now_s  # the output follows at once (neutral, where it can go)
        return self._take(None)

    def link_up(self, link: str, now_s: float) -> Outbox:
        """The shell's ``link`` is open again at ``now_s``: said once (NOTICE). On the flight
        controller's, the first thing sent is neutral, never what was output before the break
        (driving needs the flight controller's HEARTBEAT and arming again)."""
        self.now_s = now_s
        self._unsettle()
        self.say(Severity.NOTICE, f"{_LINK_LABELS[link]} link reconnected")
        if link == "fc":
            return self._take(self._override(self.pwm.neutral(), now_s))
        return self._take(None)

    def next_due_s(self) -> float:
        """When :meth:`tick` must run next if no message arrives first (monotonic s)."""
        now_s = self.now_s
        if now_s < self._housekeeping_due_s:  # its timers as housekeeping left them
            if now_s < self._lane_until_s and self._lane_driving:
                # Driving in MANUAL (no control ticks), and the vehicle's timeouts only move
                # later without a message (which unsettles): until the one housekeeping saw,
                # that one stands for them (a wake at most early).
                return min(self._next_output_s, self._housekeeping_timers_s,
                           self._lane_until_s)
            return min(self._next_output_s, self._housekeeping_timers_s,
                       self.vehicle.next_due_s(), self.autopilot.next_due_s())
        return min(self._next_output_s, self._next_heartbeat_s, self.vehicle.next_due_s(),
                   self.streams.next_due_s(), self.autopilot.next_due_s(),
                   self.mission.next_due_s(), self.fc_check.next_due_s)

    def reconfigure(self) -> None:
        """Re-read the parameter views the loop uses (after a parameter changed)."""
        self._unsettle()
        self.read_views()  # identity, input, rc_input, receiver_config, pwm, output
        self._lane = compile_stick_lane(self.input, self.pwm, self.identity, FC_LINK_COMPID)
        if not self.receiver_config.enabled:
            self._fc.rc_stream_asked = False  # (asked again when it is turned on)
        for part in (self._gcs, self.vehicle, self.estimator, self.autopilot):
            part.reconfigure(self.params)

    def status_line(self) -> str:
        """One line of counts for people (:mod:`~mecanum_mav.control.reports`)."""
        return self._reports.status_line()

    @property
    def origin(self) -> GlobalOrigin | None:
        """Where local (0, 0) is on the earth: SET_GPS_GLOBAL_ORIGIN, else ORIGIN_LAT/LON."""
        return self._gcs.origin()

