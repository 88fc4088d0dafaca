"""Who a ``udpin:`` link answers: peers that sent a valid (and, with a key, correctly signed)
message; garbage and unsigned datagrams make no one a peer; silent peers are forgotten; and
the companion's loop answers a pilot's stick datagram in the lane."""

from __future__ import annotations

import hashlib
import io
import select
import selectors
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager

from support import deliver, lane_answers, wait_until

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.io import links
from mecanum_mav.io.links import Link, open_link
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.signing import ticks_from_unix
from mecanum_mav.sim.groundstation import udp_ground_station
from mecanum_mav.sim.simfc import SimFlightController

KEY = hashlib.sha256(b"peers").digest()


@contextmanager
def rover_link(signing_key: bytes | None = None) -> Iterator[Link]:
    link = open_link("udpin:127.0.0.1:0", source_system=1, source_component=1, name="gcs",
                     signing_key=signing_key)
    try:
        yield link
    finally:
        link.close()


@contextmanager
def senders(count: int) -> Iterator[list[socket.socket]]:
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(count)]
    for sock in socks:
        sock.bind(("127.0.0.1", 0))
        sock.setblocking(False)
    try:
        yield socks
    finally:
        for sock in socks:
            sock.close()


def heartbeat(key: bytes | None = None) -> bytes:
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    if key is not None:
        mav.signing.secret_key, mav.signing.sign_outgoing = KEY, True
        mav.signing.timestamp = ticks_from_unix(time.time())
    return bytes(mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(mav))


def who_gets_the_next_message(link: Link, socks: list[socket.socket]) -> list[int]:
    """Send one message from the link; the indices of ``socks`` that receive it (the last
    listed sender is always a peer, so its arrival bounds the wait for the others)."""
    link.mav.heartbeat_send(6, 8, 0, 0, 4, 3)
    with selectors.DefaultSelector() as selector:
        selector.register(socks[-1], selectors.EVENT_READ)
        assert selector.select(2.0), "the peer heard nothing"
    got = []
    for i, sock in enumerate(socks):
        try:
            sock.recv(4096)
            got.append(i)
        except BlockingIOError:
            pass
    return got


def test_garbage_makes_no_peer_and_a_valid_message_does():
    with rover_link() as link, senders(3) as (junk, truncated, gcs):
        assert deliver(link, junk, bytes(range(200))) == []
        assert deliver(link, truncated, heartbeat()[:-4]) == []
        assert [m.get_type() for m in deliver(link, gcs, heartbeat())] == ["HEARTBEAT"]
        assert who_gets_the_next_message(link, [junk, truncated, gcs]) == [2]


def test_on_a_signed_link_only_a_correctly_signed_sender_becomes_a_peer():
    with rover_link(KEY) as link, senders(3) as (unsigned, wrong_key, pilot):
        assert deliver(link, unsigned, heartbeat()) == []
        forged = bytearray(heartbeat(KEY))
        forged[-1] ^= 0xFF
        assert deliver(link, wrong_key, bytes(forged)) == []
        assert [m.get_type() for m in deliver(link, pilot, heartbeat(KEY))] == ["HEARTBEAT"]
        assert who_gets_the_next_message(link, [unsigned, wrong_key, pilot]) == [2]


def test_a_silent_peer_is_forgotten_once_another_is_heard():
    with rover_link() as link, senders(2) as (old, new):
        link.peer_timeout_s = 0.0  # every earlier peer is "silent too long"
        deliver(link, old, heartbeat())
        assert who_gets_the_next_message(link, [old]) == [0]
        deliver(link, new, heartbeat())
        assert who_gets_the_next_message(link, [old, new]) == [1]


def test_at_most_max_peers_are_sent_to_the_longest_silent_dropped_first():
    count = links.MAX_PEERS + 2
    with rover_link() as link, senders(count) as socks:
        for sock in socks:
            deliver(link, sock, heartbeat())
        assert who_gets_the_next_message(link, socks) == list(range(2, count))


def test_a_ground_station_that_only_sends_sticks_is_a_peer_and_its_stick_is_read_alone():
    stick = bytes(mavlink.MAVLink_manual_control_message(1, 250, 0, 500, 0, 0).pack(
        mavlink.MAVLink(None, srcSystem=255, srcComponent=190)))
    with rover_link() as link, senders(2) as (other, sock):
        deliver(link, other, heartbeat())  # (the first datagram settles the MAVLink version)
        assert sock.getsockname() not in link.conn.clients
        sock.sendto(stick, ("127.0.0.1", link.local_port))
        with selectors.DefaultSelector() as selector:
            selector.register(link.fileno(), selectors.EVENT_READ)
            assert selector.select(2.0)
        received = link.received
        first = link.read(1)
        assert [(m.get_type(), m.x, m.get_srcSystem()) for m in first] == [
            ("MANUAL_CONTROL", 250, 255)]
        assert link.received == received + 1
        assert sock.getsockname() in link.conn.clients
        assert link.read(1) == []  # nothing else waits


def test_a_ground_station_whose_stick_the_lane_answered_is_a_peer_and_counted():
    stick = bytes(mavlink.MAVLink_manual_control_message(1, 250, 0, 500, 0, 0).pack(
        mavlink.MAVLink(None, srcSystem=255, srcComponent=190)))
    with rover_link() as link, senders(2) as (other, sock):
        deliver(link, other, heartbeat())  # (the first datagram settles the MAVLink version)
        sock.sendto(stick, ("127.0.0.1", link.local_port))
        with selectors.DefaultSelector() as selector:
            selector.register(link.fileno(), selectors.EVENT_READ)
            assert selector.select(2.0)
        received = link.received
        data, address = link.receive_datagram()
        assert data == stick and link.received == received  # unparsed, not yet counted
        link.answered(data, address)  # (as the companion does after the lane's send)
        assert link.received == received + 1
        assert sock.getsockname() in link.conn.clients
        assert link.receive_datagram() is None  # nothing else waits


def test_a_stick_the_lane_answered_is_recorded_in_the_tlog_as_a_read_one_is():
    """``DatagramLink.answered``: "counted, recorded, as if read": the tlog (8-byte stamp,
    raw packet: ``tlog.tlog_record``) gets the answered datagram's bytes, as it gets those
    of a stick read the long way."""
    sender = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    sticks = [bytes(mavlink.MAVLink_manual_control_message(1, x, 0, 500, 0, 0).pack(sender))
              for x in (250, -250)]
    tlog = io.BytesIO()
    with rover_link() as link, senders(1) as (sock,):
        deliver(link, sock, heartbeat())  # (the first datagram settles the MAVLink version)
        link.record_to(tlog)
        sock.sendto(sticks[0], ("127.0.0.1", link.local_port))
        assert select.select([link.fileno()], [], [], 2.0)[0]
        got = link.receive_datagram()
        assert got is not None
        link.answered(*got)
        assert [m.x for m in deliver(link, sock, sticks[1])] == [-250]
    records = tlog.getvalue()
    first = records[8:8 + len(sticks[0])]
    assert first == sticks[0]  # the lane's, exactly its bytes
    assert records[8 + len(first) + 8:] == sticks[1]  # the one read: the same form


def test_the_companions_loop_answers_a_pilots_sticks_in_the_lane_on_real_sockets():
    """The shipped loop on real UDP sockets (the companion between a ground station and a
    simulated board): while the rover drives in MANUAL, the pilot's stick datagrams are
    answered in the stick lane, unparsed (``Link.answered``), and the wheels follow them."""
    gcs, port = udp_ground_station()
    board = SimFlightController("udpin:127.0.0.1:0", Params())
    board.start()
    companion = Companion(Params(), port.url, f"udpout:127.0.0.1:{board.local_port}")
    answered = lane_answers(companion.gcs)
    companion.start()
    try:
        assert gcs.wait("STATUSTEXT", lambda m: m.text == "Flight controller link up", 5.0)
        gcs.arm()

        def pushed() -> bool:  # a stick, then what came back
            gcs.sticks(1000)
            gcs.pump(0.02)
            return len(answered) >= 10

        assert wait_until(pushed, 5.0), len(answered)
        for data in answered:
            (msg,) = mavlink.MAVLink(None).parse_buffer(data)
            assert (msg.get_type(), msg.x) == ("MANUAL_CONTROL", 1000)
        forward = board.wait_for(lambda s: [s.channel_pwm.get(ch) for ch in (1, 2, 3, 4)]
                                 == [2000] * 4, 2.0)
        assert forward is not None
    finally:
        companion.close()
        board.stop()
        port.close()
