"""A fleet on one machine: ``mecanum-mav sim --instance N`` and three rovers behind MAVProxy as
the router, armed and driven by system id from one ground-station socket."""

from __future__ import annotations

import math
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from mecanum_mav.app.cli import build_parser, load_params, main, sim_gcs_url
from mecanum_mav.app.fleet import Fleet, FleetDrive, drive_fleet
from mecanum_mav.io.storage import FileInUseError, claim_parameter_file

# ------------------------------------------------------------------ --instance arithmetic


def sim_args(*argv: str) -> tuple[str, int]:
    """(ground-station URL, SYSID_THISMAV) that ``mecanum-mav sim ARGV`` would run with."""
    args = build_parser().parse_args(["sim", *argv])
    params = load_params(args.params, args.set, args.instance)
    return sim_gcs_url(args), int(params["SYSID_THISMAV"])


def test_instance_n_is_system_n_plus_1_sending_to_port_14560_plus_10n() -> None:
    assert sim_args() == ("udpout:127.0.0.1:14550", 1)
    assert sim_args("--instance", "0") == ("udpout:127.0.0.1:14560", 1)
    assert sim_args("--instance", "2") == ("udpout:127.0.0.1:14580", 3)
    assert sim_args("--instance", "254") == ("udpout:127.0.0.1:17100", 255)


def test_gcs_and_set_win_over_the_instance_and_the_instance_over_the_params_file(
        tmp_path: Path) -> None:
    """The file may hold a system id an earlier run saved; the command line is explicit."""
    parm = tmp_path / "rover.parm"
    parm.write_text("SYSID_THISMAV 7\n")
    assert sim_args("--instance", "2", "--gcs", "udpout:127.0.0.1:9") == (
        "udpout:127.0.0.1:9", 3)
    assert sim_args("--instance", "2", "--set", "SYSID_THISMAV=42")[1] == 42
    assert sim_args("--instance", "2", "--params", str(parm))[1] == 3
    assert sim_args("--params", str(parm))[1] == 7


@pytest.mark.parametrize(("bad", "why"), [("-1", "must be 0 .. 254, got -1"),
                                          ("255", "must be 0 .. 254, got 255"),
                                          ("two", "not a whole number: 'two'")])
def test_an_instance_outside_0_to_254_is_a_usage_error_saying_what_is_allowed(
        bad: str, why: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["sim", "--instance", bad])
    assert exit_info.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == (
        f"mecanum-mav sim: error: argument --instance: {why}")


def test_a_parameter_file_is_held_by_one_process_at_a_time(tmp_path: Path) -> None:
    parm = tmp_path / "rover.parm"
    with claim_parameter_file(parm), pytest.raises(FileInUseError), claim_parameter_file(parm):
        pass
    with claim_parameter_file(parm):  # released when the holder let go
        pass


def test_a_second_rover_started_on_a_params_file_in_use_refuses_to_start(
        tmp_path: Path) -> None:
    """Two instances saving into one file would overwrite each other's changes (and the
    mission beside it): the second one exits with status 2 and says why."""
    parm = tmp_path / "fleet.parm"
    parm.write_text("INP_EXPO 0.2\n")
    with claim_parameter_file(parm):
        done = subprocess.run(
            [sys.executable, "-m", "mecanum_mav", "sim", "--instance", "1", "--params",
             str(parm), "--gcs", "udpout:127.0.0.1:9"],
            capture_output=True, text=True, timeout=30)
    assert done.returncode == 2
    assert "in use by another running rover" in done.stderr
    assert parm.read_text() == "INP_EXPO 0.2\n"


# ------------------------------------------------------------------ three rovers, one router


@pytest.fixture(scope="module")
def fleet_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[FleetDrive, Fleet]]:
    """Three ``sim --instance 0/1/2`` processes behind MAVProxy, driven once
    (:func:`~mecanum_mav.app.fleet.drive_fleet`); the tests below read what happened."""
    try:
        fleet = Fleet(3, tmp_path_factory.mktemp("fleet"))
    except FileNotFoundError:
        pytest.skip("MAVProxy is not installed (pip install '.[test]')")
    with fleet:
        try:
            drive = drive_fleet(fleet.stations)
        except RuntimeError as exc:
            pytest.fail(f"{exc}\n{fleet.log('router.log')}")
        yield drive, fleet


def moved(drive: FleetDrive, phase: str) -> dict[int, float]:
    return {sysid: math.hypot(*d) for sysid, d in drive.moved[phase].items()}


@pytest.mark.slow
def test_each_instance_reaches_the_ground_station_through_the_router_with_its_own_id(
        fleet_run: tuple[FleetDrive, Fleet]) -> None:
    _, fleet = fleet_run
    for sysid, gcs in fleet.stations.items():
        beats = gcs.received("HEARTBEAT")
        assert beats and all(m.get_srcSystem() == sysid for m in beats)
    router = fleet.log("router.log")
    for link, sysid in enumerate((1, 2, 3)):
        assert f"Detected vehicle {sysid}:1 on link {link}" in router
    assert fleet.port.unclaimed == 0  # nothing but the three rovers reached the station


@pytest.mark.slow
def test_rc_override_addressed_to_one_rover_moves_that_rover_alone(
        fleet_run: tuple[FleetDrive, Fleet]) -> None:
    drive, _ = fleet_run
    forward = drive.moved["RC override to 2"]
    assert forward[2][0] > 0.2 and abs(forward[2][1]) < 0.02
    right = drive.moved["RC override to 3"]
    assert right[3][1] > 0.2 and abs(right[3][0]) < 0.02
    for phase, driven in (("RC override to 2", 2), ("RC override to 3", 3)):
        others = {s: d for s, d in moved(drive, phase).items() if s != driven}
        assert all(d < 0.01 for d in others.values()), (phase, others)


@pytest.mark.slow
def test_manual_control_through_mavproxy_moves_no_rover(
        fleet_run: tuple[FleetDrive, Fleet]) -> None:
    """MAVProxy routes by ``target_system``; MANUAL_CONTROL's field is ``target``, so sticks
    for rover 2 go to the first link, where rover 1 ignores them (the README says so)."""
    drive, _ = fleet_run
    assert all(d < 0.01 for d in moved(drive, "MANUAL_CONTROL to 2").values())


@pytest.mark.slow
def test_two_rovers_run_one_mission_at_once_while_the_third_stands(
        fleet_run: tuple[FleetDrive, Fleet]) -> None:
    drive, _ = fleet_run
    (start1, end1), (start2, end2) = drive.auto[1], drive.auto[2]
    assert start1 < end2 and start2 < end1  # both in AUTO at the same time
    for sysid in (1, 2):
        _, north, east = drive.paths[sysid][-1]
        assert math.dist((north, east), drive.planned[sysid][-1]) < 0.1, sysid
    assert moved(drive, "mission")[3] < 0.01
