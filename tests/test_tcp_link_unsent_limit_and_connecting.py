"""TCP links at their edges (mecanum_mav/io/links/tcp.py): the kernel's unsent bytes pace what
is handed over (at most TCP_UNSENT_LIMIT unsent: at the limit more goes), a connect that hangs
is abandoned after TCP_CONNECT_TIMEOUT_S and started anew, closing never waits on a connection
that has nothing left to say and holds a silent one open for the linger (none by default), and
a ``tcpin:`` link with no client reads nothing, waits on its listening socket, says "no client
connected" to a send, and reads a client's first packet in the read that takes it. Real
sockets on 127.0.0.1, times on a fake clock the test moves."""

from __future__ import annotations

import array
import contextlib
import fcntl
import select
import socket
import termios
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from support import wait_until
from test_links import FakeClock
from test_stream_link_reads_records_and_breaks import tcp_pair

from mecanum_mav.io import links
from mecanum_mav.io.links import Link, LinkDownError, mavlink, open_link, tcp

SIOCOUTQNSD = 0x894B
"""Linux: the bytes of a TCP socket's queue not yet sent (what the link's pacing reads)."""
LARGEST_TEXT = 62
"""Bytes of the largest STATUSTEXT the tests send (MAVLink 2, its text trimmed)."""


def unsent(fd: int) -> int:
    count = array.array("i", [0])
    fcntl.ioctl(fd, SIOCOUTQNSD, count, True)
    return count[0]


def tcp_link(server: socket.socket, clock: FakeClock) -> Link:
    host, port = server.getsockname()
    return open_link(f"tcp:{host}:{port}", source_system=255, source_component=190,
                     name="fc", clock=clock)


def open_sockets() -> set[int]:
    """The descriptors of this process that are sockets."""
    return set(socket_inodes())


def socket_inodes() -> dict[int, str]:
    """Each socket descriptor of this process, with its socket's kernel name
    (``socket:[inode]``: a new socket has a new one, whatever descriptor number it gets)."""
    sockets = {}
    for path in Path("/proc/self/fd").iterdir():
        with contextlib.suppress(OSError):  # (the listing's own descriptor, gone now)
            target = str(path.readlink())
            if target.startswith("socket:"):
                sockets[int(path.name)] = target
    return sockets


def readable(sock: socket.socket, wait_s: float) -> None:
    select.select([sock], [], [], wait_s)


# --------------------------------------------------------------------------- pacing


def test_a_tcp_link_hands_over_more_only_while_the_kernel_holds_at_most_its_unsent_limit():
    clock = FakeClock()
    server = socket.socket()
    server.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 2048)  # a small window: a peer
    server.bind(("127.0.0.1", 0))  # that stops reading fills it at once
    server.listen(1)
    link = tcp_link(server, clock)
    peer, _ = server.accept()
    try:
        texts = [f"text {i:04d}" for i in range(300)]
        for text in texts:
            link.mav.statustext_send(6, text.encode())
        assert link.pending, "the link handed everything over to a peer that does not read"
        held = unsent(link.fileno())
        assert links.TCP_UNSENT_LIMIT < held <= links.TCP_UNSENT_LIMIT + LARGEST_TEXT
        assert link.next_send_s == clock.now + links.TCP_POLL_S  # it looks again then
        link.flush()
        assert unsent(link.fileno()) == held  # nothing more while the kernel holds that much

        parser = mavlink.MAVLink(None)
        parsed: list = []
        peer.setblocking(False)
        deadline = time.monotonic() + 10.0
        while len(parsed) < len(texts) and time.monotonic() < deadline:  # the peer reads
            readable(peer, 0.01)
            with contextlib.suppress(BlockingIOError):
                parsed += parser.parse_buffer(peer.recv(65536)) or []
            clock.now += links.TCP_POLL_S
            link.flush()
            assert unsent(link.fileno()) <= links.TCP_UNSENT_LIMIT + LARGEST_TEXT
        assert [m.text for m in parsed] == texts  # none lost, in order
    finally:
        link.close()
        peer.close()
        server.close()


def test_a_tcp_link_hands_over_more_while_the_kernel_holds_exactly_its_unsent_limit(
        monkeypatch: pytest.MonkeyPatch):
    """"At most TCP_UNSENT_LIMIT" (module description): at the limit itself the next packet
    goes; one byte more and it waits TCP_POLL_S. (The kernel's count is set here: a real
    socket's unsent bytes cannot be stopped at an exact count.)"""
    held = [links.TCP_UNSENT_LIMIT]
    monkeypatch.setattr(tcp, "queued_bytes", lambda fd, request: held[0])
    clock = FakeClock()
    server = socket.create_server(("127.0.0.1", 0))
    link = tcp_link(server, clock)
    peer, _ = server.accept()
    try:
        link.mav.statustext_send(6, b"at the limit")
        assert not link.pending and link.next_send_s == float("inf")  # handed over
        held[0] = links.TCP_UNSENT_LIMIT + 1
        link.mav.statustext_send(6, b"over it")
        assert link.pending and link.next_send_s == clock.now + links.TCP_POLL_S
        peer.settimeout(2.0)
        parsed = mavlink.MAVLink(None).parse_buffer(peer.recv(4096)) or []
        assert [m.text for m in parsed] == ["at the limit"]
    finally:
        link.close()
        peer.close()
        server.close()


# --------------------------------------------------------------------------- connecting


@contextlib.contextmanager
def connecting_link(clock: FakeClock) -> Iterator[tuple[Link, socket.socket, socket.socket]]:
    """A ``tcp:`` link whose peer closed, trying to connect again to a server that takes no
    more connections: its accept queue (backlog 0: one connection) is held by another client,
    so the kernel drops the link's SYN and the connect stays pending. Yields (the link, the
    server, the client holding the queue); the link has made its first attempt."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(0)
    link = tcp_link(server, clock)
    holder = None
    try:
        peer, _ = server.accept()
        peer.close()
        assert wait_until(lambda: (link.read(), not link.up)[1], 5.0,
                          pump=lambda s: select.select([link.fileno()], [], [], s))
        holder = socket.create_connection(server.getsockname(), timeout=5.0)
        clock.now = link.next_reopen_s
        assert not link.reopen(clock.now)  # connecting
        yield link, server, holder
    finally:
        link.close()
        if holder is not None:
            holder.close()
        server.close()


def test_a_tcp_connect_pending_longer_than_the_connect_timeout_is_abandoned_and_started_anew():
    clock = FakeClock()
    before = set(socket_inodes().values())
    with connecting_link(clock) as (link, server, holder):
        theirs = {socket_inodes()[server.fileno()], socket_inodes()[holder.fileno()]}
        pending = set(socket_inodes().values()) - before - theirs
        assert len(pending) == 1  # the connect under way
        started_s = clock.now
        for tries in range(1, 7):  # up to exactly the timeout: that connect may still complete
            clock.now = started_s + tries * links.REOPEN_PERIOD_S
            began = time.monotonic()
            assert not link.reopen(clock.now), clock.now - started_s
            assert time.monotonic() - began < 0.2  # a look at the connect, never a wait
            # the same connect goes on: no second one, no socket left behind
            assert set(socket_inodes().values()) - before - theirs == pending
        assert clock.now - started_s == links.TCP_CONNECT_TIMEOUT_S
        queued, _ = server.accept()  # the server takes connections again
        try:
            clock.now = started_s + links.TCP_CONNECT_TIMEOUT_S + links.REOPEN_PERIOD_S
            # the hung connect (its SYN dropped; the kernel retries it a second or more
            # later) is abandoned: a new one to the free server completes at once
            assert link.reopen(clock.now)
            assert link.up
        finally:
            queued.close()


def test_closing_a_tcp_link_while_it_connects_leaves_no_socket_open():
    clock = FakeClock()
    before = open_sockets()
    with connecting_link(clock) as (link, server, holder):
        pending = open_sockets() - before - {server.fileno(), holder.fileno()}
        assert len(pending) == 1  # the connect under way (the broken socket was closed)
        link.close()
        assert not open_sockets() & pending


# --------------------------------------------------------------------------- closing


def test_closing_a_tcp_link_with_a_linger_ends_as_soon_as_the_peer_has_closed():
    server = socket.create_server(("127.0.0.1", 0))
    link = tcp_link(server, FakeClock())
    peer, _ = server.accept()
    try:
        peer.close()  # the flight controller closed first: nothing more will come
        assert wait_until(lambda: select.select([link.fileno()], [], [], 0.05)[0], 5.0)
        start = time.monotonic()
        link.close(linger_s=3.0)
        assert time.monotonic() - start < 1.5  # not the whole linger
    finally:
        server.close()


def test_closing_a_tcp_link_without_a_linger_ends_the_connection_at_once():
    """No linger is the default (``close()``: immediate; the companion asks for one)."""
    with tcp_pair(clock=FakeClock()) as (link, peer):  # a peer that says nothing
        start = time.monotonic()
        link.close()
        assert time.monotonic() - start < 0.9  # (a default linger of 1 s would show)
        peer.settimeout(2.0)
        assert peer.recv(4096) == b""  # the end of the stream is there already


def test_closing_a_tcp_link_with_a_linger_holds_a_silent_peers_connection_for_the_linger():
    """Module description: the connection stays open for the linger (the peer may still
    be reading the last packets), then ends; a peer that says nothing neither cuts it short
    nor holds it longer."""
    linger_s = 0.2
    with tcp_pair(clock=FakeClock()) as (link, peer):  # a peer that says nothing
        start = time.monotonic()
        link.close(linger_s=linger_s)
        took = time.monotonic() - start
        assert linger_s <= took < linger_s + 0.7  # (polls of 1 s would show)
        peer.settimeout(2.0)
        assert peer.recv(4096) == b""


def tcpin_port() -> int:
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = int(probe.getsockname()[1])
    probe.close()  # (pymavlink's tcpin binds the port it is given)
    return port


def test_a_tcpin_link_with_no_client_reads_nothing_and_waits_on_its_listening_socket():
    port = tcpin_port()
    link = open_link(f"tcpin:127.0.0.1:{port}", source_system=255, source_component=190,
                     name="fc", clock=FakeClock())
    try:
        assert link.read() == []  # nobody connected: nothing, and no error
        assert link.bad == 0 and link.received == 0  # (and nothing bad was read)
        listening = link.wait_fd()
        assert listening is not None
        with socket.create_connection(("127.0.0.1", port), timeout=5.0) as client:
            sender = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
            client.sendall(sender.heartbeat_encode(10, 3, 0, 0, 3).pack(sender))
            got: list = []
            assert wait_until(lambda: got.extend(link.read()) or got, 5.0,
                              pump=lambda s: select.select([listening], [], [], s))
            assert [m.get_type() for m in got] == ["HEARTBEAT"]
            assert link.wait_fd() != listening  # the client's, now
    finally:
        link.close()


def test_closing_a_tcpin_link_that_has_no_client_with_a_linger_returns_at_once():
    link = open_link(f"tcpin:127.0.0.1:{tcpin_port()}", source_system=255,
                     source_component=190, name="fc", clock=FakeClock())
    start = time.monotonic()
    link.close(linger_s=3.0)  # no one to linger for
    assert time.monotonic() - start < 1.5


def test_a_tcpin_link_with_no_client_refuses_a_send_saying_no_client_connected():
    """A send there raises LinkDownError with the reason (``Link.write``): the caller, and
    a log that prints it, sees why nothing went out; ``send`` counts it unsent."""
    link = open_link(f"tcpin:127.0.0.1:{tcpin_port()}", source_system=255,
                     source_component=190, name="fc", clock=FakeClock())
    try:
        with pytest.raises(LinkDownError) as raised:
            link.mav.heartbeat_send(6, 8, 0, 0, 4)
        assert str(raised.value) == "no client connected"
        assert link.send(link.mav.heartbeat_encode(6, 8, 0, 0, 4)) is False
        assert link.unsent == 1
        assert link.send(link.mav.heartbeat_encode(6, 8, 0, 0, 4)) is False
        assert (link.unsent, link.send_errors) == (2, 0)  # each one counted, not a failure
    finally:
        link.close()


def unacknowledged(sock: socket.socket) -> int:
    """Bytes ``sock`` sent that its peer's kernel has not acknowledged yet (TIOCOUTQ)."""
    count = array.array("i", [0])
    fcntl.ioctl(sock.fileno(), termios.TIOCOUTQ, count, True)
    return count[0]


def test_a_tcpin_link_reads_a_new_clients_first_message_in_the_read_that_takes_it():
    """A client is taken when it connects (TcpServerLink): the read that finds it waiting
    reads what it sent too, not one read later."""
    port = tcpin_port()
    link = open_link(f"tcpin:127.0.0.1:{port}", source_system=255, source_component=190,
                     name="fc", clock=FakeClock())
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=5.0) as client:
            sender = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
            client.sendall(sender.heartbeat_encode(10, 3, 0, 0, 3).pack(sender))
            # the connection waits to be taken and its heartbeat is in our kernel
            assert wait_until(lambda: unacknowledged(client) == 0, 5.0)
            assert select.select([link.wait_fd()], [], [], 5.0)[0]
            assert [m.get_type() for m in link.read()] == ["HEARTBEAT"]
            assert link.up
    finally:
        link.close()


@pytest.mark.parametrize("url", ["tcp:127.0.0.1:{port}", "tcpin:127.0.0.1:{port}"])
def test_a_tcp_link_keeps_the_url_it_was_opened_with(url: str):
    """``Link.url``: the connection string, as given (what status and logs name)."""
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1] if url.startswith("tcp:") else tcpin_port()
    given = url.format(port=port)
    link = open_link(given, source_system=255, source_component=190, name="fc",
                     clock=FakeClock())
    try:
        assert (link.url, link.name) == (given, "fc")
    finally:
        link.close()
        server.close()
