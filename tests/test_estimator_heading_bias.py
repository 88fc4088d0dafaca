"""The flight controller's heading bias, estimated from its own position track
(control/headingbias.py) and taken off the odometry's yaw (control/estimator.py); synthetic
tracks in virtual time (time passed in)."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.control.headingbias import REFUSE_AFTER, SETTLED_COUNT, HeadingBias

Track = Callable[[float], tuple[float, float]]
"""Time (s) -> position (north, east m)."""


def rotated(track: Track, angle_deg: float) -> Track:
    """``track`` turned clockwise by ``angle_deg`` about its start (as a heading that far off
    turns every odometry step)."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))

    def at(t: float) -> tuple[float, float]:
        n, e = track(t)
        return n * c - e * s, n * s + e * c
    return at


def straight(t: float) -> tuple[float, float]:
    """North-east at 1 m/s."""
    return t * math.sqrt(0.5), t * math.sqrt(0.5)


def feed(bias: HeadingBias, fc: Track, odometry: Track, seconds: float, start_s: float = 0.0,
         rate_hz: float = 10.0) -> list[str]:
    """The positions of ``seconds`` at ``rate_hz`` (no correction applied: the raw odometry);
    what it said."""
    said = []
    for k in range(round(seconds * rate_hz) + 1):
        t = start_s + k / rate_hz
        update = bias.on_position(*fc(t), *odometry(t), 0.0, t)
        if update.notice is not None:
            said.append(update.notice)
    return said


def test_a_straight_track_3_degrees_off_the_flight_controllers_gives_a_3_degree_bias():
    bias = HeadingBias()
    said = feed(bias, straight, rotated(straight, 3.0), 5.0)
    assert math.degrees(bias.bias_rad) == pytest.approx(3.0, abs=1e-6)
    assert said == ["Heading: FC yaw +3.0 deg off its track: corrected"]


def test_turning_in_place_gives_no_estimate():
    bias = HeadingBias()
    feed(bias, lambda t: (0.004 * math.sin(t), 0.0), lambda t: (0.0, 0.0), 20.0)
    assert bias.measurements == 0 and bias.bias_rad == 0.0


def test_a_curved_track_gives_no_estimate_its_lag_would_look_like_degrees():
    """A 0.75 m circle at 1 m/s, the odometry 8 cm ahead along it (a motor lag): its chords
    are 6 degrees off the flight controller's, yet no heading is off."""
    def circle(t: float) -> tuple[float, float]:
        return 0.75 * math.sin(t / 0.75), 0.75 * (1.0 - math.cos(t / 0.75))
    bias = HeadingBias()
    feed(bias, circle, lambda t: circle(t + 0.08), 10.0)
    assert bias.measurements == 0 and bias.bias_rad == 0.0


def weaving(t: float) -> tuple[float, float]:
    """North at 1 m/s, weaving 6 cm either side once a metre."""
    return t, 0.06 * math.sin(2 * math.pi * t)


def test_a_flight_controller_track_that_weaves_gives_no_estimate():
    """An EKF swinging about the line the odometry drove (after a start or a stop it follows
    its own heading until GPS pulls it back): its chords point everywhere."""
    bias = HeadingBias()
    feed(bias, weaving, lambda t: (t, 0.0), 10.0)
    assert bias.measurements == 0


def test_an_odometry_track_that_weaves_gives_no_estimate():
    bias = HeadingBias()
    feed(bias, lambda t: (t, 0.0), weaving, 10.0)
    assert bias.measurements == 0


def test_a_rover_that_keeps_speeding_up_and_slowing_down_gives_no_estimate():
    """1 m/s and 0.3 m/s by turns every 0.3 s: no window of steady driving (while it starts
    and stops an EKF's track follows its own heading)."""
    def surging(t: float) -> tuple[float, float]:
        whole, part = divmod(t, 0.6)
        return whole * 0.39 + min(part, 0.3) * 1.0 + max(part - 0.3, 0.0) * 0.3, 0.0
    bias = HeadingBias()
    feed(bias, surging, rotated(surging, 2.0), 10.0)
    assert bias.measurements == 0


def speeding_up(t: float) -> tuple[float, float]:
    """North from rest at 0.5 m/s/s up to 1 m/s."""
    return (0.25 * t * t if t < 2.0 else 1.0 + (t - 2.0)), 0.0


def late(track: Track, lag_s: float) -> Track:
    """``track`` as fixes that come ``lag_s`` late (ArduPilot SITL's GPS: about 0.15 s)."""
    return lambda t: track(max(t - lag_s, 0.0))


def test_gps_fixes_measure_the_bias_while_the_rover_speeds_up_from_rest():
    """Late GPS fixes slide along a straight line (and fall short of a window that speeds
    up): the first window of a mission's first leg counts, not the first one after the rover
    reached its speed. Fixes at 5 Hz, 0.3 s late, as ArduPilot SITL's reach the companion."""
    bias = HeadingBias()
    odometry = rotated(speeding_up, 2.0)
    for k in range(21):
        t = k / 5.0
        bias.on_position(*late(speeding_up, 0.3)(t), *odometry(t), 0.0, t, follows_yaw=False)
        if bias.measurements:
            break
    assert math.degrees(bias.bias_rad) == pytest.approx(2.0, abs=1e-6)
    assert speeding_up(t)[0] < 0.7  # metres driven when it was first measured (1.0 m with
    # the chords' lengths held to within 20 %, with or without the steady rule)


def test_an_ekf_position_is_measured_against_only_once_the_rover_drives_steadily():
    """The same start against the EKF's position (it follows the flight controller's own
    heading while the speed changes): no measurement until the speed is steady."""
    bias = HeadingBias()
    odometry = rotated(speeding_up, 2.0)
    for k in range(41):
        t = k / 10.0
        bias.on_position(*speeding_up(t), *odometry(t), 0.0, t)
        if bias.measurements:
            break
    assert speeding_up(t)[0] > 0.8


def test_a_bias_beyond_10_degrees_is_not_corrected_and_said_once():
    bias = HeadingBias()
    said = feed(bias, straight, rotated(straight, 15.0), 20.0)
    assert bias.bias_rad == 0.0 and bias.rejected >= REFUSE_AFTER
    assert said == ["Heading: FC yaw +15.0 deg off its track, beyond 10: not corrected"]


def said_at(bias: HeadingBias, fc: Track, odometry: Track, seconds: float, count: str,
            start_s: float = 0.0) -> list[tuple[int, str]]:
    """Like :func:`feed` at 10 Hz; each notice with the bias's counter ``count`` then."""
    said = []
    for k in range(round(seconds * 10.0) + 1):
        t = start_s + k / 10.0
        update = bias.on_position(*fc(t), *odometry(t), 0.0, t)
        if update.notice is not None:
            said.append((getattr(bias, count), update.notice))
    return said


def test_the_estimate_is_said_with_its_tenth_measurement_and_settled_from_then_on():
    """SETTLED_COUNT: "measurements before the estimate is said" (and ``settled``)."""
    bias = HeadingBias()
    settled_at = []
    for k in range(41):
        t = k / 10.0
        update = bias.on_position(*straight(t), *rotated(straight, 2.0)(t), 0.0, t)
        settled_at.append((bias.measurements, bias.settled))
        if update.notice is not None:
            assert bias.measurements == SETTLED_COUNT == 10
            assert update.notice == "Heading: FC yaw +2.0 deg off its track: corrected"
    assert all(settled is (count >= SETTLED_COUNT) for count, settled in settled_at)
    assert settled_at[-1][0] > SETTLED_COUNT  # (measured past it: said once)


def test_a_bias_beyond_the_bound_is_said_at_the_twentieth_window_in_a_row():
    """REFUSE_AFTER: measurements beyond MAX_BIAS_RAD in a row before it is said."""
    said = said_at(HeadingBias(), straight, rotated(straight, 15.0), 20.0, "rejected")
    assert [count for count, _ in said] == [REFUSE_AFTER] == [20]


def test_from_the_tenth_measurement_on_a_window_far_off_the_estimate_is_an_outlier():
    """"Once settled, a measurement further than OUTLIER_RAD from the estimate is an
    outlier": the window right after the tenth measurement, 4 degrees off, moves nothing."""
    bias = HeadingBias()
    t = 0.0
    while bias.measurements < SETTLED_COUNT:
        t += 0.1
        bias.on_position(*straight(t), *rotated(straight, 2.0)(t), 0.0, t)
    start_s = t + 2.0  # a gap (the window starts over, the estimate stays), then a new track
    drive_s = 0.0
    while bias.outliers == 0 and bias.measurements == SETTLED_COUNT:
        bias.on_position(*straight(drive_s), *rotated(straight, 6.0)(drive_s), 0.0,
                         start_s + drive_s)
        drive_s += 0.1
    assert (bias.outliers, bias.measurements) == (1, SETTLED_COUNT)
    assert math.degrees(bias.bias_rad) == pytest.approx(2.0, abs=1e-6)


def test_a_moved_bias_is_learnt_again_after_twenty_outliers_in_a_row():
    """Once settled, a measurement more than OUTLIER_RAD off is an outlier; REFUSE_AFTER of
    them in a row mean the bias moved: the estimate starts over from the next measurement."""
    bias = HeadingBias()
    feed(bias, straight, rotated(straight, 2.0), 4.0)
    assert bias.settled
    outliers_seen = []
    for k in range(41):
        t = 4.1 + k / 10.0
        bias.on_position(*straight(t), *rotated(straight, 6.0)(t), 0.0, t)
        outliers_seen.append((bias.outliers, bias.measurements))
    first_restart = next(i for i, (_, measured) in enumerate(outliers_seen) if measured == 0)
    assert outliers_seen[first_restart - 1][0] == REFUSE_AFTER - 1  # 19 outliers, then the 20th
    assert math.degrees(bias.bias_rad) == pytest.approx(6.0, abs=1e-6)


def test_a_flight_controller_position_that_jumps_sideways_does_not_move_a_settled_estimate():
    """A GPS glitch: the flight controller's position 6 cm east for good, from 4 s on."""
    bias = HeadingBias()
    odometry = rotated(lambda t: (t, 0.0), 2.0)
    feed(bias, lambda t: (t, 0.0), odometry, 4.0)
    assert math.degrees(bias.bias_rad) == pytest.approx(2.0, abs=1e-6)
    feed(bias, lambda t: (t, 0.06), odometry, 4.0, start_s=4.1)
    assert math.degrees(bias.bias_rad) == pytest.approx(2.0, abs=0.05)


def test_a_flight_controller_position_that_drifts_sideways_hardly_moves_a_settled_estimate():
    """Multipath: the flight controller's position slides 6 cm east over 0.6 s from 4 s on;
    the windows along the slide that are more than 3 degrees off the estimate are outliers."""
    bias = HeadingBias()
    odometry = rotated(lambda t: (t, 0.0), 2.0)
    feed(bias, lambda t: (t, 0.0), odometry, 4.0)
    feed(bias, lambda t: (t, 0.1 * min(max(t - 4.0, 0.0), 0.6)), odometry, 4.0, start_s=4.1)
    assert math.degrees(bias.bias_rad) == pytest.approx(2.0, abs=0.15)  # 1.71 without


def test_a_bias_that_moved_for_good_is_learnt_again():
    bias = HeadingBias()
    feed(bias, straight, rotated(straight, 2.0), 4.0)
    feed(bias, straight, rotated(straight, 6.0), 8.0, start_s=4.1)
    assert math.degrees(bias.bias_rad) == pytest.approx(6.0, abs=1e-6)


# ---------------------------------------------------------------------------- the estimator

def estimator(**values: float) -> WheelOdometryEstimator:
    params = Params()
    params.update({"ODOM_SRC": 2, **values})  # commanded wheels, WHL_MAX_SPD 1 m/s
    return WheelOdometryEstimator(params)


def drive_north(est: WheelOdometryEstimator, bias_deg: float, seconds: float,
                positions: bool = True, ekf: bool = False) -> list[str]:
    """Forward (truly north) at 1 m/s; the flight controller's yaw ``bias_deg`` off, its GPS
    fixes (or its EKF's positions) the truth at 10 Hz; what the estimator said."""
    said = []
    yaw = math.radians(bias_deg)
    est.on_attitude(yaw, 0.0, 0.0)  # (its heading the start's)
    for k in range(1, round(seconds / 0.02) + 1):
        t = 0.02 * k
        if k % 5 == 0:
            est.on_attitude(yaw, 0.0, t)
            position = est.on_position if ekf else est.on_gps
            if positions and (notice := position(t, 0.0, t)) is not None:
                said.append(notice)
        est.on_commanded([1.0] * 4, 0.02, t)
    return said


def test_the_bias_is_taken_off_the_heading_and_the_track_since_the_origin_turned_back():
    est = estimator()
    said = drive_north(est, 2.5, 4.0)
    pose = est.pose
    assert math.degrees(est.yaw_correction) == pytest.approx(2.5, abs=0.01)
    assert math.degrees(pose.yaw_rad) == pytest.approx(0.0, abs=0.01)
    assert pose.x_m == pytest.approx(4.0, abs=0.01)
    assert abs(pose.y_m) < 0.002  # 17 cm east without the correction
    assert said == ["Heading: FC yaw +2.5 deg off its track: corrected"]


def test_with_odom_yaw_bias_1_the_ekfs_position_is_the_reference_and_the_gps_is_not():
    ekf, gps = estimator(ODOM_YAW_BIAS=1), estimator(ODOM_YAW_BIAS=1)
    drive_north(ekf, 2.5, 4.0, ekf=True)
    drive_north(gps, 2.5, 4.0)
    assert math.degrees(ekf.yaw_correction) == pytest.approx(2.5, abs=0.01)
    assert gps.yaw_correction == 0.0


def test_with_odom_yaw_bias_0_the_positions_change_nothing():
    est = estimator(ODOM_YAW_BIAS=0)
    drive_north(est, 2.5, 4.0)
    assert est.yaw_correction == 0.0
    assert math.degrees(est.pose.yaw_rad) == pytest.approx(2.5)


def test_without_positions_the_odometry_is_what_it_was_without_the_estimator():
    on, off = estimator(), estimator(ODOM_YAW_BIAS=0)
    drive_north(on, 2.5, 4.0, positions=False)
    drive_north(off, 2.5, 4.0)
    assert on.pose == off.pose and on.yaw_correction == 0.0


def test_turning_odom_yaw_bias_off_takes_the_correction_off_at_once():
    params = Params()
    params.update({"ODOM_SRC": 2})
    est = WheelOdometryEstimator(params)
    drive_north(est, 2.5, 4.0)
    params.set("ODOM_YAW_BIAS", 0)
    est.reconfigure(params)
    assert est.yaw_correction == 0.0
    assert math.degrees(est.pose.yaw_rad) == pytest.approx(2.5, abs=0.01)


def test_with_the_wheels_heading_there_is_no_estimate():
    est = estimator(ODOM_YAW_SRC=1)
    drive_north(est, 2.5, 4.0)
    assert est.yaw_correction == 0.0 and est.heading_bias.measurements == 0


def test_a_position_that_is_not_a_number_is_ignored():
    est = estimator()
    est.on_attitude(0.0, 0.0, 0.0)
    assert est.on_position(math.nan, 0.0, 0.01) is None
    assert est.on_gps(0.0, math.inf, 0.02) is None
    assert est.heading_bias.measurements == 0 and est.yaw_correction == 0.0


def test_once_settled_a_new_correction_does_not_move_the_rover_on_the_map():
    """The track driven since the origin is turned while the estimate settles; a later change
    (the flight controller's bias drifting) applies from then on: the rover stays put."""
    est = estimator()
    drive_north(est, 2.5, 4.0)
    assert est.heading_bias.settled
    before = est.pose
    est.on_attitude(math.radians(3.5), 0.0, 4.05)  # the bias moved by 1 degree
    t = 4.0
    for k in range(1, 41):  # 0.8 s more north, the bias learnt anew bit by bit
        t = 4.0 + 0.02 * k
        if k % 5 == 0:
            est.on_attitude(math.radians(3.5), 0.0, t)
            est.on_gps(t, 0.0, t)
        est.on_commanded([1.0] * 4, 0.02, t)
    assert est.yaw_correction > math.radians(2.6)
    # 0.8 m driven up to 1 degree off: 1.2 cm east. Turning the 4 m behind by the 0.2 degree
    # learnt meanwhile would have put it 1.9 cm further west.
    assert 0.008 < est.pose.y_m - before.y_m < 0.015


def test_a_position_fused_pulls_the_odometry_toward_the_fcs_track_at_its_time_constant():
    """ODOM_POS_TAU 1 s; the flight controller's position 10 cm east of the odometry's, all
    the way north at 1 m/s: after 1 s the odometry has come 1 - 1/e of the way."""
    est = estimator(ODOM_POS_TAU=1.0, ODOM_YAW_BIAS=0)
    est.on_attitude(0.0, 0.0, 0.0)
    t = 0.0
    for k in range(1, 101):
        t = 0.02 * k
        est.on_commanded([1.0] * 4, 0.02, t)
        if k % 5 == 0:  # after the odometry's update: the position of the same moment
            est.on_position(100.0 + t, 50.1, t)  # its origin elsewhere; 10 cm east
    # anchored at the first (t 0.1, where it was 10 cm east too): nothing to pull
    assert est.pose.y_m == pytest.approx(0.0, abs=1e-9)
    assert est.pose.x_m == pytest.approx(2.0, abs=1e-9)
    for k in range(101, 151):  # now the flight controller's track is 10 cm further east
        t = 0.02 * k
        est.on_commanded([1.0] * 4, 0.02, t)
        if k % 5 == 0:
            est.on_position(100.0 + t, 50.2, t)
    assert est.pose.y_m == pytest.approx(0.1 * (1 - math.exp(-1.0)), abs=1e-3)
    assert est.pose.x_m == pytest.approx(3.0, abs=1e-3)  # and nothing along the track


def test_a_fused_position_that_jumps_is_not_followed_until_it_stays():
    est = estimator(ODOM_POS_TAU=0.5, ODOM_YAW_BIAS=0)
    est.on_attitude(0.0, 0.0, 0.0)
    est.on_position(0.0, 0.0, 0.0)  # anchors
    for k in range(1, 11):  # 1 s: the flight controller's position 3 m away (an EKF reset)
        est.on_position(3.0, 0.0, 0.1 * k)
    assert est.pose == (0.0, 0.0, 0.0)
    for k in range(11, 41):  # it stays there: re-anchored, still nothing moves
        est.on_position(3.0, 0.0, 0.1 * k)
    assert est.pose == (0.0, 0.0, 0.0)


def test_a_fused_position_between_two_gps_fixes_leaves_the_heading_bias_its_steps():
    """With ODOM_POS_TAU the EKF's positions pull the odometry between the GPS fixes: the pull
    is not a step the rover drove, but the driving in between still is."""
    est = estimator(ODOM_POS_TAU=2.0)
    yaw = math.radians(2.5)
    est.on_attitude(yaw, 0.0, 0.0)
    for k in range(1, 201):
        t = 0.02 * k
        est.on_commanded([1.0] * 4, 0.02, t)
        if k % 5 == 0:
            est.on_attitude(yaw, 0.0, t)
            est.on_position(t, 0.0, t)  # the EKF's, 10 Hz
        if k % 10 == 5:
            est.on_gps(t, 0.0, t)  # the GPS's, 5 Hz, between them
    assert math.degrees(est.yaw_correction) == pytest.approx(2.5, abs=0.05)


def speed_up_north(est: WheelOdometryEstimator, bias_deg: float, metres: float,
                   ekf: bool) -> None:
    """From rest north at 0.5 m/s/s (wheel commands ramping, WHL_MAX_SPD 1 m/s) until
    ``metres``; the flight controller's yaw ``bias_deg`` off, its positions the truth at 10 Hz
    (its EKF's with ``ekf``, else GPS fixes)."""
    yaw = math.radians(bias_deg)
    est.on_attitude(yaw, 0.0, 0.0)
    position = est.on_position if ekf else est.on_gps
    k = 0
    while speeding_up(0.02 * k)[0] < metres:
        k += 1
        t = 0.02 * k
        if k % 5 == 0:
            est.on_attitude(yaw, 0.0, t)
            position(speeding_up(t)[0], 0.0, t)
        est.on_commanded([min(0.5 * t, 1.0)] * 4, 0.02, t)


def test_from_a_standing_start_gps_fixes_correct_the_heading_within_0_6_m_and_an_ekf_not():
    gps, ekf = estimator(ODOM_YAW_BIAS=2), estimator(ODOM_YAW_BIAS=1)
    speed_up_north(gps, 2.0, 0.6, ekf=False)
    speed_up_north(ekf, 2.0, 0.6, ekf=True)
    assert math.degrees(gps.yaw_correction) == pytest.approx(2.0, abs=0.2)
    assert ekf.yaw_correction == 0.0
