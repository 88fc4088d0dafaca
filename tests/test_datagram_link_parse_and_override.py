"""A datagram link's two halves the loop uses one datagram at a time
(mecanum_mav/io/links/datagram.py, ``DatagramLink``):

- ``parse_datagram``: a datagram holding several packets yields each message, in order, and
  ``received`` counts every message as :meth:`read` counts them, adding up over datagrams; a
  signing link then signs what it sends next no earlier than the newest verified packet it
  parsed (ArduPilot drops a stream more than a minute behind its own timestamp);
- ``send_rc_override``: the board gets exactly the override given (its target and 18
  channels), with the link's own sequence numbers and signature, and ``sent`` counts each.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from support import mavlink_sender, override_channels, wait_until

from mecanum_mav.io.links import mavlink, open_link, parts
from mecanum_mav.io.links.datagram import DatagramLink
from mecanum_mav.protocol.signing import TICKS_PER_S, ticks_from_unix

KEY = bytes(range(32))
NEUTRAL = [1500] * 4 + [65535] * 4 + [0] * 10
RELEASE = [0] * 4 + [65535] * 4 + [0] * 10


@contextmanager
def udpout_to_board(
        signing_key: bytes | None = None) -> Iterator[tuple[DatagramLink, socket.socket]]:
    """A ``udpout:`` link and the board's socket at its destination (blocking, 5 s)."""
    board = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    board.bind(("127.0.0.1", 0))
    board.settimeout(5.0)
    link = open_link(f"udpout:127.0.0.1:{board.getsockname()[1]}", source_system=255,
                     source_component=190, name="fc", signing_key=signing_key)
    assert isinstance(link, DatagramLink)
    try:
        yield link, board
    finally:
        link.close()
        board.close()


def datagram_from(board: socket.socket, link: DatagramLink, data: bytes) -> tuple[bytes, Any]:
    """Send ``data`` from the board; the datagram as the link receives it."""
    board.sendto(data, ("127.0.0.1", link.local_port))
    got = wait_until(link.receive_datagram, 5.0)
    assert got is not None, "the datagram never arrived"
    return got


def beat(mav: Any, custom_mode: int) -> bytes:
    return bytes(mavlink.MAVLink_heartbeat_message(10, 3, 0, custom_mode, 3, 3).pack(mav))


def test_each_message_of_each_datagram_parsed_is_yielded_in_order_and_counted():
    with udpout_to_board() as (link, board):
        mav = mavlink_sender(sysid=1, compid=1)
        first = link.parse_datagram(
            *datagram_from(board, link, beat(mav, 1) + beat(mav, 2) + beat(mav, 3)))
        assert [m.custom_mode for m in first] == [1, 2, 3]
        assert link.received == 3
        second = link.parse_datagram(
            *datagram_from(board, link, beat(mav, 4) + beat(mav, 5)))
        assert [m.custom_mode for m in second] == [4, 5]
        assert link.received == 5  # (added up, as read() counts them)


def test_a_signing_link_signs_no_earlier_than_the_newest_verified_packet_it_parsed():
    """As :meth:`read` does (tests/test_links.py): the next override is signed from the
    board's verified timestamp, ten minutes ahead of this machine's clock."""
    ahead = ticks_from_unix(time.time()) + 600 * TICKS_PER_S
    with udpout_to_board(KEY) as (link, board):
        mav = mavlink_sender(KEY, sysid=1, compid=1, link_id=1, timestamp=ahead)
        assert link.parse_datagram(
            *datagram_from(board, link, beat(mav, 7)))
        link.send_rc_override(1, 1, NEUTRAL)
        stamp = int.from_bytes(board.recv(300)[-12:-6], "little")
        assert ahead <= stamp < ahead + TICKS_PER_S, stamp - ahead


def test_each_override_sent_is_the_one_given_signed_in_sequence_and_counted_once():
    with udpout_to_board(KEY) as (link, board):
        sent = link.sent
        link.send_rc_override(1, 1, NEUTRAL)
        link.send_rc_override(2, 3, RELEASE)
        assert link.sent == sent + 2
        parser = mavlink.MAVLink(None)
        parser.signing.secret_key = KEY  # (refuses a packet whose signature is wrong)
        got = [parser.parse_char(board.recv(300)) for _ in range(2)]
        assert [(m.get_type(), m.target_system, m.target_component, override_channels(m))
                for m in got] == [("RC_CHANNELS_OVERRIDE", 1, 1, NEUTRAL),
                                  ("RC_CHANNELS_OVERRIDE", 2, 3, RELEASE)]
        assert [(m.get_srcSystem(), m.get_srcComponent()) for m in got] == [(255, 190)] * 2
        assert got[1].get_seq() == (got[0].get_seq() + 1) & 0xFF
        assert all(m.get_signed() for m in got)


def test_each_override_sent_is_recorded_in_the_tlog_as_it_went(tmp_path: Path) -> None:
    """``Link.record_to``: every message sent is recorded (the tlog MAVProxy and Mission
    Planner read: 8-byte stamp, the packet)."""
    with udpout_to_board() as (link, board), (tmp_path / "fc.tlog").open("wb") as tlog:
        link.record_to(tlog)
        link.send_rc_override(1, 1, NEUTRAL)
        packet = board.recv(300)
        tlog.flush()
        records = (tmp_path / "fc.tlog").read_bytes()
        assert len(records) == 8 + len(packet) and records[8:] == packet


def test_a_signing_link_signs_what_it_sends_from_the_wall_clock_as_it_moves_on(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """``Signing``: the signing timestamp starts at the wall clock and follows it: a message
    sent two minutes after the link opened is signed two minutes later."""
    with udpout_to_board(KEY) as (link, board):
        later = time.time() + 120.0
        monkeypatch.setattr(parts, "time", SimpleNamespace(time=lambda: later))
        assert link.send(link.mav.heartbeat_encode(6, 8, 0, 0, 4))
        stamp = int.from_bytes(board.recv(300)[-12:-6], "little")
        assert ticks_from_unix(later) <= stamp < ticks_from_unix(later) + TICKS_PER_S
