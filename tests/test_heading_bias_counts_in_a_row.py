"""The heading-bias estimate's counts (control/headingbias.py's module docstring): it is
settled, and says so once, after SETTLED_COUNT measurements; a bias beyond MAX_BIAS_RAD is
said after REFUSE_AFTER such windows in a row, none accepted between; once settled,
REFUSE_AFTER outliers in a row start the filter again. ``rejected`` and ``outliers`` count
the windows in a row."""

from __future__ import annotations

import math

from mecanum_mav.control.headingbias import REFUSE_AFTER, SETTLED_COUNT, BiasUpdate, HeadingBias


def drive(estimate: HeadingBias, bias_deg: float, start_s: float, seconds: float,
          until_measurements: int | None = None) -> list[tuple[BiasUpdate, int, int, int]]:
    """Drive east at 1 m/s from a fresh window, a position every 0.1 s, the odometry's track
    turned ``bias_deg`` clockwise of the flight controller's (stopping once there are
    ``until_measurements``); each update with the measurements, rejected and outliers counts
    after it."""
    estimate.restart()
    b = math.radians(bias_deg)
    out = []
    for k in range(round(seconds / 0.1) + 1):
        east = 0.1 * k
        update = estimate.on_position(0.0, east, -east * math.sin(b), east * math.cos(b), 0.0,
                                      start_s + 0.1 * k)
        out.append((update, estimate.measurements, estimate.rejected, estimate.outliers))
        if estimate.measurements == until_measurements:
            break
    return out


def test_the_estimate_is_said_settled_once_at_its_tenth_measurement() -> None:
    steps = drive(HeadingBias(), 2.0, 0.0, 4.0)
    said = [(u.notice, m) for u, m, _, _ in steps if u.notice is not None]
    assert said == [("Heading: FC yaw +2.0 deg off its track: corrected", SETTLED_COUNT)]


def test_a_bias_beyond_the_bound_is_counted_window_by_window_and_said_at_the_twentieth() -> None:
    estimate = HeadingBias()
    steps = drive(estimate, 15.0, 0.0, 4.0)
    counts = [r for _, _, r, _ in steps if r]
    assert counts == list(range(1, len(counts) + 1)) and len(counts) > REFUSE_AFTER
    said = [r for u, _, r, _ in steps if u.notice is not None]
    assert said == [REFUSE_AFTER]
    accepted = drive(estimate, 2.0, 10.0, 1.0)
    assert accepted[-1][1] > 0 and accepted[-1][2] == 0  # a window accepted: none in a row


def test_once_settled_an_outlier_is_counted_and_twenty_in_a_row_start_the_filter_again() -> None:
    estimate = HeadingBias()
    assert drive(estimate, 2.0, 0.0, 10.0, SETTLED_COUNT)[-1][1] == SETTLED_COUNT  # just settled
    steps = drive(estimate, 7.0, 20.0, 4.0)
    windows = [(m, o) for _, m, _, o in steps if m != SETTLED_COUNT or o]
    outliers = [o for _, o in windows[:REFUSE_AFTER]]
    assert outliers == [*range(1, REFUSE_AFTER), 0]  # the twentieth starts again
    assert windows[REFUSE_AFTER - 1][0] == 0
    assert windows[REFUSE_AFTER] == (1, 0)  # the next is the first of a plain mean
    assert estimate.outliers == 0
