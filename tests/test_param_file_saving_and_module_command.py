"""Parameter files (io/paramfile.py): saving into a file that is not there yet or holds a
value that does not read, and ``python -m mecanum_mav.params`` with one option or none."""

from __future__ import annotations

from pathlib import Path

import pytest

from mecanum_mav.config.params import Params, markdown_table
from mecanum_mav.io.paramfile import format_text, load, main, save_keeping_layout


def test_saving_into_a_file_that_does_not_exist_yet_writes_every_parameter(tmp_path: Path):
    path = tmp_path / "rover.parm"
    params = Params({"GEO_HALF_LEN": 0.25})
    save_keeping_layout(params, path)
    assert path.read_text(encoding="utf-8") == format_text(params)
    assert load(path) == params
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rover.parm"]  # no .bak


def test_a_line_whose_value_does_not_read_gets_the_parameters_value_and_keeps_its_comment(
        tmp_path: Path):
    """A value edited by hand into the file while the rover ran (the file would not load):
    the next save writes the parameter's value there, so the file loads again."""
    path = tmp_path / "rover.parm"
    path.write_text("# my base\nGEO_HALF_LEN wide  # wheelbase\nOUT_RATE 25\n", encoding="utf-8")
    params = Params({"GEO_HALF_LEN": 0.2, "OUT_RATE": 25})
    save_keeping_layout(params, path)
    assert path.read_text(encoding="utf-8") == \
        "# my base\nGEO_HALF_LEN 0.2  # wheelbase\nOUT_RATE 25\n"
    assert load(path) == params


def test_the_module_command_without_an_option_prints_its_help_and_writes_nothing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch):
    monkeypatch.chdir(tmp_path)
    assert main([]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: python -m mecanum_mav.params [-h] [--table]")
    assert "--write-defaults PATH" in out and "| `" not in out
    assert list(tmp_path.iterdir()) == []


def test_the_module_command_does_only_what_it_is_asked(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]):
    assert main(["--table"]) == 0
    assert capsys.readouterr().out == markdown_table()
    assert main(["--write-defaults", str(tmp_path / "d.parm")]) == 0
    assert capsys.readouterr().out == ""
    assert load(tmp_path / "d.parm") == Params()


def test_the_documented_module_command_regenerates_the_committed_default_file(tmp_path: Path):
    """docs/development.md: ``python -m mecanum_mav.params --write-defaults
    params/default.parm``, run as a user runs it (a process of its own)."""
    import subprocess
    import sys

    out = tmp_path / "default.parm"
    done = subprocess.run([sys.executable, "-m", "mecanum_mav.params", "--write-defaults",
                           str(out)], capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0, done.stderr
    committed = Path(__file__).resolve().parent.parent / "params" / "default.parm"
    assert out.read_text(encoding="utf-8") == committed.read_text(encoding="utf-8")
