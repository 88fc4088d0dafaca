"""``run`` and ``sim`` in the foreground (``mecanum_mav.app.foreground``), in process: what
the cli's docstring and docs/companion.md promise a person at the terminal.

- the line ``mecanum-mav: rover system N on GCS, flight controller on FC`` says where it
  runs, ``(signed)`` after each link that signs;
- SIGUSR1 prints the status line (messages received, malformed, send failures, refusals) to
  stderr, and so does the stop; SIGTERM stops it with exit 0;
- ``--tlog FILE`` appends (a restart keeps the earlier flight);
- a parameter file is the rover's: PARAM_SET is saved into it, and a second rover on it, or
  on the same system id and ground station, is refused with exit 2 and the reason;
- on a terminal a status line every 5 s, unless ``--quiet``.

``simfc`` (``serve_simfc``) says where it listens and answers as ArduPilot's board does.

The signals are real (``os.kill`` of this process) and sent from a thread once the ground
station hears the rover; serve() runs in the main thread, as the cli runs it.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from mecanum_mav.app import progress
from mecanum_mav.app.foreground import serve, serve_simfc
from mecanum_mav.config.params import Params
from mecanum_mav.io.claims import claim_ground_station
from mecanum_mav.io.storage import claim_parameter_file
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.groundstation import ScriptedGroundStation, udp_ground_station
from mecanum_mav.sim.process import free_port

DEADLINE_S = 10.0
KEY = bytes(range(32))


@pytest.fixture(autouse=True)
def _handlers_back(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """serve() leaves SIGINT and SIGTERM ignored once one came (the process is on its way
    out); this test's process is not: the handlers come back after."""
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))  # the claims of this test alone
    saved = {sig: signal.getsignal(sig)
             for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGUSR1)}
    yield
    for sig, handler in saved.items():
        signal.signal(sig, handler)


def heard(gcs: ScriptedGroundStation) -> bool:
    return gcs.wait("HEARTBEAT", lambda m: m.get_srcSystem() == 1, DEADLINE_S) is not None


def serve_while(script: Callable[[ScriptedGroundStation], None], *args: object,
                **kwargs: object) -> int:
    """serve() with ``sim`` as its board and a ground station on a port of its own, while
    ``script`` runs in a thread once the rover is heard; then SIGTERM. The exit code."""
    gcs, port = udp_ground_station()
    done = threading.Event()
    failures: list[BaseException] = []

    def drive() -> None:
        try:
            if not heard(gcs):
                raise AssertionError("the rover's HEARTBEAT never reached the ground station")
            script(gcs)
        except BaseException as exc:  # reported by the test, in its thread
            failures.append(exc)
        finally:
            if not done.is_set():
                os.kill(os.getpid(), signal.SIGTERM)

    thread = threading.Thread(target=drive, daemon=True)
    thread.start()
    try:
        code = serve(Params(), port.url, "sim", *args, **kwargs)  # type: ignore[arg-type]
    finally:
        done.set()
        thread.join(DEADLINE_S)
        port.close()
    if failures:
        raise failures[0]
    return code


def nothing(gcs: ScriptedGroundStation) -> None:
    pass


# ---------------------------------------------------------------------------- the running line

@pytest.mark.parametrize(("keys", "gcs_signed", "fc_signed"), [
    ((None, None), False, False), ((KEY, None), True, False), ((None, KEY), False, True)])
def test_the_running_line_names_both_links_and_says_which_one_signs(
        keys: tuple[bytes | None, bytes | None], gcs_signed: bool, fc_signed: bool,
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(progress.Progress, "started",
                        lambda self: os.kill(os.getpid(), signal.SIGTERM))
    gcs_url = f"udpout:127.0.0.1:{free_port()}"
    assert serve(Params(), gcs_url, "sim", None, None, keys) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "rover system" in x)
    gcs_part, fc_part = line.split(", flight controller on ")
    assert gcs_part == f"mecanum-mav: rover system 1 on {gcs_url}" + " (signed)" * gcs_signed
    fc_url, rest = fc_part.split(". ", 1)
    assert fc_url.startswith("udpout:127.0.0.1:")
    assert fc_url.endswith(" (signed)") == fc_signed
    assert int(fc_url.removesuffix(" (signed)").rsplit(":", 1)[1]) > 0  # the board's port
    assert rest == "Ctrl-C stops (wheels to neutral, channels released)."


# ---------------------------------------------------------------------------- status and stop

def test_sigusr1_prints_the_status_line_to_stderr_and_the_stop_prints_it_again(
        capsys: pytest.CaptureFixture[str]) -> None:
    def ask_status(gcs: ScriptedGroundStation) -> None:
        os.kill(os.getpid(), signal.SIGUSR1)
        gcs.pump(0.3)

    assert serve_while(ask_status, None, None) == 0
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if x.startswith("mecanum-mav: received ")]
    assert len(lines) == 2, err
    assert all(", malformed 0, send failures " in x and ", refused " in x for x in lines)
    assert int(lines[1].split()[2].rstrip(",")) > 0  # the ground station's messages counted


def test_the_waiting_and_found_lines_name_the_board_the_rover_drives(
        monkeypatch: pytest.MonkeyPatch) -> None:
    stdout = io.StringIO()
    monkeypatch.setattr("sys.stdout", stdout)

    def until_found(gcs: ScriptedGroundStation) -> None:
        deadline = time.monotonic() + DEADLINE_S
        while "flight controller found" not in stdout.getvalue() \
                and time.monotonic() < deadline:
            gcs.pump(0.05)

    assert serve_while(until_found, None, None) == 0
    out = stdout.getvalue()
    board = out.split("flight controller on ", 1)[1].split(". Ctrl-C", 1)[0]  # its real URL
    assert f"mecanum-mav: waiting for the flight controller's HEARTBEAT (system 1) on " \
           f"{board}" in out
    assert f"mecanum-mav: flight controller found (system 1) on {board}" in out


# ---------------------------------------------------------------------------- files

def test_the_tlog_is_appended_so_a_restart_keeps_the_earlier_flight(tmp_path: Path) -> None:
    tlog = tmp_path / "rover.tlog"
    tlog.write_bytes(b"the earlier flight")

    def until_logged(gcs: ScriptedGroundStation) -> None:
        deadline = time.monotonic() + DEADLINE_S
        while tlog.stat().st_size < 200 and time.monotonic() < deadline:
            gcs.pump(0.05)

    assert serve_while(until_logged, None, tlog) == 0
    data = tlog.read_bytes()
    assert data.startswith(b"the earlier flight")
    assert len(data) > 200


def test_a_param_set_is_saved_into_the_rovers_parameter_file(tmp_path: Path) -> None:
    parm = tmp_path / "rover.parm"
    parm.write_text("WP_SPEED 0.5\n")

    def set_speed(gcs: ScriptedGroundStation) -> None:
        since = gcs.mark()
        gcs.mav.param_set_send(1, 1, b"WP_SPEED", 0.75, mavlink.MAV_PARAM_TYPE_REAL32)
        assert gcs.wait("PARAM_VALUE", lambda m: m.param_id == "WP_SPEED", DEADLINE_S,
                        since=since) is not None

    assert serve_while(set_speed, parm, None) == 0
    values = dict(line.split()[:2] for line in parm.read_text().splitlines()
                  if line.strip() and not line.startswith("#"))
    assert float(values["WP_SPEED"]) == pytest.approx(0.75)


# ---------------------------------------------------------------------------- refusals

def refused(capsys: pytest.CaptureFixture[str], *args: object, **kwargs: object) -> str:
    """serve() that must refuse to start: exit 2, one line on stderr (returned)."""
    code = serve(Params(), *args, **kwargs)  # type: ignore[arg-type]
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("mecanum-mav: ") and err.count("\n") == 1, err
    return err


def test_a_second_rover_on_the_same_parameter_file_is_refused_with_exit_2(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    parm = tmp_path / "rover.parm"
    with claim_parameter_file(parm):
        err = refused(capsys, f"udpout:127.0.0.1:{free_port()}", "sim", parm, None)
    assert "rover.parm" in err


def test_a_second_rover_with_the_same_system_id_and_ground_station_is_refused_with_exit_2(
        capsys: pytest.CaptureFixture[str]) -> None:
    gcs_url = f"udpout:127.0.0.1:{free_port()}"
    with claim_ground_station(1, gcs_url):
        err = refused(capsys, gcs_url, "sim", None, None)
    assert f"system id 1 on --gcs {gcs_url} is in use" in err


def test_an_unknown_chassis_model_for_the_built_in_board_is_refused_with_exit_2(
        capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(capsys, f"udpout:127.0.0.1:{free_port()}", "sim", None, None,
                  physics="rigid")
    assert "unknown physics 'rigid'" in err


def test_a_tlog_that_cannot_be_opened_is_refused_with_exit_2(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(capsys, f"udpout:127.0.0.1:{free_port()}", "sim", None,
                  tmp_path / "no-such-folder" / "rover.tlog")
    assert "no-such-folder" in err


# ---------------------------------------------------------------------------- terminal

class Terminal(io.StringIO):
    """A stdout that says it is a terminal."""

    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("quiet", [False, True])
def test_on_a_terminal_a_status_line_comes_periodically_unless_quiet(
        quiet: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(progress, "STATUS_PERIOD_S", 0.2)
    terminal = Terminal()
    monkeypatch.setattr("sys.stdout", terminal)

    def a_few_periods(gcs: ScriptedGroundStation) -> None:
        deadline = time.monotonic() + 3.5  # the progress looks once a second
        while time.monotonic() < deadline:
            gcs.pump(0.05)

    kwargs = {"quiet": True} if quiet else {}  # the default is not quiet
    assert serve_while(a_few_periods, None, None, **kwargs) == 0
    periodic = [x for x in terminal.getvalue().splitlines() if x.startswith(
        "mecanum-mav: ") and "flight controller " not in x and "rover system" not in x
        and "waiting" not in x]
    if quiet:
        assert periodic == []
    else:
        assert len(periodic) >= 2, terminal.getvalue()


# ---------------------------------------------------------------------------- simfc

def test_simfc_says_where_it_listens_answers_as_the_board_and_stops_on_sigterm(
        capsys: pytest.CaptureFixture[str]) -> None:
    fc_port = free_port()
    params = Params()
    answers: list[object] = []

    def talk() -> None:
        gcs, port = udp_ground_station(f"udpout:127.0.0.1:{fc_port}")
        try:
            answers.append(gcs.wait("HEARTBEAT", lambda m: m.get_srcSystem() == 1,
                                    DEADLINE_S))
        finally:
            port.close()
            os.kill(os.getpid(), signal.SIGTERM)

    thread = threading.Thread(target=talk, daemon=True)
    thread.start()
    assert serve_simfc(f"udpin:127.0.0.1:{fc_port}", params) == 0
    thread.join(DEADLINE_S)
    out = capsys.readouterr().out
    assert out == (f"simfc: simulated ArduPilot Rover, system 1 component 1, listening on "
                   f"udpin:127.0.0.1:{fc_port} (port {fc_port})\n")
    assert answers and answers[0] is not None
    assert answers[0].type == mavlink.MAV_TYPE_GROUND_ROVER  # type: ignore[attr-defined]


def test_simfc_on_a_link_it_cannot_open_says_why_and_exits_1(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert serve_simfc("udpin:203.0.113.1:14550", Params()) == 1
    err = capsys.readouterr().err
    assert err.startswith("simfc: ") and err.count("\n") == 1


def test_a_mission_file_it_cannot_read_is_said_to_the_ground_station_and_the_rover_runs(
        tmp_path: Path) -> None:
    parm = tmp_path / "rover.parm"
    parm.write_text("WP_SPEED 0.5\n")
    (tmp_path / "rover.waypoints").write_text("not a waypoint file\n")
    said: list[object] = []

    def listen(gcs: ScriptedGroundStation) -> None:
        said.append(gcs.wait("STATUSTEXT", lambda m: "Mission file" in m.text, DEADLINE_S,
                             since=0))

    assert serve_while(listen, parm, None) == 0
    assert said[0] is not None
    assert said[0].text == "Mission file unreadable: rover.waypoints"  # type: ignore[attr-defined]
    assert said[0].severity == mavlink.MAV_SEVERITY_ERROR  # type: ignore[attr-defined]
    assert (tmp_path / "rover.waypoints").read_text() == "not a waypoint file\n"  # left as is


# ---------------------------------------------------------------------------- signing keys

def accepted_with(key: bytes, data: bytes) -> list[object]:
    """The messages in ``data`` a receiver holding ``key`` accepts (signed with it)."""
    parser = mavlink.MAVLink(None)
    parser.signing.secret_key = key
    parser.robust_parsing = True
    return [m for m in parser.parse_buffer(data) or [] if m.get_type() != "BAD_DATA"]


def heartbeats_seen(sock: socket.socket, wait_s: float = DEADLINE_S) -> bytes:
    """What arrives on ``sock`` until a HEARTBEAT-sized burst came (at least one datagram
    holding a HEARTBEAT packet), raw."""
    data = b""
    deadline = time.monotonic() + wait_s
    sock.settimeout(0.1)
    while time.monotonic() < deadline:
        with contextlib.suppress(TimeoutError):
            data += sock.recv(65536)
        if len(data) > 200:
            break
    return data


@pytest.mark.parametrize("which", ["gcs", "fc"])
def test_each_links_key_signs_what_goes_out_on_that_link_and_only_there(which: str) -> None:
    gcs_key, fc_key = bytes(range(32)), bytes(range(32, 64))
    keys = (gcs_key, None) if which == "gcs" else (None, fc_key)
    gcs_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    fc_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    seen: dict[str, bytes] = {}
    try:
        for sock in (gcs_sock, fc_sock):
            sock.bind(("127.0.0.1", 0))

        def listen() -> None:
            try:
                seen["gcs"] = heartbeats_seen(gcs_sock)
                seen["fc"] = heartbeats_seen(fc_sock)
            finally:
                os.kill(os.getpid(), signal.SIGTERM)

        thread = threading.Thread(target=listen, daemon=True)
        thread.start()
        code = serve(Params(), f"udpout:127.0.0.1:{gcs_sock.getsockname()[1]}",
                     f"udpout:127.0.0.1:{fc_sock.getsockname()[1]}", None, None, keys)
        thread.join(DEADLINE_S)
    finally:
        gcs_sock.close()
        fc_sock.close()
    assert code == 0
    key = gcs_key if which == "gcs" else fc_key
    other = "fc" if which == "gcs" else "gcs"
    assert accepted_with(key, seen[which])  # signed with its own key
    assert not accepted_with(key, seen[other])  # the other link is not signed
    plain = mavlink.MAVLink(None)
    plain.robust_parsing = True
    assert all(not m.get_signed() for m in plain.parse_buffer(seen[other]) or [])


def test_simfcs_listening_line_reaches_a_pipe_while_it_serves(monkeypatch) -> None:
    """(A script starts ``simfc`` and waits for this line before it connects.)"""
    read_end, write_end = os.pipe()
    stdout = io.TextIOWrapper(io.FileIO(write_end, "w"), write_through=False)
    monkeypatch.setattr("sys.stdout", stdout)
    got = b""

    def wait_for_the_line() -> None:
        nonlocal got
        deadline = time.monotonic() + DEADLINE_S
        os.set_blocking(read_end, False)
        while b"\n" not in got and time.monotonic() < deadline:
            with contextlib.suppress(BlockingIOError):
                got += os.read(read_end, 4096)
            time.sleep(0.01)
        os.kill(os.getpid(), signal.SIGTERM)

    thread = threading.Thread(target=wait_for_the_line, daemon=True)
    thread.start()
    try:
        assert serve_simfc("udpin:127.0.0.1:0", Params()) == 0
    finally:
        thread.join(DEADLINE_S)
        stdout.close()
        os.close(read_end)
    assert got.startswith(b"simfc: simulated ArduPilot Rover, system 1 component 1, "
                          b"listening on udpin:127.0.0.1:0 (port ")


def test_simfc_on_a_serial_device_names_it_without_a_port(monkeypatch) -> None:
    from support import RawPty
    stdout = io.StringIO()
    monkeypatch.setattr("sys.stdout", stdout)
    pty = RawPty()

    def stop_once_it_said_so() -> None:
        deadline = time.monotonic() + DEADLINE_S
        while "\n" not in stdout.getvalue() and time.monotonic() < deadline:
            time.sleep(0.01)
        os.kill(os.getpid(), signal.SIGTERM)

    thread = threading.Thread(target=stop_once_it_said_so, daemon=True)
    thread.start()
    try:
        assert serve_simfc(f"{pty.path},115200", Params()) == 0
    finally:
        thread.join(DEADLINE_S)
        pty.close()
    assert stdout.getvalue() == (f"simfc: simulated ArduPilot Rover, system 1 component 1, "
                                 f"listening on {pty.path},115200\n")
