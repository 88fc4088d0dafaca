"""The odometry estimator's guards against old or implausible flight-controller data
(control/estimator.py, control/headingbias.py): an ATTITUDE that stops coming, positions after
a gap, the gate of position fusion, and the heading bias's check that the two chords agree in
length. Synthetic inputs in virtual time (time passed in)."""

from __future__ import annotations

import math

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.control.headingbias import HeadingBias
from mecanum_mav.mecanum.geometry import wrap_pi


def estimator(**values: float) -> WheelOdometryEstimator:
    """Commanded-speed odometry (WHL_MAX_SPD 1 m/s: a wheel command of 1 rolls 1 m/s)."""
    params = Params()
    params.update({"ODOM_SRC": 2, **values})
    return WheelOdometryEstimator(params)


# ------------------------------------------------------------ an ATTITUDE that stops coming

def test_an_attitude_that_stops_coming_steers_the_heading_for_half_a_second_then_the_wheels_do():
    """ODOM_YAW_SRC auto: the flight controller's yaw "while fresh" (docs/companion.md), carried
    at its rate; once FRESH_S (0.5 s) has passed without one the wheels' own turn counts, so a
    flight controller that fell silent while turning does not spin the heading on."""
    est = estimator()
    est.on_attitude(0.0, 1.0, 0.0)  # heading 0, turning clockwise at 1 rad/s; the last one
    headings = {}
    for k in range(1, 101):  # 2 s straight ahead on the wheels (which do not turn)
        t = k / 50
        est.on_commanded([1.0] * 4, 0.02, t)
        headings[k] = est.pose.yaw_rad
    assert headings[25] == pytest.approx(0.5, abs=1e-12)  # at 0.5 s: still carried, 1 rad/s
    assert headings[26] == pytest.approx(0.5, abs=1e-12)  # then held: the wheels do not turn
    assert headings[100] == pytest.approx(0.5, abs=1e-12)  # (2.0 rad on the stale attitude)
    assert est.yaw_rate == 0.0  # the wheels' turn rate, not the silent gyro's 1 rad/s


def test_gps_fixes_while_the_attitude_has_stopped_coming_do_not_measure_a_heading_bias():
    """The bias is measured "while the flight controller's yaw is in use" (estimator module
    docstring): with its ATTITUDE gone the wheels steer, and there is no yaw to correct."""
    est = estimator()
    est.on_attitude(math.radians(2.5), 0.0, 0.0)  # the only one: 2.5 degrees off the truth
    for k in range(1, 201):  # 4 s truly north at 1 m/s, fixes of the truth at 10 Hz
        t = 0.02 * k
        if k % 5 == 0:
            assert est.on_gps(t, 0.0, t) is None
        est.on_commanded([1.0] * 4, 0.02, t)
    assert est.heading_bias.measurements == 0 and est.yaw_correction == 0.0


# ------------------------------------------------------------------------ position fusion

def fused(tau_s: float = 1.0) -> WheelOdometryEstimator:
    """ODOM_POS_TAU ``tau_s``, standing at the origin facing north, the flight controller's
    track anchored there at time 0 (the first position moves nothing)."""
    est = estimator(ODOM_POS_TAU=tau_s, ODOM_YAW_BIAS=0)
    est.on_attitude(0.0, 0.0, 0.0)
    est.on_position(0.0, 0.0, 0.0)
    assert est.pose == (0.0, 0.0, 0.0)
    return est


def test_a_position_after_a_long_gap_pulls_no_more_than_half_a_second_of_fusion_would():
    """POSITION_GAP_S: "the fusion's step counts at most this long after a gap in the
    positions" (estimator.py): 10 s without a position, then one 10 cm east, is pulled
    1 - exp(-0.5 / tau) of the way, not (nearly) all of it."""
    est = fused(tau_s=1.0)
    est.on_position(0.0, 0.1, 10.0)
    assert est.pose.y_m == pytest.approx(0.1 * (1.0 - math.exp(-0.5)), rel=1e-9)  # 3.9 cm
    assert est.pose.x_m == 0.0


def test_a_position_further_than_half_a_metre_from_the_odometrys_is_not_fused():
    """POSITION_GATE_M 0.5 m (estimator module docstring): a position further than that from
    the odometry's "is not used (a glitch, an EKF reset)"; one within it is."""
    est = fused(tau_s=1.0)
    est.on_position(0.0, 0.55, 0.1)
    assert est.pose == (0.0, 0.0, 0.0)
    est.on_position(0.0, 0.45, 0.2)
    assert est.pose.y_m == pytest.approx(0.45 * (1.0 - math.exp(-0.1)), rel=1e-9)
    at_the_gate = fused(tau_s=1.0)  # exactly 0.5 m off is not "further than" it: fused
    at_the_gate.on_position(0.0, 0.5, 0.1)
    assert at_the_gate.pose.y_m == pytest.approx(0.5 * (1.0 - math.exp(-0.1)), rel=1e-9)


def test_positions_far_off_re_anchor_the_track_only_after_20_in_a_row():
    """POSITION_GATE_COUNT 20: that many far positions in a row re-anchor the flight
    controller's track (the next position anchors it); fewer, or as many with one good position
    among them, are glitches: the old anchor stays and a position near it is fused."""
    gain = 1.0 - math.exp(-0.1)  # tau 1 s, positions 0.1 s apart

    est = fused()
    for k in range(1, 20):  # 19 in a row, 3 m north: not used
        est.on_position(3.0, 0.0, 0.1 * k)
    est.on_position(0.1, 0.0, 2.0)  # near the old anchor: fused
    assert est.pose.x_m == pytest.approx(0.1 * gain, rel=1e-9)

    est = fused()
    for k in range(1, 11):  # 10 far, one good, 10 far: not 20 in a row
        est.on_position(3.0, 0.0, 0.1 * k)
    est.on_position(0.0, 0.0, 1.1)
    for k in range(12, 22):
        est.on_position(3.0, 0.0, 0.1 * k)
    est.on_position(0.1, 0.0, 2.2)
    assert est.pose.x_m == pytest.approx(0.1 * gain, rel=1e-9)

    est = fused()
    for k in range(1, 21):  # 20 in a row: the flight controller's track is re-anchored
        est.on_position(3.0, 0.0, 0.1 * k)
    est.on_position(3.0, 0.0, 2.1)  # anchors it here
    assert est.pose == (0.0, 0.0, 0.0)
    est.on_position(3.1, 0.0, 2.2)  # 10 cm along from the new anchor: fused
    assert est.pose.x_m == pytest.approx(0.1 * gain, rel=1e-9)


def test_each_fused_position_pulls_one_minus_exp_of_minus_dt_over_tau_of_the_way():
    """ODOM_POS_TAU is the fusion's time constant: a position 0.2 s after the last, 10 cm
    east of the odometry, pulls it 1 - exp(-0.2 / 2) of the way with tau 2 s."""
    est = fused(tau_s=2.0)
    est.on_position(0.0, 0.1, 0.2)
    assert est.pose.y_m == pytest.approx(0.1 * (1.0 - math.exp(-0.1)), rel=1e-9)


@pytest.mark.parametrize(("north", "east"), [(0.0, math.nan), (math.nan, 0.0), (0.0, 2e7),
                                             (-2e7, 0.0)])
def test_a_position_with_either_coordinate_not_a_number_or_absurd_is_not_one(north, east):
    est = fused(tau_s=1.0)
    assert est.on_position(north, east, 0.1) is None
    assert est.pose == (0.0, 0.0, 0.0)
    est.on_position(0.0, 0.1, 0.2)  # the next good one is fused as if it had not come
    assert est.pose.y_m == pytest.approx(0.1 * (1.0 - math.exp(-0.2)), rel=1e-9)


def test_one_good_position_starts_the_count_of_far_ones_again_and_so_does_a_re_anchoring():
    gain = 1.0 - math.exp(-0.1)
    est = fused()
    for k in range(1, 11):  # 10 far, one good, then 19 far: never 20 in a row
        est.on_position(3.0, 0.0, 0.1 * k)
    est.on_position(0.0, 0.0, 1.1)
    for k in range(12, 31):
        est.on_position(3.0, 0.0, 0.1 * k)
    est.on_position(0.1, 0.0, 3.1)  # near the old anchor: fused
    assert est.pose.x_m == pytest.approx(0.1 * gain, rel=1e-9)

    est = fused()
    for k in range(1, 21):  # 20 in a row: re-anchored 3 m north
        est.on_position(3.0, 0.0, 0.1 * k)
    est.on_position(3.0, 0.0, 2.1)  # (anchors it)
    for k in range(22, 41):  # 19 more far from the new anchor: not 20 in a row
        est.on_position(9.0, 0.0, 0.1 * k)
    est.on_position(3.1, 0.0, 4.1)  # near the new anchor: fused
    assert est.pose.x_m == pytest.approx(0.1 * gain, rel=1e-9)


def test_the_flight_controllers_track_is_anchored_where_the_odometry_is_at_its_first_position():
    """The flight controller's origin does not matter: its first position, wherever the rover
    has got to by then, is where the odometry is; later ones are fused relative to it."""
    est = estimator(ODOM_POS_TAU=1.0, ODOM_YAW_BIAS=0)
    est.on_attitude(math.pi / 2, 0.0, 0.0)  # facing east
    for k in range(1, 51):  # 1 m east on the wheels
        est.on_commanded([1.0] * 4, 0.02, 0.02 * k)
    assert est.pose.y_m == pytest.approx(1.0)
    est.on_position(5.0, 7.0, 1.0)  # the flight controller's own frame: anchors here
    # 0.1 s on, the odometry is carried 10 cm further at its 1 m/s: 20 cm is 10 cm ahead
    est.on_position(5.0, 7.2, 1.1)
    assert est.pose.y_m == pytest.approx(1.0 + 0.1 * (1.0 - math.exp(-0.1)), rel=1e-9)
    assert est.pose.x_m == pytest.approx(0.0, abs=1e-12)


# ---------------------------------------------------------------------------- heading bias

def rotated(north_m: float, east_m: float, angle_deg: float) -> tuple[float, float]:
    """(north, east) turned clockwise by ``angle_deg`` (as a heading that far off turns every
    odometry step)."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    return north_m * c - east_m * s, north_m * s + east_m * c


def one_window(steps_m: list[float], fc_over_odometry: float, bias_deg: float = 2.0,
               start_s: float = 0.0) -> HeadingBias:
    """One straight window: raw odometry steps ``steps_m`` north-ish (turned ``bias_deg``) at
    10 Hz, the flight controller's fixes on the true line with its chord ``fc_over_odometry``
    times the odometry's (GPS fixes: no steady-driving rule)."""
    bias = HeadingBias()
    along, t = 0.0, start_s
    bias.on_position(0.0, 0.0, 0.0, 0.0, 0.0, t, follows_yaw=False)
    for step in steps_m:
        along, t = along + step, t + 0.1
        bias.on_position(along * fc_over_odometry, 0.0, *rotated(along, 0.0, bias_deg), 0.0, t,
                         follows_yaw=False)
    return bias


STEADY = [0.104] * 5
"""0.52 m at 1.04 m/s: one window of at least BASELINE_M, no change of speed."""


@pytest.mark.parametrize("fc_over_odometry", [0.81, 1.19])
def test_a_flight_controller_chord_within_20_percent_of_the_odometrys_is_measured(
        fc_over_odometry):
    bias = one_window(STEADY, fc_over_odometry)
    assert bias.measurements == 1
    assert math.degrees(bias.bias_rad) == pytest.approx(2.0, abs=1e-9)


@pytest.mark.parametrize("fc_over_odometry", [0.79, 1.21])
def test_a_flight_controller_chord_more_than_20_percent_off_the_odometrys_is_not_a_heading(
        fc_over_odometry):
    """SCALE_TOLERANCE 0.2: a GPS glitch, an EKF reset or wheels slipping are not a heading
    (headingbias module docstring), longer or shorter alike."""
    bias = one_window(STEADY, fc_over_odometry)
    assert bias.measurements == 0 and bias.bias_rad == 0.0


SPEEDING_UP = [0.1, 0.1, 0.1, 0.1, 0.12]
"""0.52 m, its first step at 1.0 m/s and its last at 1.2 m/s: a change of speed of 0.2 m/s,
which late fixes explain FIX_LAG_S x 0.2 = 8 cm of."""
SLOWING_DOWN = SPEEDING_UP[::-1]


@pytest.mark.parametrize(("steps", "sign"), [(SPEEDING_UP, -1.0), (SLOWING_DOWN, 1.0)],
                         ids=["short_of_a_window_that_speeds_up", "long_of_one_that_slows"])
def test_late_fixes_are_allowed_0_4_s_times_the_change_of_speed_beyond_the_20_percent(
        steps, sign):
    """The chords agree within SCALE_TOLERANCE "and within what the positions' lateness
    explains besides: FIX_LAG_S times the change of speed over the window" (headingbias module
    docstring): 0.2 x 0.52 m + 0.4 s x 0.2 m/s = 18.4 cm here, whether the speed rises (late
    fixes fall short) or falls (they overshoot); 1 cm inside it is measured, 1 cm beyond it is
    not."""
    chord = sum(steps)
    allowed = 0.2 * chord + 0.4 * 0.2  # SCALE_TOLERANCE, FIX_LAG_S
    inside = one_window(steps, 1.0 + sign * (allowed - 0.01) / chord)
    assert inside.measurements == 1
    assert math.degrees(inside.bias_rad) == pytest.approx(2.0, abs=1e-9)
    beyond = one_window(steps, 1.0 + sign * (allowed + 0.01) / chord)
    assert beyond.measurements == 0


def drive(bias: HeadingBias, times_s: list[float]) -> list[int]:
    """North at 1 m/s, the odometry 2 degrees off the fixes, a fix at each of ``times_s``; the
    measurement count after each."""
    counts = []
    for t in times_s:
        bias.on_position(t, 0.0, *rotated(t, 0.0, 2.0), 0.0, t, follows_yaw=False)
        counts.append(bias.measurements)
    return counts


def test_after_a_gap_of_more_than_a_second_in_the_fixes_the_window_starts_again():
    """GAP_S 1 s: "a gap in the positions longer than GAP_S restarts the window" (headingbias
    module docstring): no window reaches back across it, so the next measurement waits for
    another BASELINE_M (0.5 m) of fixes; a gap of exactly 1 s does not restart it."""
    bias = HeadingBias()
    before = drive(bias, [k / 10 for k in range(21)])  # 2 m, fixes at 10 Hz
    assert before[-1] > 0
    after = drive(bias, [3.1 + k / 10 for k in range(7)])  # 1.1 s without a fix
    assert after[:5] == [before[-1]] * 5  # 0.4 m since the gap: no window yet
    assert after[6] > before[-1]  # 0.6 m: measured again

    bias = HeadingBias()
    before = drive(bias, [k / 10 for k in range(21)])
    after = drive(bias, [3.0])  # 1.0 s without: the window reaches back across it
    assert after[0] == before[-1] + 1


def test_following_the_odometry_before_the_first_position_changes_nothing():
    """HeadingBias.follow: "before the first position, or after a restart, it changes
    nothing: the next position starts the window" (also after a gap in the fixes)."""
    steps = STEADY * 3
    plain = one_window(steps, 1.0)
    followed = HeadingBias()
    followed.follow(4.0, -2.0)  # (an odometry reset, say, before any position)
    along, t = 0.0, 0.0
    followed.on_position(0.0, 0.0, 0.0, 0.0, 0.0, t, follows_yaw=False)
    for step in steps:
        along, t = along + step, t + 0.1
        followed.on_position(along, 0.0, *rotated(along, 0.0, 2.0), 0.0, t, follows_yaw=False)
    assert followed.measurements == plain.measurements > 0
    assert followed.bias_rad == plain.bias_rad
    followed.restart()
    followed.follow(1.0, 1.0)
    followed.on_position(0.0, 0.0, 0.0, 0.0, 0.0, 5.0, follows_yaw=False)  # starts a window



# ------------------------------------------------------------------ a new origin (DO_SET_HOME)

def test_a_new_origin_while_turning_keeps_the_heading_on_the_flight_controllers_yaw():
    """reset() (DO_SET_HOME) moves the origin and "the heading is kept": the flight
    controller's yaw keeps steering it from that moment, including the step right after, even
    when the wheels slip and say the rover does not turn."""
    est = estimator()
    offsets = []
    for k in range(0, 61):  # 1.5 s turning clockwise at 1 rad/s on wheels that roll straight
        t = k / 40  # (each tick beyond COMMANDED_UPDATE_S: each moves the odometry)
        assert est.on_attitude(t, 1.0, t) is None
        est.on_commanded([1.0] * 4, 0.025, t)
        if k == 40:
            est.reset(t)  # the new origin at 1 s
            assert (est.pose.x_m, est.pose.y_m) == (0.0, 0.0)
        offsets.append(est.pose.yaw_rad - wrap_pi(t))
    assert est.reset_counter == 1
    assert offsets == pytest.approx([0.0] * len(offsets), abs=1e-9)
