"""GUIDED and AUTO: the setpoint controller and the mission executor on a fixed control grid.

The :class:`Autopilot` is what happens when a mode change involves a controller (it is the
:class:`~mecanum_mav.control.vehicle.ModeHooks` of the vehicle's mode state machine):

- entering AUTO resolves the mission's positions first and is refused with a reason when it
  cannot run (no mission, a global item and no origin); a finished mission starts over;
- entering GUIDED or AUTO starts the velocity and heading controller standing still, holding
  the current heading, and restarts the control grid;
- while AUTO may drive (armed, no failsafe) the mission runs; otherwise it pauses at its
  current item, and resumes from where the rover is.

The controllers tick on a fixed grid of ``CTL_RATE`` (the rate does not drift with the
companion's wake-ups); between ticks the last output is held.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import OutputConfig
from mecanum_mav.control.chain import Output, autonomous_output
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.control.executor import MissionExecutor
from mecanum_mav.control.guided import GuidedController
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.mecanum.geometry import Pose2d, wrap_pi
from mecanum_mav.protocol.modes import Mode

__all__ = ["Autopilot"]

_CONTROLLED = (Mode.GUIDED, Mode.AUTO)
MAX_POSE_LEAD_S = 0.15
"""The pose is carried forward at most this far (s): 1.5 periods of a 10 Hz WHEEL_DISTANCE."""
TIMER_SLACK_S = 1e-6
"""Timers fall due this much early (the control grid here, the core's refresh and heartbeat),
so that a clock that adds in floating point never misses a period by a rounding error."""


class Autopilot:
    """The GUIDED controller and the AUTO executor, ticked on the ``CTL_RATE`` grid.

    Args:
        params: the parameter store (the controllers read their ``GUID_*``/``WP_*`` limits).
        estimator: where the rover is (pose, local NED).
        origin: returns the global origin of the local frame, or None.
    """

    def __init__(self, params: Params, estimator: WheelOdometryEstimator,
                 origin: Callable[[], GlobalOrigin | None]) -> None:
        self.guided = GuidedController(params)
        self.executor = MissionExecutor(params)
        self.estimator = estimator
        self.kinematics = estimator.odometry.kinematics  # one geometry for odometry and output
        self._origin = origin
        self._next_tick_s = math.inf
        self._held: Output | None = None
        self._pose_seen: tuple[float, float] = (math.nan, math.nan)
        self._pose_seen_s = -math.inf
        self._yaw_seen = math.nan
        self._yaw_seen_s = -math.inf

    def reconfigure(self, params: Params) -> None:
        """Take the ``GUID_*`` and ``WP_*`` parameters from ``params``."""
        self.guided.reconfigure(params)
        self.executor.reconfigure(params)

    # ------------------------------------------------------------------ mode hooks

    def refuse_entry(self, mode: Mode, now_s: float) -> str | None:
        """Why ``mode`` cannot start now (AUTO without a runnable mission), or None."""
        if mode is not Mode.AUTO:
            return None
        reason = self.executor.prepare(self._origin())
        if reason is not None:
            return reason
        if self.executor.complete:
            self.executor.restart()
        return None

    def on_mode_change(self, before: Mode, after: Mode, now_s: float) -> None:
        """GUIDED and AUTO start standing still, holding the heading, on a new grid."""
        if after in _CONTROLLED:
            self.guided.start(self.estimator.pose, now_s)
            self._held = None

    # ------------------------------------------------------------------ the mission

    def sync(self, may_run: bool, now_s: float) -> str | None:
        """Run the mission while AUTO may drive, pause it otherwise.

        Returns the reason the mission could not start (the caller switches to HOLD), or None.
        """
        ex = self.executor
        if ex.running and not may_run:
            ex.pause()
        elif may_run and not ex.running and not ex.complete:
            pose = self.estimator.pose
            reason = ex.start(pose, now_s, self._origin())
            if reason is not None:
                return reason
            self.guided.start(pose, now_s)
            self._held = None
        return None

    # ------------------------------------------------------------------ output

    def output(self, auto: bool, now_s: float, config: OutputConfig, priority: int,
               pwm: PwmMap) -> Output:
        """The wheel output in GUIDED (``auto`` False) or AUTO, ticked on the control grid."""
        if self._held is not None and now_s < self._next_tick_s - TIMER_SLACK_S:
            return self._held  # between control ticks: hold
        period = config.control_period_s
        if self._held is None:  # a new grid starts now
            self._next_tick_s = now_s
        self._next_tick_s += period  # a fixed grid, so the rate does not drift
        if self._next_tick_s <= now_s:  # fell behind: skip ahead
            self._next_tick_s = now_s + period
        self._held = autonomous_output(
            self.guided, self.executor if auto else None, self.pose_now(now_s), now_s,
            self.kinematics, config.wheel_speed_max_mps, priority, pwm)
        return self._held

    def pose_now(self, now_s: float) -> Pose2d:
        """The estimator's pose carried forward to ``now_s`` (local NED m, rad).

        Wheel odometry and the gyro's yaw move in steps (WHEEL_DISTANCE at 10 Hz, ATTITUDE at
        20 Hz on the built-in board): between steps the position is the last one plus the
        commanded velocity times the time since it changed, and the heading the last one plus
        the commanded yaw rate times the time since it changed, each at most
        :data:`MAX_POSE_LEAD_S` ahead.
        """
        pose = self.estimator.pose
        if (pose.x_m, pose.y_m) != self._pose_seen:
            self._pose_seen, self._pose_seen_s = (pose.x_m, pose.y_m), now_s
        if pose.yaw_rad != self._yaw_seen:
            self._yaw_seen, self._yaw_seen_s = pose.yaw_rad, now_s
        lead = min(max(now_s - self._pose_seen_s, 0.0), MAX_POSE_LEAD_S)
        yaw_lead = min(max(now_s - self._yaw_seen_s, 0.0), MAX_POSE_LEAD_S)
        vn, ve = self.guided.velocity_ned
        return Pose2d(pose.x_m + vn * lead, pose.y_m + ve * lead,
                      wrap_pi(pose.yaw_rad + self.guided.yaw_rate * yaw_lead))

    def idle(self) -> None:
        """Not driving autonomously: no control ticks until the next :meth:`output`."""
        self._next_tick_s = math.inf
        self._held = None

    def next_due_s(self) -> float:
        """When the next control tick is due (inf while idle), monotonic seconds."""
        return self._next_tick_s - TIMER_SLACK_S
