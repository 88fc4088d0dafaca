"""The Rerun viewer's process around a view (mecanum_mav.app.view): started, refused, left
open or stopped as the docstrings say.

A fake viewer stands in where the real one cannot run here (a native window needs a display):
``RERUN_CLI_PATH`` (rerun-sdk's own variable) names the program to start instead.
"""

from __future__ import annotations

import io
import json
import os
import select
import signal
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("rerun", reason="the view extra (rerun-sdk) is not installed")

from support import child_processes, wait_until

from mecanum_mav.app.cli import build_parser
from mecanum_mav.app.view import (
    Viewer,
    follow_in_viewer,
    run_view,
    serve_rrd,
    show_log,
    stop_view,
)
from mecanum_mav.config.params import Params
from mecanum_mav.io.tlog import TlogEntry, parse_tlog, tlog_record
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.process import free_port

FAKE_NATIVE_VIEWER = """#!{python} -S
import json, socket, sys
args = sys.argv[1:]
port = int(args[args.index("--port") + 1])
with socket.socket() as s:
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    s.bind(("127.0.0.1", port))
    s.listen()
    open({record!r}, "w").write(json.dumps(args))
    conn, _ = s.accept()  # the caller saw it listening: the window "closes"
    conn.close()
"""
"""A native viewer that records its command line, listens on ``--port`` and closes its
window once someone has connected."""


def _program(path: Path, text: str) -> Path:
    path.write_text(text)
    path.chmod(0o755)
    return path


def _entries() -> list[TlogEntry]:
    """A tlog of a few rover HEARTBEATs, read."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    data = b"".join(
        tlog_record(1_800_000_000_000_000 + k * 100_000,
                    mav.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,
                                         mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3).pack(mav))
        for k in range(3))
    return parse_tlog(data).entries


@pytest.fixture
def fake_viewer(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The native fake viewer installed; yields where it records its command line."""
    record = tmp_path / "viewer-args.json"
    program = _program(tmp_path / "rerun",
                       FAKE_NATIVE_VIEWER.format(python=sys.executable, record=str(record)))
    monkeypatch.setenv("RERUN_CLI_PATH", str(program))
    yield record


def test_with_a_display_log_view_opens_the_native_viewer_on_the_written_view(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fake_viewer: Path) -> None:
    # 'log --view' where $DISPLAY is set: the native viewer, given the .rrd, and the command
    # waits for its window to close (no callback given).
    monkeypatch.setenv("DISPLAY", ":0")
    rrd = tmp_path / "drive.rrd"
    out, err = io.StringIO(), io.StringIO()
    assert show_log(_entries(), Params(), rrd, True, 0, out, err) == 0
    args = json.loads(fake_viewer.read_text())
    assert str(rrd) in args and "--serve-web" not in args
    assert "the view: the native viewer" in out.getvalue()
    assert err.getvalue() == ""


def test_with_a_display_view_says_it_shows_in_the_native_viewer(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fake_viewer: Path) -> None:
    # 'view' where $DISPLAY is set: the native viewer (no address to print), named as such.
    monkeypatch.setenv("DISPLAY", ":0")
    source = tmp_path / "drive.tlog"
    source.write_bytes(b"".join(tlog_record(1_800_000_000_000_000, e.msg.get_msgbuf())
                                for e in _entries()))
    out = io.StringIO()
    assert run_view(str(source), Params(), out=out,
                    stop_when=lambda mapping: mapping.messages >= 3) == 0
    assert "--serve-web" not in json.loads(fake_viewer.read_text())
    assert out.getvalue().splitlines()[0] == f"mecanum-mav view: {source} -> the native viewer"


def test_log_rerun_without_view_writes_the_file_and_starts_no_viewer(
        tmp_path: Path, fake_viewer: Path) -> None:
    rrd = tmp_path / "only.rrd"
    assert show_log(_entries(), Params(), rrd, False, 0, io.StringIO(), io.StringIO()) == 0
    assert rrd.stat().st_size > 0
    assert not fake_viewer.exists()


def test_log_view_without_the_viewer_binary_exits_2_saying_what_is_missing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("RERUN_CLI_PATH", raising=False)
    monkeypatch.setitem(sys.modules, "rerun_cli", None)  # not installed
    err = io.StringIO()
    status = show_log(_entries(), Params(), tmp_path / "v.rrd", True, 0, io.StringIO(), err)
    assert status == 2
    assert err.getvalue().startswith("mecanum-mav log: ") and "rerun_cli" in err.getvalue()


def test_a_viewer_that_exits_at_once_is_reported_with_its_status(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("RERUN_CLI_PATH", "/bin/false")
    with pytest.raises(RuntimeError, match=r"exited at once \(status 1\)"):
        serve_rrd(None, 0, native=False)


def test_a_viewer_that_never_listens_is_stopped_and_reported(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    program = _program(tmp_path / "rerun", "#!/bin/sh\nexec sleep 30\n")
    monkeypatch.setenv("RERUN_CLI_PATH", str(program))
    before = child_processes()
    with pytest.raises(RuntimeError, match=r"did not listen on port \d+ in 0.3 s"):
        serve_rrd(None, 0, native=False, timeout_s=0.3)
    assert child_processes() == before  # killed and reaped: nothing left behind


def _sleeper() -> subprocess.Popen[bytes]:
    return subprocess.Popen(["sleep", "30"], stdin=subprocess.DEVNULL)


def test_closing_a_native_viewer_leaves_its_window_open() -> None:
    process = _sleeper()
    try:
        Viewer(process, "rerun+http://127.0.0.1:9/proxy", None).close()
        assert process.poll() is None
    finally:
        process.kill()
        process.wait()


def test_closing_a_web_viewer_stops_its_server_and_one_already_gone_is_left_as_it_is() -> None:
    process = _sleeper()
    viewer = Viewer(process, "rerun+http://127.0.0.1:9/proxy", "http://127.0.0.1:9/")
    viewer.close()
    assert process.returncode == -signal.SIGTERM
    viewer.close()  # already ended: nothing to do, nothing raised
    assert process.returncode == -signal.SIGTERM


def test_stop_view_kills_a_view_that_has_not_ended_in_time() -> None:
    process = subprocess.Popen(["sh", "-c", 'trap "" INT; echo ready; exec sleep 30'],
                               stdin=subprocess.DEVNULL, stdout=subprocess.PIPE)
    try:
        assert process.stdout is not None
        assert select.select([process.stdout], [], [], 5.0)[0]
        assert process.stdout.readline() == b"ready\n"  # SIGINT is ignored from now on
        stop_view(process, timeout_s=0.2)
        assert process.returncode == -signal.SIGKILL
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        if process.stdout is not None:
            process.stdout.close()


def _serving(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


def test_sim_view_follows_the_given_tlog_with_the_rovers_params_and_stop_view_ends_it(
        tmp_path: Path) -> None:
    # 'sim --view --tlog FILE --params P --set A': the view process follows that tlog (created
    # now), with those parameters. stop_view ends it as Ctrl-C does, its web viewer with it,
    # even while it is still starting (the web viewer just up); stopping it again is harmless.
    tlog = tmp_path / "drive.tlog"
    params = tmp_path / "rover.parm"
    params.write_text("GEO_HALF_LEN 0.4\n")
    web_port = free_port(socket.SOCK_STREAM)
    path, process = follow_in_viewer(tlog, params, ["GEO_HALF_WID=0.3"], web_port)
    try:
        assert path == tlog and tlog.exists()
        args = build_parser().parse_args(list(process.args)[3:])  # after 'python -m pkg'
        assert (args.command, args.connect, args.params, args.set, args.web_port) == (
            "view", [str(tlog)], params, ["GEO_HALF_WID=0.3"], web_port)
        assert wait_until(lambda: _serving(web_port), 30.0), "the web viewer never came up"
        stop_view(process)
        assert process.returncode is not None
        # (the web viewer runs in a session of its own: its port closes as it exits, which
        # can come a moment after the view process's own end on a busy machine)
        assert wait_until(lambda: not _serving(web_port), 5.0), "the web viewer still serves"
        stop_view(process)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


FAKE_WEB_VIEWER = """#!{python} -S
import socket, sys, time
args = sys.argv[1:]
with socket.socket() as s:
    s.bind(("127.0.0.1", int(args[args.index("--port") + 1])))
    s.listen()
    time.sleep(60)
"""
"""A web viewer that listens on ``--port`` and serves until it is stopped."""


def _ended(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


def test_a_view_killed_before_it_could_stop_its_web_viewer_leaves_no_server_behind(
        tmp_path: Path) -> None:
    # kill -9 of the process that started the web viewer (stop_view's last resort, a killed
    # sim): the viewer, in a session of its own, ends with it.
    viewer = _program(tmp_path / "rerun", FAKE_WEB_VIEWER.format(python=sys.executable))
    starter = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\n"
         "from mecanum_mav.app.view import serve_rrd\n"
         "print(serve_rrd(None, 0, native=False).process.pid, flush=True)\n"
         "time.sleep(60)\n"],
        stdout=subprocess.PIPE, env={**os.environ, "RERUN_CLI_PATH": str(viewer)})
    try:
        assert starter.stdout is not None
        pid = int(starter.stdout.readline())
        assert not _ended(pid)
        starter.kill()
        starter.wait()
        assert wait_until(lambda: _ended(pid), 5.0), "the web viewer outlived its view"
    finally:
        starter.kill()
        starter.wait()
        starter.stdout.close()  # type: ignore[union-attr]
