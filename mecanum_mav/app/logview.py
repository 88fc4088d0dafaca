"""``mecanum-mav log FILE.tlog [--png OUT]``: look at a drive.

Reads a tlog (:mod:`mecanum_mav.io.tlog`: recorded with ``--tlog``, by MAVProxy or by Mission
Planner, of this companion or of any flight controller), analyses it
(:mod:`mecanum_mav.app.loganalysis`), prints a short summary (distance, time per mode, the
failsafes, the worst cross-track per mission leg) and draws a PNG: the path (odometry, the
simulator's true pose where the log has it, the planned mission; east m on x, north m on y),
and on one time axis the stick input (MANUAL_CONTROL and the pilot's RC overrides, each
labelled by its source), the PWM (the companion's RC_CHANNELS_OVERRIDE and SERVO_OUTPUT_RAW;
the normalized wheel commands are not on the wire, so PWM is shown) and the mission progress,
with the modes as shaded bands and the failsafes as red lines. Positions are (north, east)
metres in the printed tables, and say so. A stick series breaks where its samples stop for
longer than the input timeout (:data:`~mecanum_mav.app.loganalysis.INPUT_TIMEOUT_S`): each
sample is drawn until the next one or for that long, whichever is first, as the rover holds
it; a PWM series likewise with the flight controller's override timeout
(:data:`~mecanum_mav.app.loganalysis.OVERRIDE_TIMEOUT_S`). Needs matplotlib for the PNG (the
``plot`` extra); the summary does not.

Damaged parts of the file are reported on stderr, each with its byte range, and the rest is
read: exit status 0 when any message was read, 2 when none (unreadable, empty, or not a tlog).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TextIO

from mecanum_mav.app.loganalysis import (
    INPUT_TIMEOUT_S,
    OVERRIDE_TIMEOUT_S,
    LogAnalysis,
    ModeSpan,
    analyse,
)
from mecanum_mav.config.params import Params
from mecanum_mav.io.tlog import TlogRead, read_tlog
from mecanum_mav.protocol.dialect import mavlink

__all__ = ["default_png", "gapped", "log_figure", "plot_log", "run_log", "summary"]

MODE_COLOURS = {"MANUAL": "tab:green", "HOLD": "tab:gray", "AUTO": "tab:blue",
                "GUIDED": "tab:purple"}
"""Band colours of the Rover modes; other modes cycle through the rest."""
_OTHER_COLOURS = ("tab:olive", "tab:cyan", "tab:brown", "tab:pink")
NO_OVERRIDE = (0, 65535, 65534)
"""RC_CHANNELS_OVERRIDE values that carry no pulse (leave alone / release)."""
MAX_CHANNELS = 8
"""PWM channels drawn at most per source."""
STICK_AXES = ("x forward", "y right", "r clockwise")
"""The stick panel's axes, in the order of a stick sample's values."""
_SOURCE_STYLES = ("-", "--", "-.", ":")


def default_png(tlog: Path) -> Path:
    """Where the PNG goes without ``--png``: beside the tlog, ``.png`` for its suffix."""
    return tlog.with_suffix(".png")


def _severity(value: int) -> str:
    entry = mavlink.enums["MAV_SEVERITY"].get(value)
    return entry.name.removeprefix("MAV_SEVERITY_") if entry is not None else str(value)


def summary(read: TlogRead, a: LogAnalysis) -> str:
    """The printed summary of a tlog."""
    when = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(a.start_unix_s))
    vehicle = f"; vehicle {a.vehicle[0]}/{a.vehicle[1]}" if a.vehicle else "; no vehicle found"
    lines = [f"{read.name}: {a.messages} messages over {a.duration_s:.1f} s from {when}"
             f"{vehicle}"]
    if read.unknown:
        lines.append(f"{read.unknown} packets of message ids this dialect does not know "
                     f"(skipped)")
    if a.path:
        line = f"distance {a.distance_m:.2f} m ({a.path_source})"
        if a.true_path:
            line += f"; true path {a.true_distance_m:.2f} m (simulator)"
        lines.append(line)
    else:
        lines.append("distance: no position in the log")
    if a.modes:
        per_mode = ", ".join(f"{mode} {s:.1f} s" for mode, s in a.time_per_mode().items())
        lines.append(f"modes: {per_mode}; armed {a.armed_s():.1f} s")
    else:
        lines.append("modes: no HEARTBEAT from the vehicle")
    failsafes = a.failsafes
    lines.append(f"failsafes: {len(failsafes)}")
    lines += [f"  {e.time_s:8.2f} s  {_severity(e.severity):<9} {e.text}" for e in failsafes]
    if a.planned:
        reached = ", ".join(str(seq) for _, seq in a.reached) or "none"
        lines.append(f"mission: {len(a.planned)} positions; reached items: {reached}")
    if a.legs:
        lines.append(f"{'leg':<4}{'item':>5}  {'from (N, E) m':>16} -> {'to (N, E) m':<16}"
                     f"{'time s':>8}{'worst cross-track cm':>22}")
        for k, leg in enumerate(a.legs, start=1):
            lines.append(f"{k:<4}{leg.seq:>5}  {_ne(leg.start):>16} -> {_ne(leg.goal):<16}"
                         f"{leg.time_s:8.2f}{leg.max_cross_track_m * 100:22.2f}")
    return "\n".join(lines)


def _ne(position: tuple[float, float]) -> str:
    """A (north, east) position in metres as the tables print it."""
    return f"({position[0]:.2f}, {position[1]:.2f})"


def gapped(samples: Sequence[Sequence[float]], timeout_s: float) -> list[tuple[float, ...]]:
    """``samples`` ((time s, value, ...), in time order) ready for a step plot (``where=
    "post"``) that breaks where they stop: after a sample followed by none within
    ``timeout_s`` (or by none at all), a row at its time + ``timeout_s`` whose values are NaN.
    So each sample is drawn until the next or for ``timeout_s``, whichever is first, and
    nothing is drawn across the gap."""
    out: list[tuple[float, ...]] = []
    for k, row in enumerate(samples):
        out.append(tuple(row))
        t = row[0]
        if k + 1 == len(samples) or samples[k + 1][0] - t > timeout_s:
            out.append((t + timeout_s, *([math.nan] * (len(row) - 1))))
    return out


def _mode_colour(mode: str, seen: dict[str, str]) -> str:
    if mode not in seen:
        seen[mode] = MODE_COLOURS.get(mode, _OTHER_COLOURS[len(seen) % len(_OTHER_COLOURS)])
    return seen[mode]


def _bands(ax: Any, spans: list[ModeSpan], colours: dict[str, str], *, label: bool) -> None:
    labelled: set[str] = set()
    for span in spans:
        name = span.mode + ("" if span.armed else " (disarmed)")
        ax.axvspan(span.start_s, span.end_s, color=_mode_colour(span.mode, colours),
                   alpha=0.15 if span.armed else 0.05, lw=0,
                   label=name if label and name not in labelled else None)
        labelled.add(name)


def _varying(series: list[tuple[float, list[int]]]) -> list[int]:
    """Channel indices (0-based) that carry pulses and change, at most MAX_CHANNELS."""
    out = []
    for ch in range(len(series[0][1]) if series else 0):
        values = {row[ch] for _, row in series} - set(NO_OVERRIDE)
        if len(values) > 1:
            out.append(ch)
    return out[:MAX_CHANNELS]


def _steps(ax: Any, series: list[tuple[float, list[int]]], style: str, prefix: str) -> None:
    for ch in _varying(series):
        points = [(t, row[ch]) for t, row in series if row[ch] not in NO_OVERRIDE]
        if points:
            t, v = zip(*gapped(points, OVERRIDE_TIMEOUT_S), strict=True)
            ax.step(t, v, style, where="post", lw=1.0, color=f"C{ch % 10}",
                    label=f"{prefix} ch{ch + 1}")


def _stick_sources(a: LogAnalysis) -> dict[str, list[tuple[float, float, float, float]]]:
    """Source label -> (time, x, y, r) of every stick input in the log."""
    sources = {"MANUAL_CONTROL": a.sticks} if a.sticks else {}
    for sender, sticks in a.pilot_sticks.items():
        sources[f"RC override {sender}"] = sticks
    return sources


def log_figure(a: LogAnalysis, title: str) -> Any:
    """The matplotlib figure of the analysis (see the module docstring for what is drawn); its
    axes are the path, the sticks, the PWM and the mission progress, in that order."""
    from mecanum_mav.app.plots import _pyplot

    plt = _pyplot()
    fig = plt.figure(figsize=(14, 7.5))
    grid = fig.add_gridspec(3, 2, width_ratios=(1.0, 1.45))
    ax_path = fig.add_subplot(grid[:, 0])
    ax_stick = fig.add_subplot(grid[0, 1])
    ax_pwm = fig.add_subplot(grid[1, 1], sharex=ax_stick)
    ax_mission = fig.add_subplot(grid[2, 1], sharex=ax_stick)

    if a.planned:
        _, pn, pe = zip(*a.planned, strict=True)
        ax_path.plot(pe, pn, "o--", color="0.6", label="planned mission")
        for seq, n, e in a.planned:
            ax_path.annotate(str(seq), (e, n), textcoords="offset points", xytext=(5, 5),
                             color="0.4", fontsize=8)
    if a.true_path:
        _, tn, te = zip(*a.true_path, strict=True)
        ax_path.plot(te, tn, "-", color="tab:blue", lw=2.5, alpha=0.5,
                     label="true pose (simulator)")
    if a.path:
        _, on, oe = zip(*a.path, strict=True)
        ax_path.plot(oe, on, "-", color="tab:orange", lw=1.0, label=a.path_source.lower())
        ax_path.plot(oe[0], on[0], "k^", label="start")
    ax_path.set_xlabel("east m")
    ax_path.set_ylabel("north m")
    ax_path.set_aspect("equal", adjustable="datalim")
    ax_path.grid(True, alpha=0.3)
    if a.planned or a.path or a.true_path:
        ax_path.legend(loc="best", fontsize=8)
    ax_path.set_title(f"path: {a.distance_m:.2f} m" if a.path else "path: no position")

    colours: dict[str, str] = {}
    for ax in (ax_stick, ax_pwm, ax_mission):
        _bands(ax, a.modes, colours, label=ax is ax_mission)
        for event in a.failsafes:
            ax.axvline(event.time_s, color="tab:red", ls="--", lw=1.0)
        ax.grid(True, alpha=0.3)
    for event in a.failsafes:
        ax_stick.annotate(event.text, (event.time_s, 1.0), xycoords=("data", "axes fraction"),
                          rotation=90, va="top", ha="right", fontsize=7, color="tab:red")

    sources = _stick_sources(a)
    for k, (source, sticks) in enumerate(sources.items()):
        t, *axes = zip(*gapped(sticks, INPUT_TIMEOUT_S), strict=True)
        for n, (name, values) in enumerate(zip(STICK_AXES, axes, strict=True)):
            ax_stick.step(t, values, _SOURCE_STYLES[k % len(_SOURCE_STYLES)], where="post",
                          color=f"C{n}", label=f"{name} ({source})")
    if sources:
        ax_stick.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    ax_stick.set_ylim(-1.1, 1.1)
    ax_stick.set_ylabel("stick input")

    for label, series in a.overrides.items():
        _steps(ax_pwm, series, "-", f"companion override {label}")
    _steps(ax_pwm, a.servo, ":", "SERVO_OUTPUT_RAW")
    ax_pwm.set_ylabel("PWM (us)")
    if ax_pwm.lines:
        ax_pwm.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=6)

    if a.mission_current:
        t_cur, seq_cur = zip(*a.mission_current, strict=True)
        ax_mission.step([*t_cur, a.duration_s], [*seq_cur, seq_cur[-1]], where="post",
                        color="tab:blue", label="current item")
    if a.reached:
        t_reached, seq_reached = zip(*a.reached, strict=True)
        ax_mission.plot(t_reached, seq_reached, "kx", label="item reached")
    ax_mission.set_ylabel("mission item")
    ax_mission.set_xlabel("time (s from the log's start)")
    ax_mission.set_xlim(0.0, max(a.duration_s, 1e-3))
    ax_mission.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    worst = max((leg.max_cross_track_m for leg in a.legs), default=None)
    ax_mission.set_title("mission progress" + (
        f": worst cross-track {worst * 100:.1f} cm" if worst is not None else ""), fontsize=9)

    fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_log(a: LogAnalysis, path: Path, title: str) -> Path:
    """Draw the analysis (:func:`log_figure`) to ``path`` (PNG)."""
    from mecanum_mav.app.plots import _pyplot

    plt = _pyplot()
    fig = log_figure(a, title)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def run_log(tlog: Path, png: Path | None, out: TextIO | None = None,
            err: TextIO | None = None, *, rerun: Path | None = None, view: bool = False,
            params: Params | None = None, web_port: int = 9090) -> int:
    """The ``log`` command: summary to ``out`` (stdout), problems to ``err`` (stderr), the
    PNG to ``png`` (its default beside the tlog); with ``rerun`` the Rerun view to that
    ``.rrd``, with ``view`` that view opened (:mod:`~mecanum_mav.app.view`; ``params``: the
    PWM map and chassis size), and then the PNG only when ``png`` is given (drawing it takes
    most of a long log's time). Returns the exit status: 1 when the PNG asked for with
    ``png`` could not be drawn or written (no matplotlib, an unwritable path; the summary is
    printed all the same), 0 when only the default one beside the tlog could not."""
    out = out or sys.stdout
    err = err or sys.stderr
    from mecanum_mav.app.view import gc_paused

    with gc_paused(keep=True):
        read = read_tlog(tlog)
    for problem in read.problems:
        print(f"mecanum-mav log: {problem}", file=err)
    if not read.entries:
        print(f"mecanum-mav log: {tlog}: no MAVLink messages read", file=err)
        return 2
    viewing = rerun is not None or view
    asked_png_failed = False

    def report() -> None:  # the summary, and the PNG unless a view was asked without one
        nonlocal asked_png_failed
        analysis = analyse(read.entries)
        print(summary(read, analysis), file=out)
        if png is not None or not viewing:
            target = png or default_png(tlog)
            try:
                print(f"wrote {plot_log(analysis, target, tlog.name)}", file=out)
                return
            except RuntimeError as exc:  # no matplotlib
                print(f"mecanum-mav log: no PNG: {exc}", file=err)
            except OSError as exc:
                print(f"mecanum-mav log: cannot write {target}: {exc}", file=err)
            asked_png_failed = png is not None

    if not viewing:
        report()
        return int(asked_png_failed)
    from mecanum_mav.app.view import show_log

    # (the view first: a long log's summary comes while the viewer is already up)
    status = show_log(read.entries, params or Params(), rerun, view, web_port, out, err,
                      then=report)
    return status or int(asked_png_failed)
