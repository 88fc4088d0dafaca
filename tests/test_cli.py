"""The `mecanum-mav` command line: mix (single and batch), params, plot."""

from __future__ import annotations

import io
import json
import re
import signal
import socket
import subprocess
import sys

import pytest
from sitl import CompanionProcess
from support import wait_until

from mecanum_mav.app import cli
from mecanum_mav.app.cli import main, run_batch
from mecanum_mav.config.params import SCHEMA, Params
from mecanum_mav.mecanum.mixing import Desaturation
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.groundstation import udp_ground_station


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_mix_prints_normalized_wheels_and_pwm_for_a_polar_command(capsys):
    code, out, _ = run(capsys, "mix", "--algo", "polar_2011", "-m", "1", "-d", "90")
    assert code == 0
    rows = {line.split()[0]: line.split()[1:] for line in out.splitlines()[2:]}
    assert rows["FL"][:2] == ["+1.0000", "2000"]
    assert rows["FR"][:2] == ["-1.0000", "1000"]


def test_mix_json_reports_channels_and_desaturation(capsys):
    code, out, _ = run(capsys, "mix", "-x", "1", "-r", "1", "--json", "--desat",
                       "rotation_priority")
    doc = json.loads(out)
    assert code == 0 and doc["desaturation"] == "rotation_priority"
    assert doc["wheels"] == [1.0, -1.0, 1.0, -1.0]  # rotation kept, translation gave way
    assert doc["channels"] == [1, 2, 3, 4]


def test_mix_uses_parameter_file_and_set_overrides(capsys, tmp_path):
    path = tmp_path / "robot.parm"
    path.write_text("MOT_FL_REV 1  # mirrored\nMIX_ALGO,3\n")
    code, out, _ = run(capsys, "mix", "-x", "1", "--params", str(path), "--set",
                       "MOT_RR_MAX=1900", "--json")
    doc = json.loads(out)
    assert code == 0 and doc["algorithm"] == "holonomic_2010"
    assert doc["pwm"][0] < 1500 and doc["pwm"][3] == 1500 + round(0.7071068 * 400)


def test_a_parameter_file_with_a_typo_is_rejected_with_file_line_and_suggestion(capsys, tmp_path):
    path = tmp_path / "typo.parm"
    path.write_text("# robot\nMIX_ALOG 1\n")
    code, _, err = run(capsys, "mix", "-x", "1", "--params", str(path))
    assert code == 2
    assert f"{path}:2:" in err and "MIX_ALGO" in err


def test_a_bad_set_override_is_rejected(capsys):
    code, _, err = run(capsys, "mix", "-x", "1", "--set", "INP_EXPO=7")
    assert code == 2 and "INP_EXPO" in err


def test_mix_rejects_polar_and_cartesian_together(capsys):
    code, _, err = run(capsys, "mix", "-x", "1", "-m", "1")
    assert code == 2 and "not both" in err


def batch(text, algo="cartesian"):
    out, err = io.StringIO(), io.StringIO()
    code = run_batch(io.StringIO(text), out, err, Params(), algo, Desaturation.PROPORTIONAL)
    return code, out.getvalue().splitlines(), err.getvalue()


def test_batch_writes_one_line_per_command_and_a_header_for_a_header():
    code, lines, err = batch("x,y,rotation\n0.5,0,0\n# comment\n\n0,1,0\n")
    assert code == 0 and err == ""
    assert lines[0].startswith("w_fl,w_fr,w_rl,w_rr,pwm_fl")
    assert lines[1:] == ["0.5,0.5,0.5,0.5,1750,1750,1750,1750,",
                         "1.0,-1.0,-1.0,1.0,2000,1000,1000,2000,"]


def test_batch_without_header_reads_the_algorithms_own_columns():
    code, lines, _ = batch("1,90,0\n", algo="polar_2011")
    assert code == 0 and lines == ["1.0,-1.0,-1.0,1.0,2000,1000,1000,2000,"]


def test_batch_json_lines_may_choose_their_algorithm():
    code, lines, _ = batch('{"magnitude": 1, "direction_deg": 0, "algo": "holonomic_2010"}\n'
                           '{"x": 0, "y": 0, "rotation": 0.5}\n')
    docs = [json.loads(line) for line in lines]
    assert code == 0
    assert docs[0]["algorithm"] == "holonomic_2010" and docs[0]["wheels"][0] == 0.707107
    assert docs[1]["wheels"] == [0.5, -0.5, 0.5, -0.5]


@pytest.mark.parametrize(
    ("line", "message"),
    [("abc,0,0", "not a number"), ("nan,0,0", "finite"), ("1,2,3,4,5", "at most"),
     ('{"x": 1, "speed": 2}', "unknown field"), ('{"x": ', "bad JSON"), ("[1, 2]", "not a number"),
     ('{"x": 1, "algo": "tank"}', "unknown algorithm")],
)
def test_batch_answers_a_bad_line_with_its_error_and_keeps_going(line, message):
    code, lines, err = batch(f"{line}\n0.5,0,0\n")
    assert code == 1
    assert len(lines) == 2 and message in lines[0] and message in err
    assert "line 1" in err
    assert lines[1].startswith("0.5,0.5,0.5,0.5")


def table_cells(line: str) -> list[str]:
    """The cells of one Markdown table row (``\\|`` is a pipe inside a cell)."""
    assert line.startswith("|") and line.endswith("|"), f"not a table row: {line!r}"
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line)[1:-1]]


def test_params_markdown_lists_every_parameter(capsys):
    """A Markdown table: header, separator, then one row per parameter in schema order with
    its name, default (and label), range or labels, units and description as the schema has
    them; nothing else is printed."""
    code, out, _ = run(capsys, "params", "--markdown")
    assert code == 0
    header, separator, *rows = out.strip().splitlines()
    assert table_cells(header) == ["Name", "Default", "Range / values", "Units", "Description"]
    assert table_cells(separator) == ["---"] * 5
    assert len(rows) == len(SCHEMA) == len(Params().names())
    for row, spec in zip(rows, SCHEMA, strict=True):
        name, default, values, units, description = table_cells(row)
        assert name == f"`{spec.name}`"
        number, _, label = default.partition(" (")
        assert float(number) == spec.default, row
        if spec.values is None:
            assert not label, row
            low, high = values.split(" .. ")
            assert (float(low), float(high)) == (spec.minimum, spec.maximum), row
        else:
            assert label == f"{spec.values[int(spec.default)]})", row
            assert values == ", ".join(f"{k} = {v}" for k, v in sorted(spec.values.items()))
        assert units == spec.units and description == spec.description, row


def test_params_save_writes_a_loadable_file(capsys, tmp_path):
    path = tmp_path / "saved.parm"
    code, _, _ = run(capsys, "params", "--set", "INP_EXPO=0.25", "--save", str(path))
    assert code == 0
    code, out, _ = run(capsys, "params", "--params", str(path))
    assert code == 0 and "INP_EXPO 0.25  # changed" in out


def test_params_prints_each_parameter_marking_only_those_not_at_their_default(capsys):
    """docs/commands.md (params): every parameter, ``# changed`` on those not at their
    default; one ``NAME VALUE`` line each, as in a parameter file."""
    code, out, _ = run(capsys, "params", "--set", "INP_EXPO=0.25")
    assert code == 0
    lines = out.splitlines()
    assert [line.split()[0] for line in lines] == list(Params().names())
    assert [line for line in lines if line.endswith("  # changed")] == [
        "INP_EXPO 0.25  # changed"]
    for line in lines:
        if not line.endswith("# changed"):
            name, value = line.split(" ")  # nothing after the value
            assert float(value) == Params()[name]


def test_params_save_says_how_many_parameters_it_wrote_and_where(capsys, tmp_path):
    path = tmp_path / "saved.parm"
    code, out, _ = run(capsys, "params", "--save", str(path))
    assert code == 0
    assert out == f"saved {len(Params().names())} parameters to {path}\n"


def test_console_script_runs_as_a_module():
    done = subprocess.run([sys.executable, "-m", "mecanum_mav.app.cli", "mix", "-x", "1", "--json"],
                          capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["wheels"] == [1.0, 1.0, 1.0, 1.0]


def test_a_broken_parameter_file_stops_run_unless_params_reset_says_start_on_defaults(
        capsys, tmp_path, monkeypatch):
    bad = tmp_path / "rover.parm"
    bad.write_text("GEO_HALF_LEN 0.2\nMIX_ALOG 1\n")
    served = []
    monkeypatch.setattr(cli, "serve", lambda params, gcs, fc, path, tlog, keys, **_: served.append(
        (params.as_dict(), path)) or 0)
    assert main(["run", "--fc", "udpin:127.0.0.1:0", "--params", str(bad)]) == 2
    assert "rover.parm:2: unknown parameter 'MIX_ALOG'; did you mean MIX_ALGO?" in (
        capsys.readouterr().err)
    assert served == []  # never silently on the defaults
    assert main(["run", "--fc", "udpin:127.0.0.1:0", "--params", str(bad), "--params-reset",
                 "--set", "INP_EXPO=0.2"]) == 0
    assert "--params-reset: starting on the defaults" in capsys.readouterr().err
    values, path = served[0]
    assert values == {**Params().as_dict(), "INP_EXPO": 0.2} and path is None  # not saved to
    assert bad.read_text() == "GEO_HALF_LEN 0.2\nMIX_ALOG 1\n"  # left untouched


def test_run_prints_its_refusal_counts_on_sigusr1_and_at_exit(tmp_path):
    """The status line a user asks for with ``kill -USR1`` and gets at exit, as the shell
    counts: a bad stick and a bad parameter from a real ground station, one of each kind."""
    gcs, port = udp_ground_station()
    fc = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    fc.bind(("127.0.0.1", 0))
    try:
        with CompanionProcess(port.url, f"udpout:127.0.0.1:{fc.getsockname()[1]}",
                              tmp_path) as companion:
            assert gcs.wait("HEARTBEAT", timeout_s=10.0), companion.log()
            sent = gcs.mark()  # before sending: a busy test may read the answer only later
            gcs.mav.manual_control_send(1, 4000, 0, 500, 0, 0)
            gcs.mav.param_set_send(1, 1, b"OUT_RATE", 1e30, mavlink.MAV_PARAM_TYPE_REAL32)
            assert gcs.wait("STATUSTEXT", lambda m: "Param refused" in m.text, 5.0,
                            since=sent), companion.log()

            def status_lines() -> list[str]:
                return [line for line in companion.log().splitlines() if "refused " in line]

            companion.proc.send_signal(signal.SIGUSR1)
            assert wait_until(status_lines, 5.0, pump=gcs.pump), companion.log()
            assert status_lines()[0].endswith("refused 2 (stick 1, param 1)")
            companion.terminate()
            assert companion.wait(10.0) == 0, companion.log()
            assert len(status_lines()) == 2 and status_lines()[1].endswith(
                "refused 2 (stick 1, param 1)")
    finally:
        port.close()
        fc.close()


def test_run_and_sim_start_from_the_defaults_on_a_params_file_that_does_not_exist_yet(
        capsys, tmp_path, monkeypatch):
    """The README's fleet loop from a fresh clone: ``sim --instance 0 --params rover0.parm``."""
    served = []
    monkeypatch.setattr(cli, "serve", lambda params, gcs, fc, path, tlog, keys, **_: served.append(
        (params.as_dict(), path)) or 0)
    new = tmp_path / "rover0.parm"
    assert main(["sim", "--instance", "0", "--params", str(new), "--set", "INP_EXPO=0.2"]) == 0
    assert main(["run", "--fc", "sim", "--params", str(new)]) == 0
    err = capsys.readouterr().err
    assert err.count(f"{new} does not exist: starting from the defaults; changes will be saved "
                     f"there") == 2
    assert served == [({**Params().as_dict(), "INP_EXPO": 0.2}, new),  # saved to it
                      (Params().as_dict(), new)]
    assert not new.exists()  # written when the ground station changes something


@pytest.mark.parametrize("command", [["params"], ["mix", "-x", "1"], ["setup-fc", "--fc", "sim"]])
def test_other_commands_refuse_a_params_file_that_does_not_exist(command, capsys, tmp_path):
    missing = tmp_path / "typo.parm"
    assert main([*command, "--params", str(missing)]) == 2
    assert f"--params {missing} does not exist" in capsys.readouterr().err


def test_a_params_file_in_a_folder_that_does_not_exist_is_refused(capsys, tmp_path):
    assert main(["run", "--fc", "sim", "--params", str(tmp_path / "no" / "rover.parm")]) == 2
    assert f"the folder {tmp_path / 'no'} does not exist" in capsys.readouterr().err
