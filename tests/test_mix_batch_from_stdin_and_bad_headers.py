"""``mecanum-mav mix --batch`` (docs/commands.md, mix): commands read from standard input, one
answer line each on standard output; a CSV header naming a column that is not one of ``x, y,
rotation, heading_deg, magnitude, direction_deg, algo`` stops the batch (status 1) before any
wheel value. In process: the command line's ``main`` with standard input replaced."""

from __future__ import annotations

import io
import json

import pytest

from mecanum_mav.app.cli import main


def mix_batch(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
              text: str) -> tuple[int, list[str], str]:
    monkeypatch.setattr("sys.stdin", io.StringIO(text))
    code = main(["mix", "--batch"])
    out = capsys.readouterr()
    return code, out.out.splitlines(), out.err


def test_mix_batch_reads_stdin_and_answers_each_command_on_stdout(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    code, lines, err = mix_batch(capsys, monkeypatch, "x,y\n1,0\n0,0\n")
    assert code == 0 and err == ""
    assert lines[0] == "w_fl,w_fr,w_rl,w_rr,pwm_fl,pwm_fr,pwm_rl,pwm_rr,error"
    assert lines[1:] == ["1.0,1.0,1.0,1.0,2000,2000,2000,2000,",
                         "0.0,0.0,0.0,0.0,1500,1500,1500,1500,"]


def test_a_header_naming_an_unknown_column_stops_the_batch_before_any_wheel_value(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    code, lines, err = mix_batch(capsys, monkeypatch, "x,speed,rotation\n1,0.5,0\n")
    assert code == 1
    assert err == "line 1: unknown column(s) speed\n"
    assert lines == []


def test_a_header_naming_several_unknown_columns_lists_them_all(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    code, lines, err = mix_batch(capsys, monkeypatch, "x,speed,turn\n1,0.5,0\n")
    assert (code, lines) == (1, [])
    assert err == "line 1: unknown column(s) speed, turn\n"


@pytest.mark.parametrize("desat", [[], ["--desat", "proportional"],
                                   ["--desat", "rotation_priority"],
                                   ["--desat", "translation_priority"]])
def test_a_batch_mixes_each_command_as_mix_does_the_same_command_with_the_same_desat(
        desat: list[str], capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Full forward and full rotation saturate: the desaturation chosen decides the wheels,
    for a batch line as for the flags (default: parameter MIX_DESAT)."""
    assert main(["mix", "--algo", "cartesian", "-x", "1", "-r", "1", "--json", *desat]) == 0
    single = json.loads(capsys.readouterr().out)["wheels"]
    monkeypatch.setattr("sys.stdin", io.StringIO("1,0,1\n"))
    assert main(["mix", "--batch", "--algo", "cartesian", *desat]) == 0
    line = capsys.readouterr().out.strip()
    assert [float(c) for c in line.split(",")[:4]] == single
