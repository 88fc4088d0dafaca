"""TCP links: :class:`TcpLink` (``tcp:HOST:PORT``, connects; reconnects when the connection
is lost) and :class:`TcpServerLink` (``tcpin:HOST:PORT``, listens; one client at a time).

Pacing: the kernel's unsent bytes (``SIOCOUTQNSD``) must be at most
:data:`TCP_UNSENT_LIMIT` before more is handed over; at most :data:`TCP_QUEUE_BYTES` wait in
the link besides the newest override. A ``tcp:`` link whose peer closed or reset the
connection is down and connects again, never blocking (a non-blocking connect, completed on a
later attempt, abandoned after :data:`TCP_CONNECT_TIMEOUT_S`). A ``tcpin:`` link whose client
left goes back to listening and is up again when the next client connects. Closing with a
linger keeps the connection open for the linger, reading and dropping what the peer still
sends, then sends its end-of-stream: a peer that sees the connection end while the last
bytes are still in its buffers may drop them, and unread data would turn the close into a
reset. Times are seconds on the link's clock.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import selectors
import socket
import time
from collections.abc import Callable
from typing import Any, ClassVar

from mecanum_mav.io.links.base import READ_CHUNK, LinkDownError
from mecanum_mav.io.links.stream import StreamLink, queued_bytes

log = logging.getLogger("mecanum_mav.io.links")

__all__ = ["TCP_CONNECT_TIMEOUT_S", "TCP_POLL_S", "TCP_QUEUE_BYTES", "TCP_UNSENT_LIMIT",
           "TcpLink", "TcpServerLink"]

TCP_CONNECT_TIMEOUT_S = 3.0
"""A TCP connect still pending after this long (seconds) is abandoned and started again."""
TCP_QUEUE_BYTES = 65536
"""A TCP link queues at most this many bytes besides the newest override."""
TCP_UNSENT_LIMIT = 1024
"""A TCP link hands over more only while the kernel holds at most this many unsent bytes."""
TCP_POLL_S = 0.01
"""How soon a TCP link over :data:`TCP_UNSENT_LIMIT` looks again (seconds): the kernel has
no readiness event for "the unsent queue shrank"."""
_SIOCOUTQNSD = 0x894B  # Linux: bytes of a TCP socket's queue not yet sent


class _Tcp(StreamLink):
    """What both TCP links share: a connected socket paced by its unsent bytes, and the
    linger on close."""

    closed_reason: ClassVar[str] = "closed by the peer"
    """Why it is down when the peer ended the stream."""

    def __init__(self, conn: Any, *, url: str, name: str, signing_key: bytes | None,
                 clock: Callable[[], float]) -> None:
        super().__init__(conn, url=url, name=name, signing_key=signing_key, clock=clock,
                         queue_limit=TCP_QUEUE_BYTES)

    def _read_port(self) -> bytes:
        data = self.conn.port.recv(READ_CHUNK)
        if not data:  # a stream readable with nothing in it: closed
            self._went_down(self.closed_reason, "end of stream")
            raise LinkDownError(self.down_reason)
        return bytes(data)

    def _write_port(self, data: bytes) -> int:
        return int(self.conn.port.send(data))

    def _backlog_s(self, now: float) -> float:
        if queued_bytes(self._port_fd, _SIOCOUTQNSD) > TCP_UNSENT_LIMIT:
            return TCP_POLL_S
        return 0.0

    def _flush_out(self, linger_s: float) -> None:
        """Keep the connection open for ``linger_s`` seconds, reading and dropping what the
        peer still sends, then send the end-of-stream and read what is left."""
        port = self.conn.port
        if port is None:
            return
        port.settimeout(0.05)
        deadline = time.monotonic() + linger_s
        while time.monotonic() < deadline:
            try:
                if not port.recv(READ_CHUNK):
                    return  # the peer closed first
            except TimeoutError:
                continue
        port.shutdown(socket.SHUT_WR)
        with contextlib.suppress(TimeoutError):
            while port.recv(READ_CHUNK):  # what is left, so the close is not a reset
                pass


class TcpLink(_Tcp):
    """A ``tcp:`` link: connects to its address; connects again when the connection is
    lost (module description)."""

    _connecting: socket.socket | None = None
    _connect_s = 0.0

    def _reopen(self, now_s: float) -> bool:
        """One step of a non-blocking connect: start one, or see whether it completed."""
        sock = self._connecting
        if sock is not None and now_s - self._connect_s > TCP_CONNECT_TIMEOUT_S:
            sock.close()
            sock = self._connecting = None
        if sock is None:
            sock = self._start_connect()
            if sock is None:
                return False
            self._connecting, self._connect_s = sock, now_s
        if not _writable(sock):
            return False  # still connecting: the next attempt looks again
        self._connecting = None
        code = sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)
        if code:  # refused, unreachable
            log.debug("%s: reconnecting failed: %s", self.name, os.strerror(code))
            sock.close()
            return False
        sock.setsockopt(socket.SOL_TCP, socket.TCP_NODELAY, 1)
        with contextlib.suppress(OSError):
            self.conn.port.close()
        self.conn.port = sock
        self.conn.fd = sock.fileno()
        return True

    def _start_connect(self) -> socket.socket | None:
        """A non-blocking connect to the link's address, under way (None: it failed at once,
        said in the debug log: refused, no route, a name that no longer resolves, a process
        out of descriptors)."""
        sock = None
        try:
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            sock.setblocking(False)
            code = sock.connect_ex(self.conn.destination_addr)
            if code not in (0, errno.EINPROGRESS):
                raise OSError(code, os.strerror(code))
        except OSError as exc:
            log.debug("%s: reconnecting failed: %s", self.name, exc)
            if sock is not None:
                sock.close()
            return None
        return sock

    def close(self, *, linger_s: float = 0.0) -> None:
        super().close(linger_s=linger_s)
        if self._connecting is not None:
            self._connecting.close()
            self._connecting = None


class TcpServerLink(_Tcp):
    """A ``tcpin:`` link: listens; one client at a time, taken when it connects; when it
    leaves the link is down until the next one connects (module description)."""

    gone_reason: ClassVar[str] = "client left"
    closed_reason: ClassVar[str] = "client left"

    def wait_fd(self) -> int | None:
        """The client's descriptor, or the listening socket's while there is none (down
        too: it waits for the next client)."""
        return self.fileno()

    def _receive(self) -> bytes:
        if self.conn.port is None and not self._accept():
            return b""
        return super()._receive()

    def _check_open(self) -> None:
        super()._check_open()
        if self.conn.port is None:
            raise LinkDownError("no client connected")  # nobody to send to yet

    def _went_down(self, reason: str, detail: object = "") -> None:
        """The client left: back to listening, the next client brings the link up (called
        only while it is up, as the stream link's)."""
        self._mark_down(reason, detail)
        conn = self.conn
        with contextlib.suppress(OSError):
            conn.port.close()
        conn.port = None
        conn.fd = conn.listen.fileno()

    def _accept(self) -> bool:
        """Without a client: take the one waiting, if any."""
        conn = self.conn
        try:
            port, _ = conn.listen.accept()
        except OSError:  # nobody waiting
            return False
        port.setsockopt(socket.SOL_TCP, socket.TCP_NODELAY, 1)
        port.setblocking(False)
        conn.port = port
        conn.fd = port.fileno()
        self._port_fd = port.fileno()
        if self.down_reason is not None:
            self._came_up()
        return True


def _writable(sock: socket.socket) -> bool:
    with selectors.DefaultSelector() as sel:
        sel.register(sock, selectors.EVENT_WRITE)
        return bool(sel.select(0))
