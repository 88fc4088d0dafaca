"""Links never raise: failed sends are counted and reported, at most once a second per link."""

from __future__ import annotations

import contextlib
import logging
import socket
import threading
import time

from mecanum_mav.config.params import Params
from mecanum_mav.control.core import LinkCounts, RoverCore
from mecanum_mav.io import links
from mecanum_mav.io.links import open_link
from mecanum_mav.protocol.dialect import mavlink


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def failing_link(monkeypatch):
    link = open_link("udpout:127.0.0.1:9", source_system=255, source_component=190, name="fc")

    def broken(data):
        raise OSError(111, "Connection refused")

    monkeypatch.setattr(link.conn, "write", broken)
    return link


def test_a_failing_send_is_counted_and_warned_about_once_a_second_per_link(monkeypatch, caplog):
    clock = FakeClock()
    monkeypatch.setattr(links.time, "monotonic", clock)
    link = failing_link(monkeypatch)
    try:
        with caplog.at_level(logging.WARNING, logger="mecanum_mav.io.links"):
            for _ in range(10):
                link.send_rc_override(1, 1, [1500] * 4 + [65535] * 4 + [0] * 10)
                link.send(link.mav.heartbeat_encode(6, 8, 0, 0, 4))
                clock.now += 0.05  # 20 Hz: one second of failures
            warnings = [r for r in caplog.records if "send failed" in r.getMessage()]
            assert link.send_errors == 20
            assert len(warnings) == 1 and "fc: send failed" in warnings[0].getMessage()
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


def wait_until(condition, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return True
        threading.Event().wait(0.01)
    return False
