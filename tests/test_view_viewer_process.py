"""How the Rerun viewer's process is started (mecanum_mav.app.view.serve_rrd, open_viewer):
Rerun's command line bound to 127.0.0.1, quiet (no terminal input, nothing on our stdout,
warnings only unless RUST_LOG says otherwise), in a session of its own, and the web viewer
ending with the thread that started it; where the view shows, and the web viewer's address.

A fake viewer (``RERUN_CLI_PATH``, rerun-sdk's own variable) records what it was given and
listens on ``--port`` as the real one does.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.parse
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from support import wait_until

pytest.importorskip("rerun", reason="the view extra (rerun-sdk) is not installed")

from mecanum_mav.app import view
from mecanum_mav.app.view import Viewer, has_display, open_viewer, serve_rrd, viewer_url
from mecanum_mav.sim.process import free_port

FAKE_VIEWER = """#!{python} -S
import ctypes, json, os, socket, sys, time
args = sys.argv[1:]
sig = ctypes.c_int(0)
ctypes.CDLL(None).prctl(2, ctypes.byref(sig), 0, 0, 0)  # PR_GET_PDEATHSIG
seen = {{"args": args, "rust_log": os.environ.get("RUST_LOG"),
        "stdin": os.readlink("/proc/self/fd/0"), "stdout": os.readlink("/proc/self/fd/1"),
        "session_leader": os.getsid(0) == os.getpid(), "death_signal": sig.value,
        "pid": os.getpid()}}
with socket.socket() as s:
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    s.bind(("127.0.0.1", int(args[args.index("--port") + 1])))
    s.listen()
    seen["listening_at"] = time.time()
    open({record!r} + ".part", "w").write(json.dumps(seen))
    os.replace({record!r} + ".part", {record!r})  # (whole, or not there yet)
    time.sleep(60)  # (a window, or a server, until it is stopped)
"""
"""A viewer that records its command line and how it was started, then listens on
``--port`` until it is stopped."""


@pytest.fixture
def fake_viewer(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The fake viewer installed; returns where it records what it saw."""
    record = tmp_path / "viewer.json"
    program = tmp_path / "rerun"
    program.write_text(FAKE_VIEWER.format(python=sys.executable, record=str(record)))
    program.chmod(0o755)
    monkeypatch.setenv("RERUN_CLI_PATH", str(program))
    monkeypatch.delenv("RUST_LOG", raising=False)
    return record


@pytest.fixture
def viewers() -> Iterator[list[Viewer]]:
    """Viewers a test started, each stopped at its end (a native one too)."""
    started: list[Viewer] = []
    yield started
    for viewer in started:
        if viewer.process.poll() is None:
            viewer.process.kill()
        viewer.process.wait()


def _grpc_port(viewer: Viewer) -> int:
    return int(urllib.parse.urlsplit(viewer.grpc_url).port or 0)


def _seen(record: Path) -> dict[str, Any]:
    """What the fake viewer recorded (it records right after it listens: serve_rrd, which
    returns once it listens, can be a moment ahead of the record)."""
    assert wait_until(record.exists, 10.0), "the fake viewer recorded nothing"
    return dict(json.loads(record.read_text()))


def test_the_native_viewer_is_rerun_on_the_recordings_port_quiet_and_in_a_session_of_its_own(
        fake_viewer: Path, viewers: list[Viewer]) -> None:
    viewer = serve_rrd(None, 0, native=True)
    viewers.append(viewer)
    seen = _seen(fake_viewer)
    assert seen["args"] == ["--port", str(_grpc_port(viewer))]  # no file: what is sent
    assert viewer.grpc_url == f"rerun+http://127.0.0.1:{_grpc_port(viewer)}/proxy"
    assert viewer.url is None
    assert (seen["stdin"], seen["stdout"]) == ("/dev/null", "/dev/null")
    assert seen["rust_log"] == "warn"
    assert seen["session_leader"] is True  # a Ctrl-C meant for the view leaves its window
    assert seen["death_signal"] == 0  # the window stays when the view ends


def test_serve_rrd_returns_as_soon_as_the_viewer_listens(
        fake_viewer: Path, viewers: list[Viewer]) -> None:
    viewers.append(serve_rrd(None, 0, native=True))
    returned = time.time()
    assert returned - _seen(fake_viewer)["listening_at"] < 0.5  # (it looks every 50 ms)


def test_closing_the_native_viewer_serve_rrd_started_leaves_its_window_open(
        fake_viewer: Path, viewers: list[Viewer]) -> None:
    viewer = serve_rrd(None, 0, native=True)
    viewers.append(viewer)
    viewer.close()
    assert viewer.process.poll() is None


def test_the_native_viewer_opens_the_given_recording(
        tmp_path: Path, fake_viewer: Path, viewers: list[Viewer]) -> None:
    rrd = tmp_path / "drive.rrd"
    viewer = serve_rrd(rrd, 0, native=True)
    viewers.append(viewer)
    assert _seen(fake_viewer)["args"] == ["--port", str(_grpc_port(viewer)), str(rrd)]


def test_the_web_viewer_is_served_on_127_0_0_1_quiet_and_ends_with_the_thread_that_started_it(
        tmp_path: Path, fake_viewer: Path, viewers: list[Viewer]) -> None:
    rrd = tmp_path / "drive.rrd"
    web_port = free_port(socket.SOCK_STREAM)
    viewer = serve_rrd(rrd, web_port, native=False)
    viewers.append(viewer)
    seen = _seen(fake_viewer)
    grpc_port = _grpc_port(viewer)
    assert seen["args"] == ["--serve-web", "--bind", "127.0.0.1", "--port", str(grpc_port),
                            "--web-viewer-port", str(web_port), str(rrd)]
    assert viewer.url == viewer_url(web_port, grpc_port)
    assert (seen["stdin"], seen["stdout"]) == ("/dev/null", "/dev/null")
    assert seen["rust_log"] == "warn"
    assert seen["session_leader"] is True
    assert seen["death_signal"] == signal.SIGTERM
    viewer.close()
    assert viewer.process.returncode == -signal.SIGTERM


def test_the_web_viewer_on_port_0_is_served_on_a_free_port_it_names(
        fake_viewer: Path, viewers: list[Viewer]) -> None:
    viewer = serve_rrd(None, 0, native=False)
    viewers.append(viewer)
    args = _seen(fake_viewer)["args"]
    web_port = int(args[args.index("--web-viewer-port") + 1])
    assert web_port != 0
    assert args[-1] == str(web_port)  # no file: what is sent
    assert viewer.url == viewer_url(web_port, _grpc_port(viewer))


def test_a_users_rust_log_reaches_the_viewer(
        fake_viewer: Path, viewers: list[Viewer], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("RUST_LOG", "debug")
    viewers.append(serve_rrd(None, 0, native=True))
    assert _seen(fake_viewer)["rust_log"] == "debug"


class _Recording:
    def __init__(self) -> None:
        self.sinks: tuple[Any, ...] = ()

    def set_sinks(self, *sinks: Any) -> None:
        self.sinks = sinks


@pytest.mark.parametrize("variable", ["DISPLAY", "WAYLAND_DISPLAY"])
def test_with_a_display_the_live_view_opens_the_native_viewer(
        variable: str, fake_viewer: Path, viewers: list[Viewer],
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setenv(variable, ":1" if variable == "DISPLAY" else "wayland-0")
    assert has_display()
    viewer = open_viewer(_Recording(), 0, None)
    viewers.append(viewer)
    assert viewer.url is None
    assert "--serve-web" not in _seen(fake_viewer)["args"]


def test_without_a_display_the_live_view_serves_the_web_viewer_on_the_port_asked_for(
        fake_viewer: Path, viewers: list[Viewer], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert not has_display()
    web_port = free_port(socket.SOCK_STREAM)
    recording = _Recording()
    viewer = open_viewer(recording, web_port, None)
    viewers.append(viewer)
    assert viewer.url == viewer_url(web_port, _grpc_port(viewer))
    assert len(recording.sinks) == 1  # the viewer alone: nothing saved


def test_the_web_viewers_address_carries_the_recordings_address_percent_encoded() -> None:
    url = viewer_url(9090, 9876)
    assert url == ("http://127.0.0.1:9090/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A9876%2Fproxy")
    query = urllib.parse.parse_qs(urllib.parse.urlsplit(url).query)
    assert query == {"url": ["rerun+http://127.0.0.1:9876/proxy"]}


def test_a_web_viewer_that_ignores_sigterm_is_killed_after_the_stop_wait(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(view, "_STOP_WAIT_S", 0.2)
    process = subprocess.Popen(["sh", "-c", 'trap "" TERM; echo ready; exec sleep 30'],
                               stdin=subprocess.DEVNULL, stdout=subprocess.PIPE)
    try:
        assert process.stdout is not None and process.stdout.readline() == b"ready\n"
        Viewer(process, "rerun+http://127.0.0.1:9/proxy", "http://127.0.0.1:9/").close()
        assert process.returncode == -signal.SIGKILL
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        process.stdout.close()  # type: ignore[union-attr]


@pytest.mark.parametrize("native", [True, False], ids=["native", "web"])
def test_the_viewer_never_reads_the_terminal_the_view_was_started_from(
        native: bool, fake_viewer: Path, viewers: list[Viewer]) -> None:
    read_end, write_end = os.pipe()  # (the view's own input: a pipe, as a terminal would be)
    saved = os.dup(0)
    try:
        os.dup2(read_end, 0)
        viewers.append(serve_rrd(None, 0, native=native))
    finally:
        os.dup2(saved, 0)
        for fd in (saved, read_end, write_end):
            os.close(fd)
    assert _seen(fake_viewer)["stdin"] == "/dev/null"
