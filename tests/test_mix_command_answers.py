"""What ``mecanum-mav mix`` answers, as docs/commands.md (mix) says: the table and ``--json``
of one command, a field-oriented command's heading, the errors that name what is wrong, and
a batch's answers to good and bad lines (CSV: eight empty cells and the error; JSON lines:
``{"line", "error"}``; the exit status 1 once any line failed)."""

from __future__ import annotations

import csv
import io
import json
import math

import pytest

from mecanum_mav.app.cli import main
from mecanum_mav.app.mixcommand import (
    CSV_COLUMNS,
    CommandError,
    run_batch,
    stick_from_fields,
)
from mecanum_mav.config.params import Params
from mecanum_mav.mecanum.desaturation import Desaturation
from mecanum_mav.mecanum.mixing import ALGORITHM_NAMES


def mix(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["mix", *argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def batch(text: str, algo: str = "cartesian") -> tuple[int, list[str], str]:
    out, err = io.StringIO(), io.StringIO()
    code = run_batch(io.StringIO(text), out, err, Params(), algo, Desaturation.PROPORTIONAL)
    return code, out.getvalue().splitlines(), err.getvalue()


def test_the_table_names_the_algorithm_and_desaturation_then_a_row_per_wheel(capsys):
    code, out, _ = mix(capsys, "-x", "0.5", "-y", "0.25", "--algo", "cartesian",
                       "--desat", "translation_priority")
    lines = out.splitlines()
    assert code == 0
    assert lines[:2] == ["algorithm cartesian, desaturation translation_priority",
                         "wheel  command    PWM us  channel"]
    assert [line.split() for line in lines[2:]] == [
        ["FL", "+0.7500", "1875", "1"], ["FR", "+0.2500", "1625", "2"],
        ["RL", "+0.2500", "1625", "3"], ["RR", "+0.7500", "1875", "4"]]


def test_a_field_oriented_command_is_turned_by_the_robots_heading(capsys):
    """``-x 1 --heading 90``: north while the robot faces east is its left."""
    code, out, _ = mix(capsys, "-x", "1", "--heading", "90", "--algo", "cartesian", "--json")
    assert code == 0
    assert json.loads(out)["wheels"] == [-1.0, 1.0, 1.0, -1.0]  # strafe left
    plain = json.loads(mix(capsys, "-y", "-1", "--algo", "cartesian", "--json")[1])
    assert plain["wheels"] == [-1.0, 1.0, 1.0, -1.0]


def test_polar_fields_are_magnitude_and_direction_clockwise_from_the_nose():
    x, y, rotation, heading = stick_from_fields(
        {"magnitude": "0.5", "direction_deg": "90", "rotation": "0.25", "heading_deg": "30"})
    assert (x, y) == pytest.approx((0.0, 0.5), abs=1e-12)
    assert (rotation, heading) == (0.25, 30.0)
    assert stick_from_fields({"y": "0.5"}) == (0.0, 0.5, 0.0, 0.0)  # missing fields are 0
    assert stick_from_fields({"magnitude": 1, "direction_deg": ""}) == (1.0, 0.0, 0.0, 0.0)
    assert stick_from_fields({"x": ""}) == (0.0, 0.0, 0.0, 0.0)


def test_each_error_names_what_is_wrong_and_what_is_known():
    with pytest.raises(CommandError) as unknown:
        stick_from_fields({"x": 1, "speed": 2, "bogus": 3})
    assert str(unknown.value) == (f"unknown field(s) bogus, speed; known: "
                                  f"{', '.join(CSV_COLUMNS)}")
    with pytest.raises(CommandError, match=r"^give x/y or magnitude/direction_deg, not both$"):
        stick_from_fields({"y": 0.1, "direction_deg": 10})
    code, lines, _ = batch('{"x": 1, "algo": "tank"}\n')
    assert code == 1 and json.loads(lines[0])["error"] == (
        f"unknown algorithm 'tank'; known: {', '.join(ALGORITHM_NAMES)}")
    code, lines, _ = batch("1,2,3,4,5\n")
    assert next(csv.reader(lines)) == [""] * 8 + [
        "expected at most 4 values (x,y,rotation,heading_deg), got 5"]


def test_a_batch_answers_a_bad_csv_line_with_eight_empty_cells_and_the_error():
    code, lines, err = batch("x,y\nabc,0\n")
    assert code == 1
    assert lines[1] == ",,,,,,,,x: not a number: 'abc'"
    assert err == "line 2: x: not a number: 'abc'\n"


def test_a_batch_answers_a_bad_json_line_with_its_line_number_and_error_and_a_good_one_with_pwm():
    code, lines, _ = batch('{"x": 0.5}\n{"x": "nan"}\n')
    assert code == 1
    assert json.loads(lines[0]) == {"algorithm": "cartesian", "wheels": [0.5] * 4,
                                    "pwm": [1750] * 4}
    assert json.loads(lines[1]) == {"line": 2, "error": "x: must be finite, got 'nan'"}


def test_one_bad_line_among_good_ones_still_makes_the_batch_exit_1():
    assert batch("0,0\nabc,0\n0.5,0\n0,0\n")[0] == 1
    assert batch("0,0\n0.5,0\n")[0] == 0


def test_without_a_header_a_polar_batch_reads_magnitude_direction_rotation_heading():
    code, lines, _ = batch("1,180,0,180\n", algo="polar_2011")  # back, seen from the south
    wheels = [float(c) for c in lines[0].split(",")[:4]]
    assert code == 0 and wheels == pytest.approx([1.0, 1.0, 1.0, 1.0])
    code, lines, _ = batch("1,0,0,90\n")  # cartesian: x, y, rotation, heading_deg
    wheels = [float(c) for c in lines[0].split(",")[:4]]
    assert code == 0 and wheels == pytest.approx([-1.0, 1.0, 1.0, -1.0])  # north: its left


def test_a_line_whose_first_cell_is_a_column_name_is_a_header_only_before_any_command():
    code, lines, _ = batch("heading_deg,x\n90,1\n")
    assert code == 0 and lines[0].startswith("w_fl,") and len(lines) == 2
    assert [float(c) for c in lines[1].split(",")[:4]] == pytest.approx(
        [-1.0, 1.0, 1.0, -1.0])
    assert math.isfinite(float(lines[1].split(",")[4]))


def test_a_stopped_wheel_is_answered_as_zero_never_minus_zero(capsys):
    """On a diagonal two wheels stop; a ``-0`` would read as "backwards" in the table's sign
    column and as ``-0.0`` in JSON."""
    code, out, _ = mix(capsys, "--algo", "cartesian", "-m", "1", "-d", "225", "--json")
    assert code == 0 and '"wheels": [-1.0, 0.0, 0.0, -1.0]' in out
    code, out, _ = mix(capsys, "--algo", "cartesian", "-m", "1", "-d", "315")
    assert code == 0 and "-0.0000" not in out and out.count("+0.0000") == 2
    code, lines, _ = batch("magnitude,direction_deg\n1,225\n")
    assert lines[1].split(",")[:4] == ["-1.0", "0.0", "0.0", "-1.0"]


def test_a_header_with_both_forms_mixes_rows_that_fill_one_and_leave_the_other_empty():
    """Missing fields are 0 (stick_from_fields): an empty CSV cell is a missing field, so a
    row of one form under a header naming both is that form alone."""
    code, lines, err = batch("x,y,magnitude,direction_deg\n1,0,,\n,,1,0\n,,1,90\n")
    assert code == 0 and err == ""
    assert [[float(c) for c in line.split(",")[:4]] for line in lines[1:]] == [
        pytest.approx([1.0] * 4), pytest.approx([1.0] * 4),
        pytest.approx([1.0, -1.0, -1.0, 1.0])]  # right: FL and RR forward


def test_a_batch_answers_one_newline_terminated_line_per_command_csv_and_json_alike():
    out, err = io.StringIO(), io.StringIO()
    run_batch(io.StringIO('x,y\n1,0\n{"x": 1}\nabc,0\n'), out, err, Params(), "cartesian",
              Desaturation.PROPORTIONAL)
    assert "\r" not in out.getvalue()
    assert out.getvalue().endswith("\n") and len(out.getvalue().split("\n")) == 5


def test_a_line_too_long_for_csv_is_answered_with_its_error_and_the_batch_goes_on():
    """A bad line is answered with its error and reported, never a crash of the batch (the
    csv module refuses a cell over 128 KiB)."""
    long_cell = "1" * 200_000
    code, lines, err = batch(f"{long_cell},0\n1,0\n")
    assert code == 1
    assert lines[0] == ",,,,,,,,bad CSV: field larger than field limit (131072)"
    assert lines[1] == "1.0,1.0,1.0,1.0,2000,2000,2000,2000,"
    assert err == "line 1: bad CSV: field larger than field limit (131072)\n"
    code, lines, err = batch(f'{{"x": "{"a" * 200_000}"}}\n')  # (JSON: no CSV limit)
    assert code == 1 and json.loads(lines[0])["error"].startswith("x: not a number: 'aaa")
