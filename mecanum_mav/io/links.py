"""MAVLink links: pymavlink connections driven by a selector loop, MAVLink 2, never raising.

MAVLink 2 and the ArduPilot dialect throughout (:mod:`mecanum_mav.protocol.dialect`). URLs are
pymavlink connection strings: ``udpin:HOST:PORT`` (listen; replies go to every peer heard),
``udpout:HOST:PORT`` (its socket connected there: it reads only what comes from there),
``tcp:HOST:PORT``, ``tcpin:HOST:PORT``, or a serial device ``/dev/ttyUSB0,57600``
(pyserial).

A :class:`Link` is read when its file descriptor is readable: :meth:`Link.read` returns every
message that arrived, parsed from the raw bytes by :class:`~mecanum_mav.protocol.framing.
MessageParser` (on datagram links the fast codec of :mod:`mecanum_mav.protocol.codec`
decodes whole, good packets), and :meth:`Link.send_rc_override` and :meth:`Link.send` pack
with that codec too: the control path never waits on pymavlink's pure-Python parser and
packer. Malformed
bytes, bad CRCs and truncated packets are counted in :attr:`Link.bad`, never raised; a send
that fails (peer gone, no route) is counted in :attr:`Link.send_errors` and logged at WARNING
at most once a second per link.

Stream links that break come back by themselves. A serial device that vanishes (USB unplugged,
board rebooting: reads and writes fail with EIO/ENXIO), a ``tcp:`` connection the peer closed
or reset, and a ``tcpin:`` client that left put the link *down* (:attr:`Link.down_reason`):
its dead descriptor, which would be readable forever, is no longer waited on
(:meth:`Link.wait_fd`, :func:`follow`), what is sent meanwhile is dropped and counted in
:attr:`Link.unsent`, and :meth:`Link.reopen` opens the same device path or address again
every :data:`REOPEN_PERIOD_S` without ever blocking (a TCP connect is non-blocking, and
completes on a later attempt). A ``tcpin:`` link keeps listening and is up again as soon as a
new client connects. The shell tells the core about both transitions (it reports them once).
A ``udpin:`` link answers the peers it has heard a valid message from (with a signing key:
a correctly signed one), so a ground station that restarts on a new port is answered from its
first packet on, while garbage or unsigned datagrams from other addresses make no one a peer
(they get nothing back, and cannot make the rover send everything many times over). A peer
silent for :data:`PEER_TIMEOUT_S` is forgotten once another peer is heard; at most
:data:`MAX_PEERS` are kept (the longest silent goes first). With a signing key, an address
whose well-formed MAVLink packets were all refused (unsigned, badly signed: a ground station
without the key) is no peer either, but is told why: with each of the rover's heartbeats it
gets that HEARTBEAT, signed, and a STATUSTEXT with the reason, and nothing else, at most once
per heartbeat; such addresses are few and forgotten when silent
(:mod:`~mecanum_mav.protocol.refusedsenders`), and garbage makes no one one.

Stream links (serial, TCP) never block the loop on a write, and keep no standing queue in the
kernel. What is sent waits in the link (:meth:`Link.flush` hands it over); a packet goes to
the kernel only when what the kernel already holds would be on the wire within
:data:`PACING_LEAD_S`. On a serial link that is judged from the baud rate in the URL (8N1:
``baud / 10`` bytes/s, the time the bytes handed over need on the wire) and from the tty's
own output queue (``TIOCOUTQ``), whichever is longer; a pty, a USB-CDC board or any device
faster than its nominal rate is thus paced to the nominal rate too. On TCP the kernel's unsent
bytes (``SIOCOUTQNSD``) must be at most :data:`TCP_UNSENT_LIMIT`. The kernel's own buffers
(4 KB of tty, about 0.7 s at 57600 baud; a pty's 20 KB, ~4 s) would otherwise be a standing
queue. RC_CHANNELS_OVERRIDE is *newest wins*: an override still waiting in the link is
replaced by a newer one (counted in :attr:`Link.superseded`, never packed, so the sequence
numbers the board sees have no gaps); everything else queues in order, at most
:data:`QUEUE_S` of the wire (TCP: :data:`TCP_QUEUE_BYTES`); a packet that does not fit is
dropped and counted as a send error. Overrides and queued packets take turns, so a 1 kHz
override stream never starves the heartbeat. A loop waits for :attr:`Link.next_send_s` (the
pacing timer) and calls :func:`follow` once per pass, which flushes and watches the descriptor
for writing while the kernel refuses more (``EAGAIN``). :meth:`Link.close` with a linger hands
over what is still waiting, paced, before it closes.
"""

from __future__ import annotations

import array
import contextlib
import ctypes
import errno
import fcntl
import functools
import logging
import math
import os
import select
import selectors
import socket
import termios
import time
from collections import deque
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, BinaryIO

import serial

from mecanum_mav.io.tlog import tlog_record
from mecanum_mav.protocol.codec import encode_rc_override, send_message
from mecanum_mav.protocol.dialect import mavlink, mavutil
from mecanum_mav.protocol.framing import MessageParser
from mecanum_mav.protocol.refusedsenders import RefusedSenders
from mecanum_mav.protocol.signing import REFUSED_TEXTS, Check, SignatureCheck, ticks_from_unix
from mecanum_mav.protocol.statustext import Severity, statustext_messages

log = logging.getLogger(__name__)

__all__ = ["REOPEN_PERIOD_S", "Link", "LinkDownError", "follow", "mavlink", "mavutil", "open_link"]

_READ_CHUNK = 4096
SEND_WARNING_PERIOD_S = 1.0
"""A link that keeps failing to send is logged at WARNING at most this often."""
_MAX_READS = 64  # per readiness event: bounded work, the selector calls again if more waits
DATAGRAM_BYTES = 1400
""":meth:`Link.send_all` puts at most this many bytes of whole packets in one datagram (below
a 1500-byte Ethernet MTU with IP and UDP headers: never fragmented)."""
PEER_TIMEOUT_S = 10.0
"""A ``udpin:`` peer not heard from for this long is no longer sent to, once another is heard."""
MAX_PEERS = 8
"""A ``udpin:`` link sends to at most this many peers."""
REOPEN_PERIOD_S = 0.5
"""A link that is down tries to open its device or address again this often (seconds)."""
TCP_CONNECT_TIMEOUT_S = 3.0
"""A TCP connect still pending after this long (seconds) is abandoned and started again."""
PACING_LEAD_S = 0.002
"""A stream link hands the kernel the next packet only when what the kernel holds already
would be on the wire within this time (seconds): its standing queue is at most this plus
one packet."""
QUEUE_S = 1.0
"""A serial link queues at most this much wire time (seconds; at least
:data:`QUEUE_MIN_BYTES`) of packets other than the newest override; more is dropped."""
QUEUE_MIN_BYTES = 4096
TCP_QUEUE_BYTES = 65536
"""A TCP link queues at most this many bytes besides the newest override."""
TCP_UNSENT_LIMIT = 1024
"""A TCP link hands over more only while the kernel holds at most this many unsent bytes."""
TCP_POLL_S = 0.01
"""How soon a TCP link over :data:`TCP_UNSENT_LIMIT` looks again (seconds): the kernel has
no readiness event for "the unsent queue shrank"."""
_SIOCOUTQNSD = 0x894B  # Linux: bytes of a TCP socket's queue not yet sent
_SERIAL, _TCP, _TCP_SERVER, _DATAGRAM = "serial", "tcp", "tcpin", "datagram"
_AGAIN = (BlockingIOError, InterruptedError)
_HEARTBEAT = mavlink.MAVLink_heartbeat_message
"""(By class: ``msg.id`` is no message id on STATUSTEXT, whose chunk ``id`` field shadows it.)"""
_NOTHING_TO_READ = (BlockingIOError, InterruptedError, ConnectionRefusedError)


def _writable(sock: socket.socket) -> bool:
    with selectors.DefaultSelector() as sel:
        sel.register(sock, selectors.EVENT_WRITE)
        return bool(sel.select(0))


def _gone(kind: str) -> str:
    """Why a stream link broke, in a few words (a STATUSTEXT has 50 characters)."""
    return ("device gone" if kind == _SERIAL else
            "client left" if kind == _TCP_SERVER else "connection lost")


def _queued_bytes(fd: int, request: int) -> int:
    """What the kernel holds unsent for ``fd`` (``TIOCOUTQ``, ``SIOCOUTQNSD``), bytes; 0 if
    it cannot say."""
    count = array.array("i", [0])
    try:
        fcntl.ioctl(fd, request, count, True)
    except OSError:
        return 0
    return count[0]


class LinkDownError(OSError):
    """Raised by :meth:`Link.write` while the link is down: the packet was not sent."""


def _kind(conn: Any) -> str:
    """How a pymavlink connection breaks and comes back: serial device, TCP client, TCP
    server, or connectionless (UDP and the rest, which never go down)."""
    if isinstance(conn, mavutil.mavserial):
        return _SERIAL
    if type(conn) is mavutil.mavtcp:  # not its Unix-socket subclass
        return _TCP
    if isinstance(conn, mavutil.mavtcpin):
        return _TCP_SERVER
    return _DATAGRAM


_UNSPECIFIED = bytes(16)
"""A ``struct sockaddr`` of family AF_UNSPEC (0): ``connect()`` to it undoes a UDP socket's."""


def _dissolve(sock: socket.socket) -> bool:
    """Undo a UDP socket's ``connect()``, which Python's socket module cannot express: the
    kernel forgets the peer, the route and the local address it chose for them, and the port
    it gave an unbound socket. True if it did."""
    libc = ctypes.CDLL(None, use_errno=True)
    libc.connect.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_uint32]
    return int(libc.connect(sock.fileno(), _UNSPECIFIED, len(_UNSPECIFIED))) == 0


def _fixed_destination(conn: Any) -> tuple[str, int] | None:
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


class Link:
    """One MAVLink connection with non-blocking reads for a selector-driven loop.

    Args:
        url: pymavlink connection string.
        source_system: system id this side sends as (1..255).
        source_component: component id this side sends as.
        name: short name for logs (``"gcs"``, ``"fc"``).
        signing_key: the 32-byte MAVLink 2 signing key, or None. With a key everything sent
            is signed (link id 0; the timestamp starts at the wall clock, follows it and the
            newest timestamp of the verified packets received, and never goes backwards) and
            only correctly signed, fresh packets are read
            (:class:`~mecanum_mav.protocol.signing.SignatureCheck`); the others are dropped
            and counted (:meth:`take_rejections`). Taking the peer's timestamp is what the
            MAVLink C library and pymavlink do; ArduPilot relies on it: it drops a new stream
            more than a minute behind its own timestamp, which starts a minute ahead of the one
            it stored (tests/test_sitl_signing.py).
        tell_refused: with a signing key on a ``udpin:`` link (the ground station's), tell an
            address whose packets were all refused why, with each heartbeat
            (:attr:`refused_senders`); off for the flight controller's link.
        clock: the monotonic time source (seconds) of every timer of the link: pacing to the
            baud rate (:attr:`next_send_s`), the reopen timer (:attr:`next_reopen_s`), the
            send-failure log's rate, the ``udpin:`` peers' ages and the refused senders'
            hints. The caller's loop passes its own, so the link's times and the loop's are
            one; a test passes a fake one and asserts them exactly. (Signing timestamps and
            tlog stamps follow the wall clock, ``time.time``.)

    On a stream link (serial, TCP) what is sent waits in the link until :meth:`flush` can
    hand it to the kernel without a standing queue there (see the module's description);
    call :func:`follow` once per loop pass and wake by :attr:`next_send_s`.
    """

    def __init__(self, url: str, *, source_system: int, source_component: int, name: str,
                 signing_key: bytes | None = None, tell_refused: bool = False,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.url = url
        self.name = name
        self.clock = clock
        self.conn: Any = mavutil.mavlink_connection(
            url, source_system=source_system, source_component=source_component
        )
        parse_with, check = self.conn.mav, None
        if signing_key is not None:
            now = ticks_from_unix(time.time())
            self.conn.setup_signing(signing_key, sign_outgoing=True, link_id=0,
                                    initial_timestamp=now)
            # pymavlink checks signatures itself when its parser holds the key, recording a
            # stream's timestamp before verifying it (pymavlink issue #961): parse keyless
            # and let the SignatureCheck decide.
            parse_with, check = mavlink.MAVLink(None), SignatureCheck(signing_key, now)
        self.signature_check = check
        self.parser = MessageParser(parse_with, name=name, check=check,
                                    datagrams=url.startswith(("udp:", "udpin:", "udpout:",
                                                              "udpbcast:")))
        self.received = 0
        self._warned_s = -math.inf
        self.sent = 0
        self.send_errors = 0
        self._tlog: BinaryIO | None = None
        self.conn.mav.file = self  # every packet goes out through write(), which sees a break
        self._udp_server = bool(getattr(self.conn, "udp_server", False))
        self._recvfrom: Any = getattr(self.conn.port, "recvfrom", None)  # (datagram links)
        self._sendto: Any = getattr(self.conn.port, "sendto", None)
        self._destination = _fixed_destination(self.conn)
        self._recv: Any = None  # a udpout link's socket connected to its destination:
        self._send: Any = None  # its recv and send (see _connect)
        self._next_reconnect_s = -math.inf
        self._connect()
        self._peers_s: dict[Any, float] = {}  # udpin peers -> when last heard (clock s)
        self.peer_timeout_s = PEER_TIMEOUT_S
        self._next_prune_s = -math.inf
        self.refused_senders = (RefusedSenders() if tell_refused and check is not None
                                and self._udp_server else None)
        """A signed ``udpin:`` link: the addresses it refused lately, told why with each
        heartbeat (:meth:`_tell_refused`); None on other links."""
        self.hints_sent = 0
        """Datagrams (a HEARTBEAT and the reason) sent to refused addresses."""
        self._hint_seq = 0  # the hints' own sequence numbers (the peers' have no gaps)
        self._parse_one: Callable[[bytes, Any], list[Any]] = (
            self._parse_datagram if self.refused_senders is None
            else self._parse_signed_datagram)
        # outgoing, stream links only (see flush)
        self._buffered = self._kind != _DATAGRAM
        self.steady = not self._buffered
        """A datagram link: its descriptor never changes, nothing waits in it, it never goes
        down; :func:`follow` has nothing to do for it after the first call."""
        self._batch: list[bytes] | None = None  # packets send_all() writes together
        self._head = b""  # the rest of a packet the kernel took part of: goes on first
        self._override: tuple[int, int, list[int]] | None = None  # newest, not yet packed
        self._queue: deque[bytes] = deque()  # everything else, in order
        self._queued = 0  # bytes in _queue
        self._override_turn = True  # overrides and queued packets take turns
        self._blocked = False  # the kernel refused more: wait until writable
        self._wire_free_s = 0.0  # when what was handed over is on the wire (clock s)
        baud = int(getattr(self.conn, "baud", 0) or 0) if self._kind == _SERIAL else 0
        self.bytes_per_s = baud / 10.0 if baud > 0 else None
        """The wire's capacity (8N1 at the URL's baud rate; None: not known, TCP/UDP)."""
        self._queue_limit = (TCP_QUEUE_BYTES if self.bytes_per_s is None else
                             max(QUEUE_MIN_BYTES, int(QUEUE_S * self.bytes_per_s)))
        self._port_fd = self._current_port_fd()  # the descriptor written to (serial, TCP)

    next_send_s = math.inf
    """When :meth:`flush` can hand over more (s, on the link's :attr:`clock`); inf when
    nothing waits, or while it waits for the descriptor to be writable (:attr:`wants_write`)."""
    superseded = 0
    """Overrides replaced by a newer one before they were sent (stream links)."""
    down_reason: str | None = None
    """Why the link is down (device gone, peer closed), or None while it is up."""
    next_reopen_s = math.inf
    """When :meth:`reopen` tries next (s, on the link's :attr:`clock`); inf while up or when
    it needs no timer."""
    unsent = 0
    """Packets dropped because the link was down."""
    _connecting: socket.socket | None = None
    _connect_s = 0.0

    @property
    def up(self) -> bool:
        """False from a break until the link is open again."""
        return self.down_reason is None

    @functools.cached_property
    def _kind(self) -> str:
        return _kind(self.conn)

    def record_to(self, tlog: BinaryIO) -> None:
        """Record every message received and sent to ``tlog`` in the telemetry-log format
        MAVProxy and Mission Planner read: 8-byte big-endian Unix microseconds, raw packet."""
        self._tlog = tlog
        self.conn.mav.set_send_callback(self._record)

    def _record(self, msg: Any) -> None:
        self._record_packet(msg.get_msgbuf())

    def _record_packet(self, packet: bytes) -> None:
        """Record ``packet`` in the tlog, if there is one (the hot paths look first, and skip
        the call without one)."""
        tlog = self._tlog
        if tlog is not None:
            with contextlib.suppress(OSError, ValueError):
                tlog.write(tlog_record(int(time.time() * 1e6), packet))

    @property
    def mav(self) -> Any:
        """The pymavlink ``MAVLink`` object: ``link.mav.heartbeat_send(...)`` etc."""
        return self.conn.mav

    @property
    def local_port(self) -> int | None:
        """The bound local UDP/TCP port (useful after binding port 0), else None."""
        sock = getattr(self.conn, "port", None)
        if sock is None:
            return None
        try:
            return int(sock.getsockname()[1])
        except (AttributeError, OSError, TypeError, IndexError):
            return None

    def fileno(self) -> int:
        """File descriptor to wait on (may change for ``tcpin`` after a client connects)."""
        return int(self.conn.fd)

    def wait_fd(self) -> int | None:
        """The descriptor to wait on, or None while there is none: a link that is down
        waits for :meth:`reopen` (its dead descriptor would be readable forever), except a
        ``tcpin`` link, which waits on its listening socket for the next client."""
        if self.down_reason is not None and self._kind != _TCP_SERVER:
            return None
        return self.fileno()

    @property
    def bad(self) -> int:
        """Malformed, truncated or bad-CRC packets received (counted, never raised)."""
        return self.parser.bad

    def take_rejections(self) -> dict[Check, int]:
        """Packets the signature check dropped since the last call, per kind (empty without a
        signing key)."""
        check = self.signature_check
        return {} if check is None or not check.new_rejections else check.take_rejections()

    def _connect(self) -> None:
        """A ``udpout:`` link's socket connected to its one destination, as ArduPilot's UDP
        client connects its own: the kernel keeps the route and takes no address apart per
        datagram (tools/bench_ab.py: about a tenth of the CPU per stick at 1 kHz), and reads
        only what comes from the destination, so a stranger's datagrams never reach the link.
        If the kernel refuses (a broadcast address without SO_BROADCAST), the link stays
        unconnected and its sends fail as they would have. Other links: nothing to do."""
        destination = self._destination
        if destination is None:
            return
        port = self.conn.port
        try:
            port.connect(destination)
        except OSError as exc:
            log.debug("%s: udpout socket left unconnected: %s", self.name, exc)
            return
        self._recv, self._send = port.recv, port.send

    def _reconnect(self) -> None:
        """A connected ``udpout:`` socket's send failed (not a refusal): the route, or this
        machine's own address (a new DHCP lease, another network), may have changed, and a
        connected socket keeps the ones it chose. Its connection is undone and made again, so
        the kernel chooses them anew, on the same local port; at most once every
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

    def _follow_clock(self, check: SignatureCheck) -> None:
        """The signing timestamps follow the wall clock (10 us ticks) and the newest verified
        packet's, never going back."""
        check.advance(ticks_from_unix(time.time()))
        self._catch_up(check)

    def _catch_up(self, check: SignatureCheck) -> None:
        """What is sent next is signed no earlier than the local timestamp (the clock, or the
        newest verified packet's if that is later)."""
        signing = self.conn.mav.signing
        if signing.timestamp < check.timestamp:
            signing.timestamp = check.timestamp

    def read(self, max_reads: int = _MAX_READS) -> list[Any]:
        """Every complete message waiting on the link, oldest first (from at most
        ``max_reads`` datagrams or chunks: ``read(1)`` takes one datagram); never raises."""
        if self._buffered:
            messages = self._read_stream(max_reads)
        else:  # pymavlink's recv, less its overhead (it would also make every sender on a
            # udpin link a peer, see _heard)
            receive, parse = self.receive_datagram, self._parse_one
            messages = []
            for _ in range(max_reads):
                got = receive()
                if got is None:
                    break
                messages += parse(*got)
        check = self.signature_check  # (its clock advances on sends: a heartbeat a second)
        if check is not None:
            self._catch_up(check)
        self.received += len(messages)
        return messages

    @property
    def unchecked(self) -> bool:
        """A datagram link that neither checks nor makes signatures: what it receives may be
        answered straight from the datagram (:meth:`receive_datagram`), and it may send a
        packet packed elsewhere (:meth:`send_packet`)."""
        return not self._buffered and self.signature_check is None and (
            not self.conn.mav.signing.sign_outgoing)

    def receive_datagram(self) -> tuple[bytes, Any] | None:
        """One datagram and its sender's address, unparsed and not yet counted, or None when
        none waits (or the read failed); never raises. Hand it to :meth:`parse_datagram`, or
        to :meth:`answered` when it was answered without parsing. Datagram links only."""
        try:
            if self._recv is not None:  # (connected: the sender is the destination)
                return self._recv(_READ_CHUNK), self._destination
            return self._recvfrom(_READ_CHUNK)  # type: ignore[no-any-return]
        except _NOTHING_TO_READ:  # (refused: an earlier send found no one listening)
            return None
        except OSError as exc:
            log.debug("%s: read failed: %s", self.name, exc)
            return None

    def parse_datagram(self, data: bytes, address: Any) -> list[Any]:
        """The messages of a datagram from :meth:`receive_datagram`, counted as :meth:`read`
        counts them."""
        messages = self._parse_one(data, address)
        check = self.signature_check
        if check is not None:
            self._catch_up(check)
        self.received += len(messages)
        return messages

    def answered(self, data: bytes, address: Any) -> None:
        """A datagram from :meth:`receive_datagram` holding one message, answered without
        parsing (the stick lane): counted, its sender heard, recorded, as if read."""
        self._arrived(data, address)
        if self._udp_server:
            self._heard(address)
        if self._tlog is not None:
            self._record_packet(data)
        self.received += 1

    def _arrived(self, data: bytes, address: Any) -> None:
        """What every datagram read does first, parsed or not: pymavlink's bookkeeping of
        the sender (a broadcast link's reply address) and of the MAVLink version."""
        conn = self.conn
        if conn.broadcast:
            conn.last_address = address
        if conn.first_byte:
            conn.auto_mavlink_version(data)

    def _parse_datagram(self, data: bytes, address: Any) -> list[Any]:
        self._arrived(data, address)
        parsed = self.parser.parse(data)
        if parsed:
            if self._udp_server:
                self._heard(address)
            if self._tlog is not None:
                for msg in parsed:
                    self._record(msg)
        return parsed

    def _parse_signed_datagram(self, data: bytes, address: Any) -> list[Any]:
        """:meth:`_parse_datagram` on a signed ``udpin:`` link: a sender that is not a peer
        and whose datagram held only refused MAVLink packets is kept (bounded) to be told
        why; garbage (no packet the signature check saw) is not."""
        check = self.signature_check
        assert check is not None and self.refused_senders is not None
        before = check.new_rejections
        parsed = self._parse_datagram(data, address)
        kind = check.last_rejection
        if (not parsed and check.new_rejections != before and kind is not None
                and address not in self._peers_s):
            self.refused_senders.refused(address, kind, self.clock())
        return parsed

    def _tell_refused(self, heartbeat: Any) -> None:
        """After the heartbeat went to the peers of a signed ``udpin:`` link: each refused
        address that is due (:meth:`~mecanum_mav.protocol.refusedsenders.RefusedSenders.due`)
        gets one datagram, the same HEARTBEAT (signed) and the STATUSTEXT saying why its
        packets are refused, and nothing else. Never raises."""
        refused = self.refused_senders
        assert refused is not None
        due = refused.due(self.clock())
        if not due:
            return
        mav = self.conn.mav
        peers_seq, outer_batch = mav.seq, self._batch
        captured: list[bytes] = []
        self._batch, mav.seq = captured, self._hint_seq
        reasons: dict[Check, bytes] = {}
        try:
            send_message(mav, heartbeat)
            beat = captured.pop()
            for kind in {kind for _, kind in due}:
                for msg in statustext_messages(Severity.WARNING, REFUSED_TEXTS[kind]):
                    send_message(mav, msg)
                reasons[kind] = b"".join(captured)
                captured.clear()
        except Exception as exc:  # a send must never take the control loop down
            self._send_failed(exc)
            return
        finally:
            self._hint_seq, mav.seq, self._batch = mav.seq, peers_seq, outer_batch
        for address, kind in due:
            try:
                self._sendto(beat + reasons[kind], address)
            except OSError as exc:
                self._send_failed(exc)
            else:
                self.hints_sent += 1

    def _read_stream(self, max_reads: int) -> list[Any]:
        conn, parse = self.conn, self.parser.parse
        messages: list[Any] = []
        for _ in range(max_reads):
            try:
                data = self._receive()
            except LinkDownError:
                break
            except OSError as exc:
                log.debug("%s: read failed: %s", self.name, exc)
                break
            if not data:
                break
            if conn.first_byte:
                conn.auto_mavlink_version(data)
            parsed = parse(data)
            if self._tlog is not None:
                for msg in parsed:
                    self._record(msg)
            messages += parsed
        return messages

    def _receive(self) -> bytes:
        """What is waiting on a stream link (b"" if nothing); raises :class:`LinkDownError`
        when the link broke (it is then down), other ``OSError`` for a passing failure."""
        kind, conn = self._kind, self.conn
        if kind == _TCP_SERVER and conn.port is None and not self._accept():
            return b""
        if self.down_reason is not None:
            raise LinkDownError(self.down_reason)
        try:
            data = conn.port.read(_READ_CHUNK) if kind == _SERIAL else conn.port.recv(_READ_CHUNK)
        except _AGAIN:
            return b""
        except OSError as exc:  # pyserial's SerialException is one
            self._went_down(_gone(kind), f"read: {exc}")
            raise LinkDownError(self.down_reason) from exc
        if not data and kind != _SERIAL:  # a stream readable with nothing in it: closed
            self._went_down("client left" if kind == _TCP_SERVER else "closed by the peer",
                            "end of stream")
            raise LinkDownError(self.down_reason)
        return bytes(data)

    def _heard(self, address: Any) -> None:
        """A valid message came from ``address`` on a ``udpin:`` link: it is a peer (sent
        to); peers silent for :attr:`peer_timeout_s` are dropped, at most :data:`MAX_PEERS`
        kept."""
        now = self.clock()
        peers = self._peers_s
        known = address in peers
        peers[address] = now
        if known and now < self._next_prune_s:  # the common case: a peer already sent to
            return
        if not known and self.refused_senders is not None:
            self.refused_senders.forget(address)  # signed now: a peer, told no more
        self._next_prune_s = now + 1.0
        clients = self.conn.clients
        clients.add(address)
        for old in [a for a, seen in peers.items() if now - seen > self.peer_timeout_s]:
            del peers[old]
        while len(peers) > MAX_PEERS:
            del peers[min(peers, key=peers.__getitem__)]
        clients.intersection_update(peers)

    def write(self, buf: bytes) -> None:
        """Send one packet (the pymavlink ``MAVLink`` object writes through here too): a
        datagram at once; on a stream link it queues in order and goes when :meth:`flush`
        can hand it over.

        Raises:
            LinkDownError: the link is down, or broke now (it is then down): the packet is lost.
            BlockingIOError: a stream link's queue is full: the packet is dropped.
            OSError: it could not be sent this time (no route).
        """
        self._check_open()
        if not self._buffered:
            if self._batch is not None:  # (send_all: written together at its end)
                self._batch.append(buf)
            else:
                self._put_datagram(buf)
            return
        if self._queued + len(buf) > self._queue_limit:
            raise BlockingIOError(errno.ENOBUFS, f"outgoing queue full ({self._queued} bytes)")
        self._queue.append(buf)
        self._queued += len(buf)
        self.flush()

    def _check_open(self) -> None:
        if self.down_reason is not None:
            raise LinkDownError(self.down_reason)
        if self._kind == _TCP_SERVER and self.conn.port is None:
            raise LinkDownError("no client connected")  # nobody to send to yet

    def send(self, msg: Any) -> bool:
        """Pack and send one message object; returns False (and counts) on failure.

        Packed by the fast codec (:func:`~mecanum_mav.protocol.codec.send_message`: the bytes,
        sequence numbers, signing and send callback of pymavlink's ``mav.send``)."""
        check = self.signature_check
        if check is not None:
            self._follow_clock(check)
        try:
            send_message(self.conn.mav, msg)
        except LinkDownError:
            self.unsent += 1
            return False
        except Exception as exc:  # a send must never take the control loop down
            self._send_failed(exc)
            return False
        self.sent += 1
        if check is not None and type(msg) is _HEARTBEAT and self.refused_senders:
            self._tell_refused(msg)  # (the heartbeat, 1 Hz, paces the hints)
        return True

    def send_all(self, messages: Sequence[Any]) -> None:
        """:meth:`send` each of ``messages``, in order. On a datagram link they go in as few
        datagrams as hold them, whole packets of at most :data:`DATAGRAM_BYTES` together, as
        ArduPilot sends its streams: a wake's telemetry costs one system call, not one per
        message (every MAVLink parser reads several packets from one datagram)."""
        if self._buffered or len(messages) < 2:
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

    def _put_datagram(self, data: bytes) -> None:
        """Hand one datagram to the kernel; raises what the socket raises (after trying
        every peer), so a failed send is seen: pymavlink's ``write`` drops socket errors. To
        a fixed destination (``udpout:``) or to each peer of a ``udpin:`` link (see
        :meth:`_heard`) it goes straight to the socket; a broadcast link's goes through
        pymavlink (which turns to the first address that answers)."""
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
        elif self._destination is not None:
            self._sendto(data, self._destination)
        elif self._udp_server:
            failed = None
            for address in self.conn.clients:
                try:
                    self._sendto(data, address)
                except OSError as exc:
                    failed = exc
            if failed is not None:
                raise failed
        else:
            self.conn.write(data)

    def _write_datagram(self, data: bytes) -> bool:
        """Write one datagram; False (and counted) if that failed. Never raises."""
        try:
            self._put_datagram(data)
        except Exception as exc:  # a send must never take the control loop down
            self._send_failed(exc)
            return False
        return True

    def _send_failed(self, exc: Exception) -> None:
        """Count a failed send; warn at most once a second per link (a dead peer would
        otherwise flood the log at the output rate)."""
        self.send_errors += 1
        now = self.clock()
        if now - self._warned_s >= SEND_WARNING_PERIOD_S:
            self._warned_s = now
            log.warning("%s: send failed (%d so far): %s", self.name, self.send_errors, exc)

    def send_rc_override(self, target_system: int, target_component: int,
                         channels: list[int], *, replace: bool = True) -> None:
        """RC_CHANNELS_OVERRIDE with the 18 ``chanN_raw`` fields, packed by the fast codec;
        never raises.

        On a stream link it is *newest wins* (``replace``): an override still waiting in the
        link (not yet handed to the kernel) is replaced by this one, unpacked. With
        ``replace=False`` it supersedes the waiting one and is queued in order behind what
        else waits, and a later override does not replace it (the last words at shutdown:
        neutral, then release, all of them reach the board)."""
        if not self._buffered:  # a datagram link: never down, nothing waits in it
            if self._write_datagram(self._pack_override(target_system, target_component,
                                                        channels)):
                self.sent += 1
            return
        try:
            self._check_open()
        except LinkDownError:
            self.unsent += 1
            return
        if self._override is not None:
            self.superseded += 1
            self._override = None
        if replace:
            self._override = (target_system, target_component, channels)
            self.flush()
            return
        try:
            self.write(self._pack_override(target_system, target_component, channels))
        except Exception as exc:  # the queue is full
            self._send_failed(exc)
        else:
            self.sent += 1

    def send_packet(self, packet: bytes) -> None:
        """Send a packet packed elsewhere with this link's next sequence number (the stick
        lane's override), which then advances; never raises. An :attr:`unchecked` link
        only."""
        mav = self.conn.mav
        mav.seq = (mav.seq + 1) & 0xFF
        if self._write_datagram(packet):
            self.sent += 1
        if self._tlog is not None:
            self._record_packet(packet)

    def _pack_override(self, target_system: int, target_component: int,
                       channels: list[int]) -> bytes:
        """The packet (and the tlog's record of it): packed now, with the next sequence
        number."""
        packet = encode_rc_override(self.conn.mav, target_system, target_component, channels)
        if self._tlog is not None:
            self._record_packet(packet)
        return packet

    # ----------------------------------------------------------------- pacing (stream links)

    @property
    def wants_write(self) -> bool:
        """Whether the kernel refused more and something still waits: watch the descriptor
        for writing (:func:`follow` does)."""
        return self._blocked and self.pending

    @property
    def pending(self) -> bool:
        """Whether anything waits in the link to be handed to the kernel."""
        return bool(self._head) or self._override is not None or bool(self._queue)

    def flush(self) -> None:
        """Hand the kernel what waits, as far as pacing lets it (module description): the rest
        of a packet first, then overrides and queued packets taking turns; sets
        :attr:`next_send_s`. Never blocks or raises (a break puts the link down)."""
        if not (self._head or self._override is not None or self._queue):
            self.next_send_s = math.inf
            return
        if self.down_reason is not None:
            self.next_send_s = math.inf
            return
        now = self.clock()
        while True:
            if self._head and not self._hand_over(self._head, now):
                self.next_send_s = math.inf  # writable, or reopened, wakes it
                return
            if self._override is None and not self._queue:
                self.next_send_s = math.inf
                return
            wait_s = self._backlog_s(now)
            if wait_s > 0.0:
                self.next_send_s = now + wait_s
                return
            self._head = self._next_packet()

    def _backlog_s(self, now: float) -> float:
        """How long (s) before the kernel may take the next packet: > 0 waits."""
        rate = self.bytes_per_s
        if rate is None:  # TCP: its unsent bytes
            if _queued_bytes(self._port_fd, _SIOCOUTQNSD) > TCP_UNSENT_LIMIT:
                return TCP_POLL_S
            return 0.0
        in_kernel = _queued_bytes(self._port_fd, termios.TIOCOUTQ)
        if in_kernel:  # the device is slower than its baud rate says: follow the device
            self._wire_free_s = max(self._wire_free_s, now + in_kernel / rate)
        return self._wire_free_s - now - PACING_LEAD_S

    def _next_packet(self) -> bytes:
        override = self._override
        if override is not None and (self._override_turn or not self._queue):
            self._override = None
            self._override_turn = False
            self.sent += 1
            return self._pack_override(*override)
        packet = self._queue.popleft()
        self._queued -= len(packet)
        self._override_turn = True
        return packet

    def _hand_over(self, data: bytes, now: float) -> bool:
        """Write ``data`` to the kernel; whether it took all of it (the rest stays in
        ``_head``)."""
        try:
            if self._kind == _SERIAL:
                n = os.write(self._port_fd, data)
            else:
                n = self.conn.port.send(data)
        except _AGAIN:
            self._blocked = True
            return False
        except OSError as exc:
            self._went_down(_gone(self._kind), f"write: {exc}")
            return False
        rate = self.bytes_per_s
        if rate is not None:
            self._wire_free_s = max(self._wire_free_s, now) + n / rate
        self._head = data[n:]
        self._blocked = bool(self._head)  # the kernel took only part: it is full
        return not self._blocked

    def _current_port_fd(self) -> int:
        port = getattr(self.conn, "port", None) if self._buffered else None
        if port is None:
            return -1
        fd = int(port.fileno())
        if self._kind == _SERIAL:
            os.set_blocking(fd, False)  # pyserial opens it so; its writes wait, ours do not
        return fd

    def _drop_pending(self) -> None:
        """The link broke: what waits in it is lost (counted in :attr:`unsent`)."""
        self.unsent += len(self._queue) + (self._override is not None) + bool(self._head)
        self._queue.clear()
        self._queued = 0
        self._override, self._head, self._blocked = None, b"", False
        self._wire_free_s = 0.0
        self.next_send_s = math.inf

    # ----------------------------------------------------------------- breaks and reopening

    def _went_down(self, reason: str, detail: object = "") -> None:
        """The link broke: mark it down (the shell reports it once) and stop using it."""
        if self.down_reason is not None:
            return
        self.down_reason = reason
        log.info("%s: %s: %s", self.name, reason, detail)
        self._drop_pending()
        self._port_fd = -1
        kind, conn = self._kind, self.conn
        if kind == _TCP_SERVER:  # back to listening: the next client brings it up
            with contextlib.suppress(OSError):
                conn.port.close()
            conn.port = None
            conn.fd = conn.listen.fileno()
        else:  # closed now: a USB serial node still held open keeps its name from the next plug
            with contextlib.suppress(OSError):
                conn.port.close()
            self.next_reopen_s = self.clock() + REOPEN_PERIOD_S

    def _came_up(self) -> None:
        log.debug("%s: up again (was down: %s)", self.name, self.down_reason)
        self.down_reason = None
        self.next_reopen_s = math.inf
        self._port_fd = self._current_port_fd()
        self.parser.reset()  # a partial packet from before the break is not completed now

    def reopen(self, now_s: float) -> bool:
        """While the link is down, once :attr:`next_reopen_s` has come, try to open the same
        device path or TCP address again (never blocking); whether the link is up now."""
        if self.down_reason is None:
            return True
        if now_s < self.next_reopen_s:
            return False
        self.next_reopen_s = now_s + REOPEN_PERIOD_S
        kind = self._kind
        opened = (self._reopen_serial() if kind == _SERIAL else
                  self._reopen_tcp(now_s) if kind == _TCP else False)
        if opened:
            self._came_up()
        return opened

    def _reopen_serial(self) -> bool:
        conn = self.conn
        if not Path(conn.device).exists():
            return False
        try:  # as pymavlink opens it: at 1200 baud first (a Linux driver bug), then the rate
            port = serial.Serial(conn.device, 1200, timeout=0, dsrdtr=False, rtscts=False,
                                 xonxoff=False)
        except (OSError, ValueError) as exc:  # not ready yet (permissions, enumeration)
            log.debug("%s: reopening %s failed: %s", self.name, conn.device, exc)
            return False
        with contextlib.suppress(OSError):
            conn.port.close()
        conn.port = port
        conn.set_baudrate(conn.baud)
        conn.fd = port.fileno()
        mavutil.set_close_on_exec(conn.fd)
        conn.portdead = False
        return True

    def _reopen_tcp(self, now_s: float) -> bool:
        """One step of a non-blocking connect: start one, or see whether it completed."""
        sock = self._connecting
        if sock is not None and now_s - self._connect_s > TCP_CONNECT_TIMEOUT_S:
            sock.close()
            sock = self._connecting = None
        if sock is None:
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            sock.setblocking(False)
            code = sock.connect_ex(self.conn.destination_addr)
            if code not in (0, errno.EINPROGRESS):
                sock.close()
                return False
            self._connecting, self._connect_s = sock, now_s
        if not _writable(sock):
            return False  # still connecting: the next attempt looks again
        self._connecting = None
        if sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR):  # refused, unreachable
            sock.close()
            return False
        sock.setsockopt(socket.SOL_TCP, socket.TCP_NODELAY, 1)
        mavutil.set_close_on_exec(sock.fileno())
        with contextlib.suppress(OSError):
            self.conn.port.close()
        self.conn.port = sock
        self.conn.fd = sock.fileno()
        return True

    def _accept(self) -> bool:
        """A ``tcpin`` link without a client: take the one waiting, if any."""
        conn = self.conn
        try:
            port, _ = conn.listen.accept()
        except OSError:  # nobody waiting
            return False
        port.setsockopt(socket.SOL_TCP, socket.TCP_NODELAY, 1)
        port.setblocking(False)
        mavutil.set_close_on_exec(port.fileno())
        conn.port = port
        conn.fd = port.fileno()
        self._port_fd = port.fileno()
        if self.down_reason is not None:
            self._came_up()
        return True

    def close(self, *, linger_s: float = 0.0) -> None:
        """Close the connection; idempotent.

        With ``linger_s`` what was written last reaches the peer and is read before the link
        goes: what still waits in the link is handed over first, paced as always, for at most
        ``linger_s``; then a serial port waits until its output is sent (``flush``, at most
        :data:`PACING_LEAD_S` and a packet after the pacing); a TCP socket keeps the
        connection open for ``linger_s`` seconds, reading and dropping what the peer still
        sends, then sends its end-of-stream and closes. A peer that sees the connection end
        while the last bytes are still in its buffers may drop them: measured with ArduPilot
        SITL, the companion's channel release sent right before ``close()`` never took effect.
        Draining also keeps unread data from turning the close into a reset.
        """
        with contextlib.suppress(OSError, ValueError):
            if linger_s > 0.0:
                self._hand_over_rest(linger_s)
                self._flush_out(linger_s)
        self._drop_pending()
        with contextlib.suppress(OSError):
            self.conn.close()
        if self._connecting is not None:
            self._connecting.close()
            self._connecting = None

    def _hand_over_rest(self, linger_s: float) -> None:
        """Before closing: flush until nothing waits, the link broke, or ``linger_s`` has
        passed, on the link's clock (which paces) or in real time (which the waits take)."""
        deadline = self.clock() + linger_s
        real_deadline = time.monotonic() + linger_s
        while self.pending and self.down_reason is None:
            self.flush()
            now = self.clock()
            if not self.pending or now >= deadline or time.monotonic() >= real_deadline:
                return
            if self.wants_write:
                select.select([], [self._port_fd], [], deadline - now)
            else:
                time.sleep(max(0.0, min(self.next_send_s, deadline) - now))

    def _flush_out(self, linger_s: float) -> None:
        port = getattr(self.conn, "port", None)
        if isinstance(port, socket.socket) and port.type == socket.SOCK_STREAM:
            port.settimeout(0.05)
            deadline = time.monotonic() + linger_s
            while time.monotonic() < deadline:
                try:
                    if not port.recv(_READ_CHUNK):
                        return  # the peer closed first
                except TimeoutError:
                    continue
            port.shutdown(socket.SHUT_WR)
            with contextlib.suppress(TimeoutError):
                while port.recv(_READ_CHUNK):  # what is left, so the close is not a reset
                    pass
        elif port is not None and hasattr(port, "flush"):  # pyserial: wait until sent
            port.flush()


def follow(selector: selectors.BaseSelector, link: Link, fd: int | None,
           data: object = None) -> int | None:
    """Keep ``selector`` watching ``link`` whose registered descriptor was ``fd`` (None: not
    registered); returns the one registered now (:meth:`Link.wait_fd`).

    Call it once per pass of the loop: it first hands over what waits in the link
    (:meth:`Link.flush`; the loop also wakes by :attr:`Link.next_send_s`), then watches the
    descriptor for writing too while the kernel refuses more (:attr:`Link.wants_write`).
    A ``tcpin`` link swaps its descriptor when a client connects or leaves, and a link that
    went down has none until it is reopened: re-register, or unregister, then. (A reopened
    link may get its old descriptor number back; it was unregistered in between.)"""
    link.flush()
    new_fd = link.wait_fd()
    events = _READ_WRITE if link.wants_write else selectors.EVENT_READ
    if new_fd != fd:
        if fd is not None:
            selector.unregister(fd)
        if new_fd is not None:
            selector.register(new_fd, events, data)
    elif new_fd is not None and selector.get_key(new_fd).events != events:
        selector.modify(new_fd, events, data)
    return new_fd


_READ_WRITE = selectors.EVENT_READ | selectors.EVENT_WRITE


def open_link(url: str, *, source_system: int, source_component: int, name: str,
              signing_key: bytes | None = None, tell_refused: bool = False,
              clock: Callable[[], float] = time.monotonic) -> Link:
    """Open a :class:`Link` (``clock``: its timers' time source, see there); raises
    ``OSError``/``ValueError`` with the URL on failure."""
    try:
        return Link(url, source_system=source_system, source_component=source_component,
                    name=name, signing_key=signing_key, tell_refused=tell_refused,
                    clock=clock)
    except (OSError, ValueError) as exc:
        raise type(exc)(f"cannot open {name} link {url!r}: {exc}") from exc
