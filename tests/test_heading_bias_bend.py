"""The heading bias's windows and a flight controller whose positions come late
(control/headingbias.py, TURN_GUARD_S): while the track bends, a late position's chord points
where the track went a moment before. Synthetic tracks in virtual time."""

from __future__ import annotations

import math

from mecanum_mav.control.headingbias import HeadingBias

GPS_DELAY_S = 0.15
"""How late ArduPilot SITL's GPS fixes are on the twin (a fit of its track to the truth)."""


def steering_back(t: float, start_s: float = 0.9, turn_deg: float = -4.0,
                  turn_s: float = 0.4) -> tuple[float, float]:
    """North at 1 m/s; from ``start_s`` the heading of travel turns ``turn_deg`` evenly over
    ``turn_s`` (a rover steering back onto its line after a correction), then straight on."""
    if t <= start_s:
        return t, 0.0
    rate = math.radians(turn_deg) / turn_s
    s = min(t - start_s, turn_s)
    north, east = start_s + math.sin(rate * s) / rate, (1.0 - math.cos(rate * s)) / rate
    rest, heading = t - start_s - s, rate * s
    return north + rest * math.cos(heading), east + rest * math.sin(heading)


def test_a_bending_track_with_late_positions_moves_the_estimate_little():
    """No bias at all; the rover steers back 4 degrees just as the first windows are measured,
    the flight controller's positions 0.15 s late: the estimate stays within 0.25 degrees (0.45
    without the guard: measured on the twin, the first estimate overshot by 0.8 degrees)."""
    bias = HeadingBias()
    worst = 0.0
    for k in range(61):
        t = k / 10
        fc = steering_back(max(t - GPS_DELAY_S, 0.0))
        bias.on_position(*fc, *steering_back(t), 0.0, t)
        worst = max(worst, abs(math.degrees(bias.bias_rad)))
    assert bias.measurements >= 10  # (straight again: measured)
    assert worst < 0.25


def test_a_straight_track_with_late_positions_still_gives_the_bias():
    """Straight north, 2 degrees off, the positions 0.15 s late: the lag only slides along."""
    bias = HeadingBias()
    c, s = math.cos(math.radians(2.0)), math.sin(math.radians(2.0))
    for k in range(51):
        t = k / 10
        bias.on_position(max(t - GPS_DELAY_S, 0.0), 0.0, t * c, t * s, 0.0, t)
    assert math.degrees(bias.bias_rad) >= 1.99
