"""open_link gives each transport family its own class under the common Link base
(mecanum_mav/io/links/), and the broadcast link answers whoever answered it."""

from __future__ import annotations

import contextlib
import logging
import select
import socket
from collections.abc import Iterator
from typing import Any

import pytest
from support import RawPty, wait_until
from test_links import FakeClock, _peer_socket

from mecanum_mav.io import links
from mecanum_mav.io.links import Link, open_link
from mecanum_mav.protocol.dialect import mavlink

KEY = bytes(range(32))


def opened(url: str, **kwargs: object) -> Link:
    return open_link(url, source_system=1, source_component=191, name="gcs", **kwargs)


def test_open_link_gives_each_transport_family_its_own_link_class():
    listener = socket.create_server(("127.0.0.1", 0))
    pty = RawPty()
    made: list[Link] = []
    try:
        cases = [
            ("udpin:127.0.0.1:0", {}, links.UdpinLink),
            ("udpin:127.0.0.1:0", {"signing_key": KEY, "tell_refused": True},
             links.SignedUdpinLink),
            ("udpin:127.0.0.1:0", {"signing_key": KEY}, links.UdpinLink),
            ("udpout:127.0.0.1:9", {}, links.UdpoutLink),
            ("udpbcast:127.0.0.1:9", {}, links.UdpBroadcastLink),
            (f"tcp:127.0.0.1:{listener.getsockname()[1]}", {}, links.TcpLink),
            ("tcpin:127.0.0.1:0", {}, links.TcpServerLink),
            (f"{pty.path},57600", {}, links.SerialLink),
        ]
        for url, kwargs, cls in cases:
            made.append(opened(url, **kwargs))
            assert type(made[-1]) is cls, url
        datagram = [isinstance(link, links.DatagramLink) for link in made]
        stream = [isinstance(link, links.StreamLink) for link in made]
        assert datagram == [True] * 5 + [False] * 3
        assert stream == [not d for d in datagram]
        assert [link.steady for link in made] == datagram
    finally:
        for link in made:
            link.close()
        listener.close()
        pty.close()


@contextlib.contextmanager
def broadcast_then_answer(answer: Any) -> Iterator[tuple[Link, socket.socket, socket.socket]]:
    """A ``udpbcast:`` link that has sent a HEARTBEAT to its destination (the first socket),
    then got ``answer(station)``'s datagram from another socket (the answering one)."""
    first, answering = (socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(2))
    for sock in (first, answering):
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(5.0)
    link = opened(f"udpbcast:127.0.0.1:{first.getsockname()[1]}")
    try:
        assert link.send(BEAT)
        first.recvfrom(1024)
        station = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        answering.sendto(answer(station), ("127.0.0.1", link.local_port))
        yield link, first, answering
    finally:
        link.close()
        first.close()
        answering.close()


BEAT = mavlink.MAVLink_heartbeat_message(10, 8, 0, 0, 4, 3)


def test_a_udpbcast_link_sends_to_the_address_that_answered_it():
    with broadcast_then_answer(lambda station: station.heartbeat_encode(6, 8, 0, 0, 4).pack(
            station)) as (link, _, answering):
        assert wait_until(link.read, 5.0)
        assert link.send(BEAT)
        data, _ = answering.recvfrom(1024)
        assert mavlink.MAVLink(None).parse_buffer(data)[0].get_type() == "HEARTBEAT"


def _stick(station: Any) -> bytes:
    return bytes(station.manual_control_encode(1, 250, 0, 500, 0, 0).pack(station))


def test_a_udpbcast_link_whose_answerers_datagram_the_stick_lane_answered_sends_there():
    """A datagram the stick lane answers unparsed is taken as if read
    (``DatagramLink.answered``): on a broadcast link its sender is the address that answered,
    sent to from then on, as after :meth:`read`."""
    with broadcast_then_answer(_stick) as (link, first, answering):
        got = wait_until(link.receive_datagram, 5.0)
        assert got is not None and got[0] == _stick(
            mavlink.MAVLink(None, srcSystem=255, srcComponent=190))
        link.answered(*got)  # (as the companion's loop does after the lane's send)
        assert link.send(BEAT)
        assert select.select([first, answering], [], [], 5.0)[0] == [answering]
        data, _ = answering.recvfrom(1024)
        assert mavlink.MAVLink(None).parse_buffer(data)[0].get_type() == "HEARTBEAT"


@pytest.mark.parametrize("resolves", [True, False])
def test_a_link_pymavlink_sends_for_takes_each_datagram_whole(
        resolves: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """MAVLink over UDP: each datagram carries whole packets, so a packet split over two
    datagrams is refused, as by every UDP link. Here a broadcast link, and a ``udpout:`` link
    whose host does not resolve when it opens (pymavlink then sends for it)."""
    peer = _peer_socket()
    if resolves:
        link = opened(f"udpbcast:127.0.0.1:{peer.getsockname()[1]}")
    else:
        def unresolvable(host: str) -> str:
            raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")
        with monkeypatch.context() as patch:
            patch.setattr(socket, "gethostbyname", unresolvable)
            link = opened(f"udpout:127.0.0.1:{peer.getsockname()[1]}")
    try:
        assert type(link) is (links.UdpBroadcastLink if resolves
                              else links.PymavlinkDatagramLink)
        assert link.name == "gcs" and link.url.endswith(f":{peer.getsockname()[1]}")
        assert link.send(link.mav.heartbeat_encode(10, 8, 0, 0, 4))
        _, address = peer.recvfrom(1024)
        station = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        packet = bytes(station.heartbeat_encode(6, 8, 0, 0, 4).pack(station))
        peer.sendto(packet[:7], address)
        peer.sendto(packet[7:], address)
        peer.sendto(packet, address)
        last = station.statustext_encode(6, b"last").pack(station)
        peer.sendto(bytes(last), address)
        got: list[str] = []
        assert wait_until(
            lambda: got.extend(m.get_type() for m in link.read()) or "STATUSTEXT" in got, 5.0)
        assert got == ["HEARTBEAT", "STATUSTEXT"]
    finally:
        link.close()
        peer.close()


def test_a_link_pymavlink_sends_for_warns_of_failed_sends_once_a_second_on_its_clock(
        monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    """Link: every timer of a link runs on the clock it was given, the send-failure
    warning's rate among them, and a send never raises; here a ``udpout:`` link whose host
    did not resolve (pymavlink sends for it) and whose sends fail."""
    peer = _peer_socket()
    clock = FakeClock()

    def unresolvable(host: str) -> str:
        raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")
    with monkeypatch.context() as patch:
        patch.setattr(socket, "gethostbyname", unresolvable)
        link = opened(f"udpout:127.0.0.1:{peer.getsockname()[1]}", clock=clock)

    def refused(data: bytes) -> None:
        raise OSError("refused")
    try:
        assert type(link) is links.PymavlinkDatagramLink
        link.conn.write = refused
        with caplog.at_level(logging.WARNING, logger="mecanum_mav.io.links"):
            for _ in range(30):  # 1.5 s of failures at 20 Hz on the link's clock
                assert not link.send(link.mav.heartbeat_encode(6, 8, 0, 0, 4))
                clock.now += 0.05
        assert link.send_errors == 30
        assert len([r for r in caplog.records if "send failed" in r.getMessage()]) == 2
    finally:
        link.close()
        peer.close()


def test_a_link_pymavlink_sends_for_signs_with_the_key_it_was_given():
    peer = _peer_socket()
    link = opened(f"udpbcast:127.0.0.1:{peer.getsockname()[1]}", signing_key=KEY)
    try:
        assert link.send(link.mav.heartbeat_encode(10, 8, 0, 0, 4))
        data, _ = peer.recvfrom(1024)
        assert data[0] == 0xFD and data[2] & mavlink.MAVLINK_IFLAG_SIGNED  # MAVLink 2, signed
        assert len(data) == 10 + data[1] + 2 + 13  # header, payload, CRC, signature
    finally:
        link.close()
        peer.close()


@pytest.mark.parametrize("url", ["udpout:127.0.0.1:9", "udpin:127.0.0.1:0"])
def test_a_datagram_link_never_goes_down_and_nothing_waits_in_it(url):
    link = opened(url)
    try:
        link.send_rc_override(1, 1, [1500] * 18)
        assert link.reopen(0.0) and link.up and not link.pending and not link.wants_write
        assert link.wait_fd() == link.fileno()
    finally:
        link.close()


def test_a_serial_link_is_paced_to_the_urls_baud_rate_and_refused_without_one():
    """8N1: ten bits a byte on the wire (pymavlink's 115200 where the URL gives no rate); a
    rate of 0 cannot carry anything and is refused when the link opens."""
    port = RawPty()
    try:
        for url, bytes_per_s in ((f"{port.path},57600", 5760.0), (port.path, 11520.0)):
            link = open_link(url, source_system=255, source_component=190, name="fc")
            try:
                assert link.bytes_per_s == bytes_per_s
            finally:
                link.close()
        with pytest.raises(ValueError, match=f"cannot open fc link '{port.path},0': baud rate "
                                             "0: a serial link needs a positive one"):
            open_link(f"{port.path},0", source_system=255, source_component=190, name="fc")
    finally:
        port.close()


def test_a_serial_link_at_1_baud_is_accepted_every_positive_rate_is():
    """The refusal's own words: "a serial link needs a positive one"; 1 is positive (one
    byte every 10 s on the wire, 8N1)."""
    port = RawPty()
    try:
        link = open_link(f"{port.path},1", source_system=255, source_component=190, name="fc")
        try:
            assert link.bytes_per_s == 0.1
        finally:
            link.close()
    finally:
        port.close()
