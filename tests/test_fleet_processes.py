"""What a :class:`~mecanum_mav.app.fleet.Fleet` starts and how, checked in-process: the router's
MAVProxy command line (router_command), the rovers' ``sim --instance N`` command lines, the
ports between them, where each process's output goes, which ``mavproxy.py`` runs, and that
everything is stopped; and the path a fleet drive records of each rover.

The processes are stand-ins: ``sys.executable`` is a shell script that writes what it was
started with (arguments, folder, its stdin, a line to stderr, a byte that is not UTF-8) and
then sleeps until stopped. tests/test_fleet.py starts the real ones.
"""

from __future__ import annotations

import io
import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from support import wait_until

from mecanum_mav.app.cli import build_parser, sim_gcs_url
from mecanum_mav.app.fleet import Fleet, _path, _stop, free_udp_ports, router_command
from mecanum_mav.io.links import mavlink
from mecanum_mav.sim.groundstation import fleet_ground_station

# --------------------------------------------------------------------------- the router


def test_the_router_command_is_mavproxy_routing_between_the_rovers_and_the_station() -> None:
    """MAVProxy's options (mavproxy.py --help): --master per link, --out to the ground station,
    --daemon "do not start interactive shell", --nowait "don't wait for HEARTBEAT on startup",
    --no-state "Don't save logs and other state to disk", --default-modules (empty: none)."""
    assert router_command([14601, 14602], "udpout:127.0.0.1:14550") == [
        "mavproxy.py", "--master=udpin:127.0.0.1:14601", "--master=udpin:127.0.0.1:14602",
        "--out=udpout:127.0.0.1:14550", "--daemon", "--nowait", "--no-state",
        "--default-modules="]


def test_free_udp_ports_are_distinct_udp_ports_the_os_handed_out_on_localhost(
        monkeypatch: pytest.MonkeyPatch) -> None:
    bound: list[tuple[int, int, tuple[str, int]]] = []

    class Recorded(socket.socket):
        def bind(self, address: object) -> None:
            super().bind(address)
            bound.append((self.family, self.type, self.getsockname()))

    monkeypatch.setattr(socket, "socket", Recorded)
    ports = free_udp_ports(3)
    assert len(set(ports)) == 3 and all(port > 1023 for port in ports)
    assert bound == [(socket.AF_INET, socket.SOCK_DGRAM, ("127.0.0.1", port))
                     for port in ports]


# --------------------------------------------------------------------------- a fleet of stand-ins

STAND_IN = """#!/bin/sh
for arg in "$@"; do echo "arg: $arg"; done
echo "cwd: $(pwd)"
echo "to stderr" >&2
if IFS= read -r line; then echo "stdin: $line"; else echo "stdin: nothing"; fi
printf 'not utf-8: \\377\\n'
echo ready
touch "$STAND_IN_DONE/$$"
exec sleep 60
"""
"""A process that writes what it was started with, says it has (a file named by its process
id in ``$STAND_IN_DONE``), then waits to be stopped."""


def executable(path: Path, text: str = "#!/bin/sh\n") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    path.chmod(0o755)
    return path


@pytest.fixture
def stand_in_python(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """``sys.executable`` is the stand-in (tmp/python/bin/python); PATH has the system's
    folders only (for ``sleep``). Returns the interpreter's folder."""
    (tmp_path / "done").mkdir()
    monkeypatch.setenv("STAND_IN_DONE", str(tmp_path / "done"))
    folder = tmp_path / "python" / "bin"
    monkeypatch.setattr(sys, "executable", str(executable(folder / "python", STAND_IN)))
    monkeypatch.setenv("PATH", os.defpath)
    return folder


@pytest.fixture
def terminal_input() -> Iterator[None]:
    """This process's stdin is a pipe holding a line, as a terminal a user typed into: a
    child that inherited it could read it."""
    saved = os.dup(0)
    read_end, write_end = os.pipe()
    os.write(write_end, b"typed by the user\n")
    os.close(write_end)
    os.dup2(read_end, 0)
    os.close(read_end)
    try:
        yield
    finally:
        os.dup2(saved, 0)
        os.close(saved)


def started(fleet: Fleet, log: str) -> list[str]:
    """What a stand-in wrote, line by line, once every one of the fleet's has written all."""
    done = Path(os.environ["STAND_IN_DONE"])
    assert wait_until(lambda: all((done / str(p.pid)).exists() for p in fleet.processes),
                      10.0)
    lines = fleet.log(log).splitlines()
    assert "ready" in lines, lines
    return lines


def args_of(lines: list[str]) -> list[str]:
    return [line.removeprefix("arg: ") for line in lines if line.startswith("arg: ")]


def test_a_fleet_starts_the_router_and_a_sim_instance_per_rover_on_ports_that_meet(
        tmp_path: Path, stand_in_python: Path) -> None:
    mavproxy = executable(stand_in_python / "mavproxy.py")
    with Fleet(2, tmp_path) as fleet:
        router = args_of(started(fleet, "router.log"))
        rovers = [args_of(started(fleet, f"instance{i}.log")) for i in range(2)]
        assert router[0] == str(mavproxy)
        masters = [int(arg.rsplit(":", 1)[1]) for arg in router if arg.startswith("--master=")]
        assert router[1:] == router_command(masters, fleet.port.url)[1:]
        assert len(set(masters)) == 2
        for instance, argv in enumerate(rovers):
            assert argv[:2] == ["-m", "mecanum_mav"]  # this package, on this Python
            args = build_parser().parse_args(argv[2:])
            assert (args.command, args.instance) == ("sim", instance)
            assert sim_gcs_url(args) == f"udpout:127.0.0.1:{masters[instance]}"
        assert fleet.sysids == [1, 2]
        assert list(fleet.stations) == [1, 2]


def test_each_process_logs_to_its_own_file_runs_in_the_workdir_and_reads_no_terminal(
        tmp_path: Path, stand_in_python: Path, terminal_input: None) -> None:
    executable(stand_in_python / "mavproxy.py")
    workdir = tmp_path / "work"
    workdir.mkdir()
    with Fleet(2, workdir) as fleet:
        for log in ("router.log", "instance0.log", "instance1.log"):
            lines = started(fleet, log)
            assert f"cwd: {workdir}" in lines
            assert "to stderr" in lines
            assert "stdin: nothing" in lines
            assert "not utf-8: \ufffd" in lines  # Fleet.log reads what is not UTF-8 too
        processes = list(fleet.processes)
        assert len(processes) == 3 and all(p.poll() is None for p in processes)
    assert all(p.returncode is not None for p in processes)  # stopped on exit


def test_the_mavproxy_installed_beside_this_python_runs_rather_than_one_on_path(
        tmp_path: Path, stand_in_python: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """It runs on this Python (``sys.executable mavproxy.py``): another Python's mavproxy.py
    on PATH may not find its modules here."""
    mine = executable(stand_in_python / "mavproxy.py")
    other = executable(tmp_path / "elsewhere" / "mavproxy.py")
    monkeypatch.setenv("PATH", f"{other.parent}{os.pathsep}{os.defpath}")
    with Fleet(1, tmp_path) as fleet:
        assert args_of(started(fleet, "router.log"))[0] == str(mine)


def test_without_one_beside_this_python_the_mavproxy_on_path_runs(
        tmp_path: Path, stand_in_python: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    on_path = executable(tmp_path / "elsewhere" / "mavproxy.py")
    monkeypatch.setenv("PATH", f"{on_path.parent}{os.pathsep}{os.defpath}")
    with Fleet(1, tmp_path) as fleet:
        assert args_of(started(fleet, "router.log"))[0] == str(on_path)


def test_without_mavproxy_the_fleet_says_how_to_install_it(
        tmp_path: Path, stand_in_python: Path) -> None:
    with pytest.raises(FileNotFoundError) as raised:
        Fleet(1, tmp_path)
    assert str(raised.value) == "mavproxy.py not found (pip install MAVProxy)"


class StubbornProcess:
    """A process that ignores SIGTERM: waiting for it times out until it is killed."""

    def __init__(self) -> None:
        self.signals: list[str] = []

    def terminate(self) -> None:
        self.signals.append("SIGTERM")

    def kill(self) -> None:
        self.signals.append("SIGKILL")

    def wait(self, timeout: float | None = None) -> int:
        if "SIGKILL" in self.signals:
            return -9
        if timeout is None:
            raise AssertionError("would wait forever for a process that ignores SIGTERM")
        raise subprocess.TimeoutExpired("rover", timeout)


def test_a_process_that_ignores_sigterm_is_killed() -> None:
    process = StubbornProcess()
    _stop(process)  # type: ignore[arg-type]
    assert process.signals == ["SIGTERM", "SIGKILL"]


# --------------------------------------------------------------------------- a drive's paths


def test_a_rovers_path_is_every_position_the_station_received_timed_from_the_drives_start(
        ) -> None:
    """FleetDrive.paths: (s from the drive's start, north, east) of every LOCAL_POSITION_NED,
    including one still waiting in the socket; other messages are not positions. Taking it
    waits for nothing more."""
    rover = mavlink.MAVLink(io.BytesIO(), srcSystem=5, srcComponent=1)
    stations, port = fleet_ground_station([5])
    try:
        gcs = stations[5]
        t0 = time.monotonic()
        gcs.receive([rover.local_position_ned_encode(0, 0.5, 0.25, 0.0, 0.0, 0.0, 0.0),
                     rover.heartbeat_encode(10, 3, 0, 0, 3),
                     rover.local_position_ned_encode(0, 1.0, 0.75, 0.0, 0.0, 0.0, 0.0)],
                    t0 + 1.5)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.sendto(rover.local_position_ned_encode(0, 2.0, -1.0, 0.0, 0.0, 0.0, 0.0)
                        .pack(rover), ("127.0.0.1", int(port.url.rsplit(":", 1)[1])))
            path = _path(gcs, t0)
        taken_s = time.monotonic() - t0
        assert path[:2] == [(1.5, 0.5, 0.25), (1.5, 1.0, 0.75)]
        assert len(path) == 3 and path[2][1:] == (2.0, -1.0)
        assert 0.0 <= path[2][0] <= taken_s
        begun = time.monotonic()
        assert _path(gcs, t0) == path  # nothing more arrives: it does not wait for it
        assert time.monotonic() - begun < 0.9
    finally:
        port.close()
