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


def test_saving_into_a_file_with_a_byte_order_mark_and_non_utf8_comments_changes_only_the_value(
        tmp_path: Path):
    """A file last saved by a Windows editor (a UTF-8 byte order mark) with a Latin-1 comment:
    the first line is a parameter like any other, and every byte but the new value stays."""
    path = tmp_path / "rover.parm"
    old = b"\xef\xbb\xbfGEO_HALF_LEN 0.2\n# r\xe9glage de l'\xe9quipe\nOUT_RATE 25\n"
    path.write_bytes(old)
    save_keeping_layout(Params({"GEO_HALF_LEN": 0.25, "OUT_RATE": 25}), path)
    assert path.read_bytes() == old.replace(b"0.2\n", b"0.25\n")
    assert (tmp_path / "rover.parm.bak").read_bytes() == old
    assert load(path) == Params({"GEO_HALF_LEN": 0.25, "OUT_RATE": 25})


def test_saving_unchanged_parameters_into_a_file_with_a_byte_order_mark_leaves_it_alone(
        tmp_path: Path):
    path = tmp_path / "rover.parm"
    path.write_bytes(b"\xef\xbb\xbfGEO_HALF_LEN 0.2\n# \xe9\n")
    save_keeping_layout(Params({"GEO_HALF_LEN": 0.2}), path)
    assert path.read_bytes() == b"\xef\xbb\xbfGEO_HALF_LEN 0.2\n# \xe9\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rover.parm"]  # no .bak


def test_the_module_commands_help_says_what_each_option_does(
        capsys: pytest.CaptureFixture[str]):
    with pytest.raises(SystemExit) as exit_:
        main(["--help"])
    assert exit_.value.code == 0
    lines = [" ".join(line.split()) for line in capsys.readouterr().out.splitlines()]
    assert "Generate files from the schema." in lines
    assert "--table print the parameter reference table" in lines
    assert lines[lines.index("--write-defaults PATH") + 1] == "write the defaults file"


def test_the_written_header_has_no_trailing_spaces_on_its_blank_lines(tmp_path: Path):
    text = format_text(Params(), header="first\n\nthird")
    assert text.startswith("# first\n#\n# third\n")
    assert all(line == line.rstrip() for line in text.splitlines())
