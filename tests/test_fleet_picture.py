"""The fleet drive's picture (:func:`mecanum_mav.app.fleet.fleet_figure`, drawn to a PNG by
``plot_fleet`` for docs/fleet.png): what its docstring promises a reader - each rover's path in
its own panel, north up and east right in its own local frame, one scale for all, a colour per
phase, the planned mission dashed, the start marked, each panel's legend below it and the title
naming the phases in which no rover moved.

The drives are made up (a :class:`FleetDrive` is plain data); tests/test_fleet.py drives real
rovers and tests/test_fleet_drive_faults.py checks the PNG's pixels.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from typing import Any

import pytest

from mecanum_mav.app.fleet import FleetDrive, fleet_figure

pytest.importorskip("matplotlib")

SQUARE = [(0.0, 0.0), (0.6, 0.0), (0.6, 0.6), (0.0, 0.6), (0.0, 0.0), (0.6, 0.6)]
"""The planned mission (north, east), as drive_fleet plans it: from the start, a square and
its diagonal."""
PHASES = [("MANUAL_CONTROL to 2", 1.0, 2.0), ("RC override to 2", 2.0, 4.0),
          ("RC override to 3", 4.0, 6.0), ("mission", 6.0, 12.0)]
"""drive_fleet's phases (name, start s, end s)."""
TITLE = ("3 rovers behind one MAVProxy router, one ground-station connection: sticks by "
         "system id, one mission run by two at once")


def fleet_drive() -> FleetDrive:
    """drive_fleet's drive as the real rovers drive it: nobody moves on MANUAL_CONTROL, rover 2
    drives 0.6 m north on RC override, rover 3 0.6 m east, then 1 and 2 run the square."""
    mission = [(6.0 + i, n, e) for i, (n, e) in enumerate(SQUARE)]
    return FleetDrive(
        paths={1: [(0.5, 0.0, 0.0), (1.5, 0.0, 0.0), *mission],
               2: [(0.5, 0.0, 0.0), (2.0, 0.0, 0.0), (3.0, 0.3, 0.0), (4.0, 0.6, 0.0),
                   *[(t, n + 0.6, e) for t, n, e in mission]],
               3: [(0.5, 0.0, 0.0), (4.0, 0.0, 0.0), (5.0, 0.0, 0.3), (6.0, 0.0, 0.6),
                   (12.0, 0.0, 0.6)]},
        moved={"MANUAL_CONTROL to 2": {1: (0.0, 0.0), 2: (0.0, 0.0), 3: (0.0, 0.0)},
               "RC override to 2": {1: (0.0, 0.0), 2: (0.6, 0.0), 3: (0.0, 0.0)},
               "RC override to 3": {1: (0.0, 0.0), 2: (0.0, 0.0), 3: (0.0, 0.6)},
               "mission": {1: (0.6, 0.6), 2: (0.6, 0.6), 3: (0.0, 0.0)}},
        phases=list(PHASES),
        planned={1: SQUARE, 2: SQUARE})


@pytest.fixture
def figure() -> Iterator[Any]:
    """Draws a drive (warnings are errors: a user would read them on stderr) and closes the
    figure after the test."""
    from matplotlib import pyplot as plt

    drawn: list[Any] = []

    def draw(drive: FleetDrive) -> Any:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            drawn.append(fleet_figure(drive))
        drawn[-1].canvas.draw()
        return drawn[-1]

    yield draw
    for fig in drawn:
        plt.close(fig)


def line(ax: Any, label: str) -> Any:
    """The one line of ``ax`` labelled ``label``."""
    (found,) = [ln for ln in ax.get_lines() if ln.get_label() == label]
    return found


def east_north(ln: Any) -> list[tuple[float, float]]:
    return [(float(x), float(y)) for x, y in zip(ln.get_xdata(), ln.get_ydata(), strict=True)]


def test_each_rover_has_one_panel_titled_by_its_system_id_and_instance(figure: Any) -> None:
    """``sim --instance N`` is system N + 1 (the CLI's rule); east across, north up."""
    fig = figure(fleet_drive())
    assert [ax.get_title() for ax in fig.axes] == [
        "system id 1 (instance 0)", "system id 2 (instance 1)", "system id 3 (instance 2)"]
    assert [ax.get_xlabel() for ax in fig.axes] == ["east (m)"] * 3
    assert fig.axes[0].get_ylabel() == "north (m)"  # the left panel's, for the row


def test_the_panels_share_one_scale(figure: Any) -> None:
    """Rover 3 went 2 m east, rovers 1 and 2 ran the 0.6 m square: the same metre is as long
    in every panel, so their paths compare."""
    drive = fleet_drive()
    drive.paths[3] = [(0.5, 0.0, 0.0), (4.0, 0.0, 0.0), (5.0, 0.0, 1.0), (6.0, 0.0, 2.0)]
    fig = figure(drive)
    assert len({ax.get_xlim() for ax in fig.axes}) == 1
    assert len({ax.get_ylim() for ax in fig.axes}) == 1


def test_a_rovers_path_is_drawn_east_across_and_north_up_from_its_start_marker(
        figure: Any) -> None:
    fig = figure(fleet_drive())
    rover2 = fig.axes[1]
    assert east_north(line(rover2, "RC override to 2")) == [(0.0, 0.0), (0.0, 0.3), (0.0, 0.6)]
    assert east_north(line(rover2, "mission")) == [(e, n + 0.6) for n, e in SQUARE]
    assert east_north(line(fig.axes[2], "RC override to 3")) == [
        (0.0, 0.0), (0.3, 0.0), (0.6, 0.0)]
    for ax in fig.axes:  # each in its own frame: every rover starts at its origin
        start = line(ax, "start")
        assert east_north(start) == [(0.0, 0.0)]
        assert (start.get_marker(), start.get_color(), start.get_linestyle()) == (
            "^", "k", "None")


def test_the_planned_mission_is_dashed_through_its_waypoints_where_a_rover_ran_one(
        figure: Any) -> None:
    """Dashed (the docstring) and solid paths, whatever the user's matplotlibrc makes of a
    line by default."""
    from matplotlib import rc_context

    with rc_context({"lines.linestyle": ":"}):
        fig = figure(fleet_drive())
    for ax in fig.axes[:2]:
        planned = line(ax, "mission (planned)")
        assert east_north(planned) == [(e, n) for n, e in SQUARE]
        assert (planned.get_linestyle(), planned.get_marker()) == ("--", "o")
        assert line(ax, "mission").get_linestyle() == "-"
    assert "mission (planned)" not in [ln.get_label() for ln in fig.axes[2].get_lines()]


def test_each_phase_has_its_own_colour_the_same_in_every_panel_and_not_the_plans(
        figure: Any) -> None:
    # Five phases, rover 1 and rover 2 each moving in every one (0.1 m north a second).
    phases = [(f"phase {k}", float(k), float(k + 1)) for k in range(5)]
    path = [(k / 2, k / 20, 0.0) for k in range(11)]
    drive = FleetDrive(paths={1: path, 2: [(t, n, -n) for t, n, _ in path]},
                       moved={name: {1: (0.1, 0.0), 2: (0.1, -0.1)} for name, _, _ in phases},
                       phases=phases, planned={1: SQUARE})
    fig = figure(drive)
    colours = [{name: line(ax, name).get_color() for name, _, _ in phases} for ax in fig.axes]
    assert colours[0] == colours[1]
    assert len(set(colours[0].values())) == 5
    assert line(fig.axes[0], "mission (planned)").get_color() not in colours[0].values()


def test_the_plan_does_not_take_the_missions_colour(figure: Any) -> None:
    """drive_fleet's fourth phase is the mission: its path and its plan must not look alike."""
    fig = figure(fleet_drive())
    ax = fig.axes[0]
    from matplotlib.colors import to_rgba

    assert to_rgba(line(ax, "mission (planned)").get_color()) != to_rgba(
        line(ax, "mission").get_color())


def test_consecutive_phases_paths_meet_at_the_position_on_their_boundary(
        figure: Any) -> None:
    """A position at the instant one phase ends and the next starts belongs to both: the
    lines join instead of leaving a gap."""
    drive = FleetDrive(paths={1: [(0.0, 0.0, 0.0), (1.0, 0.5, 0.0), (2.0, 0.5, 0.5)]},
                       moved={"north": {1: (0.5, 0.0)}, "east": {1: (0.0, 0.5)}},
                       phases=[("north", 0.0, 1.0), ("east", 1.0, 2.0)])
    ax = figure(drive).axes[0]
    assert east_north(line(ax, "north")) == [(0.0, 0.0), (0.0, 0.5)]
    assert east_north(line(ax, "east")) == [(0.0, 0.5), (0.5, 0.5)]


def test_each_panels_legend_names_what_it_shows_below_the_panel_and_its_axis_label(
        figure: Any) -> None:
    """The legend must not cover the track nor the axis label, and sits under its own panel,
    inside the figure, right under the label (not adrift)."""
    fig = figure(fleet_drive())
    assert [[t.get_text() for t in ax.get_legend().get_texts()] for ax in fig.axes] == [
        ["mission (planned)", "mission", "start"],
        ["mission (planned)", "RC override to 2", "mission", "start"],
        ["RC override to 3", "start"]]
    renderer = fig.canvas.get_renderer()
    page = fig.bbox
    for ax in fig.axes:
        panel = ax.get_window_extent(renderer)
        label = ax.xaxis.label.get_window_extent(renderer)
        legend = ax.get_legend().get_window_extent(renderer)
        assert legend.y1 <= label.y0 < panel.y0
        assert label.y0 - legend.y1 < 0.1 * panel.height
        assert panel.x0 < (legend.x0 + legend.x1) / 2 < panel.x1
        assert page.x0 <= legend.x0 and legend.x1 <= page.x1 and page.y0 <= legend.y0


def test_the_title_names_the_phases_in_which_no_rover_moved(figure: Any) -> None:
    # MANUAL_CONTROL: nobody moved; "RC override to 2": rover 2 went 0.5 m (not "still").
    drive = fleet_drive()
    drive.moved["RC override to 2"][2] = (0.5, 0.0)
    drive.moved["RC override to 3"] = {1: (0.0, 0.0), 2: (0.0, 0.0), 3: (0.0, 0.0)}
    assert figure(drive).get_suptitle() == TITLE + (
        "\nMANUAL_CONTROL to 2, RC override to 3: no rover moved (MAVProxy routes by "
        "target_system, which MANUAL_CONTROL lacks)")


def test_the_title_has_no_note_when_some_rover_moved_in_every_phase(figure: Any) -> None:
    drive = fleet_drive()
    drive.moved["MANUAL_CONTROL to 2"][1] = (0.3, 0.0)
    assert figure(drive).get_suptitle() == TITLE


def test_the_title_counts_the_rovers_drawn(figure: Any) -> None:
    """tools/fleet_example.py --count N draws N panels: the title says N, not three."""
    drive = fleet_drive()
    drive.paths[4] = [(0.5, 0.0, 0.0), (12.0, 0.0, 0.0)]
    for moved in drive.moved.values():
        moved[4] = (0.0, 0.0)
    fig = figure(drive)
    assert len(fig.axes) == 4
    assert fig.get_suptitle().startswith("4 rovers behind one MAVProxy router")
