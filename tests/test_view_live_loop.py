"""``mecanum-mav view``'s live loop (mecanum_mav.app.view.run_view and its sources): what makes
it exit 2, how SIGTERM ends it, and what reaches the mapping from a link or a growing tlog.

The real web viewer is served (it starts in about half a second) except where the test is
about a viewer that does not start.
"""

from __future__ import annotations

import gc
import io
import os
import re
import signal
import socket
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("rerun", reason="the view extra (rerun-sdk) is not installed")

from support import child_processes

from mecanum_mav.app.rerunview import ViewMapping
from mecanum_mav.app.view import TlogFollower, gc_paused, merged, run_view
from mecanum_mav.config.params import Params
from mecanum_mav.io.tlog import tlog_record
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.process import free_port

BASE_US = 1_800_000_000_000_000


def _heartbeat(mav: object | None = None) -> bytes:
    sender = mav or mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    return bytes(sender.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,  # type: ignore[attr-defined]
                                         mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3)
                 .pack(sender))


def _tlog(path: Path, count: int = 3) -> Path:
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    path.write_bytes(b"".join(tlog_record(BASE_US + k * 100_000, _heartbeat(mav))
                              for k in range(count)))
    return path


def _web_port(out: str) -> int:
    match = re.search(r"-> http://127\.0\.0\.1:(\d+)/", out)
    assert match, out
    return int(match.group(1))


def _serving(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


# --------------------------------------------------------------------------- exit status 2


def test_view_without_the_view_extra_exits_2_with_the_install_hint(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "rerun", None)  # rerun-sdk not installed
    assert run_view(str(_tlog(tmp_path / "a.tlog")), Params(), web_port=0) == 2
    assert "pip install 'mecanum-mav[view]'" in capsys.readouterr().err


def test_a_viewer_that_cannot_start_makes_view_exit_2(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("RERUN_CLI_PATH", "/bin/false")
    out = io.StringIO()
    assert run_view(str(_tlog(tmp_path / "a.tlog")), Params(), web_port=0, out=out) == 2
    assert "mecanum-mav view: the Rerun viewer exited at once" in capsys.readouterr().err
    assert out.getvalue() == ""  # it never said it was viewing anything


def test_view_saving_into_a_missing_folder_exits_2_and_leaves_no_viewer_running(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # 'view --save' to a path that cannot be created: the web viewer already started is
    # stopped (it runs in a session of its own: nothing else would stop it).
    before = child_processes()
    save = tmp_path / "missing" / "view.rrd"
    status = run_view(str(_tlog(tmp_path / "a.tlog")), Params(), save=save, web_port=0,
                      out=io.StringIO())
    assert status == 2
    assert str(save) in capsys.readouterr().err
    assert child_processes() == before


def test_view_on_a_port_another_program_holds_exits_2_naming_the_link(
        capsys: pytest.CaptureFixture[str]) -> None:
    # 'view --connect udpin:127.0.0.1:14550' while a ground station holds that port: exit 2,
    # the link named, the web viewer stopped.
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as holder:
        holder.bind(("127.0.0.1", 0))
        url = f"udpin:127.0.0.1:{holder.getsockname()[1]}"
        out = io.StringIO()
        before = child_processes()
        assert run_view(url, Params(), web_port=0, out=out) == 2
    assert capsys.readouterr().err.startswith(f"mecanum-mav view: {url}: ")
    assert not _serving(_web_port(out.getvalue()))
    assert child_processes() == before


# --------------------------------------------------------------------------- how it ends


def test_sigterm_ends_the_view_as_ctrl_c_does_and_then_the_previous_handler_is_back(
        tmp_path: Path) -> None:
    source = _tlog(tmp_path / "a.tlog")
    previous = signal.getsignal(signal.SIGTERM)
    out = io.StringIO()
    deadline = time.monotonic() + 20.0

    def terminate_once_fed(mapping: ViewMapping) -> bool:
        if mapping.messages >= 3:
            os.kill(os.getpid(), signal.SIGTERM)
        return time.monotonic() > deadline  # (only if SIGTERM did not end it)

    assert run_view(str(source), Params(), web_port=0, out=out,
                    stop_when=terminate_once_fed) == 0
    assert out.getvalue().endswith("mecanum-mav view: 3 messages\n")
    assert not _serving(_web_port(out.getvalue()))  # the web viewer stopped
    assert signal.getsignal(signal.SIGTERM) == previous


def test_the_view_runs_in_a_thread_other_than_the_main_one(tmp_path: Path) -> None:
    # Signal handlers can be set in the main thread only; in another the view leaves SIGTERM
    # as it is and still runs.
    source = _tlog(tmp_path / "a.tlog")
    previous = signal.getsignal(signal.SIGTERM)
    results: list[int] = []
    errors: list[BaseException] = []

    def view() -> None:
        try:
            results.append(run_view(str(source), Params(), web_port=0, out=io.StringIO(),
                                    stop_when=lambda mapping: mapping.messages >= 3))
        except BaseException as exc:
            errors.append(exc)

    thread = threading.Thread(target=view)
    thread.start()
    thread.join(30.0)
    assert not thread.is_alive()
    assert errors == [] and results == [0]
    assert signal.getsignal(signal.SIGTERM) == previous


# --------------------------------------------------------------------------- its sources


def test_bad_data_on_a_live_link_is_not_fed_to_the_view() -> None:
    port = free_port(socket.SOCK_DGRAM)
    batches: Iterator[list[tuple[float, object]]] = merged([f"udpin:127.0.0.1:{port}"])
    received: list[str] = []
    try:
        assert next(batches) == []  # listening now, nothing came yet
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            sender.sendto(b"not mavlink at all", ("127.0.0.1", port))
            sender.sendto(_heartbeat(), ("127.0.0.1", port))
        deadline = time.monotonic() + 5.0
        while "HEARTBEAT" not in received and time.monotonic() < deadline:
            received += [msg.get_type() for _, msg in next(batches)]
    finally:
        batches.close()  # type: ignore[attr-defined]
    assert received == ["HEARTBEAT"]


def test_a_tlog_whose_first_record_is_cut_short_is_read_once_it_is_complete(
        tmp_path: Path) -> None:
    record = tlog_record(BASE_US, _heartbeat())
    path = tmp_path / "live.tlog"
    path.write_bytes(record[:12])  # the stamp and the packet's first bytes
    follower = TlogFollower(path)
    try:
        assert follower.poll() == []
        with path.open("ab") as f:
            f.write(record[12:])
        read = follower.poll()
        assert [(t, msg.get_type()) for t, msg in read] == [(BASE_US / 1e6, "HEARTBEAT")]
    finally:
        follower.close()


def test_gc_paused_leaves_a_collector_that_was_off_off() -> None:
    gc.disable()
    try:
        with gc_paused():
            assert not gc.isenabled()
        assert not gc.isenabled()
    finally:
        gc.enable()
    with gc_paused():
        assert not gc.isenabled()
    assert gc.isenabled()
