"""The issue's odometry goal: a 10 m square in GUIDED, odometry against the true pose."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))

from odometry_square import run_square


def test_a_10m_square_in_guided_leaves_odometry_within_1_percent_and_1_degree():
    result = run_square(side_m=10.0, speed_mps=2.5, slip=0.0)
    assert result.odom_error_pct < 1.0, result
    assert result.odom_yaw_error_deg < 1.0, result
    assert result.final_error_m < 0.05, result  # and the rover reached the last corner
