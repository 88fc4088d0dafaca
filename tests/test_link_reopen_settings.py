"""A link that comes back after a break comes back as it was first opened, and telemetry
asked for faster than any link carries is limited.

- A serial device reopened after an unplug runs at the baud rate of the ``--fc`` URL
  (``/dev/ttyACM0,57600``: docs/commands.md, docs/troubleshooting.md), as pymavlink opens
  it the first time: at 1200 first, then the URL's rate (``serialport.SerialLink._reopen``).
  The test reads the line speed the device sees, from the pty's master.
- A ``tcp:`` socket connected again, and the next ``tcpin:`` client taken, get what the first
  socket got (pymavlink's ``mavtcp.do_connect`` and ``mavtcpin.recv``): ``TCP_NODELAY`` (a
  20-byte override is sent at once, not held back by Nagle's algorithm waiting for the last
  packet's ACK) and non-blocking (a stream link never blocks the loop on a write:
  ``stream.py``).
- ``MAV_CMD_SET_MESSAGE_INTERVAL`` asking for an interval shorter than 5 ms is taken as 5 ms
  (``telemetry.StreamSchedule.set_interval``: "at most 200 Hz"), and GET_MESSAGE_INTERVAL
  reports the interval in force; a request at or under 200 Hz is kept as asked.

Real ptys and sockets on 127.0.0.1 (port 0), the links' timers on a fake clock; the telemetry
in the lockstep harness (virtual time).
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import termios
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import lockstep
from support import RawPty, wait_until
from test_links import FakeClock

from mecanum_mav.io.links import REOPEN_PERIOD_S, Link, mavlink, open_link

CMD = mavlink
SPEEDS = {9600: termios.B9600, 57600: termios.B57600, 230400: termios.B230400}
"""Baud rates the tests use, and the termios speed constant a device opened at each has."""


def line_speed(fd: int) -> tuple[int, int]:
    """(input, output) speed constants of the tty behind ``fd`` (a pty's master reads the
    slave's: what the far end set)."""
    attrs = termios.tcgetattr(fd)
    return attrs[4], attrs[5]


def reopen_until_up(link: Link, clock: FakeClock, tries: int = 8) -> bool:
    """Call ``link.reopen`` at each reopen time, as the companion's loop does, until it is up
    (a TCP connect may complete one try later); whether it came up."""
    for _ in range(tries):
        clock.now = max(clock.now, link.next_reopen_s)
        if link.reopen(clock.now):
            return True
        clock.now += REOPEN_PERIOD_S
    return False


# --------------------------------------------------------------------------- serial


@contextlib.contextmanager
def serial_fc(device: Path, baud: int, clock: FakeClock) -> Iterator[tuple[Link, list[RawPty]]]:
    """A link opened on a pty reached by the symlink ``device`` (the list's first pty); the
    link and every pty the test adds to the list closed after."""
    ptys = [RawPty(device)]
    link = open_link(f"{device},{baud}", source_system=255, source_component=190, name="fc",
                     clock=clock)
    try:
        yield link, ptys
    finally:
        link.close()
        for pty in ptys:
            pty.close()


def unplug(link: Link, pty: RawPty) -> None:
    pty.close()  # unplugged: the node vanishes, the link's end reads EIO
    link.send_rc_override(1, 1, [1500] * 4 + [65535] * 14)
    link.read()
    assert link.down_reason == "device gone"


@pytest.mark.parametrize("baud", [9600, 57600, 230400])
def test_a_serial_device_reopened_after_an_unplug_runs_at_the_urls_baud_rate(
        tmp_path: Path, baud: int) -> None:
    """Not pyserial's or pymavlink's default (115200), nor the 1200 the reopen starts at."""
    device = tmp_path / "ttyFC"  # a symlink, as /dev/serial/by-id names are
    clock = FakeClock()
    with serial_fc(device, baud, clock) as (link, ptys):
        first = ptys[0]
        assert line_speed(first.master) == (SPEEDS[baud], SPEEDS[baud])  # as first opened
        as_first_opened = termios.tcgetattr(first.master)  # (no flow control: 8 bits raw)
        unplug(link, first)
        back = RawPty(device)  # plugged back: the same path, a new device
        ptys.append(back)
        assert line_speed(back.master) != (SPEEDS[baud], SPEEDS[baud])  # (not yet set)
        assert reopen_until_up(link, clock)
        assert line_speed(back.master) == (SPEEDS[baud], SPEEDS[baud])
        assert line_speed(link.fileno()) == (SPEEDS[baud], SPEEDS[baud])
        # every setting as first opened: no XON/XOFF (it would eat MAVLink's 0x11 and 0x13
        # bytes), no RTS/CTS or DSR/DTR handshake (a board wires none)
        assert termios.tcgetattr(back.master) == as_first_opened
        assert not os.get_inheritable(link.fileno())  # close-on-exec, as first opened
        started = time.monotonic()
        assert link.read() == []  # nothing waits: the read returns at once, never blocks
        assert time.monotonic() - started < 0.1


def test_a_serial_device_whose_old_port_fails_to_close_is_reopened_all_the_same(
        tmp_path: Path) -> None:
    """Closing the unplugged device's old port can fail (EIO: the device is gone); the
    replugged device is opened and used all the same."""
    device = tmp_path / "ttyFC"
    clock = FakeClock()
    with serial_fc(device, 57600, clock) as (link, ptys):
        unplug(link, ptys[0])
        old = link.conn.port

        def gone() -> None:
            raise OSError(5, "Input/output error")
        old.close = gone
        back = RawPty(device)
        ptys.append(back)
        assert reopen_until_up(link, clock)
        assert link.down_reason is None and link.conn.port is not old


def test_a_serial_device_that_cannot_be_opened_yet_is_tried_again_and_says_why_in_the_log(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """A device node that is there but not a terminal yet (udev still setting it up, no
    permission): the reopen fails quietly (debug log: the link, the path and the error), the
    link stays down and the next try opens it."""
    device = tmp_path / "ttyFC"
    clock = FakeClock()
    with serial_fc(device, 57600, clock) as (link, ptys):
        unplug(link, ptys[0])
        device.write_bytes(b"")  # a node, but not a terminal
        clock.now = link.next_reopen_s
        with caplog.at_level("DEBUG", logger="mecanum_mav"):
            assert not link.reopen(clock.now)
        (record,) = [r for r in caplog.records if "reopening" in r.getMessage()]
        assert record.levelname == "DEBUG"
        assert record.getMessage().startswith(f"fc: reopening {device} failed: ")
        assert "Inappropriate ioctl for device" in record.getMessage()  # (ENOTTY)
        assert link.down_reason == "device gone"
        device.unlink()
        ptys.append(RawPty(device))
        assert reopen_until_up(link, clock)


def test_after_an_unplug_the_first_packet_to_the_replugged_device_goes_at_once(
        tmp_path: Path) -> None:
    """What was handed to the unplugged device went with it: the replugged one's wire is
    free, so the first packet after the reopen goes to the kernel at once, whatever the
    link's clock reads; here virtual time from 0, as the lockstep harness keeps it."""
    device = tmp_path / "ttyFC"
    clock = FakeClock()
    clock.now = 0.0
    with serial_fc(device, 57600, clock) as (link, ptys):
        unplug(link, ptys[0])
        back = RawPty(device)
        ptys.append(back)
        assert reopen_until_up(link, clock)
        assert clock.now < 1.0  # (REOPEN_PERIOD_S after the unplug)
        assert link.takes_packet()  # the stick lane may send now
        link.send_rc_override(1, 1, [1500] * 4 + [65535] * 14)
        assert not link.pending  # handed over, the clock unmoved
        board = mavlink.MAVLink(None)
        got = board.parse_buffer(os.read(back.master, 4096)) or []
        assert [m.get_type() for m in got] == ["RC_CHANNELS_OVERRIDE"]


# --------------------------------------------------------------------------- TCP


def socket_settings(sock: socket.socket) -> tuple[bool, bool, bool]:
    """(TCP_NODELAY set, non-blocking, inherited by child processes) of ``sock``, read from
    the kernel."""
    nodelay = sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) != 0
    return nodelay, not os.get_blocking(sock.fileno()), os.get_inheritable(sock.fileno())


@contextlib.contextmanager
def tcp_fc(clock: FakeClock) -> Iterator[tuple[Link, socket.socket, list[socket.socket]]]:
    """A ``tcp:`` link to a server on 127.0.0.1 that has accepted it (the list's first peer);
    the link, the server and every peer the test adds to the list closed after."""
    server = socket.create_server(("127.0.0.1", 0))
    address = server.getsockname()
    link = open_link(f"tcp:{address[0]}:{address[1]}", source_system=255,
                     source_component=190, name="fc", clock=clock)
    peers = [server.accept()[0]]
    try:
        yield link, server, peers
    finally:
        link.close()
        for peer in peers:
            peer.close()
        server.close()


def until_down(link: Link) -> bool:
    """Read until the link sees it is down (within 5 s)."""
    return wait_until(lambda: (link.read(), not link.up)[1], 5.0,
                      pump=lambda s: select.select([link.fileno()], [], [], s))


def test_a_tcp_link_connected_again_has_nodelay_and_is_non_blocking_as_its_first_socket(
        caplog: pytest.LogCaptureFixture) -> None:
    clock = FakeClock()
    with tcp_fc(clock) as (link, server, peers):
        first = socket_settings(link.conn.port)
        assert first == (True, True, False)  # pymavlink's first connection (close-on-exec)
        peers[0].close()  # the flight controller closes the connection; its server stays
        with caplog.at_level("INFO", logger="mecanum_mav"):
            assert until_down(link)
        assert link.down_reason == "closed by the peer"
        assert "fc: closed by the peer: end of stream" in caplog.messages
        assert reopen_until_up(link, clock)
        peers.append(server.accept()[0])
        assert socket_settings(link.conn.port) == first


class _FailsToClose:
    """A connection whose close fails (EIO), standing in for the one that broke."""

    def close(self) -> None:
        raise OSError(5, "Input/output error")


def test_a_tcp_link_whose_old_connection_fails_to_close_is_connected_again_all_the_same(
        ) -> None:
    clock = FakeClock()
    with tcp_fc(clock) as (link, server, peers):
        peers[0].close()
        assert until_down(link)
        link.conn.port = _FailsToClose()
        assert reopen_until_up(link, clock)
        peers.append(server.accept()[0])
        assert link.send(link.mav.heartbeat_encode(6, 8, 0, 0, 4))
        assert wait_until(lambda: bool(select.select([peers[1]], [], [], 0.05)[0]), 5.0)


@contextlib.contextmanager
def client(port: int) -> Iterator[socket.socket]:
    sock = socket.create_connection(("127.0.0.1", port), timeout=5.0)
    try:
        yield sock
    finally:
        sock.close()


def read_returns(link: Link, timeout_s: float = 2.0) -> bool:
    """``link.read()`` in a thread of its own: whether it returned within ``timeout_s`` (a
    blocking socket with nothing to read would hold it; the test goes on and says so)."""
    reader = threading.Thread(target=link.read, daemon=True)
    reader.start()
    reader.join(timeout_s)
    return not reader.is_alive()


def test_the_next_tcpin_client_gets_nodelay_and_a_non_blocking_socket_as_the_first(
        caplog: pytest.LogCaptureFixture) -> None:
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()  # (pymavlink's tcpin: binds the port it is given)
    link = open_link(f"tcpin:127.0.0.1:{port}", source_system=255, source_component=190,
                     name="fc", clock=FakeClock())

    def taken() -> bool:
        assert read_returns(link), "a read blocked: the client's socket blocks"
        return link.up and link.conn.port is not None

    def wait_readable(wait_s: float) -> None:
        select.select([link.fileno()], [], [], wait_s)

    try:
        with client(port) as first:
            first.sendall(b"\x00")
            assert wait_until(taken, 5.0, pump=wait_readable)
            settings = socket_settings(link.conn.port)
            assert settings == (True, True, False)
        with caplog.at_level("INFO", logger="mecanum_mav"):
            assert wait_until(lambda: read_returns(link) and not link.up, 5.0,
                              pump=wait_readable)
        assert link.down_reason == "client left"
        assert "fc: client left: end of stream" in caplog.messages
        assert not link.send(link.mav.heartbeat_encode(6, 8, 0, 0, 4))  # nobody to send to
        with client(port) as second:  # (leaving, it ends a read a blocking socket holds)
            second.sendall(b"\x00")
            assert wait_until(taken, 5.0, pump=wait_readable)
            assert socket_settings(link.conn.port) == settings
    finally:
        link.close()


class _ClientFailsToClose:
    """A tcpin client's connection whose close fails (EIO); reads as the real one."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock

    def recv(self, size: int) -> bytes:
        return self.sock.recv(size)

    def fileno(self) -> int:
        return self.sock.fileno()

    def close(self) -> None:
        raise OSError(5, "Input/output error")


def test_a_tcpin_link_whose_clients_connection_fails_to_close_listens_for_the_next_all_the_same(
        ) -> None:
    """(A read never raises: ``Link.read``.)"""
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    link = open_link(f"tcpin:127.0.0.1:{port}", source_system=255, source_component=190,
                     name="fc", clock=FakeClock())

    def wait_readable(wait_s: float) -> None:
        select.select([link.fileno()], [], [], wait_s)

    try:
        with client(port) as first:
            first.sendall(b"\x00")
            assert wait_until(lambda: (link.read(), link.conn.port is not None)[1], 5.0,
                              pump=wait_readable)
            taken = link.conn.port
            link.conn.port = _ClientFailsToClose(taken)
        try:
            assert wait_until(lambda: (link.read(), not link.up)[1], 5.0, pump=wait_readable)
        finally:
            taken.close()
        assert link.down_reason == "client left"
        with client(port) as second:
            second.sendall(b"\x00")
            assert wait_until(lambda: (link.read(), link.up)[1], 5.0, pump=wait_readable)
    finally:
        link.close()


# --------------------------------------------------------------------------- telemetry


def interval_reported(h, message_id: int) -> list[int]:
    since = h.gcs.mark()
    ack = h.gcs.command(CMD.MAV_CMD_GET_MESSAGE_INTERVAL, message_id)
    assert ack.result == CMD.MAV_RESULT_ACCEPTED
    return [m.interval_us for m in h.gcs.received("MESSAGE_INTERVAL", since)]


@pytest.mark.parametrize("asked_us", [1, 100, 4999])
def test_a_message_interval_shorter_than_5_ms_is_accepted_as_200_hz(asked_us: int) -> None:
    h = lockstep({}, dt_s=0.001)  # the loop wakes every millisecond: only the cap limits
    h.run_for(1.0)
    ack = h.gcs.command(CMD.MAV_CMD_SET_MESSAGE_INTERVAL, CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE,
                        asked_us)
    assert ack.result == CMD.MAV_RESULT_ACCEPTED  # limited, not refused
    assert interval_reported(h, CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE) == [5000]
    start = h.gcs.mark()
    h.run_for(1.0)
    sent = len(h.gcs.received("WHEEL_DISTANCE", start))
    assert 195 <= sent <= 201, sent  # 200 a second, not one per wake (1000)


def test_a_message_interval_of_5_ms_or_longer_is_kept_as_asked() -> None:
    h = lockstep({}, dt_s=0.001)
    h.run_for(1.0)
    for asked_us in (5000, 5001, 10000):
        assert h.gcs.command(CMD.MAV_CMD_SET_MESSAGE_INTERVAL,
                             CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE, asked_us).result == (
            CMD.MAV_RESULT_ACCEPTED)
        assert interval_reported(h, CMD.MAVLINK_MSG_ID_WHEEL_DISTANCE) == [asked_us]
