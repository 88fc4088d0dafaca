"""`mecanum-mav demo`: the whole product in one command.

The demo's script runs in the lockstep harness here (``run_demo(..., virtual=True)``: virtual
time, a fraction of a second). The CLI's real-time run on UDP loopback takes 10 s or more even
for a small square, so it is not run here; its parts (the companion, the simulated flight
controller and the scripted ground station on real sockets) are tested in
test_end_to_end.py and test_missions.py.
"""

from __future__ import annotations

import functools
import math
import re
import time

import pytest
from support import not_installed

from mecanum_mav.app import demo
from mecanum_mav.app.cli import main
from mecanum_mav.config.params import Params

ARRIVED_M = float(Params()["WP_RADIUS"]) + 0.005
"""Where the rover truly is when MISSION_ITEM_REACHED comes: within WP_RADIUS of its
odometry, which is a few mm from the truth."""


def test_the_demo_mission_drives_every_leg_of_the_square_and_the_diagonal():
    side = 2.0
    result = demo.run_demo(side_m=side, virtual=True)
    _, points = demo.demo_mission(side)
    assert [leg.seq for leg in result.legs] == [2, 3, 4, 5, 6]
    assert [leg.goal for leg in result.legs] == points
    assert [leg.start for leg in result.legs] == [(0.0, 0.0), *points[:-1]]
    for leg in result.legs:
        assert leg.arrival_error_m < ARRIVED_M, leg
        assert leg.max_cross_track_m < ARRIVED_M + 0.01, leg  # starts off the last corner
        # no faster than WP_SPEED (0.5 m/s), and not stalled
        length = math.dist(leg.start, leg.goal)
        assert length / 0.5 < leg.time_s < length / 0.5 + 3.0, leg
    assert result.max_yaw_deg < 0.1  # CONDITION_YAW 0: facing north all the way
    assert result.total_s >= sum(leg.time_s for leg in result.legs)
    final = result.true_path[-1]
    assert math.dist(final[:2], points[-1]) < ARRIVED_M + 0.01
    assert len(result.odometry_path) > 10 * result.total_s * 0.9  # LOCAL_POSITION_NED, 10 Hz
    assert math.dist(result.odometry_path[-1], final[:2]) < 0.01


def test_the_demo_gives_the_same_figures_every_run_in_virtual_time():
    first = demo.run_demo(side_m=0.6, virtual=True)
    again = demo.run_demo(side_m=0.6, virtual=True)
    assert first.table() == again.table()
    assert first.true_path == again.true_path


def test_the_table_is_the_header_a_row_per_leg_numbered_from_1_then_the_summary():
    legs = [demo.LegReport(2, (0.0, 0.0), (2.0, 0.0), 4.2, 0.012, 0.021),
            demo.LegReport(3, (2.0, 0.0), (2.0, 2.0), 4.3, 0.015, 0.018)]
    result = demo.DemoResult(legs, [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0)], total_s=9.0,
                             max_yaw_deg=0.05)
    assert result.table().split("\n") == [demo.TABLE_HEADER, demo.leg_row(1, legs[0]),
                                          demo.leg_row(2, legs[1]), result.summary()]
    assert result.table().splitlines()[1].split()[:2] == ["1", "2"]  # leg 1, item 2


def test_demo_runs_the_mission_prints_a_table_per_leg_and_writes_the_figure(
        tmp_path, capsys, monkeypatch):
    # The CLI as users run it, with the demo in virtual time.
    monkeypatch.setattr(demo, "run_demo", functools.partial(demo.run_demo, virtual=True))
    png = tmp_path / "demo.png"
    assert main(["demo", "--side", "0.6", "--png", str(png)]) == 0
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line[:1].isdigit()]
    assert len(rows) == 5  # four sides of the square and the diagonal
    for row in rows:
        *_, seconds, cross_cm, arrival_cm = row.split()
        assert float(seconds) > 1.2  # 0.6 m at WP_SPEED 0.5 m/s
        assert float(cross_cm) < 100 * (ARRIVED_M + 0.01)
        assert float(arrival_cm) < 100 * ARRIVED_M
    heading = re.search(r"heading within ([0-9.]+) deg of north", out)
    assert heading is not None and float(heading.group(1)) < 0.1
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_the_demo_as_a_user_runs_it_drives_over_real_sockets_in_real_time(tmp_path, capsys):
    """`mecanum-mav demo` (the README's command) as typed: the simulated flight controller,
    the companion and the ground station on loopback UDP, in real time (about 10 s for a
    0.3 m square); every leg is reported and the figure written."""
    png = tmp_path / "demo.png"
    started = time.monotonic()
    assert main(["demo", "--side", "0.3", "--png", str(png)]) == 0
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line[:1].isdigit()]
    assert [row.split()[:2] for row in rows] == [["1", "2"], ["2", "3"], ["3", "4"],
                                                 ["4", "5"], ["5", "6"]]
    assert all(float(row.split()[-1]) < 100 * ARRIVED_M for row in rows)  # arrival, cm
    driving_s = sum(float(row.split()[-3]) for row in rows)
    assert time.monotonic() - started > driving_s  # (real time: at least the legs' time)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_demo_prints_the_header_first_and_each_leg_as_soon_as_it_ends(capsys, monkeypatch):
    """A mission that stops after two legs: the header and those two rows are out (flushed,
    before the failure), not held back for a table at the end."""
    seen_at_leg: list[str] = []

    def two_legs_then_stop(params, side_m, on_leg=demo._ignore_leg, **options):
        for k in (1, 2):
            on_leg(k, demo.LegReport(k + 1, (0.0, 0.0), (side_m, 0.0), 1.5, 0.01, 0.02))
            seen_at_leg.append(capsys.readouterr().out)
        raise RuntimeError("the rover stopped after 2 legs")

    monkeypatch.setattr(demo, "run_demo", two_legs_then_stop)
    assert main(["demo", "--side", "0.6"]) == 1
    first, second = seen_at_leg
    lines = first.splitlines()
    assert lines[-2] == demo.TABLE_HEADER and lines[-1].split()[:2] == ["1", "2"]
    assert second.splitlines() == [second.splitlines()[0]] and second.split()[:2] == ["2", "3"]
    assert "the rover stopped after 2 legs" in capsys.readouterr().err


def test_run_demo_tells_each_leg_in_order_as_the_result_keeps_it():
    told: list[tuple[int, demo.LegReport]] = []
    result = demo.run_demo(side_m=0.6, virtual=True, on_leg=lambda k, leg: told.append((k, leg)))
    assert told == list(enumerate(result.legs, start=1)) and len(told) == 5


def test_demo_without_matplotlib_drives_and_reports_and_says_how_to_get_the_figure(
        tmp_path, capsys, monkeypatch):
    """(matplotlib is the `plot` extra: without it the demo still runs; the PNG is skipped
    with the install command, and the exit status is 0.)"""
    monkeypatch.setattr(demo, "run_demo", functools.partial(demo.run_demo, virtual=True))
    not_installed(monkeypatch, "matplotlib")
    png = tmp_path / "demo.png"
    assert main(["demo", "--side", "0.6", "--png", str(png)]) == 0
    out, err = capsys.readouterr()
    assert len([line for line in out.splitlines() if line[:1].isdigit()]) == 5
    assert err == ("mecanum-mav demo: no PNG: plotting needs matplotlib: "
                   "pip install 'mecanum-mav[plot]'\n")
    assert not png.exists()
