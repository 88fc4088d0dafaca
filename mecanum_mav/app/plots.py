"""PNG figures of the speed envelopes (seed 000's Illustrations 1-7, and our mixers).

Needs matplotlib: ``pip install 'mecanum-mav[plot]'``. The numbers come from
:mod:`mecanum_mav.mecanum.envelope`; this module only draws them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mecanum_mav.mecanum.envelope import non_clipping_limit_2010, robot_speed, speed_grid

__all__ = ["FIGURES", "render_all"]

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


def _surface(path: Path, algorithm: str, rotation: float, title: str) -> None:
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
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _limit(path: Path) -> None:
    plt = _pyplot()
    heading = np.linspace(0.0, 360.0, 721)
    fig, ax = plt.subplots(figsize=(7, 4))
    for rotation in (0.0, 0.1, ROTATION, 0.5):
        ax.plot(heading, non_clipping_limit_2010(heading, rotation), label=f"rotation {rotation}")
    ax.set_xlabel("heading (deg clockwise from nose)")
    ax.set_ylabel("largest velocity without clipping")
    ax.set_xticks(range(0, 361, 45))
    ax.set_ylim(0.0, 1.05)
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title("Illustration 3: 2010 algorithm non-clipping limit")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _curves(path: Path, series: list[tuple[str, float]], title: str) -> None:
    plt = _pyplot()
    heading = np.linspace(0.0, 360.0, 721)
    fig, ax = plt.subplots(figsize=(7, 4))
    for (algorithm, velocity), style in zip(series, ("-", "--", ":", "-."), strict=False):
        ax.plot(heading, robot_speed(algorithm, velocity, heading, ROTATION), style,
                label=f"{LABELS[algorithm]}, velocity {velocity:.2f}")
    ax.set_xlabel("heading (deg clockwise from nose)")
    ax.set_ylabel("robot speed")
    ax.set_xticks(range(0, 361, 45))
    ax.set_ylim(0.0, 1.05)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{title}: robot speed vs heading, rotation {ROTATION}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


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
"""(file name, title) of every figure :func:`render_all` writes, in order."""


def render_all(out_dir: Path) -> list[Path]:
    """Write every figure of :data:`FIGURES` into ``out_dir`` (created); return the paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / name for name, _ in FIGURES]
    titles = [title for _, title in FIGURES]
    surfaces = [
        (0, "holonomic_2010", 0.0), (1, "holonomic_2010", ROTATION),
        (3, "polar_2011", 0.0), (4, "polar_2011", ROTATION),
        (7, "max_speed_scaled", 0.0), (8, "max_speed_scaled", ROTATION),
        (9, "cartesian", 0.0), (10, "cartesian", ROTATION),
    ]
    for index, algorithm, rotation in surfaces:
        _surface(paths[index], algorithm, rotation, titles[index])
    _limit(paths[2])
    # Seed 000: the 2011 algorithm at velocity 0.50 gives what 2010 gives at sqrt(2)/2.
    _curves(paths[5], [("polar_2011", 0.50), ("holonomic_2010", SQRT2_2)], titles[5])
    _curves(paths[6], [("polar_2011", SQRT2_2), ("holonomic_2010", SQRT2_2),
                       ("max_speed_scaled", SQRT2_2), ("cartesian", SQRT2_2)], titles[6])
    return paths
