"""Links never raise: failed sends are counted and reported, at most once a second per link."""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import select
import socket
import threading
import time

import pytest
from support import mavlink_sender, read_for, wait_until

from mecanum_mav.config.params import Params
from mecanum_mav.control.core import LinkCounts, RoverCore
from mecanum_mav.io import links
from mecanum_mav.io.links import open_link
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.signing import TICKS_PER_S, Check, ticks_from_unix


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def failing_link(clock=time.monotonic):
    """A link every send of which the kernel refuses: the broadcast address without
    SO_BROADCAST (EACCES), a failure pymavlink's own write would drop unseen."""
    return open_link("udpout:255.255.255.255:9", source_system=255, source_component=190,
                     name="fc", clock=clock)


def test_a_failing_send_is_counted_and_warned_about_once_a_second_per_link(caplog):
    clock = FakeClock()
    link = failing_link(clock)
    try:
        with caplog.at_level(logging.WARNING, logger="mecanum_mav.io.links"):
            for _ in range(10):
                link.send_rc_override(1, 1, [1500] * 4 + [65535] * 4 + [0] * 10)
                link.send(link.mav.heartbeat_encode(6, 8, 0, 0, 4))
                clock.now += 0.05  # 20 Hz: one second of failures
            warnings = [r for r in caplog.records if "send failed" in r.getMessage()]
            assert link.send_errors == 20
            assert [w.getMessage() for w in warnings] == [  # the kernel's reason, as it said
                f"fc: send failed (1 so far): [Errno {errno.EACCES}] "
                f"{os.strerror(errno.EACCES)}"]
            clock.now += 1.0
            link.send(link.mav.heartbeat_encode(6, 8, 0, 0, 4))
            warnings = [r for r in caplog.records if "send failed" in r.getMessage()]
            assert len(warnings) == 2 and "(21 so far)" in warnings[1].getMessage()
    finally:
        link.close()


def test_sys_status_errors_comm_counts_bad_packets_and_failed_sends():
    core = RoverCore(Params(), now_s=0.0, link_counts=lambda: LinkCounts(10, 3, 4))
    command = mavlink.MAVLink_command_long_message(
        1, 1, mavlink.MAV_CMD_REQUEST_MESSAGE, 0, mavlink.MAVLINK_MSG_ID_SYS_STATUS,
        0, 0, 0, 0, 0, 0)
    command._header.srcSystem, command._header.srcComponent = 255, 190
    out = core.handle(command, 1.0)
    status = [m for m in out.gcs if m.get_type() == "SYS_STATUS"]
    assert len(status) == 1 and status[0].errors_comm == 7


def test_closing_a_tcp_link_gives_the_peer_time_to_read_the_last_packet_before_it_ends():
    """ArduPilot drops what is still in its buffers when a TCP connection ends (measured with
    SITL: the release sent at shutdown never took effect). With linger the connection stays
    open, the peer's telemetry drained, for ``linger_s`` after the last packet."""
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    link = open_link(f"tcp:127.0.0.1:{server.getsockname()[1]}", source_system=255,
                     source_component=190, name="fc")
    peer, _ = server.accept()
    peer.settimeout(2.0)
    stop = threading.Event()

    def chatter():
        while not stop.is_set():
            with contextlib.suppress(OSError):
                peer.send(b"\xfd" + bytes(40))  # telemetry the link never reads
            stop.wait(0.002)

    talker = threading.Thread(target=chatter, daemon=True)
    talker.start()
    try:
        assert wait_until(lambda: len(peek(link)) > 0, 2.0)  # unread data on our side
        closer = threading.Thread(
            target=lambda: (link.send_rc_override(1, 1, [0] * 4 + [65535] * 4 + [0] * 10),
                            link.close(linger_s=0.3)))
        closer.start()
        received, got_packet_s = b"", None
        while chunk := peer.recv(4096):
            received += chunk
            if got_packet_s is None and len(received) >= 10:
                got_packet_s = time.monotonic()
        ended_s = time.monotonic()
        closer.join(2.0)
        messages = mavlink.MAVLink(None).parse_buffer(received) or []
        assert [m.get_type() for m in messages] == ["RC_CHANNELS_OVERRIDE"]
        assert messages[0].chan1_raw == 0 and messages[0].chan5_raw == 65535
        assert ended_s - got_packet_s >= 0.25  # open 0.3 s after the last packet
    finally:
        stop.set()
        peer.close()
        server.close()


def peek(link) -> bytes:
    try:
        return link.conn.port.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT)
    except BlockingIOError:
        return b""


def test_a_signing_link_signs_no_earlier_than_the_newest_verified_packet_it_received():
    """ArduPilot signs from its stored timestamp + 60 s and drops a new stream more than a
    minute behind its own timestamp: the link takes the peer's verified timestamp, as the
    MAVLink C library and pymavlink do (tests/test_sitl_signing.py with the real firmware).
    A packet that fails the signature check moves nothing."""
    key, now = bytes(range(32)), ticks_from_unix(time.time())
    link = open_link("udpin:127.0.0.1:0", source_system=255, source_component=190, name="fc",
                     signing_key=key)
    board = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    board.settimeout(5.0)
    try:
        def beat(secret: bytes, timestamp: int) -> bytes:
            mav = mavlink_sender(secret, sysid=1, compid=1, link_id=1, timestamp=timestamp)
            return bytes(mavlink.MAVLink_heartbeat_message(10, 3, 0, 0, 3, 3).pack(mav))

        def sent_timestamps() -> list[int]:
            link.send(mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))
            link.send_rc_override(1, 1, [1500] * 18)
            return [int.from_bytes(board.recv(300)[-12:-6], "little") for _ in range(2)]

        ahead = now + 600 * TICKS_PER_S
        forged = beat(bytes(32), now + 86_400 * TICKS_PER_S)  # another key, a day ahead
        for packet in (beat(key, ahead), forged):
            board.sendto(packet, ("127.0.0.1", link.local_port))
            assert wait_until(
                lambda: link.read() or link.signature_check.new_rejections, 5.0,
                pump=lambda wait_s: select.select([link.fileno()], [], [], wait_s)), (
                "the link never read the packet")
        stamps = sent_timestamps()
        assert ahead <= stamps[0] < stamps[1] < ahead + TICKS_PER_S, stamps
        assert link.take_rejections() == {Check.BAD_SIGNATURE: 1}  # the forged one
        assert link.take_rejections() == {}  # (each counted once)
    finally:
        board.close()
        link.close()


def test_a_datagram_link_without_a_key_refuses_nothing_and_takes_a_packet_at_any_time():
    """(A datagram has no queue: the stick lane's packet always goes to the kernel at once.)"""
    link = open_link("udpin:127.0.0.1:0", source_system=255, source_component=190, name="gcs")
    try:
        assert link.signature_check is None
        assert link.take_rejections() == {}
        assert link.takes_packet()
    finally:
        link.close()


def _peer_socket(address: tuple[str, int] = ("127.0.0.1", 0)) -> socket.socket:
    """A UDP socket bound to ``address``, reads waiting up to 2 s."""
    peer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    peer.bind(address)
    peer.settimeout(2.0)
    return peer


def _datagrams(sock: socket.socket, timeout_s: float = 2.0) -> list[bytes]:
    """Every datagram that reaches ``sock`` within ``timeout_s`` of the first (none: [])."""
    return read_for(sock.fileno(), lambda: [sock.recv(65536)], timeout_s,
                    settle_s=0.2)  # the rest follow at once


def test_send_all_on_a_datagram_link_packs_whole_packets_into_few_datagrams():
    sink = _peer_socket()
    link = open_link(f"udpout:127.0.0.1:{sink.getsockname()[1]}", source_system=1,
                     source_component=191, name="gcs")
    try:
        mav = mavlink.MAVLink(None)
        texts = [mav.statustext_encode(6, f"message {i:03d}".encode().ljust(50, b"."))
                 for i in range(40)]  # 40 x 71 bytes: more than one datagram's worth
        link.send_all(texts)
        datagrams = _datagrams(sink)
        assert 2 <= len(datagrams) < len(texts)
        assert all(len(d) <= links.DATAGRAM_BYTES for d in datagrams)
        parser = mavlink.MAVLink(None)
        received = [m for d in datagrams for m in parser.parse_buffer(d) or ()]
        assert [m.text for m in received] == [t.text for t in texts]
        assert [m.get_seq() for m in received] == list(range(40))  # one sequence, no gaps
        assert link.sent == 40
    finally:
        link.close()
        sink.close()


def test_send_all_of_two_messages_puts_both_in_one_datagram():
    sink = _peer_socket()
    link = open_link(f"udpout:127.0.0.1:{sink.getsockname()[1]}", source_system=1,
                     source_component=191, name="gcs")
    try:
        link.send_all([link.mav.heartbeat_encode(6, 8, 0, 0, 4),
                       link.mav.statustext_encode(6, b"two in one")])
        datagrams = _datagrams(sink)
        assert len(datagrams) == 1
        assert [m.get_type() for m in mavlink.MAVLink(None).parse_buffer(datagrams[0])] == [
            "HEARTBEAT", "STATUSTEXT"]
        assert link.sent == 2
    finally:
        link.close()
        sink.close()


def test_send_all_fills_every_datagram_up_to_datagram_bytes_exactly():
    """DatagramLink.send_all: "in as few datagrams as hold them: whole packets of at most
    DATAGRAM_BYTES together": packets that fill two datagrams to the byte go in two."""
    sink = _peer_socket()
    link = open_link(f"udpout:127.0.0.1:{sink.getsockname()[1]}", source_system=1,
                     source_component=191, name="gcs")
    try:
        mav = mavlink.MAVLink(None)
        text = b"x" * 43  # a 56-byte packet (MAVLink 2, the text's trailing zeros trimmed)
        size = len(mav.statustext_encode(6, text).pack(mav))
        assert links.DATAGRAM_BYTES % size == 0
        count = 2 * links.DATAGRAM_BYTES // size
        link.send_all([mav.statustext_encode(6, text) for _ in range(count)])
        datagrams = _datagrams(sink)
        assert [len(d) for d in datagrams] == [links.DATAGRAM_BYTES] * 2
        parser = mavlink.MAVLink(None)
        assert len([m for d in datagrams for m in parser.parse_buffer(d) or ()]) == count
    finally:
        link.close()
        sink.close()


def test_a_failing_send_to_one_udpin_peer_is_counted_and_the_others_still_get_it():
    link = open_link("udpin:127.0.0.1:0", source_system=1, source_component=1, name="gcs")
    peer = _peer_socket()
    try:
        beat = link.mav.heartbeat_encode(10, 8, 0, 0, 4)
        stick = link.mav.manual_control_encode(1, 0, 0, 500, 0, 0).pack(link.mav)
        link.answered(stick, peer.getsockname())  # a ground station, heard
        link.answered(stick, ("255.255.255.255", 9))  # a peer the kernel refuses (EACCES)
        assert link.send(beat) is False  # one peer failed: counted
        assert link.send_errors == 1
        data, _ = peer.recvfrom(1024)  # the other peer got it all the same
        assert data == bytes(beat.get_msgbuf())
    finally:
        peer.close()
        link.close()


def test_a_udpout_link_reads_its_destination_and_never_a_strangers_datagram():
    peer, stranger = _peer_socket(), _peer_socket()
    link = open_link(f"udpout:127.0.0.1:{peer.getsockname()[1]}", source_system=1,
                     source_component=1, name="gcs")
    try:
        assert link.send(link.mav.heartbeat_encode(10, 8, 0, 0, 4))
        _, link_address = peer.recvfrom(1024)
        sender = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        stick = sender.manual_control_encode(1, 0, 0, 500, 0, 0).pack(sender)
        beat = sender.heartbeat_encode(6, 8, 0, 0, 4).pack(sender)
        stranger.sendto(stick, link_address)  # first: the kernel drops it
        peer.sendto(beat, link_address)
        received: list = []
        wait_until(lambda: received.extend(link.read()) or received, 2.0)
        assert [m.get_type() for m in received] == ["HEARTBEAT"]
        assert link.read() == [] and link.received == 1
    finally:
        for sock in (peer, stranger):
            sock.close()
        link.close()


def test_a_udpout_link_keeps_the_url_it_was_opened_with():
    """``Link.url``: the connection string, as given (what status and logs name)."""
    url = "udpout:127.0.0.1:9"
    link = open_link(url, source_system=1, source_component=1, name="gcs")
    try:
        assert (link.url, link.name) == (url, "gcs")
    finally:
        link.close()


def test_a_udpout_link_whose_socket_cannot_be_connected_sends_by_sendto_and_says_why(
        monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    """UdpoutLink._connect: if the kernel refuses to connect the socket, the link stays
    unconnected and its sends go as they would have (``sendto`` to the destination); why is
    logged at DEBUG."""
    peer = _peer_socket()

    def refuse(sock: socket.socket, address: object) -> None:
        raise OSError(errno.ENETUNREACH, "Network is unreachable")

    with monkeypatch.context() as patched, caplog.at_level(logging.DEBUG,
                                                           logger="mecanum_mav.io.links"):
        patched.setattr(socket.socket, "connect", refuse)
        link = open_link(f"udpout:127.0.0.1:{peer.getsockname()[1]}", source_system=1,
                         source_component=1, name="gcs")
    try:
        assert [r.getMessage() for r in caplog.records if r.name == "mecanum_mav.io.links"] == [
            f"gcs: udpout socket left unconnected: [Errno {errno.ENETUNREACH}] "
            "Network is unreachable"]
        assert link.send(link.mav.heartbeat_encode(10, 8, 0, 0, 4))
        got = mavlink.MAVLink(None).parse_buffer(peer.recv(1024))
        assert [m.get_type() for m in got] == ["HEARTBEAT"]
        assert (link.sent, link.send_errors) == (1, 0)
    finally:
        peer.close()
        link.close()


def test_a_udpout_link_with_no_one_listening_fails_no_send_and_loses_none_once_one_listens():
    probe = _peer_socket()
    address = probe.getsockname()
    probe.close()  # no one listens there: each datagram comes back as ICMP port unreachable
    link = open_link(f"udpout:{address[0]}:{address[1]}", source_system=1, source_component=1,
                     name="gcs")
    try:
        for _ in range(5):
            assert link.send(link.mav.heartbeat_encode(10, 8, 0, 0, 4))
        assert link.send_errors == 0
        errors = select.poll()
        errors.register(link.conn.port.fileno(), select.POLLERR)
        assert errors.poll(2000), "the kernel holds a refusal for the next send"
        peer = _peer_socket(address)
        try:
            text = link.mav.statustext_encode(6, b"first one heard")
            assert link.send(text)  # not swallowed by the refusal still held
            assert mavlink.MAVLink(None).parse_buffer(peer.recv(1024))[0].text == (
                "first one heard")
            assert link.send_errors == 0
        finally:
            peer.close()
    finally:
        link.close()


def test_a_udpout_link_whose_send_fails_connects_again_on_its_port_at_most_twice_a_second(
        caplog: pytest.LogCaptureFixture) -> None:
    clock = FakeClock()
    peer = _peer_socket()
    link = open_link(f"udpout:127.0.0.1:{peer.getsockname()[1]}", source_system=1,
                     source_component=1, name="gcs", clock=clock)

    def unreachable(data: bytes) -> int:  # a connected socket whose route went away
        raise OSError(errno.ENETUNREACH, "Network is unreachable")

    try:
        local = link.conn.port.getsockname()
        beat = link.mav.heartbeat_encode(10, 8, 0, 0, 4)
        link._send = unreachable
        with caplog.at_level("WARNING", logger="mecanum_mav"):
            assert not link.send(beat)  # failed, counted; connected again
        assert [r.getMessage() for r in caplog.records] == [  # the socket's own error
            "gcs: send failed (1 so far): [Errno 101] Network is unreachable"]
        assert link.send(beat)
        assert peer.recvfrom(1024)[1] == local  # from the same port
        link._send = unreachable
        assert not link.send(beat)  # within REOPEN_PERIOD_S of the last: not again yet
        assert not link.send(beat) and link.send_errors == 3
        clock.now += links.REOPEN_PERIOD_S
        assert not link.send(beat)
        assert link.send(beat) and link.send_errors == 4
        assert peer.recvfrom(1024)[1] == local
        assert link.conn.port.getpeername() == peer.getsockname()
    finally:
        peer.close()
        link.close()


def test_a_udpout_link_whose_connection_cannot_be_undone_goes_on_sending_unconnected(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """UdpoutLink._reconnect: "If it cannot be made again, the link goes on unconnected
    (sendto, recvfrom), as pymavlink's own": here the kernel refuses to undo the connection
    (the socket stays connected to the destination, so sendto reaches it)."""
    clock = FakeClock()
    peer = _peer_socket()
    link = open_link(f"udpout:127.0.0.1:{peer.getsockname()[1]}", source_system=1,
                     source_component=1, name="gcs", clock=clock)

    def unreachable(data: bytes) -> int:
        raise OSError(errno.ENETUNREACH, "Network is unreachable")

    try:
        beat = link.mav.heartbeat_encode(10, 8, 0, 0, 4)
        link._send = unreachable
        monkeypatch.setattr(links.datagram, "_dissolve", lambda sock: False)
        assert not link.send(beat)  # failed; the connection could not be undone
        assert link.send(beat) and link.send(beat)  # unconnected: sendto
        assert [peer.recvfrom(1024)[0][7] for _ in range(2)] == [0, 0]  # two HEARTBEATs
        assert link.send_errors == 1
    finally:
        peer.close()
        link.close()


def test_dissolving_a_connected_udp_socket_forgets_its_peer_and_its_local_address():
    # What lets a udpout link choose its route and source address anew (a connected socket
    # keeps the ones it chose, and connecting it again reuses them).
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.connect(("127.0.0.1", 9))
        assert sock.getsockname()[0] == "127.0.0.1"
        assert links._dissolve(sock)
        assert sock.getsockname() == ("0.0.0.0", 0)
        with pytest.raises(OSError):  # ENOTCONN
            sock.getpeername()
