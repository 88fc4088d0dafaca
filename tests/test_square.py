"""The issue's odometry goal: a 10 m square in GUIDED, odometry against the true pose
(tools/odometry_square.py, in the lockstep harness: virtual time, the same figures every run)."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))

import odometry_square
from odometry_square import run_square


def test_a_10m_square_in_guided_leaves_odometry_well_within_1_percent_and_1_degree():
    result = run_square(side_m=10.0, speed_mps=2.5, slip=0.0)
    assert result.distance_m == 40.0
    assert result.odom_error_pct < 0.1, result  # the goal: < 1 %
    assert result.odom_yaw_error_deg < 0.1, result  # the goal: < 1 degree
    assert result.final_error_m < 0.02, result  # and the rover reached the last corner
    assert 20.0 < result.seconds < 40.0, result  # 4 x 10 m at up to 2.5 m/s, simulated


def test_the_tool_prints_one_row_per_slip_and_the_goal(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["odometry_square.py", "--side", "2", "--slip", "0",
                                      "0.05"])
    assert odometry_square.main() == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("# odometry_square: 2 m square in GUIDED")
    assert lines[1].split() == ["slip", "dist", "m", "odom", "err", "m", "%", "dist", "yaw",
                                "err", "deg", "rover", "off", "corner", "m", "time", "s"]
    rows = [line.split() for line in lines[2:4]]
    assert [row[:2] for row in rows] == [["0.00", "8.0"], ["0.05", "8.0"]]
    assert all(float(row[3]) < 1.0 and float(row[4]) < 1.0 for row in rows)  # %, degrees
    assert lines[4].startswith("goal without slip: odometry error < 1 % of distance")
