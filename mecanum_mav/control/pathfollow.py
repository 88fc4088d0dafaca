"""Following a straight leg between two points: along-track speed profile plus cross-track
correction, for a holonomic base (it need not face where it goes).

Everything is in the local NED frame: positions in metres (north, east), velocities in m/s.
The cross-track error is signed, positive when the rover is to the right of the leg (seen
facing along it).

The commanded velocity is the sum of

- along the leg: ``min(cruise, sqrt_controller(remaining))`` reached with at most ``accel``
  (the speed ramps up at ``accel`` and brakes in time to arrive at ``exit_speed``), and
- across the leg: ``sqrt_controller(-cross_track)``, which pulls the rover back onto the line
  as fast as it can stop there (a P controller near the line, braking at ``accel`` further
  out).

``sqrt_controller`` is ArduPilot's (AC_PosControl): ``p * error`` within ``accel / p**2`` of
the target, ``sqrt(2 * accel * (|error| - accel / (2 p**2)))`` beyond, so the approach is fast
and ends without overshoot.

:func:`corner_speed` picks the speed at which to pass a waypoint between two legs so that the
velocity across the new leg can be stopped within a given overshoot; :func:`exit_speed_ahead`
lowers it further where the rover must brake for a stop several legs ahead.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from mecanum_mav.mecanum.geometry import wrap_pi

__all__ = ["Leg", "LegFollower", "corner_lead", "corner_speed", "exit_speed_ahead",
           "heading_schedule", "sqrt_controller", "stops_between"]

Vec = tuple[float, float]


def sqrt_controller(error: float, p: float, accel: float) -> float:
    """Speed (same sign as ``error``) that closes ``error`` (m) without overshoot.

    Linear (``p`` 1/s) within ``accel / p**2`` metres, braking at ``accel`` (m/s/s) beyond.
    """
    linear_zone = accel / (p * p)
    size = abs(error)
    if size <= linear_zone:
        return p * error
    return math.copysign(math.sqrt(2.0 * accel * (size - linear_zone / 2.0)), error)


@dataclass(frozen=True)
class Leg:
    """A straight leg from ``start_ned`` to ``end_ned`` (north m, east m)."""

    start_ned: Vec
    end_ned: Vec

    @property
    def length_m(self) -> float:
        """Length in metres."""
        return math.hypot(self.end_ned[0] - self.start_ned[0], self.end_ned[1] - self.start_ned[1])

    @property
    def direction(self) -> Vec:
        """Unit vector (north, east) from start to end; (0, 0) for a leg of no length."""
        length = self.length_m
        if length < 1e-9:
            return 0.0, 0.0
        return ((self.end_ned[0] - self.start_ned[0]) / length,
                (self.end_ned[1] - self.start_ned[1]) / length)

    def errors(self, position_ned: Vec) -> tuple[float, float]:
        """(along-track distance from the start, signed cross-track error), metres.

        Cross-track is positive to the right of the leg. For a leg of no length both are
        measured as if it pointed north.
        """
        dn, de = position_ned[0] - self.start_ned[0], position_ned[1] - self.start_ned[1]
        un, ue = self.direction
        if un == 0.0 and ue == 0.0:
            un, ue = 1.0, 0.0
        return dn * un + de * ue, -dn * ue + de * un

    def distance_m(self, position_ned: Vec) -> float:
        """Distance from ``position_ned`` to the nearest point of the leg (a segment), m."""
        along, cross = self.errors(position_ned)
        length = self.length_m
        if along < 0.0:
            return math.hypot(along, cross)
        if along > length:
            return math.hypot(along - length, cross)
        return abs(cross)


def stops_between(incoming: Leg, outgoing: Leg) -> bool:
    """Whether the rover stops at the waypoint joining two legs, whatever its speed: the path
    turns there by 90 degrees or more, or a leg has no length."""
    a, b = incoming.direction, outgoing.direction
    return a[0] * b[0] + a[1] * b[1] <= 0.0  # (a leg of no length has direction (0, 0))


def corner_speed(incoming: Leg, outgoing: Leg, cruise: float, accel: float,
                 overshoot_m: float) -> float:
    """Speed (m/s) at which to pass the waypoint joining two legs.

    The velocity across the outgoing leg, ``v * sin(turn)``, must stop within
    ``overshoot_m`` at ``accel``: ``v = sqrt(2 * accel * overshoot_m) / sin(turn)``. Where
    :func:`stops_between` says so, 0. Never above ``cruise``.
    """
    if stops_between(incoming, outgoing):
        return 0.0
    a, b = incoming.direction, outgoing.direction
    sin_turn = abs(a[0] * b[1] - a[1] * b[0])
    if sin_turn < 1e-9:
        return cruise
    return min(cruise, math.sqrt(2.0 * accel * overshoot_m) / sin_turn)


def exit_speed_ahead(legs: Sequence[Leg], cruise: float, accel: float,
                     overshoot_m: float) -> float:
    """Speed (m/s) at which to leave ``legs[0]`` so the rover can still stop at the end of
    ``legs[-1]`` (the next stop waypoint) braking at ``accel``.

    A backward pass over the legs after the first: at each joint the speed is at most the
    :func:`corner_speed` there and at most what braking over the rest allows,
    ``v_start = sqrt(v_end**2 + 2 * accel * length)``. One leg (nothing follows): 0.
    """
    speed = 0.0  # at the end of the last leg: a stop
    for k in range(len(legs) - 1, 0, -1):
        arrive = math.sqrt(speed * speed + 2.0 * accel * legs[k].length_m)
        speed = min(arrive, corner_speed(legs[k - 1], legs[k], cruise, accel, overshoot_m))
    return speed


def corner_lead(leg: Leg, next_direction: Vec, position_ned: Vec, velocity_ned: Vec,
                exit_speed: float, lead_s: float) -> Vec:
    """``velocity_ned`` (north, east m/s) with the turn onto the next leg begun early.

    Within ``exit_speed * lead_s`` metres of the leg's end (the distance the rover covers
    while its velocity lags the command: motor lag and the acceleration limit), the speed
    along the leg is moved onto ``next_direction`` (a unit vector), in proportion to how close
    the end is, so the rover's true velocity turns at the waypoint instead of after it. The
    correction across the leg is kept.
    """
    lead_m = exit_speed * lead_s
    if lead_m <= 0.0 or next_direction == (0.0, 0.0):
        return velocity_ned
    remaining = leg.length_m - leg.errors(position_ned)[0]
    if remaining >= lead_m:
        return velocity_ned
    share = 1.0 - max(remaining, 0.0) / lead_m  # (0 at the lead's start, 1 at the end and past)
    un, ue = leg.direction
    return (velocity_ned[0] + share * exit_speed * (next_direction[0] - un),
            velocity_ned[1] + share * exit_speed * (next_direction[1] - ue))


def heading_schedule(leg: Leg, position_ned: Vec, yaw_from: float, yaw_to: float,
                     speed_along: float) -> tuple[float, float]:
    """The heading to command along a leg that turns from ``yaw_from`` to ``yaw_to`` (rad
    clockwise from north, the shorter way) in proportion to the distance driven, and the rate
    at which that heading moves at ``speed_along`` m/s (rad/s clockwise), to feed forward so
    the heading does not trail the schedule by the P controller's lag.
    """
    length = leg.length_m
    turn = wrap_pi(yaw_to - yaw_from)
    if length < 1e-9:
        return yaw_to, 0.0
    fraction = min(max(leg.errors(position_ned)[0] / length, 0.0), 1.0)
    rate = turn / length * speed_along if fraction < 1.0 else 0.0
    return wrap_pi(yaw_from + turn * fraction), rate


class LegFollower:
    """Commands a velocity that drives along a :class:`Leg` (see the module docstring).

    The along-track speed is stateful (it ramps at ``accel``); call :meth:`reset` with the
    rover's speed along the new leg when a leg starts.
    """

    def __init__(self) -> None:
        self.speed_along = 0.0

    def reset(self, speed_along: float = 0.0) -> None:
        """Start a leg at ``speed_along`` m/s (the rover's velocity projected on it)."""
        self.speed_along = max(0.0, speed_along)

    def velocity_ned(self, leg: Leg, position_ned: Vec, dt: float, *, cruise: float,
                     accel: float, exit_speed: float, gain: float) -> Vec:
        """Velocity (north m/s, east m/s) to command now.

        Args:
            leg: the leg being driven.
            position_ned: the rover's position (north m, east m).
            dt: seconds since the last call (for the acceleration ramp).
            cruise: the speed along the leg away from its ends, m/s.
            accel: acceleration and braking limit, m/s/s.
            exit_speed: the speed to have at the leg's end, m/s (0 = stop there).
            gain: P gain (1/s) of the final approach and of the cross-track correction.

        The result is not limited in magnitude beyond ``cruise`` along and the
        cross-track controller's own speed across; the velocity layer below applies the
        vehicle's speed and acceleration limits.
        """
        along, cross = leg.errors(position_ned)
        remaining = leg.length_m - along
        # Brake so as to arrive at exit_speed: v^2 = exit^2 + 2 a d, with the linear
        # zone of the sqrt controller when stopping.
        if exit_speed > 0.0:
            target = math.sqrt(exit_speed * exit_speed + 2.0 * accel * max(remaining, 0.0))
        else:
            target = sqrt_controller(remaining, gain, accel)
        target = min(cruise, target)
        ramped = self.speed_along + accel * dt
        speed = min(target, ramped) if target >= 0.0 else target
        self.speed_along = max(speed, 0.0)
        correction = sqrt_controller(-cross, gain, accel)
        un, ue = leg.direction
        if un == 0.0 and ue == 0.0:  # a point: hold it
            return (sqrt_controller(leg.end_ned[0] - position_ned[0], gain, accel),
                    sqrt_controller(leg.end_ned[1] - position_ned[1], gain, accel))
        # right of the leg = (-ue, un)
        return speed * un - correction * ue, speed * ue + correction * un
