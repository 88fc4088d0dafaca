"""Datagram links: :class:`DatagramLink`, what every one has, :class:`UdpoutLink` (its
socket connected to its one destination), :class:`UdpBroadcastLink` (``udpbcast:``) and
:class:`PymavlinkDatagramLink` (the rest pymavlink opens, sent through pymavlink). ``udpin:``
is in :mod:`~mecanum_mav.io.links.udpin`.

A datagram link never goes down and nothing waits in it: a packet is one datagram handed to
the kernel at once (:meth:`DatagramLink.send_all` puts whole packets together, at most
:data:`DATAGRAM_BYTES` a datagram). Reads skip pymavlink's ``recv``: a datagram is read
(:meth:`DatagramLink.receive_datagram`) and parsed whole by the fast codec; the stick lane of
the loop may answer one straight from its bytes (:meth:`DatagramLink.answered`) and send the
override packed elsewhere (:meth:`DatagramLink.send_packet`) when the link is
:attr:`~mecanum_mav.io.links.base.Link.unchecked`.

A ``udpout:`` link's socket is connected to its destination, as ArduPilot's UDP client
connects its own: the kernel keeps the route and takes no address apart per datagram
(tools/bench_ab.py: about a tenth of the CPU per stick at 1 kHz), and reads only what comes
from the destination, so a stranger's datagrams never reach the link. An ICMP port
unreachable for an earlier datagram (no one listening yet) is reported by the kernel on the
next send instead of sending it: that send is made again. A send that fails otherwise (the
route or this machine's address changed) connects the socket anew, on the same local port,
at most once every :data:`~mecanum_mav.io.links.base.REOPEN_PERIOD_S` (clock seconds).
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import math
import socket
from collections.abc import Callable, Sequence
from typing import Any, ClassVar

from mecanum_mav.io.links.base import MAX_READS, READ_CHUNK, REOPEN_PERIOD_S, Link
from mecanum_mav.protocol.dialect import mavutil

log = logging.getLogger("mecanum_mav.io.links")

__all__ = ["DATAGRAM_BYTES", "DatagramLink", "PymavlinkDatagramLink", "UdpBroadcastLink",
           "UdpoutLink"]

DATAGRAM_BYTES = 1400
""":meth:`DatagramLink.send_all` puts at most this many bytes of whole packets in one datagram
(below a 1500-byte Ethernet MTU with IP and UDP headers: never fragmented)."""
NOTHING_TO_READ = (BlockingIOError, InterruptedError, ConnectionRefusedError)
"""A read that found nothing (refused: an earlier send found no one listening)."""
_AGAIN = (BlockingIOError, InterruptedError)


class DatagramLink(Link):
    """What every datagram link has: whole datagrams in and out, never down, nothing waiting.

    Subclasses say where a datagram goes (:meth:`_put_datagram`) and may read from a
    connected socket (:meth:`receive_datagram`)."""

    steady: ClassVar[bool] = True
    parses_datagrams = True

    def __init__(self, conn: Any, *, url: str, name: str, signing_key: bytes | None,
                 clock: Callable[[], float]) -> None:
        super().__init__(conn, url=url, name=name, signing_key=signing_key, clock=clock)
        self._recvfrom: Any = getattr(conn.port, "recvfrom", None)
        self._sendto: Any = getattr(conn.port, "sendto", None)
        self._batch: list[bytes] | None = None  # packets send_all() writes together

    # ----------------------------------------------------------------- reading

    def read(self, max_reads: int = MAX_READS) -> list[Any]:
        """Every complete message waiting, oldest first, from at most ``max_reads``
        datagrams; never raises. (pymavlink's recv, less its overhead: it would also make
        every sender on a udpin link a peer.)"""
        receive, parse = self.receive_datagram, self._parse_one
        messages: list[Any] = []
        for _ in range(max_reads):
            got = receive()
            if got is None:
                break
            messages += parse(*got)
        signing = self.signing  # (its clock advances on sends: a heartbeat a second)
        if signing is not None:
            signing.catch_up()
        self.received += len(messages)
        return messages

    def receive_datagram(self) -> tuple[bytes, Any] | None:
        """One datagram and its sender's address, unparsed and not yet counted, or None when
        none waits (or the read failed); never raises. Hand it to :meth:`parse_datagram`, or
        to :meth:`answered` when it was answered without parsing."""
        try:
            return self._recvfrom(READ_CHUNK)  # type: ignore[no-any-return]
        except NOTHING_TO_READ:
            return None
        except OSError as exc:
            log.debug("%s: read failed: %s", self.name, exc)
            return None

    def parse_datagram(self, data: bytes, address: Any) -> list[Any]:
        """The messages of a datagram from :meth:`receive_datagram`, counted as :meth:`read`
        counts them."""
        messages = self._parse_one(data, address)
        signing = self.signing
        if signing is not None:
            signing.catch_up()
        self.received += len(messages)
        return messages

    def answered(self, data: bytes, address: Any) -> None:
        """A datagram from :meth:`receive_datagram` holding one message, answered without
        parsing (the stick lane): counted, recorded, as if read."""
        self._arrived(data, address)
        recorder = self.recorder
        if recorder is not None:
            recorder.packet(data)
        self.received += 1

    def _arrived(self, data: bytes, address: Any) -> None:
        """What every datagram read does first, parsed or not: pymavlink's bookkeeping of
        the MAVLink version."""
        conn = self.conn
        if conn.first_byte:
            conn.auto_mavlink_version(data)

    def _parse_one(self, data: bytes, address: Any) -> list[Any]:
        """The messages of one datagram (not counted)."""
        self._arrived(data, address)
        parsed: list[Any] = self.parser.parse(data)
        if parsed:
            recorder = self.recorder
            if recorder is not None:
                recorder.messages(parsed)
        return parsed

    # ----------------------------------------------------------------- sending

    def write(self, buf: bytes) -> None:
        """Send one packet as a datagram at once (within :meth:`send_all`: with the others).

        Raises:
            OSError: it could not be sent this time (no route).
        """
        batch = self._batch
        if batch is not None:  # (send_all: written together at its end)
            batch.append(buf)
        else:
            self._put_datagram(buf)

    def send_all(self, messages: Sequence[Any]) -> None:
        """:meth:`send` each of ``messages``, in order, in as few datagrams as hold them:
        whole packets of at most :data:`DATAGRAM_BYTES` together, as ArduPilot sends its
        streams: a wake's telemetry costs one system call, not one per message (every
        MAVLink parser reads several packets from one datagram)."""
        if len(messages) < 2:
            for msg in messages:
                self.send(msg)
            return
        batch: list[bytes] = []
        self._batch = batch
        try:
            for msg in messages:
                self.send(msg)
        finally:
            self._batch = None
        start, size = 0, 0
        for end, packet in enumerate(batch):
            if size + len(packet) > DATAGRAM_BYTES and end > start:
                self._write_datagram(b"".join(batch[start:end]))
                start, size = end, 0
            size += len(packet)
        if start < len(batch):
            self._write_datagram(b"".join(batch[start:]))

    def send_rc_override(self, target_system: int, target_component: int,
                         channels: list[int], *, replace: bool = True) -> None:
        """RC_CHANNELS_OVERRIDE with the 18 ``chanN_raw`` fields, packed by the fast codec
        and sent at once (nothing waits in a datagram link: ``replace`` changes nothing);
        never raises."""
        if self._write_datagram(self._pack_override(target_system, target_component,
                                                    channels)):
            self.sent += 1

    def send_packet(self, packet: bytes) -> None:
        """Send a packet packed elsewhere with this link's next sequence number (the stick
        lane's override), which then advances; never raises. An :attr:`unchecked` link
        only."""
        mav = self.conn.mav
        mav.seq = (mav.seq + 1) & 0xFF
        if self._write_datagram(packet):
            self.sent += 1
        recorder = self.recorder
        if recorder is not None:
            recorder.packet(packet)

    def _write_datagram(self, data: bytes) -> bool:
        """Write one datagram; False (and counted) if that failed. Never raises."""
        try:
            self._put_datagram(data)
        except Exception as exc:  # a send must never take the control loop down
            self._send_failed(exc)
            return False
        return True

    def _put_datagram(self, data: bytes) -> None:
        """Hand one datagram to the kernel; raises what the socket raises, so a failed send
        is seen (pymavlink's ``write`` drops socket errors)."""
        raise NotImplementedError


class PymavlinkDatagramLink(DatagramLink):
    """A ``udpout:`` link whose host does not resolve, and whatever else pymavlink opens that
    is neither a stream nor another link here: sent through pymavlink's own ``write``."""

    def __init__(self, conn: Any, *, url: str, name: str, signing_key: bytes | None,
                 clock: Callable[[], float]) -> None:
        # (set before the parser is made: whole datagrams from UDP, unicast or multicast)
        self.parses_datagrams = isinstance(conn, (mavutil.mavudp, mavutil.mavmcast))
        super().__init__(conn, url=url, name=name, signing_key=signing_key, clock=clock)

    def _put_datagram(self, data: bytes) -> None:
        self.conn.write(data)


class UdpBroadcastLink(PymavlinkDatagramLink):
    """A ``udpbcast:`` link: pymavlink sends to the broadcast address until someone answers,
    then to the address that answered last."""

    def _arrived(self, data: bytes, address: Any) -> None:
        """pymavlink's bookkeeping: the reply address, the MAVLink version."""
        self.conn.last_address = address
        super()._arrived(data, address)


class UdpoutLink(DatagramLink):
    """A ``udpout:`` link: every datagram to one destination (its host resolved once,
    ``destination``), its socket connected there (module description)."""

    def __init__(self, conn: Any, destination: tuple[str, int], *, url: str, name: str,
                 signing_key: bytes | None, clock: Callable[[], float]) -> None:
        super().__init__(conn, url=url, name=name, signing_key=signing_key, clock=clock)
        self._destination = destination
        self._recv: Any = None  # the socket connected to the destination:
        self._send: Any = None  # its recv and send (see _connect)
        self._next_reconnect_s = -math.inf
        self._connect()

    def receive_datagram(self) -> tuple[bytes, Any] | None:
        """One datagram and its sender's address (the destination, while connected), or
        None when none waits (or the read failed); never raises."""
        try:
            if self._recv is not None:  # (connected: the sender is the destination)
                return self._recv(READ_CHUNK), self._destination
            return self._recvfrom(READ_CHUNK)  # type: ignore[no-any-return]
        except NOTHING_TO_READ:  # (refused: an earlier send found no one listening)
            return None
        except OSError as exc:
            log.debug("%s: read failed: %s", self.name, exc)
            return None

    def _put_datagram(self, data: bytes) -> None:
        """To the destination, straight to the socket; a refusal held for an earlier datagram
        is sent past, another failure connects the socket anew (:meth:`_reconnect`)."""
        if self._send is not None:
            try:
                self._send(data)
            except ConnectionRefusedError:  # an earlier datagram found no one listening;
                self._send(data)  # the kernel said so instead of sending this one: again
            except _AGAIN:
                raise
            except OSError:
                self._reconnect()  # (then counted as failed, as every failed send)
                raise
        else:
            self._sendto(data, self._destination)

    def _connect(self) -> None:
        """Connect the socket to the destination (module description). If the kernel refuses
        (a broadcast address without SO_BROADCAST), the link stays unconnected and its sends
        fail as they would have."""
        port = self.conn.port
        try:
            port.connect(self._destination)
        except OSError as exc:
            log.debug("%s: udpout socket left unconnected: %s", self.name, exc)
            return
        self._recv, self._send = port.recv, port.send

    def _reconnect(self) -> None:
        """The connected socket's send failed (not a refusal): the route, or this machine's
        own address (a new DHCP lease, another network), may have changed, and a connected
        socket keeps the ones it chose. Its connection is undone and made again, so the
        kernel chooses them anew, on the same local port; at most once every
        :data:`REOPEN_PERIOD_S`. If it cannot be made again (no route yet), the link goes on
        unconnected (``sendto``, ``recvfrom``), as pymavlink's own."""
        now = self.clock()
        if now < self._next_reconnect_s:
            return
        self._next_reconnect_s = now + REOPEN_PERIOD_S
        port = self.conn.port
        local_port = port.getsockname()[1]
        self._recv = self._send = None
        if not _dissolve(port):
            return  # (still connected: sendto to the same destination works on it)
        with contextlib.suppress(OSError):  # the same port again: the peer answers there
            port.bind(("", local_port))
        self._connect()


_UNSPECIFIED = bytes(16)
"""A ``struct sockaddr`` of family AF_UNSPEC (0): ``connect()`` to it undoes a UDP socket's."""


def _dissolve(sock: socket.socket) -> bool:
    """Undo a UDP socket's ``connect()``, which Python's socket module cannot express: the
    kernel forgets the peer, the route and the local address it chose for them, and the port
    it gave an unbound socket. True if it did."""
    libc = ctypes.CDLL(None)
    libc.connect.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_uint32]
    return int(libc.connect(sock.fileno(), _UNSPECIFIED, len(_UNSPECIFIED))) == 0


def fixed_destination(conn: Any) -> tuple[str, int] | None:
    """Where every datagram of a ``udpout:`` connection goes (its host resolved once), or
    None: a ``udpin:`` link answers its peers, a broadcast link its first reply, and a host
    that does not resolve is left to pymavlink."""
    if not isinstance(conn, mavutil.mavudp) or conn.udp_server or conn.broadcast:
        return None
    host, port = conn.destination_addr
    try:
        return socket.gethostbyname(host), int(port)
    except OSError:
        return None
