"""``mecanum-mav mix --batch`` (docs/commands.md, mix): commands read from standard input, one
answer line each on standard output; a CSV header naming a column that is not one of ``x, y,
rotation, heading_deg, magnitude, direction_deg, algo`` stops the batch (status 1) before any
wheel value. In process: the command line's ``main`` with standard input replaced."""

from __future__ import annotations

import io

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
