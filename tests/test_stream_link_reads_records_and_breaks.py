"""Stream links (mecanum_mav/io/links/stream.py) at their edges, on real TCP sockets and a
pty: a read takes at most ``max_reads`` chunks, a packet split across reads is completed, a
tlog records what is read and what the stick lane sends, a signing link signs from the newest
verified timestamp it read, a lane packet whose write finds the link broken is lost and
counted, and the last words at close wait for a board whose buffer is full until it reads
again."""

from __future__ import annotations

import array
import fcntl
import logging
import os
import resource
import select
import socket
import termios
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from support import RawPty, mavlink_sender, override_channels, wait_until
from test_links import FakeClock

from mecanum_mav.io.links import Link, mavlink, mavutil, open_link
from mecanum_mav.io.links.base import READ_CHUNK
from mecanum_mav.io.links.stream import LAST_WORDS_MAX_S, ready_within
from mecanum_mav.protocol.signing import TICKS_PER_S, ticks_from_unix

KEY = bytes(range(32))
NEUTRAL, RELEASE = [1500] * 4 + [65535] * 4 + [0] * 10, [0] * 4 + [65535] * 4 + [0] * 10


@contextmanager
def tcp_pair(signing_key: bytes | None = None,
             clock: Any = time.monotonic) -> Iterator[tuple[Link, socket.socket]]:
    """A ``tcp:`` link and the flight controller's end of its connection (blocking, 5 s)."""
    server = socket.create_server(("127.0.0.1", 0))
    host, port = server.getsockname()
    link = open_link(f"tcp:{host}:{port}", source_system=255, source_component=190,
                     name="fc", signing_key=signing_key, clock=clock)
    peer, _ = server.accept()
    peer.settimeout(5.0)
    try:
        yield link, peer
    finally:
        link.close()
        peer.close()
        server.close()


def waiting_bytes(fd: int) -> int:
    count = array.array("i", [0])
    fcntl.ioctl(fd, termios.FIONREAD, count, True)
    return count[0]


def board_sender() -> Any:
    return mavlink.MAVLink(None, srcSystem=1, srcComponent=1)


def heartbeat(mav: Any, custom_mode: int = 0) -> bytes:
    return bytes(mav.heartbeat_encode(10, 3, 0, custom_mode, 3).pack(mav))


def test_a_stream_read_takes_at_most_max_reads_chunks_and_leaves_the_rest_for_the_next():
    with tcp_pair() as (link, peer):
        board = board_sender()
        packet = heartbeat(board)
        count = 2 * READ_CHUNK // len(packet)  # two chunks' worth
        peer.sendall(b"".join(heartbeat(board, i) for i in range(count)))
        assert wait_until(lambda: waiting_bytes(link.fileno()) == count * len(packet), 5.0,
                          pump=lambda s: select.select([link.fileno()], [], [], s))
        first = link.read(max_reads=1)
        assert len(first) == READ_CHUNK // len(packet)  # the whole packets of one chunk
        rest = link.read()
        assert [m.custom_mode for m in first + rest] == list(range(count))  # all, in order


def test_a_recording_stream_link_records_what_it_reads_and_what_the_stick_lane_sends(
        tmp_path: Path):
    tlog = tmp_path / "fc.tlog"
    with tcp_pair() as (link, peer), tlog.open("wb") as out:
        link.record_to(out)
        peer.sendall(heartbeat(board_sender()))
        got: list[Any] = []
        assert wait_until(lambda: got.extend(link.read()) or got, 5.0,
                          pump=lambda s: select.select([link.fileno()], [], [], s))
        lane = mavlink_sender()
        stick = bytes(lane.rc_channels_override_encode(1, 1, *NEUTRAL).pack(lane))
        assert link.takes_packet()
        link.send_packet(stick)
        assert peer.recv(1024) == stick
    log = mavutil.mavlink_connection(str(tlog))
    recorded = []
    while (msg := log.recv_match()) is not None:
        recorded.append((msg.get_type(), msg.get_srcSystem()))
    assert recorded == [("HEARTBEAT", 1), ("RC_CHANNELS_OVERRIDE", 255)]


def test_a_signing_stream_link_signs_no_earlier_than_the_newest_verified_packet_it_read():
    """As on a datagram link (test_links.py): ArduPilot drops a stream signed more than a
    minute behind its own timestamp, so the link takes the peer's verified one."""
    ahead = ticks_from_unix(time.time()) + 600 * TICKS_PER_S
    with tcp_pair(signing_key=KEY) as (link, peer):
        board = mavlink_sender(KEY, sysid=1, compid=1, link_id=1, timestamp=ahead)
        peer.sendall(heartbeat(board))
        got: list[Any] = []
        assert wait_until(lambda: got.extend(link.read()) or got, 5.0,
                          pump=lambda s: select.select([link.fileno()], [], [], s))
        link.send(mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))
        sent = peer.recv(1024)
        stamp = int.from_bytes(sent[-12:-6], "little")
        assert ahead <= stamp < ahead + TICKS_PER_S, (stamp - ahead)


def test_a_stick_lane_packet_whose_write_finds_the_connection_reset_is_lost_and_counted():
    with tcp_pair() as (link, peer):
        peer.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        peer.close()  # a reset, not an orderly end
        assert select.select([link.fileno()], [], [], 5.0)[0], "the reset never arrived"
        lane = mavlink_sender()
        stick = bytes(lane.rc_channels_override_encode(1, 1, *NEUTRAL).pack(lane))
        sent, unsent = link.sent, link.unsent
        assert link.takes_packet()  # (the link does not know yet)
        link.send_packet(stick)
        assert link.down_reason == "connection lost"
        assert (link.sent, link.unsent) == (sent, unsent + 1)


def test_reopening_a_stream_link_that_is_up_says_so_and_keeps_its_connection():
    clock = FakeClock()
    with tcp_pair(clock=clock) as (link, peer):
        clock.now += 10.0
        assert link.reopen(clock.now)
        link.send(mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))
        assert [m.get_type() for m in mavlink.MAVLink(None).parse_buffer(peer.recv(1024))] == [
            "HEARTBEAT"]


@contextmanager
def descriptors_taken_below(number: int) -> Iterator[None]:
    """Every descriptor below ``number`` in use, as in a process with many files and sockets
    open: what is opened meanwhile is numbered ``number`` or more (past ``select()``'s
    FD_SETSIZE of 1024 for 1024; the loop waits with epoll, which has no such limit)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    wanted = number + 256
    if soft != resource.RLIM_INFINITY and soft < wanted:
        if hard != resource.RLIM_INFINITY and hard < wanted:
            pytest.skip(f"at most {hard} descriptors")
        resource.setrlimit(resource.RLIMIT_NOFILE, (wanted, hard))
    fillers: list[int] = []
    try:
        while (fd := os.open(os.devnull, os.O_RDONLY)) < number:
            fillers.append(fd)
        os.close(fd)
        yield
    finally:
        for fd in fillers:
            os.close(fd)
        if soft != resource.RLIM_INFINITY and soft < wanted:
            resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))


def serial_link_numbered_from(first_fd: int, pty: RawPty, baud: int) -> Any:
    """The flight controller's serial link to ``pty``, its descriptor ``first_fd`` or more."""
    with descriptors_taken_below(first_fd):
        link = open_link(f"{pty.path},{baud}", source_system=255, source_component=190,
                         name="fc")
    assert link.fileno() >= first_fd
    return link


@pytest.mark.parametrize("first_fd", [0, 1024], ids=["any descriptor", "past select's 1024"])
def test_the_last_words_reach_a_serial_board_whose_buffer_was_full_once_it_reads_again(
        first_fd: int):
    """A board that stops reading for a moment (busy, its USB buffer full) fills the tty: the
    kernel takes nothing more. Closing then waits for the device to take the last words
    (neutral, then the release), longer than the close's linger; whatever number the link's
    descriptor has."""
    pty = RawPty()
    link = serial_link_numbered_from(first_fd, pty, 921600)
    try:
        deadline = time.monotonic() + 10.0
        while not link.wants_write and time.monotonic() < deadline:  # the board reads nothing
            link.mav.statustext_send(6, b"telemetry for a board that does not read")
            if link.next_send_s < deadline:  # (paced to 921600 baud)
                time.sleep(max(0.0, link.next_send_s - time.monotonic()))
                link.flush()
        assert link.wants_write, "the pty never filled"
        link.send_rc_override(1, 1, NEUTRAL, replace=False)
        link.send_rc_override(1, 1, RELEASE, replace=False)
        received = bytearray()
        board_back = threading.Event()

        def board() -> None:
            board_back.wait(5.0)
            end = time.monotonic() + 5.0
            while time.monotonic() < end:
                if select.select([pty.master], [], [], 0.05)[0]:
                    try:
                        received.extend(os.read(pty.master, 65536))
                    except OSError:
                        return
                elif closed.is_set():
                    return

        closed = threading.Event()
        reader = threading.Thread(target=board, daemon=True)
        reader.start()
        timer = threading.Timer(0.2, board_back.set)  # the board reads again 0.2 s later
        timer.start()
        start = time.monotonic()
        link.close(linger_s=0.05)
        took = time.monotonic() - start
        closed.set()
        reader.join(6.0)
        parser = mavlink.MAVLink(None)
        parser.robust_parsing = True
        overrides = [override_channels(m) for m in parser.parse_buffer(bytes(received)) or ()
                     if m.get_type() == "RC_CHANNELS_OVERRIDE"]
        assert overrides == [NEUTRAL, RELEASE]
        assert took < LAST_WORDS_MAX_S + 0.5
    finally:
        link.close()
        pty.close()


@pytest.mark.parametrize("first_fd", [0, 1024], ids=["any descriptor", "past select's 1024"])
def test_a_serial_link_reads_what_its_board_sends_and_goes_down_when_it_is_unplugged(
        first_fd: int, caplog: pytest.LogCaptureFixture):
    """``read()`` never raises, whatever number the link's descriptor has: a packet is read
    once the board sent it, nothing while the board is silent, and an unplugged board puts
    the link down (``device gone``), the log saying why in pyserial's words."""
    caplog.set_level(logging.INFO, logger="mecanum_mav.io.links")
    pty = RawPty()
    link = serial_link_numbered_from(first_fd, pty, 115200)
    try:
        assert link.read() == [] and link.down_reason is None  # silent: nothing, still up
        os.write(pty.master, heartbeat(board_sender(), 7))
        got: list[Any] = []
        assert wait_until(lambda: got.extend(link.read()) or got, 5.0,
                          pump=lambda s: select.select([pty.master], [], [], s))
        assert [(m.get_type(), m.custom_mode) for m in got] == [("HEARTBEAT", 7)]
        pty.close()
        assert wait_until(lambda: link.read() == [] and link.down_reason is not None, 5.0)
        assert link.down_reason == "device gone"
        assert "fc: device gone: read: device reports readiness to read but returned no data " \
            "(device disconnected?)" in caplog.text
    finally:
        link.close()


@pytest.mark.parametrize("first_fd", [0, 1024], ids=["any descriptor", "past select's 1024"])
def test_ready_within_answers_at_once_when_ready_and_waits_the_time_given_when_not(
        first_fd: int):
    """``ready_within(fd, events, timeout_s)``: the time is in seconds, whatever number the
    descriptor has (poll, not select)."""
    with descriptors_taken_below(first_fd):
        read_end, write_end = os.pipe()
    try:
        assert read_end >= first_fd
        start = time.monotonic()
        assert not ready_within(read_end, select.POLLIN, 0.0)
        assert not ready_within(read_end, select.POLLIN, 0.2)
        assert time.monotonic() - start >= 0.19  # (poll's milliseconds: 200)
        os.write(write_end, b"x")
        start = time.monotonic()
        assert ready_within(read_end, select.POLLIN, 5.0)
        assert time.monotonic() - start < 1.0
    finally:
        os.close(read_end)
        os.close(write_end)


def test_a_packet_split_across_reads_is_completed_by_the_next_read():
    """TCP delivers a byte stream: a packet may come in two pieces, with nothing waiting in
    between; the first read leaves its start waiting, the next completes it."""
    with tcp_pair() as (link, peer):
        packet = heartbeat(board_sender(), custom_mode=5)
        peer.sendall(packet[:7])
        assert wait_until(lambda: waiting_bytes(link.fileno()) == 7, 5.0,
                          pump=lambda s: select.select([link.fileno()], [], [], s))
        assert link.read() == []  # (read the start, then found nothing more)
        peer.sendall(packet[7:])
        got: list[Any] = []
        assert wait_until(lambda: got.extend(link.read()) or got, 5.0,
                          pump=lambda s: select.select([link.fileno()], [], [], s))
        assert [(m.get_type(), m.custom_mode) for m in got] == [("HEARTBEAT", 5)]
        assert link.received == 1
