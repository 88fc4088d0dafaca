"""PNG figures of the speed envelopes (seed 000's Illustrations 1-7, and our mixers).

Needs matplotlib: ``pip install 'mecanum-mav[plot]'``. The numbers come from
:mod:`mecanum_mav.mecanum.envelope`; this module only draws them.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mecanum_mav.mecanum.envelope import non_clipping_limit_2010, robot_speed, speed_grid

__all__ = ["FIGURES", "figure", "figures", "render_all"]

ROTATION = 0.29
SQRT2_2 = float(np.sqrt(0.5))
"""The rotation seed 000 uses in Illustrations 2, 3, 5, 6 and 7."""

LABELS = {
    "holonomic_2010": "2010 HolonomicDrive",
    "polar_2011": "2011 MecanumDrive_Polar",
    "max_speed_scaled": "max_speed_scaled (seed 004)",
    "cartesian": "cartesian (square stick)",
}


def _pyplot() -> Any:
    try:
        import matplotlib as mpl

        mpl.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:
        raise RuntimeError(
            "plotting needs matplotlib: pip install 'mecanum-mav[plot]'"
        ) from exc
    return plt


def _surface(algorithm: str, rotation: float, title: str) -> Any:
    plt = _pyplot()
    velocity, heading, speed = speed_grid(algorithm, rotation)
    h = np.radians(heading)
    fig = plt.figure(figsize=(7, 5.5))
    ax = fig.add_subplot(projection="3d")
    ax.plot_surface(velocity * np.sin(h), velocity * np.cos(h), speed, cmap="viridis",
                    linewidth=0, antialiased=True)
    ax.set_xlabel("velocity x sin(heading)  (right)")
    ax.set_ylabel("velocity x cos(heading)  (forward)")
    ax.set_zlabel("robot speed")
    ax.set_zlim(0.0, 1.0)
    ax.set_title(f"{title}\n{LABELS[algorithm]}, rotation {rotation:.2f}, peak {speed.max():.3f}")
    fig.tight_layout()
    return fig


def _speed_axes(plt: Any, title: str) -> tuple[Any, Any, NDArray[np.float64]]:
    """A figure of robot speed (or velocity) against heading: 0-360 deg in half degrees."""
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.set_xlabel("heading (deg clockwise from nose)")
    ax.set_xticks(range(0, 361, 45))
    ax.set_ylim(0.0, 1.05)
    ax.grid(True, alpha=0.3)
    ax.set_title(title)
    return fig, ax, np.linspace(0.0, 360.0, 721)


def _limit(title: str) -> Any:
    fig, ax, heading = _speed_axes(_pyplot(), f"{title}: 2010 algorithm non-clipping limit")
    for rotation in (0.0, 0.1, ROTATION, 0.5):
        ax.plot(heading, non_clipping_limit_2010(heading, rotation), label=f"rotation {rotation}")
    ax.set_ylabel("largest velocity without clipping")
    ax.legend()
    fig.tight_layout()
    return fig


def _curves(series: list[tuple[str, float]], title: str) -> Any:
    fig, ax, heading = _speed_axes(
        _pyplot(), f"{title}: robot speed vs heading, rotation {ROTATION}")
    for (algorithm, velocity), style in zip(series, ("-", "--", ":", "-."), strict=False):
        ax.plot(heading, robot_speed(algorithm, velocity, heading, ROTATION), style,
                label=f"{LABELS[algorithm]}, velocity {velocity:.2f}")
    ax.set_ylabel("robot speed")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


FIGURES: tuple[tuple[str, str], ...] = (
    ("illustration1_2010_rot0.png", "Illustration 1"),
    ("illustration2_2010_rot029.png", "Illustration 2"),
    ("illustration3_2010_nonclip_limit.png", "Illustration 3"),
    ("illustration4_2011_rot0.png", "Illustration 4"),
    ("illustration5_2011_rot029.png", "Illustration 5"),
    ("illustration6_speed_vs_heading_v050.png", "Illustration 6"),
    ("illustration7_speed_vs_heading_v071.png", "Illustration 7"),
    ("max_speed_scaled_rot0.png", "max_speed_scaled"),
    ("max_speed_scaled_rot029.png", "max_speed_scaled"),
    ("cartesian_rot0.png", "cartesian"),
    ("cartesian_rot029.png", "cartesian"),
)
"""(file name, title) of every figure :func:`figures` builds and :func:`render_all` writes,
in order."""


def figure(name: str) -> Any:
    """Build the figure of :data:`FIGURES` whose file name is ``name`` (a matplotlib Figure;
    the caller saves and closes it: ``plt.close(fig)``). KeyError for another name.

    Surfaces: robot speed (fraction of full wheel speed) over commanded velocity [0, 1] and
    heading, drawn with x to the right and y forward. Curves: robot speed or the 2010
    non-clipping velocity against heading, degrees clockwise from the nose.
    """
    title = dict(FIGURES)[name]
    surfaces = {
        "illustration1_2010_rot0.png": ("holonomic_2010", 0.0),
        "illustration2_2010_rot029.png": ("holonomic_2010", ROTATION),
        "illustration4_2011_rot0.png": ("polar_2011", 0.0),
        "illustration5_2011_rot029.png": ("polar_2011", ROTATION),
        "max_speed_scaled_rot0.png": ("max_speed_scaled", 0.0),
        "max_speed_scaled_rot029.png": ("max_speed_scaled", ROTATION),
        "cartesian_rot0.png": ("cartesian", 0.0),
        "cartesian_rot029.png": ("cartesian", ROTATION),
    }
    curves = {
        # Seed 000: the 2011 algorithm at velocity 0.50 gives what 2010 gives at sqrt(2)/2.
        "illustration6_speed_vs_heading_v050.png": [
            ("polar_2011", 0.50), ("holonomic_2010", SQRT2_2)],
        "illustration7_speed_vs_heading_v071.png": [
            ("polar_2011", SQRT2_2), ("holonomic_2010", SQRT2_2),
            ("max_speed_scaled", SQRT2_2), ("cartesian", SQRT2_2)],
    }
    if name in surfaces:
        return _surface(*surfaces[name], title)
    if name in curves:
        return _curves(curves[name], title)
    return _limit(title)


def figures() -> Iterator[tuple[str, Any]]:
    """Each figure of :data:`FIGURES`, in order, as ``(file name, Figure)``, built one at a
    time (:func:`figure`); the caller saves and closes each."""
    for name, _ in FIGURES:
        yield name, figure(name)


def render_all(out_dir: Path) -> list[Path]:
    """Write every figure of :data:`FIGURES` into ``out_dir`` (created) as PNG at 110 dpi;
    return the paths, in order."""
    plt = _pyplot()
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, fig in figures():
        fig.savefig(out_dir / name, dpi=110)
        plt.close(fig)
        paths.append(out_dir / name)
    return paths
