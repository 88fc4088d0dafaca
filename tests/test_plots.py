"""`mecanum-mav plot`'s figures show what seed 000's Illustrations 1-7 show (docs/api.md,
"The speed envelope"), for the algorithms and rotations their titles name."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from support import png_size_and_dpi

from mecanum_mav.app.plots import FIGURES, figure, figures, render_all
from mecanum_mav.mecanum.envelope import (
    non_clipping_limit_2010,
    robot_speed,
    speed_grid,
)

pytestmark = pytest.mark.filterwarnings("error")  # a figure that warns, warns the user

R2 = float(np.sqrt(0.5))
HEADINGS = np.linspace(0.0, 360.0, 721)  # every half degree, both ends drawn

SURFACES = {
    "illustration1_2010_rot0.png": ("holonomic_2010", 0.0),
    "illustration2_2010_rot029.png": ("holonomic_2010", 0.29),
    "illustration4_2011_rot0.png": ("polar_2011", 0.0),
    "illustration5_2011_rot029.png": ("polar_2011", 0.29),
    "max_speed_scaled_rot0.png": ("max_speed_scaled", 0.0),
    "max_speed_scaled_rot029.png": ("max_speed_scaled", 0.29),
    "cartesian_rot0.png": ("cartesian", 0.0),
    "cartesian_rot029.png": ("cartesian", 0.29),
}
LABELS = {
    "holonomic_2010": "2010 HolonomicDrive",
    "polar_2011": "2011 MecanumDrive_Polar",
    "max_speed_scaled": "max_speed_scaled (seed 004)",
    "cartesian": "cartesian (square stick)",
}


@pytest.fixture
def built() -> Any:
    """The figures a test asks for (``built[name]``), each built when first asked for and
    closed after the test."""
    from mecanum_mav.app.plots import _pyplot

    plt = _pyplot()  # (matplotlib's file-only backend)
    plt.close("all")  # (figures other tests left open count towards pyplot's warning)

    class Built(dict):
        def __missing__(self, name: str) -> Any:
            self[name] = figure(name)
            return self[name]

    figs = Built()
    yield figs
    for fig in figs.values():
        plt.close(fig)


def test_plot_writes_every_figure_in_order_as_a_110_dpi_png_into_a_new_folder(tmp_path):
    out = tmp_path / "new" / "figures"
    paths = render_all(out)
    assert render_all(out) == paths  # (again into the same folder: the figures replaced)
    assert paths == [out / name for name, _ in FIGURES]
    for path in paths:
        width, height, dpi = png_size_and_dpi(path)
        assert dpi == pytest.approx(110, abs=0.1)
        # 7 inches wide; surfaces 5.5 inches high, curves 4.
        assert (width, height) == ((770, 605) if path.name in SURFACES else (770, 440))


def test_builds_every_figure_in_the_order_of_the_table_each_titled_with_what_it_shows():
    from mecanum_mav.app.plots import _pyplot

    plt = _pyplot()
    names = []
    for name, fig in figures():
        names.append(name)
        title = fig.axes[0].get_title()
        plt.close(fig)
        assert title.startswith(dict(FIGURES)[name]), name
        if name in SURFACES:
            algorithm, rotation = SURFACES[name]
            assert f"{LABELS[algorithm]}, rotation {rotation:.2f}, peak " in title, name
    assert names == [name for name, _ in FIGURES] and len(names) == 11


def test_a_figure_not_in_the_table_is_a_key_error():
    with pytest.raises(KeyError):
        figure("illustration8.png")


@pytest.mark.parametrize("name", list(SURFACES))
def test_each_surface_is_robot_speed_at_its_velocity_and_heading_x_right_y_forward(built, name):
    algorithm, rotation = SURFACES[name]
    ax = built[name].axes[0]
    (surface,) = ax.collections
    x, y, z = np.asarray(surface._faces).reshape(-1, 3).T  # every vertex drawn
    velocity = np.hypot(x, y)
    heading = np.degrees(np.arctan2(x, y))  # clockwise from the nose: x right, y forward
    np.testing.assert_allclose(z, robot_speed(algorithm, velocity, heading, rotation), atol=1e-12)
    assert velocity.max() == pytest.approx(1.0) and velocity.min() == pytest.approx(0.0)
    assert x.max() == pytest.approx(1.0) and x.min() == pytest.approx(-1.0)
    assert y.max() == pytest.approx(1.0) and y.min() == pytest.approx(-1.0)
    assert ax.get_zlim() == (0.0, 1.0)
    assert ax.get_xlabel() == "velocity x sin(heading)  (right)"
    assert ax.get_ylabel() == "velocity x cos(heading)  (forward)"
    assert ax.get_zlabel() == "robot speed"
    title = dict(FIGURES)[name]
    peak = speed_grid(algorithm, rotation)[2].max()
    assert ax.get_title() == (
        f"{title}\n{LABELS[algorithm]}, rotation {rotation:.2f}, peak {peak:.3f}")


def test_the_2010_surfaces_peak_at_sqrt2_over_2_and_the_2011_at_one(built):
    # docs/api.md: 2010 peaks at sqrt(2)/2 everywhere, 2011 gives 1.0 on the cardinals.
    assert built["illustration1_2010_rot0.png"].axes[0].get_title().endswith("peak 0.707")
    assert built["illustration4_2011_rot0.png"].axes[0].get_title().endswith("peak 1.000")


def _curve_axes_are_speed_against_heading(ax: Any) -> None:
    assert ax.get_xlabel() == "heading (deg clockwise from nose)"
    assert list(ax.get_xticks()) == list(range(0, 361, 45))
    assert ax.get_ylim() == (0.0, 1.05)
    assert all(line.get_visible() for line in ax.xaxis.get_gridlines())
    assert all(line.get_visible() for line in ax.yaxis.get_gridlines())
    for line in ax.get_lines():
        np.testing.assert_array_equal(line.get_xdata(), HEADINGS)
    legend = ax.get_legend()
    assert [t.get_text() for t in legend.get_texts()] == [
        line.get_label() for line in ax.get_lines()]


def test_illustration3_is_the_2010_non_clipping_limit_at_four_rotations(built):
    ax = built["illustration3_2010_nonclip_limit.png"].axes[0]
    _curve_axes_are_speed_against_heading(ax)
    assert ax.get_ylabel() == "largest velocity without clipping"
    assert ax.get_title() == "Illustration 3: 2010 algorithm non-clipping limit"
    rotations = (0.0, 0.1, 0.29, 0.5)
    assert [line.get_label() for line in ax.get_lines()] == [f"rotation {r}" for r in rotations]
    for line, rotation in zip(ax.get_lines(), rotations, strict=True):
        np.testing.assert_allclose(line.get_ydata(), non_clipping_limit_2010(HEADINGS, rotation))


@pytest.mark.parametrize(("name", "series"), [
    ("illustration6_speed_vs_heading_v050.png", [("polar_2011", 0.50), ("holonomic_2010", R2)]),
    ("illustration7_speed_vs_heading_v071.png", [
        ("polar_2011", R2), ("holonomic_2010", R2), ("max_speed_scaled", R2), ("cartesian", R2)]),
])
def test_speed_against_heading_curves_at_rotation_029_one_style_per_algorithm(
        built, name, series):
    ax = built[name].axes[0]
    _curve_axes_are_speed_against_heading(ax)
    assert ax.get_ylabel() == "robot speed"
    assert ax.get_title() == f"{dict(FIGURES)[name]}: robot speed vs heading, rotation 0.29"
    lines = ax.get_lines()
    assert [line.get_label() for line in lines] == [
        f"{LABELS[algorithm]}, velocity {velocity:.2f}" for algorithm, velocity in series]
    assert len({line.get_linestyle() for line in lines}) == len(lines)
    for line, (algorithm, velocity) in zip(lines, series, strict=True):
        np.testing.assert_allclose(
            line.get_ydata(), robot_speed(algorithm, velocity, HEADINGS, 0.29))


def test_illustration6_shows_2011_at_half_speed_equal_to_2010_at_sqrt2_over_2(built):
    # Seed 000: the 2011 algorithm at velocity 0.50 gives what 2010 gives at sqrt(2)/2.
    polar, holonomic = built["illustration6_speed_vs_heading_v050.png"].axes[0].get_lines()
    np.testing.assert_allclose(polar.get_ydata(), holonomic.get_ydata(), atol=1e-12)
