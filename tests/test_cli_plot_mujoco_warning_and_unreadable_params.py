"""The command line (app/cli.py): ``plot``'s output and its missing-matplotlib refusal, the
warning of a MuJoCo chassis too slow for real time (docs/commands.md: "warns below 3x"), and a
``--params`` that cannot be read."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pytest

from mecanum_mav.app import cli, plots
from mecanum_mav.sim.physics import MIN_REAL_TIME_FACTOR


def test_plot_prints_the_path_of_every_figure_it_wrote_one_a_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch):
    asked: list[Path] = []

    def render_all(out_dir: Path) -> list[Path]:  # (the real one takes seconds: test_envelope)
        asked.append(out_dir)
        return [out_dir / name for name, _ in plots.FIGURES]

    monkeypatch.setattr(plots, "render_all", render_all)
    assert cli.main(["plot", "--out", str(tmp_path / "figs")]) == 0
    assert asked == [tmp_path / "figs"]
    assert capsys.readouterr().out.splitlines() == [
        str(tmp_path / "figs" / name) for name, _ in plots.FIGURES]


def test_plot_without_matplotlib_exits_2_with_the_install_hint(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # (import matplotlib raises)
    assert cli.main(["plot", "--out", str(tmp_path)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == ("mecanum-mav plot: plotting needs matplotlib: pip install "
                            "'mecanum-mav[plot]'\n")
    assert list(tmp_path.iterdir()) == []


def test_a_mujoco_chassis_slower_than_the_minimum_real_time_factor_is_warned_of_and_runs(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch):
    slow = MIN_REAL_TIME_FACTOR - 1.5
    served: list[dict[str, Any]] = []
    monkeypatch.setattr(cli, "mujoco_real_time_factor", lambda params: slow)
    monkeypatch.setattr(cli, "serve", lambda *args, **options: served.append(options) or 0)
    assert cli.main(["sim", "--physics", "mujoco", "--gcs", "udpout:127.0.0.1:9"]) == 0
    captured = capsys.readouterr()
    assert f"MuJoCo chassis: {slow:.1f}x real time\n" in captured.out
    assert captured.err == (
        f"mecanum-mav sim: warning: the MuJoCo chassis runs only {slow:.1f}x real time (under "
        f"{MIN_REAL_TIME_FACTOR:g}x): a busy machine may make it fall behind\n")
    assert [options["physics"] for options in served] == ["mujoco"]  # it still runs


def test_a_params_path_that_cannot_be_read_exits_2_naming_the_error(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    assert cli.main(["params", "--params", str(tmp_path)]) == 2  # a folder
    err = capsys.readouterr().err
    assert err.startswith("mecanum-mav: cannot read parameters: ") and str(tmp_path) in err
