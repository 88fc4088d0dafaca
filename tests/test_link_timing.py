"""The links' timers asserted exactly, on a fake clock (issue 23.4).

A :class:`~mecanum_mav.io.links.Link` takes every time it acts on from its ``clock``: pacing
to the baud rate, the reopen timer of a broken stream link, the ``udpin:`` peers' ages (the
send-failure log's rate and a ``udpout:`` link's reconnect: test_links.py). Here that clock
is a fake one the test moves, on real ptys and sockets: what the kernel was handed is read
back from the far end, and every time is compared exactly (times are binary fractions, so the
float sums are exact too; byte times at a baud rate to a nanosecond). The real processes over
the same transports (test_serial_pacing.py, test_link_reconnect.py) keep only causal checks.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from support import RawPty
from test_links import FakeClock

from mecanum_mav.io import links
from mecanum_mav.io.links import Link, mavlink, open_link

HALF_SECOND = 0.5
"""The documented reopen cadence of a broken serial or TCP link (seconds)."""
START_S = 100.0
"""Where :class:`FakeClock` starts (seconds)."""


class Pty(RawPty):
    """A pty behind ``path`` (a symlink, as udev names a USB serial device); its master is
    read only when the test asks (:meth:`take`)."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self.mav = mavlink.MAVLink(None)
        self.mav.robust_parsing = True

    def take(self) -> bytes:
        """Every byte the link handed to the kernel so far (a pty passes written bytes on at
        once: the slave's write returns after they reached the master's buffer)."""
        data = b""
        while select.select([self.master], [], [], 0)[0]:
            try:
                chunk = os.read(self.master, 65536)
            except OSError:
                break
            if not chunk:
                break
            data += chunk
        return data

    def messages(self) -> list[Any]:
        return [m for m in self.mav.parse_buffer(self.take()) or ()
                if m.get_type() != "BAD_DATA"]

    def unplug(self) -> None:
        """The cable is pulled: the node vanishes, the link's end reads EIO."""
        self.close()


@contextlib.contextmanager
def serial(tmp_path: Path, baud: int, clock: FakeClock) -> Iterator[tuple[Link, Pty]]:
    pty = Pty(tmp_path / "ttyFC")
    link = open_link(f"{pty.path},{baud}", source_system=255, source_component=190,
                     name="fc", clock=clock)
    try:
        yield link, pty
    finally:
        link.close()
        pty.unplug()


def exactly(time_s: float) -> Any:
    """``time_s`` to a nanosecond (sums of byte times at a baud rate are not binary
    fractions; the pacing's own sums round differently in the last bit)."""
    return pytest.approx(time_s, rel=0.0, abs=1e-9)


def override(pulse: int) -> list[int]:
    return [pulse] * 4 + [65535] * 4 + [0] * 10


# --------------------------------------------------------------------------- pacing


@pytest.mark.parametrize("baud", [9600, 57600, 115200])
def test_an_override_handed_to_a_serial_link_frees_the_wire_after_exactly_its_bits_at_the_baud_rate(
        tmp_path: Path, baud: int) -> None:
    clock = FakeClock()
    with serial(tmp_path, baud, clock) as (link, pty):
        link.send_rc_override(1, 1, override(1100))  # the wire is free: handed over at once
        first = pty.take()
        assert first and not link.pending
        link.send_rc_override(1, 1, override(1200))  # waits for the wire
        assert pty.take() == b"" and link.pending
        on_wire_s = len(first) * 10 / baud  # 8N1: ten bits a byte
        due = START_S + on_wire_s - links.PACING_LEAD_S
        assert link.next_send_s == due
        clock.now = due - 2.0 ** -20  # a hair before: still waiting
        link.flush()
        assert pty.take() == b"" and link.next_send_s == due
        clock.now = due
        link.flush()
        second = pty.take()
        assert [m.chan1_raw for m in pty.mav.parse_buffer(second) or ()] == [1200]
        assert not link.pending and link.next_send_s == float("inf")
        # the wire is busy until the first packet's end, then the second's
        link.send_rc_override(1, 1, override(1300))
        assert link.next_send_s == exactly(
            START_S + (len(first) + len(second)) * 10 / baud - links.PACING_LEAD_S)


def test_a_serial_link_idle_longer_than_a_packet_hands_over_at_once_without_banking_time(
        tmp_path: Path) -> None:
    clock = FakeClock()
    with serial(tmp_path, 57600, clock) as (link, pty):
        link.send_rc_override(1, 1, override(1100))
        size = len(pty.take())
        clock.now = START_S + 1.0  # long idle: the wire is free again
        link.send_rc_override(1, 1, override(1200))
        assert len(pty.take()) == size  # at once
        link.send_rc_override(1, 1, override(1300))
        # the idle second is not credit: the next waits for the packet just handed over
        assert link.next_send_s == exactly(
            START_S + 1.0 + size * 10 / 57600 - links.PACING_LEAD_S)


def test_a_heartbeat_queued_behind_a_stream_of_overrides_goes_after_at_most_one_override(
        tmp_path: Path) -> None:
    """Overrides and queued packets take turns: a 1 kHz override stream on a 57600-baud
    wire never starves the heartbeat."""
    clock = FakeClock()
    with serial(tmp_path, 57600, clock) as (link, pty):
        link.send_rc_override(1, 1, override(1000))
        link.send(link.mav.heartbeat_encode(6, 8, 0, 0, 4))
        got: list[Any] = pty.messages()
        for i in range(1, 40):  # an override every millisecond
            clock.now = START_S + i * 2.0 ** -10
            link.send_rc_override(1, 1, override(1000 + i))
            link.flush()
            got += pty.messages()
        kinds = [m.get_type() for m in got]
        assert kinds[:3] == ["RC_CHANNELS_OVERRIDE", "HEARTBEAT", "RC_CHANNELS_OVERRIDE"]
        assert link.superseded > 0  # the wire carries fewer than 1000 a second


# --------------------------------------------------------------------------- reopening


def step_reopen(link: Link, clock: FakeClock, until_s: float, dt_s: float = 2.0 ** -7
                ) -> list[float]:
    """Call ``link.reopen`` at every ``dt_s`` up to ``until_s`` as the companion's loop does
    while the link is down; the times it tried (its timer moved), until it came up."""
    tried = []
    while clock.now < until_s and not link.up:
        clock.now += dt_s
        before = link.next_reopen_s
        up = link.reopen(clock.now)
        if up or link.next_reopen_s != before:
            tried.append(clock.now)
    return tried


def test_an_unplugged_serial_link_tries_to_reopen_exactly_every_half_second_until_plugged_back(
        tmp_path: Path) -> None:
    clock = FakeClock()
    with serial(tmp_path, 57600, clock) as (link, pty):
        pty.unplug()
        link.send_rc_override(1, 1, override(1500))  # the write finds the device gone
        link.read()
        assert not link.up and link.down_reason == "device gone"
        assert link.wait_fd() is None  # its dead descriptor is not waited on
        assert link.next_reopen_s == START_S + HALF_SECOND
        tried = step_reopen(link, clock, START_S + 2.1)
        assert tried == [START_S + k * HALF_SECOND for k in (1, 2, 3, 4)]
        assert not link.up
        plugged_s = START_S + 2.25  # back between two tries
        clock.now = plugged_s
        back = Pty(Path(pty.path))
        try:
            tried = step_reopen(link, clock, START_S + 5.0)
            assert tried == [START_S + 2.5]  # the next try after the plug opens it
            assert link.up and link.next_reopen_s == float("inf")
            link.send_rc_override(1, 1, override(1500))
            assert [m.chan1_raw for m in back.messages()] == [1500]
        finally:
            back.unplug()


def test_a_serial_path_that_reappears_as_something_else_than_a_tty_keeps_the_link_down_trying(
        tmp_path: Path) -> None:
    """(A udev name briefly pointing elsewhere, or a file left at the path: it is not opened
    as the board; the link goes on trying every half second, and opens the tty once it is
    back.)"""
    clock = FakeClock()
    with serial(tmp_path, 57600, clock) as (link, pty):
        pty.unplug()
        link.send_rc_override(1, 1, override(1500))
        link.read()
        assert not link.up
        Path(pty.path).write_text("not a serial device\n")
        tried = step_reopen(link, clock, START_S + 1.1)
        assert tried == [START_S + 0.5, START_S + 1.0] and not link.up
        Path(pty.path).unlink()
        back = Pty(Path(pty.path))
        try:
            assert step_reopen(link, clock, START_S + 2.0) == [START_S + 1.5]
            assert link.up
        finally:
            back.unplug()


def test_a_tcp_link_whose_server_is_gone_tries_to_connect_exactly_every_half_second(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    clock = FakeClock()
    server = socket.create_server(("127.0.0.1", 0))
    address = server.getsockname()
    link = open_link(f"tcp:{address[0]}:{address[1]}", source_system=255,
                     source_component=190, name="fc", clock=clock)
    try:
        peer, _ = server.accept()
        peer.close()
        server.close()  # the flight controller is gone, and its server
        for _ in range(100):  # (the end of stream arrives a moment after the close)
            link.read()
            if not link.up:
                break
            select.select([link.fileno()], [], [], 0.1)
        assert link.down_reason == "closed by the peer"
        assert link.next_reopen_s == START_S + HALF_SECOND
        with caplog.at_level("DEBUG", logger="mecanum_mav"):
            tried = step_reopen(link, clock, START_S + 2.1)
        assert tried == [START_S + k * HALF_SECOND for k in (1, 2, 3, 4)]  # each refused
        said = [r.getMessage() for r in caplog.records if r.levelname == "DEBUG"]
        assert len(said) == 4, said  # each try says why, in the debug log
        for line in said:
            assert line.startswith("fc: reconnecting failed: ") and "Connection refused" in line
        server = socket.create_server(address)  # back on the same port
        tried = step_reopen(link, clock, START_S + 5.0)
        # the next try connects; a connect still in flight then completes at the one after
        assert tried in ([START_S + 2.5], [START_S + 2.5, START_S + 3.0]), tried
        assert link.up
    finally:
        link.close()
        server.close()


# --------------------------------------------------------------------------- udpin peers


def test_a_udpin_peer_silent_for_exactly_the_peer_timeout_is_kept_and_one_silent_longer_forgotten(
        ) -> None:
    clock = FakeClock()
    link = open_link("udpin:127.0.0.1:0", source_system=1, source_component=1, name="gcs",
                     clock=clock)
    url = f"udpout:127.0.0.1:{link.local_port}"
    stations = [open_link(url, source_system=255, source_component=190, name=f"gcs{i}")
                for i in range(3)]
    addresses = [("127.0.0.1", s.local_port) for s in stations]

    def hear(i: int, at_s: float) -> None:
        clock.now = at_s
        stations[i].mav.heartbeat_send(6, 8, 0, 0, 4)
        for _ in range(100):
            if link.read():
                return
            select.select([link.fileno()], [], [], 0.1)
        raise AssertionError("nothing arrived")

    try:
        hear(0, START_S)
        hear(1, START_S + links.PEER_TIMEOUT_S)  # station 0 silent for exactly the timeout
        assert link.conn.clients == set(addresses[:2])
        hear(2, START_S + links.PEER_TIMEOUT_S + 2.0 ** -10)  # now a hair longer
        assert link.conn.clients == set(addresses[1:])
    finally:
        link.close()
        for s in stations:
            s.close()
