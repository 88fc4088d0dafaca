"""Datagram links (mecanum_mav/io/links/datagram.py) when sending fails or the socket could not
be connected: a stick-lane packet the kernel refuses is counted, never raised; messages that
cannot be packed put no datagram on the wire; a ``udpout:`` link left unconnected still reads
(each sender with its own address); and only a ``udpout:`` connection has one fixed
destination."""

from __future__ import annotations

import errno
import logging
import os
import select
import socket

import pytest
from test_links import _peer_socket, failing_link

from mecanum_mav.io.links import mavlink, mavutil, open_link
from mecanum_mav.io.links.datagram import fixed_destination


def test_a_stick_lane_packet_the_kernel_refuses_is_counted_as_failed_not_sent():
    link = failing_link()  # (the broadcast address without SO_BROADCAST: EACCES)
    try:
        lane = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        stick = bytes(lane.manual_control_encode(1, 0, 0, 500, 0, 0).pack(lane))
        seq = link.mav.seq
        link.send_packet(stick)  # never raises
        assert (link.sent, link.send_errors) == (0, 1)
        assert link.mav.seq == (seq + 1) & 0xFF  # its sequence number was used all the same
    finally:
        link.close()


def test_a_stick_lane_packet_sent_is_counted_once_on_the_wire_and_recorded_whole(tmp_path):
    sink = _peer_socket()
    link = open_link(f"udpout:127.0.0.1:{sink.getsockname()[1]}", source_system=1,
                     source_component=191, name="gcs")
    tlog = (tmp_path / "lane.tlog").open("wb")
    try:
        link.record_to(tlog)
        lane = mavlink.MAVLink(None, srcSystem=1, srcComponent=191)
        stick = bytes(lane.manual_control_encode(1, 0, 0, 500, 0, 0).pack(lane))
        sent = link.sent
        link.send_packet(stick)
        link.send_packet(stick)
        assert link.sent == sent + 2 and link.send_errors == 0
        assert sink.recv(1024) == stick and sink.recv(1024) == stick
        tlog.flush()
        records = (tmp_path / "lane.tlog").read_bytes()
        assert records[8:8 + len(stick)] == stick  # stamp, then the packet as it went
        assert len(records) == 2 * (8 + len(stick))
    finally:
        link.close()
        tlog.close()
        sink.close()


def test_send_all_of_messages_none_of_which_can_be_packed_puts_no_datagram_on_the_wire():
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    link = open_link(f"udpout:127.0.0.1:{sink.getsockname()[1]}", source_system=1,
                     source_component=191, name="gcs")
    try:
        mav = mavlink.MAVLink(None)
        unpackable = [mav.heartbeat_encode(300, 8, 0, 0, 4),  # a uint8 field of 300
                      mav.heartbeat_encode(6, 300, 0, 0, 4)]
        link.send_all(unpackable)  # never raises
        assert link.send_errors == 2
        assert link.send(mav.heartbeat_encode(6, 8, 0, 0, 4))
        assert select.select([sink], [], [], 2.0)[0]
        first = sink.recv(65536)  # not an empty datagram from send_all
        assert [m.get_type() for m in mavlink.MAVLink(None).parse_buffer(first) or ()] == [
            "HEARTBEAT"]
    finally:
        link.close()
        sink.close()


def test_a_udpout_link_left_unconnected_reads_each_datagram_with_its_senders_address():
    link = failing_link()  # the kernel refused to connect it: it stays unconnected
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sender.bind(("127.0.0.1", 0))
    try:
        board = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        beat = bytes(board.heartbeat_encode(10, 3, 0, 0, 3).pack(board))
        sender.sendto(beat, ("127.0.0.1", link.local_port))
        assert select.select([link.fileno()], [], [], 2.0)[0], "the datagram never arrived"
        assert link.receive_datagram() == (beat, sender.getsockname())
        assert link.receive_datagram() is None  # nothing more waits
    finally:
        sender.close()
        link.close()


def test_only_a_udpout_connection_has_a_fixed_destination_its_host_resolved_once():
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    conns = {url: mavutil.mavlink_connection(url, source_system=255)
             for url in (f"udpout:localhost:{port}", "udpin:127.0.0.1:0",
                         f"udpbcast:127.255.255.255:{port}")}
    try:
        assert fixed_destination(conns[f"udpout:localhost:{port}"]) == ("127.0.0.1", port)
        assert fixed_destination(conns["udpin:127.0.0.1:0"]) is None  # answers its peers
        # a broadcast link answers whoever replied first
        assert fixed_destination(conns[f"udpbcast:127.255.255.255:{port}"]) is None
    finally:
        for conn in conns.values():
            conn.close()


@pytest.mark.parametrize("url", ["udpin:127.0.0.1:0", "udpout:127.0.0.1:9"],
                         ids=["answering its peers", "connected to its destination"])
def test_a_datagram_link_whose_socket_fails_every_read_reads_nothing_and_never_raises(
        url: str, caplog: pytest.LogCaptureFixture) -> None:
    """(The socket's descriptor made a folder's: every read fails with ENOTSOCK, not a "none
    waits" error.) Each failure is logged at DEBUG with the system's reason."""
    link = open_link(url, source_system=255, source_component=190, name="gcs")
    folder = os.open("/", os.O_RDONLY)
    try:
        os.dup2(folder, link.fileno())
        with caplog.at_level(logging.DEBUG, logger="mecanum_mav.io.links"):
            assert link.receive_datagram() is None
            assert link.read() == []
        reason = f"[Errno {errno.ENOTSOCK}] {os.strerror(errno.ENOTSOCK)}"
        assert [r.getMessage() for r in caplog.records if r.name == "mecanum_mav.io.links"] == [
            f"gcs: read failed: {reason}"] * 2
    finally:
        os.close(folder)
        link.close()


def test_a_udpout_host_that_is_no_host_name_is_refused_when_the_link_opens():
    """(``rover..local``: IDNA refuses an empty label; pymavlink would raise at each send.)"""
    with pytest.raises(ValueError, match=r"cannot open gcs link 'udpout:rover\.\.local:14550'"):
        open_link("udpout:rover..local:14550", source_system=255, source_component=190,
                  name="gcs")
