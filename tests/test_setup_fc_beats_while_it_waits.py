"""``setup-fc`` keeps a ground station's HEARTBEAT going at 1 Hz while it waits on the board
(mecanum_mav.app.setupfc.FcSession): the board's GCS failsafe and ArduPilot's choice of the
ground station it answers go by it. Against a silent board on a real socket (127.0.0.1,
port 0)."""

from __future__ import annotations

import io
import socket
import time

import pytest
from support import FakeFlightController

from mecanum_mav.app import setupfc
from mecanum_mav.app.setupfc import FcSession
from mecanum_mav.config.params import Params
from mecanum_mav.control.core import FC_LINK_COMPID
from mecanum_mav.protocol.dialect import mavlink


def test_a_heartbeat_a_second_goes_to_a_silent_board_until_setup_fc_gives_up_on_it() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as board:
        board.bind(("127.0.0.1", 0))
        session = FcSession(f"udpout:127.0.0.1:{board.getsockname()[1]}", Params())
        try:
            started = time.monotonic()
            assert session.wait_heartbeat(1.5) is False
            assert time.monotonic() - started < 1.5 + 0.4  # given up on time
        finally:
            session.close()
        board.setblocking(False)
        parser = mavlink.MAVLink(None)
        heard = []
        while True:
            try:
                heard += parser.parse_buffer(board.recv(65536)) or []
            except BlockingIOError:
                break
    beats = [m for m in heard if m.get_type() == "HEARTBEAT"]
    assert len(beats) == 2  # at once, and a second later
    for beat in beats:
        assert (beat.get_srcSystem(), beat.get_srcComponent()) == (
            int(Params()["FC_GCS_SYSID"]), FC_LINK_COMPID)
        assert (beat.type, beat.autopilot) == (mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID)


def test_only_the_heartbeat_of_the_system_fc_sysid_names_counts(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """FC_SYSID 3, FC_COMPID 1: a board beating as system 1 (component 1) is another one."""
    monkeypatch.setattr(setupfc, "HEARTBEAT_TIMEOUT_S", 0.6)
    params = Params()
    params.update({"FC_SYSID": 3.0})
    with FakeFlightController(sysid=1, compid=1) as board:
        status = setupfc.run_setup(board.url, params, apply=False, out=io.StringIO())
    assert status == 2
    assert capsys.readouterr().err == (
        f"mecanum-mav setup-fc: no HEARTBEAT from system 3 on {board.url}\n")
