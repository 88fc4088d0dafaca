"""What every link has: :class:`Link`, the common base of the transport classes, and
:func:`follow`, which keeps a selector watching a link.

A :class:`Link` is one pymavlink connection (MAVLink 2, the ArduPilot dialect) read when its
file descriptor is readable: :meth:`Link.read` returns every message that arrived, parsed from
the raw bytes by :class:`~mecanum_mav.protocol.framing.MessageParser`, and
:meth:`Link.send_rc_override` and :meth:`Link.send` pack with the fast codec of
:mod:`mecanum_mav.protocol.codec`: the control path never waits on pymavlink's pure-Python
parser and packer. Malformed bytes, bad CRCs and truncated packets are counted in
:attr:`Link.bad`, never raised; a send that fails (peer gone, no route) is counted in
:attr:`Link.send_errors` and logged at WARNING at most once every
:data:`SEND_WARNING_PERIOD_S` per link.

How a link moves its bytes is its class's (:mod:`~mecanum_mav.io.links.datagram`,
:mod:`~mecanum_mav.io.links.udpin`, :mod:`~mecanum_mav.io.links.stream` and the serial and
TCP ones); signing and tlog recording are parts it holds (:mod:`~mecanum_mav.io.links.parts`,
None without). The base answers for a link that never goes down and in which nothing waits
(a datagram link): :meth:`Link.reopen`, :meth:`Link.flush` and the pacing attributes do
nothing there; the stream links override them.

Every timer of a link runs on its ``clock`` (monotonic seconds, the caller's loop's own).
"""

from __future__ import annotations

import contextlib
import logging
import math
import selectors
from collections.abc import Callable, Sequence
from typing import Any, BinaryIO, ClassVar

from mecanum_mav.io.links.parts import Recorder, Signing
from mecanum_mav.protocol.codec import encode_rc_override, send_message
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.framing import MessageParser
from mecanum_mav.protocol.refusedsenders import RefusedSenders
from mecanum_mav.protocol.signing import Check, SignatureCheck

log = logging.getLogger("mecanum_mav.io.links")

__all__ = ["REOPEN_PERIOD_S", "SEND_WARNING_PERIOD_S", "Link", "LinkDownError", "follow"]

READ_CHUNK = 4096
"""Bytes asked of the kernel per read (a datagram, or a stream's chunk)."""
MAX_READS = 64
"""Datagrams or chunks read per readiness event: bounded work, the selector calls again if
more waits."""
SEND_WARNING_PERIOD_S = 1.0
"""A link that keeps failing to send is logged at WARNING at most this often."""
REOPEN_PERIOD_S = 0.5
"""A link that is down tries to open its device or address again this often (seconds)."""


class LinkDownError(OSError):
    """Raised by :meth:`Link.write` while the link is down: the packet was not sent."""


class Link:
    """One MAVLink connection with non-blocking reads for a selector-driven loop: what every
    transport has. Made by :func:`~mecanum_mav.io.links.open_link`, which picks the class.

    Args:
        conn: the pymavlink connection (opened from ``url``).
        url: pymavlink connection string.
        name: short name for logs (``"gcs"``, ``"fc"``).
        signing_key: the 32-byte MAVLink 2 signing key, or None (:class:`~mecanum_mav.io.
            links.parts.Signing` says what a key does).
        clock: the monotonic time source (seconds) of every timer of the link: pacing to the
            baud rate (:attr:`next_send_s`), the reopen timer (:attr:`next_reopen_s`), the
            send-failure log's rate, the ``udpin:`` peers' ages and the refused senders'
            hints. The caller's loop passes its own, so the link's times and the loop's are
            one; a test passes a fake one and asserts them exactly. (Signing timestamps and
            tlog stamps follow the wall clock, ``time.time``.)
    """

    steady: ClassVar[bool] = False
    """A datagram link: its descriptor never changes, nothing waits in it, it never goes
    down; :func:`follow` has nothing to do for it after the first call."""
    parses_datagrams = False
    """Whether what is read comes in whole datagrams (the parser's fast path)."""
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
    """Packets dropped unsent: the link was down, or (a stream link) the last words at
    shutdown passed them in its queue."""
    refused_senders: RefusedSenders | None = None
    """A signed ``udpin:`` link told to: the addresses it refused lately, told why with each
    heartbeat (:class:`~mecanum_mav.io.links.udpin.SignedUdpinLink`); None on other links."""
    hints_sent = 0
    """Datagrams (a HEARTBEAT and the reason) sent to refused addresses."""

    def __init__(self, conn: Any, *, url: str, name: str, signing_key: bytes | None,
                 clock: Callable[[], float]) -> None:
        self.url = url
        self.name = name
        self.clock = clock
        self.conn: Any = conn
        self.signing = None if signing_key is None else Signing(conn, signing_key)
        """The signing part, or None: a link without a key neither signs nor checks."""
        check = None if self.signing is None else self.signing.check
        self.signature_check: SignatureCheck | None = check
        self.parser = MessageParser(conn.mav if check is None else mavlink.MAVLink(None),
                                    name=name, check=check, datagrams=self.parses_datagrams)
        self.recorder: Recorder | None = None
        """The tlog recorder (:meth:`record_to`), or None."""
        self.received = 0
        self.sent = 0
        self.send_errors = 0
        self._warned_s = -math.inf
        conn.mav.file = self  # every packet goes out through write(), which sees a break

    # ----------------------------------------------------------------- what every link has

    @property
    def up(self) -> bool:
        """False from a break until the link is open again."""
        return self.down_reason is None

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

    @property
    def bad(self) -> int:
        """Malformed, truncated or bad-CRC packets received (counted, never raised)."""
        return self.parser.bad

    @property
    def unchecked(self) -> bool:
        """It neither checks nor makes signatures: what it receives may be answered straight
        from the datagram (the loop's stick lane), and it may send a packet packed elsewhere
        (:meth:`send_packet`)."""
        return self.signature_check is None and not self.conn.mav.signing.sign_outgoing

    def takes_packet(self) -> bool:
        """Whether a packet given to :meth:`send_packet` now goes to the kernel at once, ahead
        of nothing (the stick lane asks before it answers). A datagram link: always."""
        return True

    def record_to(self, tlog: BinaryIO) -> None:
        """Record every message received and sent to ``tlog`` (:class:`~mecanum_mav.io.links.
        parts.Recorder`)."""
        self.recorder = Recorder(tlog)
        self.conn.mav.set_send_callback(self.recorder.message)

    def take_rejections(self) -> dict[Check, int]:
        """Packets the signature check dropped since the last call, per kind (empty without a
        signing key)."""
        check = self.signature_check
        return {} if check is None or not check.new_rejections else check.take_rejections()

    def fileno(self) -> int:
        """File descriptor to wait on (may change for ``tcpin`` after a client connects)."""
        return int(self.conn.fd)

    def wait_fd(self) -> int | None:
        """The descriptor to wait on, or None while there is none: a link that is down
        waits for :meth:`reopen` (its dead descriptor would be readable forever)."""
        if self.down_reason is not None:
            return None
        return self.fileno()

    def reopen(self, now_s: float) -> bool:
        """While the link is down, once :attr:`next_reopen_s` has come, try to open it again
        (never blocking); whether the link is up now. This one never goes down."""
        return True

    @property
    def wants_write(self) -> bool:
        """Whether the kernel refused more and something still waits: watch the descriptor
        for writing (:func:`follow` does)."""
        return False

    @property
    def pending(self) -> bool:
        """Whether anything waits in the link to be handed to the kernel."""
        return False

    def flush(self) -> None:
        """Hand the kernel what waits in the link, as pacing lets it; nothing waits in this
        one."""

    def read(self, max_reads: int = MAX_READS) -> list[Any]:
        """Every complete message waiting on the link, oldest first (from at most
        ``max_reads`` datagrams or chunks: ``read(1)`` takes one datagram); never raises."""
        raise NotImplementedError

    def receive_datagram(self) -> tuple[bytes, Any] | None:
        """One datagram and its sender's address, unparsed (datagram links: the loop's stick
        lane); a stream has none."""
        return None

    def parse_datagram(self, data: bytes, address: Any) -> list[Any]:
        """The messages of a datagram from :meth:`receive_datagram`, counted."""
        raise NotImplementedError

    def answered(self, data: bytes, address: Any) -> None:
        """A datagram from :meth:`receive_datagram` answered unparsed: counted."""
        raise NotImplementedError

    def write(self, buf: bytes) -> None:
        """Send one packet (the pymavlink ``MAVLink`` object writes through here too).

        Raises:
            LinkDownError: the link is down, or broke now (it is then down): the packet is lost.
            BlockingIOError: a stream link's queue is full: the packet is dropped.
            OSError: it could not be sent this time (no route).
        """
        raise NotImplementedError

    def close(self, *, linger_s: float = 0.0) -> None:
        """Close the connection; idempotent (``linger_s``: see the stream links)."""
        with contextlib.suppress(OSError):
            self.conn.close()

    # ----------------------------------------------------------------- sending

    def send(self, msg: Any) -> bool:
        """Pack and send one message object; returns False (and counts) on failure.

        Packed by the fast codec (:func:`~mecanum_mav.protocol.codec.send_message`: the bytes,
        sequence numbers, signing and send callback of pymavlink's ``mav.send``)."""
        signing = self.signing
        if signing is not None:
            signing.follow_clock()
        try:
            send_message(self.conn.mav, msg)
        except LinkDownError:
            self.unsent += 1
            return False
        except Exception as exc:  # a send must never take the control loop down
            self._send_failed(exc)
            return False
        self.sent += 1
        return True

    def send_all(self, messages: Sequence[Any]) -> None:
        """:meth:`send` each of ``messages``, in order."""
        for msg in messages:
            self.send(msg)

    def send_rc_override(self, target_system: int, target_component: int,
                         channels: list[int], *, replace: bool = True) -> None:
        """RC_CHANNELS_OVERRIDE with the 18 ``chanN_raw`` fields, packed by the fast codec;
        never raises (``replace``: a stream link's newest-wins, see there)."""
        raise NotImplementedError

    def send_packet(self, packet: bytes) -> None:
        """Send a packet packed elsewhere with this link's next sequence number (the stick
        lane's override), which then advances; never raises. An :attr:`unchecked` link
        only, right after :meth:`takes_packet` said yes."""
        raise NotImplementedError

    def _pack_override(self, target_system: int, target_component: int,
                       channels: list[int]) -> bytes:
        """The packet (and the tlog's record of it): packed now, with the next sequence
        number."""
        packet = encode_rc_override(self.conn.mav, target_system, target_component, channels)
        recorder = self.recorder
        if recorder is not None:
            recorder.packet(packet)
        return packet

    def _send_failed(self, exc: Exception) -> None:
        """Count a failed send; warn at most once a second per link (a dead peer would
        otherwise flood the log at the output rate)."""
        self.send_errors += 1
        now = self.clock()
        if now - self._warned_s >= SEND_WARNING_PERIOD_S:
            self._warned_s = now
            log.warning("%s: send failed (%d so far): %s", self.name, self.send_errors, exc)


_READ_WRITE = selectors.EVENT_READ | selectors.EVENT_WRITE


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
