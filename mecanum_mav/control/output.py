"""What the wheels are told: the output stage under the core's timing.

:class:`OutputStage` is the part of the rover core that turns the decided input into wheel
commands and the RC_CHANNELS_OVERRIDE carrying them: neutral (each wheel's trim) when faulted
or not driving, the GUIDED/AUTO controllers' output while they drive, else the pilot's stick
mixed; the override and what it set; the last overrides at shutdown (neutral, then the
channels released); and the mode hooks that start and stop the controllers.

:class:`~mecanum_mav.control.core.RoverCore` is an :class:`OutputStage` (itself a
:class:`~mecanum_mav.control.context.Context`), so the hot path reads this state as its own
attributes; :meth:`~mecanum_mav.control.core.RoverCore.tick` decides when an override goes out.
"""

from __future__ import annotations

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import OutputConfig
from mecanum_mav.control.autopilot import TIMER_SLACK_S, Autopilot
from mecanum_mav.control.chain import Output, manual_output
from mecanum_mav.control.context import Context
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.control.outbox import NOTHING, Outbox, RcOverride, new_outbox, new_override
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.control.vehicle import Vehicle
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.rcoverride import override_fields, release_fields

__all__ = ["NEUTRAL_WHEELS", "OutputStage"]

NEUTRAL_WHEELS = (0.0, 0.0, 0.0, 0.0)


class OutputStage(Context):
    """The wheels' output for one rover (module docstring).

    Args:
        params: the parameter store.
        vehicle: arming, mode and failsafes.
        estimator: the odometry the commanded wheels are integrated into.
        autopilot: the GUIDED and AUTO controllers.
        now_s: the time now, monotonic s.
    """

    pwm: PwmMap
    """The PWM edge: channels, trims, reverses (:meth:`read_views`)."""
    output: OutputConfig
    """The output's refresh and control rates (:meth:`read_views`)."""

    def __init__(self, params: Params, vehicle: Vehicle, estimator: WheelOdometryEstimator,
                 autopilot: Autopilot, now_s: float) -> None:
        super().__init__(params, vehicle, now_s)
        self.estimator = estimator
        self.autopilot = autopilot
        self.wheels = NEUTRAL_WHEELS
        """The wheel commands being output, normalized FL, FR, RL, RR."""
        self.pulses_us: tuple[int, ...] = ()
        """The pulse widths last sent to the flight controller (us), FL, FR, RL, RR."""
        self._wheels_s: float | None = None
        self._output_wheels = NEUTRAL_WHEELS
        """The wheels of the output last computed (odometry takes them in housekeeping)."""
        self._autopilot_active = False
        self._next_output_s = now_s
        """When the override must be sent again (the refresh), monotonic s."""
        self._last_override: RcOverride | None = None

    def read_views(self) -> None:
        """The context's views, and the PWM edge and the output's rates."""
        super().read_views()
        self.pwm = PwmMap.from_params(self.params)
        self.output = OutputConfig.from_params(self.params)

    # ------------------------------------------------------------------ mode hooks

    def refuse_entry(self, mode: Mode, now_s: float) -> str | None:
        """:class:`~mecanum_mav.control.vehicle.ModeHooks`: the autopilot decides."""
        return self.autopilot.refuse_entry(mode, now_s)

    def on_mode_change(self, before: Mode, after: Mode, now_s: float) -> None:
        """A mode change clears an exception's neutral latch and starts the controllers."""
        self.faulted = False
        self.autopilot.on_mode_change(before, after, now_s)

    # ------------------------------------------------------------------ the output

    def _compute_output(self, now_s: float) -> Output:
        vehicle = self.vehicle
        if self.faulted:
            self._autopilot_active = False
            self.autopilot.idle()
            return NEUTRAL_WHEELS, self.pwm.neutral()
        if vehicle.autonomous():
            self._autopilot_active = True
            return self.autopilot.output(vehicle.mode is Mode.AUTO, now_s, self.output,
                                         self.input.desaturation, self.pwm)
        if self._autopilot_active:
            self._autopilot_active = False
            self.autopilot.idle()
        if not vehicle.driving():
            return NEUTRAL_WHEELS, self.pwm.neutral()
        x, y, r = self.stick
        return manual_output(x, y, r, self.input, self.pwm)

    def _override(self, pulses: tuple[int, ...], now_s: float,
                  fields: list[int] | None = None) -> RcOverride:
        """The override setting the wheels to ``pulses`` (its ``fields`` if already made)."""
        self.pulses_us = pulses
        self.new_input = False
        self._next_output_s = now_s + self.output.refresh_period_s - TIMER_SLACK_S
        identity = self.identity
        if fields is None:
            fields = override_fields(self.pwm.channels, pulses)
        override = self._last_override = new_override((identity.fc_sysid, identity.fc_compid,
                                                       fields))
        return override

    def _take(self, override: RcOverride | None) -> Outbox:
        """The outbox: what the handlers queued on both links, and ``override``."""
        gcs, fc = self.to_gcs, self.to_fc
        if not (gcs.messages or fc.messages or override):
            return NOTHING
        return new_outbox((gcs.take() if gcs.messages else (),
                           fc.take() if fc.messages else (), override))

    def _wheels_held(self, wheels: tuple[float, float, float, float], now_s: float) -> None:
        """The odometry of the wheels commanded until ``now_s``; ``wheels`` from then on."""
        if self._wheels_s is not None:
            self.estimator.on_commanded(self.wheels, now_s - self._wheels_s, now_s)
        self.wheels, self._wheels_s = wheels, now_s

    def shutdown(self) -> list[RcOverride]:
        """The last overrides before the companion lets go: neutral (twice, the wheels stop),
        then the channels released to the flight controller's radio."""
        neutral = self.pwm.neutral()
        self.pulses_us = neutral
        target = self.identity.fc_sysid, self.identity.fc_compid
        hold = RcOverride(*target, override_fields(self.pwm.channels, neutral))
        return [hold, hold, RcOverride(*target, release_fields(self.pwm.channels))]
