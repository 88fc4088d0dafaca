"""GUIDED driving: SET_POSITION_TARGET_LOCAL_NED setpoints and the holonomic controller.

A mecanum rover moves in any direction while it holds or turns its heading independently, so
translation and heading are two separate controllers here (ArduPilot Rover turns to face its
velocity; this does not):

- translation: a position target (P controller, ``GUID_POS_P``) plus an optional velocity
  feed-forward, or a velocity alone; limited to ``GUID_SPD_MAX``, to ``GUID_ACC_MAX`` (slew),
  and near a position target to ``sqrt(2 * GUID_ACC_MAX * distance)`` so it brakes in time and
  does not overshoot;
- heading: a yaw target (P controller, ``GUID_YAW_P``) or a yaw rate, limited to
  ``GUID_YAW_RATE``; with neither, the heading at the time of the setpoint is held.

``type_mask`` is honoured bit by bit (1/2/4 position, 8/16/32 velocity, 64/128/256
acceleration, 512 force, 1024 yaw, 2048 yaw rate; a set bit means "ignore"). z and
accelerations are ignored. Frames, with ArduPilot Rover's meaning (what MAVProxy's ``position``
and ``velocity`` commands and MAVSDK expect): LOCAL_NED (1) absolute position, NED velocity;
LOCAL_OFFSET_NED (7) position an NED offset from the current position, NED velocity;
BODY_NED (8), BODY_OFFSET_NED (9) and BODY_FRD (12) position an offset from the current
position in the body frame (forward, right: rotated by the heading), body FRD velocity; in 9
and 12 the yaw is relative to the current heading. Velocity and yaw-rate setpoints lapse after
``GUID_TIMEOUT`` (the rover stops); position and yaw targets persist until replaced.

All outputs are body FRD velocities (m/s) and a clockwise yaw rate (rad/s); positions are
local NED metres, yaw radians clockwise from north.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import GuidedConfig
from mecanum_mav.mecanum.geometry import ChassisSpeeds, Pose2d, body_to_ned, ned_to_body, wrap_pi
from mecanum_mav.protocol.limits import (
    MAX_SETPOINT_POSITION_M,
    MAX_SETPOINT_YAW_RATE_RADPS,
    MAX_SPEED_MPS,
)

_chassis_speeds = partial(tuple.__new__, ChassisSpeeds)
"""``ChassisSpeeds(*values)`` without the generated ``__new__``'s Python frame (each tick)."""

__all__ = ["FRAMES", "GuidedController", "Setpoint", "SetpointError", "decode_setpoint"]

FRAMES = {1: "LOCAL_NED", 7: "LOCAL_OFFSET_NED", 8: "BODY_NED", 9: "BODY_OFFSET_NED",
          12: "BODY_FRD"}
_BODY_FRAMES = frozenset({8, 9, 12})
"""Frames whose positions and velocities are in the body frame (rotated by the heading)."""
_OFFSET_FRAMES = frozenset({7, 8, 9, 12})
"""Frames whose positions are offsets from the current position (ArduPilot Rover)."""
_RELATIVE_YAW = frozenset({9, 12})
"""Frames whose yaw is relative to the current heading."""
IGNORE_X, IGNORE_Y, IGNORE_VX, IGNORE_VY = 1, 2, 8, 16
IGNORE_YAW, IGNORE_YAW_RATE = 1024, 2048


class SetpointError(ValueError):
    """A setpoint that must not move the rover; the text says why (for STATUSTEXT)."""


@dataclass(frozen=True)
class Setpoint:
    """A decoded setpoint, resolved into the local NED frame at the time it arrived.

    Attributes:
        position_ned: target (north m, east m), or None.
        velocity_ned: velocity (north m/s, east m/s): feed-forward with a position, else the
            command; None if not given.
        yaw: target heading (rad clockwise from north), or None.
        yaw_rate: commanded yaw rate (rad/s clockwise), or None.
        time_s: when it arrived (monotonic seconds).
        yaw_rate_max: a lower yaw-rate limit than ``GUID_YAW_RATE`` (rad/s), or None.
        yaw_rate_ff: with a yaw target, the rate at which that target moves (rad/s
            clockwise), added to the P controller's (AUTO's heading schedule); else unused.
    """

    position_ned: tuple[float, float] | None
    velocity_ned: tuple[float, float] | None
    yaw: float | None
    yaw_rate: float | None
    time_s: float
    yaw_rate_max: float | None = None
    yaw_rate_ff: float = 0.0


def _pair(a: float, b: float, ignore_a: bool, ignore_b: bool, what: str, limit: float
          ) -> tuple[float, float] | None:
    if ignore_a and ignore_b:
        return None
    if ignore_a != ignore_b:
        raise SetpointError(f"{what}: give both or neither")
    if not (math.isfinite(a) and math.isfinite(b)):
        raise SetpointError(f"{what} not finite")
    if math.hypot(a, b) > limit:
        raise SetpointError(f"{what} absurd ({math.hypot(a, b):.0f})")
    return a, b


def decode_setpoint(frame: int, type_mask: int, x: float, y: float, vx: float, vy: float,
                    yaw: float, yaw_rate: float, pose: Pose2d, now_s: float) -> Setpoint:
    """Decode SET_POSITION_TARGET_LOCAL_NED fields into a :class:`Setpoint` in local NED.

    Args:
        frame: ``coordinate_frame``; one of :data:`FRAMES`.
        type_mask: the message's ignore bits.
        x, y, vx, vy, yaw, yaw_rate: the message's fields (m, m/s, rad, rad/s).
        pose: the rover's current pose (for offset and body frames).
        now_s: arrival time.

    Raises:
        SetpointError: unknown frame, non-finite or absurd value, half a pair, or nothing
            usable (only z or accelerations).
    """
    if frame not in FRAMES:
        raise SetpointError(f"frame {frame} not supported")
    position = _pair(x, y, bool(type_mask & IGNORE_X), bool(type_mask & IGNORE_Y),
                     "position", MAX_SETPOINT_POSITION_M)
    velocity = _pair(vx, vy, bool(type_mask & IGNORE_VX), bool(type_mask & IGNORE_VY),
                     "velocity", MAX_SPEED_MPS)
    yaw_target = None if type_mask & IGNORE_YAW else yaw
    rate = None if type_mask & IGNORE_YAW_RATE else yaw_rate
    if yaw_target is not None and not math.isfinite(yaw_target):
        raise SetpointError("yaw not finite")
    if rate is not None and not (
        math.isfinite(rate) and abs(rate) <= MAX_SETPOINT_YAW_RATE_RADPS
    ):
        raise SetpointError("yaw rate not finite or absurd")
    if position is None and velocity is None and yaw_target is None and rate is None:
        raise SetpointError("nothing usable (z and accelerations are ignored)")
    body = frame in _BODY_FRAMES
    offset = frame in _OFFSET_FRAMES
    if position is not None:
        if body:
            position = body_to_ned(*position, pose.yaw_rad)
        if offset:
            position = (pose.x_m + position[0], pose.y_m + position[1])
    if velocity is not None and body:
        velocity = body_to_ned(*velocity, pose.yaw_rad)
    if yaw_target is not None:
        yaw_target = wrap_pi(yaw_target + (pose.yaw_rad if frame in _RELATIVE_YAW else 0.0))
    return Setpoint(position, velocity, yaw_target, rate, now_s)


class GuidedController:
    """Setpoint + pose -> body velocity and yaw rate, with the ``GUID_*`` limits.

    Args:
        params: the ``GUID_*`` gains and limits are read from it here and by
            :meth:`reconfigure` (after a parameter changed).
    """

    def __init__(self, params: Params) -> None:
        self.config = GuidedConfig.from_params(params)
        self.setpoint: Setpoint | None = None
        self.hold_yaw: float | None = None
        self.velocity_ned = (0.0, 0.0)  # last commanded, for the acceleration limit
        self.yaw_rate = 0.0
        """The last commanded yaw rate, rad/s clockwise."""
        self._last_s: float | None = None

    def reconfigure(self, params: Params) -> None:
        """Take the ``GUID_*`` parameters from ``params``."""
        self.config = GuidedConfig.from_params(params)

    def start(self, pose: Pose2d, now_s: float) -> None:
        """Entering GUIDED: stand still and hold the current heading."""
        self.setpoint = None
        self.hold_yaw = pose.yaw_rad
        self.velocity_ned = (0.0, 0.0)
        self.yaw_rate = 0.0
        self._last_s = now_s

    def accept(self, setpoint: Setpoint, pose: Pose2d) -> None:
        """A new setpoint replaces the old one; its heading is held if it sets none."""
        self.setpoint = setpoint
        if setpoint.yaw is None and setpoint.yaw_rate is None:
            self.hold_yaw = pose.yaw_rad

    def arrived(self, pose: Pose2d, tolerance_m: float) -> bool:
        """Whether a position target exists and the rover is within ``tolerance_m`` of it."""
        sp = self.setpoint
        if sp is None or sp.position_ned is None:
            return False
        return math.hypot(sp.position_ned[0] - pose.x_m, sp.position_ned[1] - pose.y_m) <= (
            tolerance_m)

    def update(self, pose: Pose2d, now_s: float) -> ChassisSpeeds:
        """The body velocity to drive now (FRD m/s, yaw rate rad/s clockwise)."""
        c = self.config
        dt = 0.0 if self._last_s is None else max(0.0, now_s - self._last_s)
        self._last_s = now_s
        speed_max, accel_max = c.speed_max_mps, c.accel_max_mps2
        sp = self.setpoint
        lapsed = sp is not None and now_s - sp.time_s > c.timeout_s
        want = self._translation(sp, pose, lapsed, speed_max, accel_max)
        # Acceleration limit: slew the commanded velocity.
        dvn, dve = want[0] - self.velocity_ned[0], want[1] - self.velocity_ned[1]
        step = math.hypot(dvn, dve)
        if dt > 0.0 and step > accel_max * dt:
            k = accel_max * dt / step
            want = (self.velocity_ned[0] + dvn * k, self.velocity_ned[1] + dve * k)
        self.velocity_ned = want
        yaw_rate = self.yaw_rate = self._yaw_rate(sp, pose, lapsed)
        # Rotate into the body as it will be one delay from now (motor lag, pose age), so a
        # turn does not bend the path.
        heading = pose.yaw_rad + yaw_rate * c.yaw_lead_s
        vx, vy = ned_to_body(*want, heading)
        return _chassis_speeds((vx, vy, yaw_rate))

    def _translation(self, sp: Setpoint | None, pose: Pose2d, lapsed: bool, speed_max: float,
                     accel_max: float) -> tuple[float, float]:
        if sp is None:
            return 0.0, 0.0
        if sp.position_ned is not None:
            en, ee = sp.position_ned[0] - pose.x_m, sp.position_ned[1] - pose.y_m
            distance = math.hypot(en, ee)
            gain = self.config.position_gain
            vn, ve = en * gain, ee * gain
            if sp.velocity_ned is not None and not lapsed:
                vn, ve = vn + sp.velocity_ned[0], ve + sp.velocity_ned[1]
            # Brake in time: never faster than the speed that can stop within the distance.
            limit = min(speed_max, math.sqrt(2.0 * accel_max * distance))
        elif sp.velocity_ned is not None and not lapsed:
            vn, ve = sp.velocity_ned
            limit = speed_max
        else:
            return 0.0, 0.0
        speed = math.hypot(vn, ve)
        if speed > limit:
            vn, ve = vn * limit / speed, ve * limit / speed
        return vn, ve

    def _yaw_rate(self, sp: Setpoint | None, pose: Pose2d, lapsed: bool) -> float:
        c = self.config
        rate_max = c.yaw_rate_max
        if sp is not None and sp.yaw_rate_max is not None:
            rate_max = min(rate_max, sp.yaw_rate_max)
        feed_forward = 0.0
        if sp is not None and sp.yaw is not None:
            target, feed_forward = sp.yaw, sp.yaw_rate_ff
        elif sp is not None and sp.yaw_rate is not None and not lapsed:
            self.hold_yaw = pose.yaw_rad  # when the rate lapses, hold where it stopped
            return max(-rate_max, min(rate_max, sp.yaw_rate))
        else:
            target = pose.yaw_rad if self.hold_yaw is None else self.hold_yaw
        rate = feed_forward + c.yaw_gain * wrap_pi(target - pose.yaw_rad)
        return max(-rate_max, min(rate_max, rate))
