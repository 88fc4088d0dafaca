"""What ``mecanum-mav view`` and ``mecanum-mav log --rerun/--view`` print, and when
(mecanum_mav.app.view.run_view, show_log): the sources and where the view shows, the file
written and its rows, the viewer's address while it is open (flushed: ``sim --view`` and a
pipe read it at once), and what ends a view.

The real web viewer is served where a test needs one (no display here).
"""

from __future__ import annotations

import io
import re
import socket
import sys
from pathlib import Path

import pytest

pytest.importorskip("rerun", reason="the view extra (rerun-sdk) is not installed")

from mecanum_mav.app.view import run_view, show_log, viewer_url
from mecanum_mav.config.params import Params
from mecanum_mav.io.tlog import TlogEntry, parse_tlog, tlog_record
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.process import free_port

BASE_US = 1_800_000_000_000_000


class FlushedOut(io.StringIO):
    """An output that keeps what had been written at its last flush."""

    def __init__(self) -> None:
        super().__init__()
        self.flushed = ""

    def flush(self) -> None:
        super().flush()
        self.flushed = self.getvalue()


def _tlog_bytes(count: int, sysid: int = 1) -> bytes:
    mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=1)
    return b"".join(
        tlog_record(BASE_US + k * 100_000,
                    mav.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,
                                         mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3).pack(mav))
        for k in range(count))


def _entries(count: int = 3) -> list[TlogEntry]:
    return parse_tlog(_tlog_bytes(count)).entries


def _serving(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


@pytest.fixture(autouse=True)
def _no_display(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.delenv("RERUN_CLI_PATH", raising=False)


# --------------------------------------------------------------------------- view


def test_view_names_every_source_the_web_viewers_address_and_the_file_it_records_to(
        tmp_path: Path) -> None:
    a, b = tmp_path / "a.tlog", tmp_path / "b.tlog"
    a.write_bytes(_tlog_bytes(3, sysid=1))
    b.write_bytes(_tlog_bytes(3, sysid=2))
    save = tmp_path / "view.rrd"
    web_port = free_port(socket.SOCK_STREAM)
    out = FlushedOut()
    first_line_flushed: list[bool] = []

    def fed(mapping: object) -> bool:
        first_line_flushed.append(out.flushed.count("\n") == 1)
        return getattr(mapping, "messages", 0) >= 6

    assert run_view([str(a), str(b)], Params(), save=save, web_port=web_port, out=out,
                    stop_when=fed) == 0
    first, last = out.getvalue().splitlines()
    match = re.fullmatch(rf"mecanum-mav view: {re.escape(str(a))}, {re.escape(str(b))} -> "
                         rf"(\S+); recording to {re.escape(str(save))}", first)
    assert match, first
    grpc_port = int(re.search(r"%3A(\d+)%2Fproxy", match.group(1)).group(1))  # type: ignore[union-attr]
    assert match.group(1) == viewer_url(web_port, grpc_port)
    assert last == "mecanum-mav view: 6 messages"
    assert first_line_flushed[0]  # seen before the view ends
    assert out.flushed == out.getvalue()  # the count too
    assert save.stat().st_size > 0


def test_view_without_save_says_only_where_it_shows(tmp_path: Path) -> None:
    source = tmp_path / "a.tlog"
    source.write_bytes(_tlog_bytes(2))
    web_port = free_port(socket.SOCK_STREAM)
    out = io.StringIO()
    assert run_view(str(source), Params(), web_port=web_port, out=out,
                    stop_when=lambda mapping: mapping.messages >= 2) == 0
    first = out.getvalue().splitlines()[0]
    assert re.fullmatch(rf"mecanum-mav view: {re.escape(str(source))} -> "
                        rf"http://127\.0\.0\.1:{web_port}/\?url=rerun%2Bhttp%3A%2F%2F127\.0\.0\.1"
                        r"%3A\d+%2Fproxy", first), first


# --------------------------------------------------------------------------- log --view


def test_log_view_without_a_file_writes_a_temporary_rrd_serves_it_and_ctrl_c_ends_it() -> None:
    out, err = FlushedOut(), io.StringIO()
    web_port = free_port(socket.SOCK_STREAM)
    seen_while_open: list[str] = []

    def ctrl_c() -> None:
        seen_while_open.append(out.flushed)
        assert _serving(web_port)
        raise KeyboardInterrupt

    assert show_log(_entries(3), Params(), None, True, web_port, out, err, then=ctrl_c) == 0
    assert err.getvalue() == ""
    wrote, view = out.getvalue().splitlines()
    match = re.fullmatch(r"wrote (\S+) \((\d+) rows in (\d+\.\d\d) s\)", wrote)
    assert match, wrote
    rrd = Path(match.group(1))
    assert rrd.suffix == ".rrd" and int(match.group(2)) > 0
    assert 0.0 <= float(match.group(3)) < 60.0  # how long the writing took
    assert not rrd.exists() and not rrd.parent.exists()  # the temporary file is gone
    assert re.fullmatch(rf"mecanum-mav log: the view: http://127\.0\.0\.1:{web_port}/\?url=\S+ "
                        r"\(Ctrl-C ends\)", view), view
    assert seen_while_open == [out.getvalue()]  # both lines shown while the view was open
    assert not _serving(web_port)  # Ctrl-C stopped the web viewer


def test_log_rerun_into_a_folder_not_there_yet_creates_it_and_says_so_at_once(
        tmp_path: Path) -> None:
    rrd = tmp_path / "runs" / "today" / "drive.rrd"
    out = FlushedOut()
    called: list[str] = []
    assert show_log(_entries(3), Params(), rrd, False, 0, out, io.StringIO(),
                    then=lambda: called.append(out.flushed)) == 0
    assert rrd.stat().st_size > 0
    assert out.getvalue().startswith(f"wrote {rrd} (")
    assert called == [out.getvalue()]


def test_log_view_without_the_viewer_names_what_is_missing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "rerun_cli", None)  # not installed
    err = io.StringIO()
    assert show_log(_entries(), Params(), tmp_path / "v.rrd", True, 0, io.StringIO(), err) == 2
    assert err.getvalue() == (
        "mecanum-mav log: the Rerun viewer (rerun_cli, in rerun-sdk) is not installed\n")
