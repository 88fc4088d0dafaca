"""Dead reckoning for the companion: where the rover is, from its wheels and its gyro.

Sources (parameter ``ODOM_SRC``):

- 0 auto (default): ``WHEEL_DISTANCE`` from the flight controller while it keeps coming
  (encoders measure what the wheels really did); when none has arrived for
  :data:`FRESH_S`, the commanded wheel speeds (wheel command x ``WHL_MAX_SPD``) stand in.
- 1 wheel distances only; 2 commanded wheel speeds only.

The commanded speeds reach the ground late: the flight controller's loop, the ESCs and the
motors' own lag. ``ODOM_CMD_TAU`` (s, 0 = none) passes each commanded wheel speed through a
first-order lag, discretized exactly as the simulated chassis's motors
(``w += (target - w) * (1 - exp(-dt / tau))``, the distance integrating the step's mean speed),
so the odometry moves when the wheels do. Without it the commanded distance leads the true one
by ``tau x speed``, and on a rover that turns while it drives that lead is rotated by the
heading of the moment it was commanded, not of the moment it was driven (a 90 deg/s turn with
0.08 s of lag: 7 degrees of error in the direction of travel). Motors under load also run a
little below their command (the MuJoCo chassis's at 1 m/s: 0.3 % forward, 0.9 % strafing):
``ODOM_CMD_GAIN`` scales every commanded wheel speed (1 = none; measured as
``WHL_STRAFE_EFF`` is, over a long straight run).

Heading (parameter ``ODOM_YAW_SRC``): 0 auto (default) takes the flight controller's
``ATTITUDE`` yaw while it is fresh, because a gyro beats wheel-derived yaw on a slipping
mecanum base; 1 uses the wheels' own turn. The first ATTITUDE, if the odometry has not moved
yet, sets the starting heading itself (its north is the local frame's north); later ones steer
the heading from where it is (a gyro that came back after a gap does not turn it).

Heading bias (parameter ``ODOM_YAW_BIAS``, on by default): while the flight controller's yaw
is in use and it sends a position (its GPS's fixes, GPS_RAW_INT, by default; or its EKF's
LOCAL_POSITION_NED), its yaw's constant offset from the true heading is estimated from the two
tracks
(:mod:`mecanum_mav.control.headingbias`) and taken off the yaw the odometry, and so the heading
controller, uses; until the estimate has settled, each change of the correction also turns the
track driven since the origin (the last reset) about the origin by as much, as if it had been
driven with the corrected heading all along (later changes, as the flight controller's bias
drifts, apply from then on). No position from the flight controller: no correction.

Position fusion (parameter ``ODOM_POS_TAU``, s, 0 = off): the same positions, moved to the
odometry's origin (the flight controller's position when the odometry was last reset or first
saw one), pull the odometry's position toward them, a complementary filter of that time
constant: the wheels (or commanded speeds) for what happens within it, the flight controller's
GPS-fused track for what accumulates beyond it. A position more than :data:`POSITION_GATE_M`
from the odometry's is not used (a glitch, an EKF reset); :data:`POSITION_GATE_COUNT` of them in
a row re-anchor the origin instead. Translation
always comes from the wheels by least squares
(:class:`~mecanum_mav.mecanum.kinematics.MecanumKinematics`) and the SE(2) exponential.

Everything is in the local NED frame (x north, y east, yaw clockwise from north) with the
origin where the companion started or was last reset; velocities are body FRD. Time is passed
in (monotonic seconds).

The flight controller's numbers are checked before they are used: a WHEEL_DISTANCE that is not
finite, beyond +-:data:`MAX_WHEEL_DISTANCE_M`, or a step no wheel can roll in the time since the
last one (faster than :data:`JUMP_SPEED_FACTOR` x ``WHEEL_MAX_SPD`` plus :data:`JUMP_MARGIN_M`:
an encoder glitch, a rebooted flight controller's counters back at 0) moves nothing: a step too
far re-anchors the distances, as after a gap. An ATTITUDE whose yaw is not within +-2 pi or
whose yaw rate is not within +-:data:`MAX_YAW_RATE` is not used. Each such input is reported
(the methods return the reason) so the core can count it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import OdometryConfig
from mecanum_mav.control.headingbias import HeadingBias
from mecanum_mav.mecanum.geometry import Pose2d, body_to_ned, ned_to_body, wrap_pi
from mecanum_mav.mecanum.kinematics import MecanumKinematics
from mecanum_mav.mecanum.odometry import MecanumOdometry

__all__ = ["FRESH_S", "WheelOdometryEstimator"]

FRESH_S = 0.5
"""A WHEEL_DISTANCE or ATTITUDE older than this no longer counts as a live source (s)."""
SOURCE_AUTO, SOURCE_WHEEL_DISTANCE, SOURCE_COMMANDED = 0, 1, 2
"""``ODOM_SRC`` values."""
BIAS_FROM_EKF, BIAS_FROM_GPS = 1, 2
"""``ODOM_YAW_BIAS`` values (0: off)."""
COMMANDED_UPDATE_S = 0.02
"""Commanded speeds are integrated every tick but fed to the odometry at most this often."""
SETTLED_MPS = 1e-6
"""A lagged commanded wheel speed under this (m/s) with its command 0 has settled: it is 0."""
MAX_WHEEL_DISTANCE_M = 1e7
"""A cumulative wheel distance beyond +- this (m, 10,000 km) is not a measurement."""
JUMP_SPEED_FACTOR = 2.0
JUMP_MARGIN_M = 0.2
"""A fresh WHEEL_DISTANCE step longer than ``JUMP_SPEED_FACTOR x WHL_MAX_SPD x dt +
JUMP_MARGIN_M`` (m) on any wheel is a jump: re-anchored, not driven."""
POSITION_GATE_M = 0.5
"""A flight-controller position further than this (m) from the odometry's is not fused."""
POSITION_GATE_COUNT = 20
"""... and this many of them in a row re-anchor the flight controller's track to the odometry."""
POSITION_GAP_S = 0.5
"""The fusion's step counts at most this long (s) after a gap in the positions."""
MAX_YAW_RATE = 50.0
"""An ATTITUDE yaw rate beyond +- this (rad/s, 8 turns a second) is not a measurement."""



def _is_position(north_m: float, east_m: float) -> bool:
    """Whether a flight controller's position (m) is one: finite (NaN is not) and within
    :data:`MAX_WHEEL_DISTANCE_M`."""
    return abs(north_m) <= MAX_WHEEL_DISTANCE_M and abs(east_m) <= MAX_WHEEL_DISTANCE_M


class WheelOdometryEstimator:
    """Pose and velocity of the rover from wheel distances, commanded speeds and gyro yaw.

    Args:
        params: the ``ODOM_*`` sources and ``WHL_MAX_SPD`` are read from it here and by
            :meth:`reconfigure`; the geometry (``GEO_HALF_*``, ``WHL_STRAFE_EFF``) only here,
            so a live change cannot bend the odometry's history (it takes effect at the next
            start).
    """

    def __init__(self, params: Params) -> None:
        self._take_config(params)
        kinematics = MecanumKinematics.from_half_extents(
            self.config.half_length_m, self.config.half_width_m,
            strafe_efficiency=float(params["WHL_STRAFE_EFF"]))
        self.odometry = MecanumOdometry(kinematics)
        self._virtual = [0.0, 0.0, 0.0, 0.0]  # cumulative metres fed to the odometry
        self._lagged = [0.0, 0.0, 0.0, 0.0]  # commanded wheel speeds through ODOM_CMD_TAU, m/s
        self._measured: list[float] | None = None  # last WHEEL_DISTANCE
        self._measured_s = -math.inf
        self._attitude_s = -math.inf
        self._yaw: float | None = None
        self._yaw_rate_gyro = 0.0
        self._first_attitude = True  # none used yet (it may set the starting heading)
        self._last_update_s: float | None = None
        self._moved = False  # commanded distance added since the last odometry update
        self.velocity_body = (0.0, 0.0)
        """Body velocity (forward, right) in m/s, from the last update."""
        self.yaw_rate = 0.0
        """Yaw rate in rad/s, clockwise positive."""
        self.heading_bias = HeadingBias()
        """The flight controller's yaw bias, from its position track (``ODOM_YAW_BIAS``)."""
        self.yaw_correction = 0.0
        """The bias taken off the flight controller's yaw now (rad, clockwise)."""
        self._origin = (0.0, 0.0)  # where the track since the last reset began (m, NED)
        self._fc_anchor: tuple[float, float] | None = None  # FC position minus odometry's
        self._fc_position_s = -math.inf
        self._fc_far = 0  # positions in a row beyond POSITION_GATE_M

    def reconfigure(self, params: Params) -> None:
        """Take the odometry sources and the wheel speed from ``params`` (``ODOM_YAW_BIAS``
        turned off takes the correction off at once)."""
        self._take_config(params)
        if not self.config.yaw_bias:
            self._correct(0.0, turn_track=False)
            self.heading_bias.restart()

    def _take_config(self, params: Params) -> None:
        self.config = config = OdometryConfig.from_params(params)
        self._commanded_mps = config.wheel_speed_max_mps * config.commanded_gain
        """What a wheel command of 1 rolls, m/s: ``WHL_MAX_SPD`` x ``ODOM_CMD_GAIN`` (read
        once here: the commanded odometry adds every stick)."""

    @property
    def pose(self) -> Pose2d:
        """Pose in the local NED frame (m, m, rad clockwise from north)."""
        return self.odometry.pose

    @property
    def wheel_distances_m(self) -> tuple[float, ...]:
        """Cumulative distance each wheel rolled, FL, FR, RL, RR (m), as the odometry used."""
        return tuple(self._virtual)

    @property
    def reset_counter(self) -> int:
        """Incremented by every :meth:`reset` (MAVLink ODOMETRY ``reset_counter``)."""
        return self.odometry.reset_counter

    def _yaw_if_used(self, now_s: float) -> float | None:
        """The flight controller's yaw carried to ``now_s`` at its own rate (an ATTITUDE is
        up to a period old: at 20 Hz and 90 deg/s, 4.5 degrees), or None when not in use."""
        age = now_s - self._attitude_s
        if not self.config.yaw_from_gyro or age > FRESH_S or self._yaw is None:
            return None
        return wrap_pi(self._yaw + self._yaw_rate_gyro * max(age, 0.0))

    def on_attitude(self, yaw_rad: float, yaw_rate: float, now_s: float) -> str | None:
        """ATTITUDE from the flight controller: yaw (rad, clockwise from north) and rate
        (rad/s); the reason it was not used, or None."""
        if not (abs(yaw_rad) <= 2 * math.pi and abs(yaw_rate) <= MAX_YAW_RATE):  # NaN too
            return f"ATTITUDE yaw {yaw_rad:g} rad, rate {yaw_rate:g} rad/s"
        yaw_rad -= self.yaw_correction  # (the bias estimated, 0 without one)
        self._yaw, self._yaw_rate_gyro, self._attitude_s = yaw_rad, yaw_rate, now_s
        first, self._first_attitude = self._first_attitude, False
        if first and self.config.yaw_from_gyro and self.odometry.reset_counter == 0 \
                and self.odometry.pose == (0.0, 0.0, 0.0):
            # The first one, not moved yet: start from the flight controller's heading itself,
            # so the local frame's north is its north (not the heading the rover started at).
            self.odometry = MecanumOdometry(self.odometry.kinematics, self._virtual,
                                            Pose2d(0.0, 0.0, wrap_pi(yaw_rad)), yaw_rad)
        return None

    def on_position(self, north_m: float, east_m: float, now_s: float) -> str | None:
        """The flight controller's own position (LOCAL_POSITION_NED, m; its origin does not
        matter): a sample for the heading bias while its yaw is in use, and the fusion's
        (module docstring). Returns what to say once (the bias settled, or too large to
        correct), else None."""
        if not _is_position(north_m, east_m):
            return None
        notice = self._bias_sample(north_m, east_m, now_s, BIAS_FROM_EKF)
        if self.config.position_tau_s > 0.0:
            self._fuse(north_m, east_m, now_s)
        return notice

    def on_gps(self, north_m: float, east_m: float, now_s: float) -> str | None:
        """A new GPS fix (GPS_RAW_INT about its first fix, m): a sample for the heading bias
        while its yaw is in use (module docstring); what to say once, else None."""
        if not _is_position(north_m, east_m):
            return None
        return self._bias_sample(north_m, east_m, now_s, BIAS_FROM_GPS)

    def _bias_sample(self, north_m: float, east_m: float, now_s: float,
                     source: int) -> str | None:
        """A position from ``source`` to the heading bias, if it is the configured one and the
        flight controller's yaw is in use; the correction follows."""
        if self.config.yaw_bias != source or self._yaw_if_used(now_s) is None:
            return None
        north, east = self._carried(now_s)
        settled = self.heading_bias.settled
        update = self.heading_bias.on_position(north_m, east_m, north, east,
                                               self.yaw_correction, now_s,
                                               follows_yaw=source == BIAS_FROM_EKF)
        self._correct(update.bias_rad, turn_track=not settled)
        self.heading_bias.follow(*self._carried(now_s))
        return update.notice

    def _carried(self, now_s: float) -> tuple[float, float]:
        """The odometry's position (m, NED) carried to ``now_s`` at its velocity: it updates
        every :data:`COMMANDED_UPDATE_S` or so, and a sample 20 ms stale is 2 cm at 1 m/s, 4 %
        of a 0.5 m window."""
        pose = self.odometry.pose
        ahead = 0.0 if self._last_update_s is None else min(now_s - self._last_update_s,
                                                             FRESH_S)
        north, east = body_to_ned(*self.velocity_body, pose.yaw_rad)
        return pose.x_m + north * ahead, pose.y_m + east * ahead

    def _fuse(self, north_m: float, east_m: float, now_s: float) -> None:
        """Pull the odometry's position toward the flight controller's (module docstring)."""
        odom_n, odom_e = self._carried(now_s)
        dt = min(now_s - self._fc_position_s, POSITION_GAP_S)
        self._fc_position_s = now_s
        if self._fc_anchor is None:
            self._fc_anchor = (north_m - odom_n, east_m - odom_e)
            return
        error_n = north_m - self._fc_anchor[0] - odom_n
        error_e = east_m - self._fc_anchor[1] - odom_e
        if not math.hypot(error_n, error_e) <= POSITION_GATE_M:
            self._fc_far += 1
            if self._fc_far >= POSITION_GATE_COUNT:
                self._fc_anchor, self._fc_far = None, 0
            return
        self._fc_far = 0
        gain = -math.expm1(-max(dt, 0.0) / self.config.position_tau_s)
        self.odometry.shift(gain * error_n, gain * error_e)
        self.heading_bias.shifted(gain * error_n, gain * error_e)

    def _correct(self, bias_rad: float, turn_track: bool) -> None:
        """Take ``bias_rad`` off the flight controller's yaw from now on; ``turn_track``: turn
        the track since the origin by the change too (module docstring)."""
        change = bias_rad - self.yaw_correction
        if change == 0.0:
            return
        self.yaw_correction = bias_rad
        if self._yaw is not None:
            self._yaw -= change
        self.odometry.rotate(-change, self._origin if turn_track else
                             (self.odometry.pose.x_m, self.odometry.pose.y_m))
        pose = self.odometry.pose
        self.heading_bias.follow(pose.x_m, pose.y_m)

    def on_wheel_distance(self, distances_m: Sequence[float], now_s: float) -> str | None:
        """WHEEL_DISTANCE: cumulative metres FL, FR, RL, RR from the flight controller; the
        reason it moved nothing (not a measurement, or a jump), or None."""
        if not all(abs(d) <= MAX_WHEEL_DISTANCE_M for d in distances_m):  # NaN too
            return f"WHEEL_DISTANCE {list(distances_m)} m"
        if self.config.source == SOURCE_COMMANDED:
            return None
        elapsed = now_s - self._measured_s
        problem = None
        if self._measured is not None and elapsed <= FRESH_S:
            reach = JUMP_SPEED_FACTOR * self.config.wheel_speed_max_mps * elapsed + JUMP_MARGIN_M
            steps = [d - m for d, m in zip(distances_m, self._measured, strict=True)]
            if all(abs(step) <= reach for step in steps):
                for i in range(4):
                    self._virtual[i] += steps[i]
            else:
                problem = f"WHEEL_DISTANCE jumped {max(steps, key=abs):+g} m in {elapsed:g} s"
        # After a gap (or a jump) the commanded speeds covered it: re-anchor, no jump.
        self._measured = list(distances_m)
        self._measured_s = now_s
        self._update(now_s)
        return problem

    def on_commanded(self, wheel_commands: Sequence[float], dt_s: float, now_s: float) -> None:
        """Commanded wheels (normalized, FL, FR, RL, RR) held for ``dt_s`` seconds.

        Used when the source is "commanded", or "auto" with no fresh WHEEL_DISTANCE; each
        wheel's speed goes through the ``ODOM_CMD_TAU`` lag (module docstring) either way, so
        it is current when the commanded speeds take over.
        """
        lagged = self.config.commanded_tau_s > 0.0  # (its state advances whatever the source)
        rolled = self._roll(wheel_commands, dt_s) if lagged else None
        source = self.config.source
        if source == SOURCE_WHEEL_DISTANCE or (
                source == SOURCE_AUTO and now_s - self._measured_s <= FRESH_S):
            return
        if rolled is None:  # no lag (the default): the commanded speeds as they are, no list
            fl, fr, rl, rr = wheel_commands
            if fl or fr or rl or rr:
                speed, virtual = self._commanded_mps * max(dt_s, 0.0), self._virtual
                virtual[0] += fl * speed
                virtual[1] += fr * speed
                virtual[2] += rl * speed
                virtual[3] += rr * speed
                self._moved = True
        else:
            for i in range(4):
                if rolled[i]:
                    self._virtual[i] += rolled[i]
                    self._moved = True
        last = self._last_update_s
        if last is not None and now_s - last < COMMANDED_UPDATE_S:
            return
        if self._moved:
            self._update(now_s)
        else:  # standing still: nothing to integrate
            self.velocity_body, self.yaw_rate, self._last_update_s = (0.0, 0.0), 0.0, now_s

    def _roll(self, wheel_commands: Sequence[float], dt_s: float) -> list[float]:
        """The metres each wheel rolls in ``dt_s`` s with ``wheel_commands`` held, through the
        ``ODOM_CMD_TAU`` lag (positive; its state advanced here)."""
        if dt_s <= 0.0:
            return [0.0, 0.0, 0.0, 0.0]
        speed = self._commanded_mps
        targets = [c * speed for c in wheel_commands]
        tau = self.config.commanded_tau_s
        gain = -math.expm1(-dt_s / tau)  # 1 - exp(-dt/tau), accurate for small dt
        mean_weight = tau * gain / dt_s  # the step's mean = target + (w0 - target) * this
        rolled = []
        for i in range(4):
            w, t = self._lagged[i], targets[i]
            rolled.append((t + (w - t) * mean_weight) * dt_s)
            w += (t - w) * gain
            self._lagged[i] = w if abs(w) > SETTLED_MPS or t else 0.0
        return rolled

    def _update(self, now_s: float) -> None:
        self._moved = False
        before = self.odometry.pose
        gyro_yaw = self._yaw_if_used(now_s)
        after = self.odometry.update(self._virtual, gyro_yaw)
        dt = None if self._last_update_s is None else now_s - self._last_update_s
        self._last_update_s = now_s
        if dt is None or dt <= 1e-4:
            return
        # Body velocity: the displacement in the frame of the start heading, over dt.
        forward, right = ned_to_body(after.x_m - before.x_m, after.y_m - before.y_m,
                                     before.yaw_rad)
        self.velocity_body = (forward / dt, right / dt)
        # The gyro's own rate when its yaw is in use; else the wheels' turn over dt.
        turn_rate = wrap_pi(after.yaw_rad - before.yaw_rad) / dt
        self.yaw_rate = self._yaw_rate_gyro if gyro_yaw is not None else turn_rate

    def reset(self, now_s: float) -> None:
        """Move the origin here at ``now_s`` (DO_SET_HOME): the position becomes (0, 0), the
        heading is kept, and the odometry's :attr:`reset_counter` counts it."""
        self.odometry.reset(Pose2d(0.0, 0.0, self.odometry.pose.yaw_rad), self._virtual,
                            self._yaw_if_used(now_s))
        self._origin = (0.0, 0.0)
        self.heading_bias.restart()
        self._fc_anchor = None  # (the next position anchors the flight controller's track)
