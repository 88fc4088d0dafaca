"""A stream link's queue, reads and signing, as ``mecanum_mav.io.links.stream`` and
``mecanum_mav.io.links.base.Link`` promise, on a real pty with the link's clock in the test's
hands (at 115200 baud the link queues at most a second of the wire, 11520 bytes):

- a packet that fits the queue exactly is taken; one byte more is dropped with ENOBUFS and
  the reason the log shows (``outgoing queue full (N bytes)``);
- a link that is down refuses a write with its reason;
- with the wire busy, the newest override goes before the packets queued, then they take
  turns; a link the kernel never refused is not watched for writing;
- a read takes every chunk waiting (up to ``MAX_READS``), and ``received`` counts them all;
- on a signed link, what is sent after a read is signed no earlier than the newest packet
  verified (MAVLink signing: a timestamp older than the peer's last is refused).
"""

from __future__ import annotations

import errno
import math
import os
import termios
import time
from collections.abc import Iterator

import pytest
from support import RawPty, mavlink_sender, tcp_link_to_a_board
from test_stream_link_counts_and_sequence import (
    BAUD,
    NEUTRAL,
    Clock,
    board_reads,
    drain,
    serial_link,
)

from mecanum_mav.io.links import open_link
from mecanum_mav.io.links.base import READ_CHUNK, LinkDownError
from mecanum_mav.io.links.serialport import QUEUE_MIN_BYTES, QUEUE_S, SerialLink
from mecanum_mav.io.links.stream import queued_bytes
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.signing import ticks_from_unix

KEY = bytes(range(32))


@pytest.fixture
def pty() -> Iterator[RawPty]:
    end = RawPty()
    yield end
    end.close()


def busy(link: SerialLink) -> None:
    """Put 100 bytes on the wire (9 ms at 115200 baud): what comes next waits in the link."""
    link.write(bytes(100))
    assert not link.pending


def three_waiting(pty: RawPty) -> tuple[SerialLink, Clock]:
    """A link with the wire busy and three packets waiting in it: two SYSTEM_TIME queued,
    then an override."""
    clock = Clock()
    link = serial_link(pty, clock)
    busy(link)
    link.conn.mav.system_time_send(1, 0)
    link.conn.mav.system_time_send(2, 0)
    link.send_rc_override(1, 1, NEUTRAL)
    return link, clock


def test_a_packet_that_fits_the_queue_exactly_is_taken_and_a_byte_more_is_refused(pty):
    link = serial_link(pty, Clock())
    limit = link.queue_limit
    assert limit == max(QUEUE_MIN_BYTES, int(QUEUE_S * BAUD / 10))
    busy(link)
    link.write(b"x" * (limit - 10))
    link.write(b"y" * 10)  # exactly full
    with pytest.raises(BlockingIOError) as refused:
        link.write(b"z")
    assert refused.value.errno == errno.ENOBUFS
    assert refused.value.strerror == f"outgoing queue full ({limit} bytes)"
    link.close()


def test_a_link_that_is_down_refuses_a_write_with_its_reason(pty):
    link = serial_link(pty, Clock())
    pty.close()
    link.read()
    with pytest.raises(LinkDownError, match=r"^device gone$"):
        link.write(b"x")
    assert link.read() == []  # and reads nothing, without raising
    link.close()


def test_with_the_wire_busy_the_newest_override_goes_first_then_the_queue_takes_turns(pty):
    link, clock = three_waiting(pty)
    assert link.pending and not link.wants_write  # the kernel never refused: not watched
    drain(link, clock)
    kinds = [m.get_type() for m in board_reads(pty) if m.get_type() != "BAD_DATA"]
    assert kinds == ["RC_CHANNELS_OVERRIDE", "SYSTEM_TIME", "SYSTEM_TIME"]
    link.close()


def test_a_read_takes_every_chunk_waiting_and_received_counts_every_message():
    with tcp_link_to_a_board(sysid=1, compid=191) as (link, board_end):
        board = mavlink_sender(sysid=1, compid=1)
        packet = board.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER, 3, 0, 0, 4).pack(board)
        count = 3 * READ_CHUNK // len(packet) + 1  # more than three of the link's chunks
        board_end.sendall(packet * count)
        waiting = 0
        deadline = time.monotonic() + 5.0
        while waiting < len(packet) * count and time.monotonic() < deadline:
            waiting = queued_bytes(link.conn.port.fileno(), termios.FIONREAD)
        got = link.read()  # one call
        assert len(got) == count and link.received == count
        board_end.sendall(packet)
        deadline = time.monotonic() + 5.0
        while link.received == count and time.monotonic() < deadline:
            link.read()
        assert link.received == count + 1


def test_after_a_read_a_signed_link_signs_no_earlier_than_the_newest_packet_it_verified(pty):
    link = open_link(f"{pty.path},115200", source_system=1, source_component=191, name="fc",
                     signing_key=KEY, clock=Clock())
    ahead = ticks_from_unix(time.time() + 3600.0)  # a peer whose clock is an hour ahead
    peer = mavlink_sender(KEY, sysid=1, compid=1, timestamp=ahead)
    os.write(pty.master, peer.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER, 3, 0, 0, 4)
             .pack(peer))
    deadline = time.monotonic() + 5.0
    while not link.read() and time.monotonic() < deadline:
        pass
    link.conn.mav.heartbeat_send(mavlink.MAV_TYPE_ONBOARD_CONTROLLER, 8, 0, 0, 4)
    sent = board_reads(pty)
    assert len(sent) == 1 and sent[0].get_msgbuf()[2] & mavlink.MAVLINK_IFLAG_SIGNED
    stamp = int.from_bytes(sent[0].get_msgbuf()[-12:-6], "little")
    assert stamp >= ahead
    link.close()


def test_what_the_kernel_holds_is_0_for_a_descriptor_it_cannot_ask(tmp_path):
    with (tmp_path / "not-a-tty").open("wb") as file:  # TIOCOUTQ: ENOTTY
        assert queued_bytes(file.fileno(), termios.TIOCOUTQ) == 0


def test_a_packet_the_kernel_took_part_of_is_finished_whole_first_once_it_is_writable(pty):
    """A device that stops taking bytes (its buffer full): the rest of the packet begun waits
    at the head, the link asks to be woken when the descriptor is writable and sets no
    timer; once the device takes bytes again every packet arrives whole and in order."""
    clock = Clock()
    link = serial_link(pty, clock)
    sent = 0
    while not link.pending and sent < 10_000:
        clock.now_s += 10.0  # pacing never holds it back: the kernel's buffer fills
        link.conn.mav.statustext_send(6, f"packet {sent:05d}".encode().ljust(50, b"."))
        sent += 1
    # the first packet the kernel did not take whole (here it took a part: 63-byte packets
    # do not fill a pty's buffer exactly) is watched for at once
    assert link.wants_write and link.pending
    assert link.next_send_s == math.inf  # woken by the descriptor, not a timer
    clock.now_s += 10.0
    link.flush()  # still full: the kernel takes nothing (EAGAIN), nothing changes
    assert link.wants_write and link.next_send_s == math.inf
    parser = mavlink.MAVLink(None)  # one parser: a packet may come in two reads
    got: list = []

    def board_reads_more() -> None:
        while True:
            try:
                data = os.read(pty.master, 65536)
            except BlockingIOError:
                return
            got.extend(parser.parse_buffer(data) or [])

    for _ in range(10_000):
        board_reads_more()
        clock.now_s += 10.0
        link.flush()
        if not link.pending:
            break
    board_reads_more()
    texts = [m.text for m in got]
    assert texts == [f"packet {k:05d}".ljust(50, ".") for k in range(sent)]
    assert not link.wants_write
    link.close()


def test_a_break_drops_and_counts_every_packet_waiting_in_the_link(pty):
    link, clock = three_waiting(pty)
    assert link.unsent == 0
    pty.close()
    drain_until_down(link, clock)
    assert link.unsent == 3 and not link.pending


def test_a_break_drops_and_counts_the_last_words_waiting_too(pty):
    clock = Clock()
    link = serial_link(pty, clock)
    busy(link)
    link.send_rc_override(1, 1, NEUTRAL, replace=False)
    link.send_rc_override(1, 1, [0] * 18, replace=False)
    link.send_rc_override(1, 1, NEUTRAL)  # (a late tick's, after them)
    pty.close()
    drain_until_down(link, clock)
    assert link.unsent == 3 and not link.pending


def drain_until_down(link: SerialLink, clock: Clock) -> None:
    for _ in range(100):
        clock.now_s += 1.0
        link.flush()
        if link.down_reason is not None:
            return
    raise AssertionError("the write never failed")
