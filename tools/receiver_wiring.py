"""Draw the wiring of an RC receiver through the flight controller (docs/receiver_wiring.png).

    python tools/receiver_wiring.py [OUT.png]

The receiver's sticks and switches on channels 1-8 reach the companion in RC_CHANNELS; the
companion's wheel commands come back as RC overrides on channels 9-12, which the flight
controller passes through to the four ESCs (SERVO9..12_FUNCTION 148..151, RCIN9..12Scaled).
"""

from __future__ import annotations

import sys
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import FancyBboxPatch


def box(ax: Any, x: float, y: float, w: float, h: float, title: str, lines: list[str],
        colour: str) -> None:
    ax.add_patch(FancyBboxPatch((x, y), w, h, boxstyle="round,pad=0.02", fc=colour,
                                ec="black", lw=1.2))
    ax.text(x + w / 2, y + h - 0.04, title, ha="center", va="top", fontsize=11,
            fontweight="bold")
    for i, line in enumerate(lines):
        ax.text(x + 0.08, y + h - 0.36 - i * 0.21, line, ha="left", va="top", fontsize=8.5,
                family="monospace")


def arrow(ax: Any, x0: float, y0: float, x1: float, y1: float, label: str) -> None:
    ax.annotate("", xy=(x1, y1), xytext=(x0, y0),
                arrowprops={"arrowstyle": "-|>", "lw": 1.6})
    ax.text((x0 + x1) / 2, (y0 + y1) / 2 + 0.05, label, ha="center", va="bottom",
            fontsize=8.5)


def main(out: str = "docs/receiver_wiring.png") -> None:
    fig, ax = plt.subplots(figsize=(11, 4.6))
    ax.set_xlim(0, 11)
    ax.set_ylim(0, 4.6)
    ax.axis("off")
    box(ax, 0.2, 2.3, 2.2, 1.9, "RC receiver", ["ch1 steering", "ch3 throttle",
                                                  "ch4 lateral", "ch7 arm switch",
                                                  "ch8 mode switch", "(9-12 unused)"],
        "#fde9c9")
    box(ax, 3.5, 1.2, 3.0, 3.1, "ArduPilot flight controller",
        ["RC IN (SBUS/PPM): ch1-8", "RC_CHANNELS -> companion", "overrides ch9-12 <-",
         "SERVO9..12_FUNCTION", "  148..151 (RCIN9..12Scaled)", "SERVO_RC_FS_MSK bits 8-11",
         "RCMAP_THROTTLE 9", "RC_OVERRIDE_TIME 0.5"], "#dbe9f7")
    box(ax, 7.7, 2.6, 3.0, 1.7, "mecanum-mav companion",
        ["RCIN_ENABLE 1", "RCMAP_* 1, 3, 4", "RCIN_ARM_CH 7, MODE_CH 8", "MOT_FL..RR_CH 9..12"],
        "#e2f3dc")
    box(ax, 7.7, 0.2, 3.0, 1.9, "four ESCs", ["SERVO9  -> front-left", "SERVO10 -> front-right",
                                             "SERVO11 -> rear-left", "SERVO12 -> rear-right"],
        "#f2dede")
    ax.text(5.6, 4.45, "ground station (MAVLink) -> companion: its fresh sticks take over",
            ha="center", fontsize=8.5, style="italic")
    arrow(ax, 2.45, 3.3, 3.45, 3.3, "pulses")
    arrow(ax, 6.55, 3.6, 7.65, 3.6, "RC_CHANNELS\n25 Hz")
    arrow(ax, 7.65, 2.75, 6.55, 2.75, "overrides\n9-12")
    arrow(ax, 6.55, 1.5, 7.65, 1.2, "PWM 9-12")
    fig.savefig(out, dpi=110, bbox_inches="tight")
    print(out)


if __name__ == "__main__":
    main(*sys.argv[1:2])
