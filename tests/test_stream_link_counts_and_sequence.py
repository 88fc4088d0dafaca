"""A stream link's promises to the board and to whoever reads its counters
(``mecanum_mav.io.links.stream``, ``mecanum_mav.io.links.base.Link``), on a real pty with the
link's clock in the test's hands:

- MAVLink's sequence number goes up by one per packet, 255 then 0, whichever path a packet
  takes (the stick lane's packet packed elsewhere, the newest override packed when handed
  over, any other message queued): the board counts lost packets by its gaps; the last
  words at shutdown reach it in sequence too, what they passed a counted gap;
- ``sent`` counts every packet that went or waits to go, ``superseded`` every override a
  newer one replaced before it went, ``unsent`` every packet dropped while the link is down;
- a break is logged once at INFO as ``NAME: REASON: DETAIL``; the port is closed even when
  closing it fails, and the link never raises to its caller;
- back up, a partial packet from before the break is not completed by what comes after.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator
from typing import Any

import pytest
from support import RawPty

from mecanum_mav.io.links import open_link
from mecanum_mav.io.links.serialport import SerialLink
from mecanum_mav.protocol.dialect import mavlink

BAUD = 115200
NEUTRAL = [1500] * 4 + [65535] * 4 + [0] * 10


class Clock:
    """The link's clock: stands still until the test moves it."""

    def __init__(self) -> None:
        self.now_s = 100.0

    def __call__(self) -> float:
        return self.now_s


@pytest.fixture
def pty() -> Iterator[RawPty]:
    end = RawPty()
    yield end
    end.close()


def serial_link(pty: RawPty, clock: Clock) -> SerialLink:
    link = open_link(f"{pty.path},{BAUD}", source_system=1, source_component=191,
                     name="fc", clock=clock)
    assert isinstance(link, SerialLink)
    return link


def lane_packet(link: SerialLink) -> bytes:
    """An override packed elsewhere with the link's next sequence number (the stick lane's)."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=191)
    mav.seq = link.conn.mav.seq
    return mav.rc_channels_override_encode(1, 1, *NEUTRAL).pack(mav)


def drain(link: SerialLink, clock: Clock) -> None:
    """Let the wire carry everything that waits (the clock moved on as pacing asks)."""
    for _ in range(200):
        if not link.pending:
            return
        clock.now_s = max(clock.now_s, link.next_send_s) if link.next_send_s < 1e9 \
            else clock.now_s + 0.01
        link.flush()
    raise AssertionError("the link never emptied")


def board_reads(pty: RawPty) -> list[Any]:
    parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    messages: list[Any] = []
    while True:
        try:
            data = os.read(pty.master, 65536)
        except BlockingIOError:
            return messages
        messages += parser.parse_buffer(data) or []


def test_sequence_numbers_go_up_by_one_per_packet_on_every_path_and_wrap_to_0(pty):
    clock = Clock()
    link = serial_link(pty, clock)
    link.conn.mav.seq = 250
    sends = [
        lambda: link.send_packet(lane_packet(link)),  # the stick lane: straight to the kernel
        lambda: link.conn.mav.heartbeat_send(mavlink.MAV_TYPE_GROUND_ROVER, 0, 0, 0, 0),
        lambda: link.send_rc_override(1, 1, NEUTRAL),
        lambda: link.send_packet(lane_packet(link)),  # queued behind what waits
        lambda: link.conn.mav.system_time_send(0, 0),
        lambda: link.send_rc_override(1, 1, NEUTRAL),
        lambda: link.conn.mav.heartbeat_send(mavlink.MAV_TYPE_GROUND_ROVER, 0, 0, 0, 0),
        lambda: link.send_packet(lane_packet(link)),
    ]
    for send in sends:
        send()
    drain(link, clock)
    seqs = [m.get_seq() for m in board_reads(pty)]
    assert seqs == [(250 + k) % 256 for k in range(len(seqs))]
    assert len(seqs) == len(sends) - link.superseded  # (an override replaced is not packed)
    link.close()


def test_send_all_on_a_stream_link_sends_each_message_in_order(pty):
    """``Link.send_all``: each of the messages is sent, in order (a wake's telemetry)."""
    clock = Clock()
    link = serial_link(pty, clock)
    mav = link.conn.mav
    link.send_all([mav.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER, 0, 0, 0, 0),
                   mav.system_time_encode(7, 8),
                   mav.statustext_encode(6, b"third")])
    drain(link, clock)
    seen = board_reads(pty)
    assert [m.get_type() for m in seen] == ["HEARTBEAT", "SYSTEM_TIME", "STATUSTEXT"]
    assert (seen[1].time_unix_usec, seen[1].time_boot_ms, seen[2].text) == (7, 8, "third")
    assert link.sent == 3 and link.send_errors == 0
    link.close()


def test_the_last_words_reach_the_board_in_sequence_what_they_passed_is_a_counted_gap(pty):
    clock = Clock()
    link = serial_link(pty, clock)
    link.send_packet(lane_packet(link))  # on the wire
    link.conn.mav.heartbeat_send(mavlink.MAV_TYPE_GROUND_ROVER, 0, 0, 0, 0)  # waits, numbered
    link.conn.mav.system_time_send(0, 0)  # waits, numbered
    link.send_rc_override(1, 1, NEUTRAL, replace=False)  # passes them
    link.conn.mav.heartbeat_send(mavlink.MAV_TYPE_GROUND_ROVER, 0, 0, 0, 0)  # after it
    link.send_rc_override(1, 1, NEUTRAL, replace=False)  # passes that one too
    link.send_rc_override(1, 1, [0] * 18, replace=False)
    drain(link, clock)
    seen = board_reads(pty)
    assert [m.get_type() for m in seen] == ["RC_CHANNELS_OVERRIDE"] * 4
    seqs = [m.get_seq() for m in seen]
    assert seqs == sorted(seqs)
    assert link.unsent == 3
    assert seqs[-1] - seqs[0] + 1 == len(seqs) + link.unsent
    assert link.sent == 4  # the lane's packet and the three last words
    link.write(b"x" * link.queue_limit)  # (what they dropped no longer counts against it)
    link.close()


def test_sent_counts_every_packet_and_superseded_every_override_replaced_before_it_went(pty):
    clock = Clock()
    link = serial_link(pty, clock)
    link.send_packet(lane_packet(link))  # the lane's packets go to the kernel at once
    link.send_packet(lane_packet(link))
    assert link.sent == 2 and link.superseded == 0
    link.send_rc_override(1, 1, NEUTRAL)  # the wire is busy: waits in the link
    link.send_rc_override(1, 1, NEUTRAL)  # replaces the override that waited
    assert link.superseded == 1
    link.send_packet(lane_packet(link))  # the lane's newer override replaces it too
    assert link.superseded == 2
    drain(link, clock)
    assert link.sent == 3  # the three lane packets; the replaced overrides never went
    link.send_rc_override(1, 1, NEUTRAL)
    drain(link, clock)
    assert link.sent == 4 and link.superseded == 2
    assert len(board_reads(pty)) == 4
    link.close()


def test_a_break_is_logged_at_info_with_the_link_reason_and_detail_and_drops_what_waits(
        pty, caplog: pytest.LogCaptureFixture):
    clock = Clock()
    link = serial_link(pty, clock)
    link.send_packet(lane_packet(link))
    link.conn.mav.heartbeat_send(mavlink.MAV_TYPE_GROUND_ROVER, 0, 0, 0, 0)  # waits
    port = link.conn.port
    pty.close()  # the board unplugged: the next write fails
    with caplog.at_level(logging.INFO, logger="mecanum_mav.io.links"):
        drain(link, clock)
    assert link.down_reason == "device gone"
    downs = [r for r in caplog.records if r.levelno == logging.INFO]
    assert len(downs) == 1
    assert downs[0].getMessage().startswith("fc: device gone: write: ")
    assert not port.is_open  # closed now: the next plug gets the same device name
    assert link.unsent == 1
    link.send_packet(lane_packet(link))
    link.send_rc_override(1, 1, NEUTRAL)
    assert link.unsent == 3 and link.sent == 1
    link.close()


def test_a_port_that_fails_to_close_still_leaves_the_link_down_without_raising(pty):
    clock = Clock()
    link = serial_link(pty, clock)

    def close_fails() -> None:
        raise OSError(5, "Input/output error")

    link.conn.port.close = close_fails
    pty.close()
    assert link.read() == []  # the read fails: down, and nothing raised
    assert link.down_reason == "device gone"
    assert link.wait_fd() is None
    link.close()


def test_after_a_break_a_packet_begun_before_it_is_not_completed_by_what_comes_after(
        tmp_path, caplog: pytest.LogCaptureFixture):
    device = RawPty(tmp_path / "ttyFC")
    clock = Clock()
    link = serial_link(device, clock)
    board = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    packet = board.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER, 3, 0, 0, 4).pack(board)
    os.write(device.master, packet[:10])  # half a packet, then the board is unplugged
    assert link.read() == []
    device.close()
    assert link.read() == []
    assert link.down_reason == "device gone"
    replugged = RawPty(tmp_path / "ttyFC")
    try:
        clock.now_s = link.next_reopen_s
        with caplog.at_level(logging.DEBUG, logger="mecanum_mav.io.links"):
            assert link.reopen(clock.now_s)
        assert "fc: up again (was down: device gone)" in caplog.messages
        os.write(replugged.master, packet[10:] + packet)  # the rest of the old one: noise
        got = []
        for _ in range(50):
            got += link.read()
            if got:
                break
        assert [m.get_type() for m in got] == ["HEARTBEAT"]
        assert got[0].get_seq() == packet[4]  # the whole packet, not the old one completed
    finally:
        link.close()
        replugged.close()
