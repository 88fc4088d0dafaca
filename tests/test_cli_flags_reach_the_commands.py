"""The command line hands what the user typed to the command that does the work: each flag of
``run``, ``sim``, ``setup-fc``, ``simfc`` and ``view`` (docs/reference/cli.md, the argparse
help) reaches it, and ``--params``/``--set`` reach it as its parameters. In process: the
real parser and handlers, the long-running function replaced by a recorder that binds its
arguments as the real function's signature would."""

from __future__ import annotations

import inspect
import sys
from pathlib import Path
from typing import Any

import pytest

from mecanum_mav.app import cli, setupfc, view
from mecanum_mav.config.params import Params

KEY_HEX = "ab" * 32  # a key file: 64 hex digits (docs/signing.md)
FC_KEY_HEX = "cd" * 32


def record(monkeypatch: pytest.MonkeyPatch, owner: object, name: str,
           answer: int = 0) -> list[dict[str, Any]]:
    """Replace ``owner.name`` by a recorder: each call's arguments by parameter name, the
    defaults included, as the real function would get them (a call it would refuse raises)."""
    signature = inspect.signature(getattr(owner, name))
    calls: list[dict[str, Any]] = []

    def recorder(*args: Any, **kwargs: Any) -> int:
        bound = signature.bind(*args, **kwargs)
        bound.apply_defaults()
        calls.append(dict(bound.arguments))
        return answer

    monkeypatch.setattr(owner, name, recorder)
    return calls


def key_file(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text + "\n")
    path.chmod(0o600)  # (a key readable by others is refused)
    return path


def changed(params: Params) -> dict[str, float]:
    return {name: params[name] for name in params.changed()}


# ------------------------------------------------------------------------------------- run


def test_run_gives_the_companion_every_link_file_and_key_typed(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    served = record(monkeypatch, cli, "serve")
    parm, tlog = tmp_path / "rover.parm", tmp_path / "drive.tlog"
    parm.write_text("INP_EXPO 0.25\n")
    gcs_key, fc_key = key_file(tmp_path, "gcs.key", KEY_HEX), key_file(tmp_path, "fc.key",
                                                                        FC_KEY_HEX)
    assert cli.main(["run", "--gcs", "udpin:127.0.0.1:14555", "--fc", "/dev/ttyACM0,115200",
                     "--params", str(parm), "--set", "OUT_RATE=25", "--tlog", str(tlog),
                     "--signing-key", str(gcs_key), "--fc-signing-key", str(fc_key),
                     "--quiet"]) == 0
    [call] = served
    assert changed(call["params"]) == {"INP_EXPO": 0.25, "OUT_RATE": 25}
    assert (call["gcs_url"], call["fc_url"]) == ("udpin:127.0.0.1:14555", "/dev/ttyACM0,115200")
    assert (call["param_path"], call["tlog_path"]) == (parm, tlog)  # saved to, recorded to
    assert call["keys"] == (bytes.fromhex(KEY_HEX), bytes.fromhex(FC_KEY_HEX))
    assert call["quiet"] is True


def test_run_without_its_options_is_unsigned_unrecorded_and_prints_its_status_line(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """``--gcs`` defaults to udpout:127.0.0.1:14550 (docs/commands.md); no tlog, no
    signing, the status line on (``--quiet`` turns it off)."""
    served = record(monkeypatch, cli, "serve")
    assert cli.main(["run", "--fc", "sim"]) == 0
    [call] = served
    assert (call["gcs_url"], call["fc_url"]) == ("udpout:127.0.0.1:14550", "sim")
    assert (call["param_path"], call["tlog_path"], call["keys"]) == (None, None, (None, None))
    assert not call["quiet"]


# ------------------------------------------------------------------------------------- sim


def test_sim_runs_the_companion_on_the_built_in_board_with_what_was_typed(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """``sim`` is ``run --fc sim`` (the built-in simulator) with its own defaults."""
    served = record(monkeypatch, cli, "serve")
    parm, tlog = tmp_path / "rover.parm", tmp_path / "sim.tlog"
    gcs_key = key_file(tmp_path, "gcs.key", "a passphrase")
    assert cli.main(["sim", "--gcs", "udpout:127.0.0.1:9", "--params", str(parm), "--set",
                     "INP_EXPO=0.2", "--tlog", str(tlog), "--signing-key", str(gcs_key),
                     "--quiet"]) == 0
    capsys.readouterr()
    [call] = served
    assert changed(call["params"]) == {"INP_EXPO": 0.2}
    assert (call["gcs_url"], call["fc_url"]) == ("udpout:127.0.0.1:9", "sim")
    assert (call["param_path"], call["tlog_path"]) == (parm, tlog)
    assert call["keys"][0] is not None and call["keys"][1] is None
    assert call["quiet"] is True and call["physics"] == "kinematic"


def test_sim_with_an_instance_sends_to_the_instances_port(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    served = record(monkeypatch, cli, "serve")
    assert cli.main(["sim", "--instance", "2"]) == 0
    capsys.readouterr()
    [call] = served
    assert call["gcs_url"] == "udpout:127.0.0.1:14580" and call["params"]["SYSID_THISMAV"] == 3
    assert not call["quiet"]


def test_sim_measures_the_mujoco_chassis_of_the_parameters_it_will_run(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """The real-time factor printed at the start (docs/commands.md) is that of the chassis
    the parameters make (its mass, wheels, floor)."""
    measured = record(monkeypatch, cli, "mujoco_real_time_factor", answer=10)
    served = record(monkeypatch, cli, "serve")
    assert cli.main(["sim", "--physics", "mujoco", "--set", "SIM_FRICTION=0.4"]) == 0
    capsys.readouterr()
    [measure], [call] = measured, served
    assert changed(measure["params"]) == {"SIM_FRICTION": 0.4}
    assert measure["params"] is call["params"] and call["physics"] == "mujoco"


def test_a_mujoco_chassis_at_exactly_the_minimum_real_time_factor_is_not_warned_of(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """docs/commands.md: it "warns below 3x"."""
    monkeypatch.setattr(cli, "mujoco_real_time_factor", lambda params: cli.MIN_REAL_TIME_FACTOR)
    record(monkeypatch, cli, "serve")
    assert cli.main(["sim", "--physics", "mujoco"]) == 0
    captured = capsys.readouterr()
    assert f"MuJoCo chassis: {cli.MIN_REAL_TIME_FACTOR:.1f}x real time\n" in captured.out
    assert captured.err == ""


# -------------------------------------------------------------------------------- setup-fc


def test_setup_fc_checks_the_board_typed_with_apply_reboot_and_its_key(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    checked = record(monkeypatch, setupfc, "run_setup", answer=3)
    fc_key = key_file(tmp_path, "fc.key", FC_KEY_HEX)
    assert cli.main(["setup-fc", "--fc", "/dev/ttyACM0,115200", "--apply", "--reboot",
                     "--fc-signing-key", str(fc_key), "--set", "FC_SYSID=2"]) == 3
    [call] = checked
    assert call["url"] == "/dev/ttyACM0,115200" and changed(call["params"]) == {"FC_SYSID": 2}
    assert call["apply"] is True and call["reboot"] is True
    assert call["signing_key"] == bytes.fromhex(FC_KEY_HEX)


def test_setup_fc_without_apply_only_checks(monkeypatch: pytest.MonkeyPatch) -> None:
    """Its exit status is the check's (0 safe, 1 hazard, 2 unreachable, 3 reboot pending)."""
    checked = record(monkeypatch, setupfc, "run_setup", answer=1)
    assert cli.main(["setup-fc", "--fc", "udpout:127.0.0.1:14551"]) == 1
    [call] = checked
    assert call["url"] == "udpout:127.0.0.1:14551"
    assert not call["apply"] and not call["reboot"] and call["signing_key"] is None


# ----------------------------------------------------------------------------------- simfc


def test_simfc_listens_where_told_with_the_parameters_given(
        monkeypatch: pytest.MonkeyPatch) -> None:
    served = record(monkeypatch, cli, "serve_simfc")
    assert cli.main(["simfc", "--listen", "udpin:127.0.0.1:14999", "--set",
                     "SIM_SLIP=0.1"]) == 0
    assert cli.main(["simfc"]) == 0
    assert [(call["url"], changed(call["params"])) for call in served] == [
        ("udpin:127.0.0.1:14999", {"SIM_SLIP": 0.1}),
        ("udpin:127.0.0.1:14551", {})]  # the default (docs/commands.md, simfc)


def test_simfc_exits_with_the_status_of_its_link(monkeypatch: pytest.MonkeyPatch) -> None:
    record(monkeypatch, cli, "serve_simfc", answer=1)  # (1: the link could not be opened)
    assert cli.main(["simfc"]) == 1


# ------------------------------------------------------------------------------------ view


def test_view_follows_each_source_given_in_order_and_saves_where_told(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    watched = record(monkeypatch, view, "run_view")
    assert cli.main(["view", "--connect", "udpin:127.0.0.1:14551", "--connect",
                     str(tmp_path / "twin.tlog"), "--save", str(tmp_path / "out.rrd"),
                     "--web-port", "9123", "--set", "GEO_HALF_LEN=0.3"]) == 0
    [call] = watched
    assert list(call["connect"]) == ["udpin:127.0.0.1:14551", str(tmp_path / "twin.tlog")]
    assert call["save"] == tmp_path / "out.rrd" and call["web_port"] == 9123
    assert changed(call["params"]) == {"GEO_HALF_LEN": 0.3}  # the chassis drawn to scale


def test_view_without_a_source_listens_on_mavproxys_extra_output(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The default source is udpin:127.0.0.1:14551, the web viewer's port 9090, nothing
    saved (the view's --help)."""
    watched = record(monkeypatch, view, "run_view", answer=2)
    assert cli.main(["view"]) == 2
    [call] = watched
    assert list(call["connect"]) == ["udpin:127.0.0.1:14551"]
    assert call["save"] is None and call["web_port"] == 9090


# -------------------------------------------------------------- what sim says before it runs


class Terminal:
    """A stdout that keeps what was flushed apart from what is still buffered: a pipe to a
    script or a terminal multiplexer sees only the former."""

    def __init__(self) -> None:
        self.buffered = ""
        self.flushed = ""

    def write(self, text: str) -> int:
        self.buffered += text
        return len(text)

    def flush(self) -> None:
        self.flushed += self.buffered
        self.buffered = ""


def said_before_serving(monkeypatch: pytest.MonkeyPatch, *argv: str,
                        factor: float = 10.0) -> str:
    """What ``sim ARGV`` had flushed to stdout when the rover started (it then runs until
    Ctrl-C: what was not flushed by then does not reach a pipe)."""
    stdout = Terminal()
    seen: list[str] = []
    monkeypatch.setattr(sys, "stdout", stdout)
    monkeypatch.setattr(cli, "mujoco_real_time_factor", lambda params: factor)

    def serve(*args: object, **kwargs: object) -> int:
        seen.append(stdout.flushed)
        return 0

    monkeypatch.setattr(cli, "serve", serve)
    assert cli.main(["sim", *argv]) == 0
    return seen[0]


def test_sim_says_where_to_point_a_ground_station_before_it_starts(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The README's quick start: the rover sends to 14550, where ground stations listen;
    MAVProxy connects with ``mavproxy.py --master=udpin:127.0.0.1:14550``."""
    assert said_before_serving(monkeypatch) == (
        "mecanum-mav sim: point a ground station at UDP 127.0.0.1:14550 (QGroundControl and "
        "Mission Planner listen on 14550; MAVProxy: mavproxy.py "
        "--master=udpin:127.0.0.1:14550)\n")


def test_sim_on_a_listening_link_tells_mavproxy_to_send_to_it(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """docs/signing.md: "When the rover listens (--gcs udpin:127.0.0.1:14550), connect
    MAVProxy to it with --master=udpout:127.0.0.1:14550"."""
    assert said_before_serving(monkeypatch, "--gcs", "udpin:127.0.0.1:14550") == (
        "mecanum-mav sim: listening for a ground station on UDP 127.0.0.1:14550 (MAVProxy: "
        "mavproxy.py --master=udpout:127.0.0.1:14550)\n")


@pytest.mark.parametrize("gcs", ["tcpin:127.0.0.1:5760", "/dev/ttyUSB0,57600"])
def test_sim_on_a_link_that_is_not_udp_names_it_whole(
        gcs: str, monkeypatch: pytest.MonkeyPatch) -> None:
    assert said_before_serving(monkeypatch, "--gcs", gcs) == (
        f"mecanum-mav sim: ground-station link {gcs}\n")


def test_sim_instance_names_its_system_id_and_the_routers_master_for_it(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """docs/fleet.md: instance N is system N + 1 and sends to 14560 + 10 N; the router takes
    it with ``--master=udpin:127.0.0.1:14560+10N``."""
    assert said_before_serving(monkeypatch, "--instance", "2") == (
        "mecanum-mav sim: instance 2, system id 3, sending to UDP 127.0.0.1:14580: one "
        "--master=udpin:127.0.0.1:14580 of the router (see docs/fleet.md)\n")
    assert said_before_serving(monkeypatch, "--instance", "1", "--gcs",
                               "udpin:127.0.0.1:14600") == (
        "mecanum-mav sim: instance 1, system id 2, listening on UDP 127.0.0.1:14600: one "
        "--master=udpout:127.0.0.1:14600 of the router (see docs/fleet.md)\n")
    assert said_before_serving(monkeypatch, "--instance", "1", "--gcs",
                               "tcp:127.0.0.1:5762") == (
        "mecanum-mav sim: instance 1, system id 2, ground-station link tcp:127.0.0.1:5762\n")


def test_sim_prints_the_mujoco_chassis_real_time_factor_before_it_starts(
        monkeypatch: pytest.MonkeyPatch) -> None:
    said = said_before_serving(monkeypatch, "--physics", "mujoco", factor=10.74)
    assert said.splitlines()[-1] == "MuJoCo chassis: 10.7x real time"
