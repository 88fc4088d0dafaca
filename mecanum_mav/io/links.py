"""MAVLink links: pymavlink connections driven by a selector loop, MAVLink 2, never raising.

MAVLink 2 and the ArduPilot dialect throughout (:mod:`mecanum_mav.protocol.dialect`). URLs are
pymavlink connection strings: ``udpin:HOST:PORT`` (listen; replies go to every peer heard),
``udpout:HOST:PORT``, ``tcp:HOST:PORT``, ``tcpin:HOST:PORT``, or a serial device
``/dev/ttyUSB0,57600`` (pyserial).

A :class:`Link` is read when its file descriptor is readable: :meth:`Link.read` returns every
message that arrived, parsed from the raw bytes by :class:`~mecanum_mav.protocol.framing.
MessageParser` (on datagram links a lone MANUAL_CONTROL takes the fast codec of
:mod:`mecanum_mav.protocol.codec`), and :meth:`Link.send_rc_override` packs with that codec
too: the control path never waits on pymavlink's pure-Python parser and packer. Malformed
bytes, bad CRCs and truncated packets are counted in :attr:`Link.bad`, never raised; a send
that fails (peer gone, no route) is counted in :attr:`Link.send_errors` and logged at WARNING
at most once a second per link.
"""

from __future__ import annotations

import contextlib
import logging
import math
import selectors
import socket
import struct
import time
from typing import Any, BinaryIO

from mecanum_mav.protocol.codec import encode_rc_override
from mecanum_mav.protocol.dialect import mavlink, mavutil
from mecanum_mav.protocol.framing import MessageParser
from mecanum_mav.protocol.signing import Check, SignatureCheck, ticks_from_unix

log = logging.getLogger(__name__)

__all__ = ["Link", "follow", "mavlink", "mavutil", "open_link"]

_READ_CHUNK = 4096
_TLOG_STAMP = struct.Struct(">Q")
SEND_WARNING_PERIOD_S = 1.0
"""A link that keeps failing to send is logged at WARNING at most this often."""
_MAX_READS = 64  # per readiness event: bounded work, the selector calls again if more waits


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
    """

    def __init__(self, url: str, *, source_system: int, source_component: int, name: str,
                 signing_key: bytes | None = None) -> None:
        self.url = url
        self.name = name
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

    def record_to(self, tlog: BinaryIO) -> None:
        """Record every message received and sent to ``tlog`` in the telemetry-log format
        MAVProxy and Mission Planner read: 8-byte big-endian Unix microseconds, raw packet."""
        self._tlog = tlog
        self.conn.mav.set_send_callback(self._record)

    def _record(self, msg: Any) -> None:
        if self._tlog is not None:
            with contextlib.suppress(OSError, ValueError):
                self._tlog.write(_TLOG_STAMP.pack(int(time.time() * 1e6)) + msg.get_msgbuf())

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

    @property
    def bad(self) -> int:
        """Malformed, truncated or bad-CRC packets received (counted, never raised)."""
        return self.parser.bad

    def take_rejections(self) -> dict[Check, int]:
        """Packets the signature check dropped since the last call, per kind (empty without a
        signing key)."""
        check = self.signature_check
        return {} if check is None or not check.new_rejections else check.take_rejections()

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

    def read(self) -> list[Any]:
        """Every complete message waiting on the link, oldest first; never raises."""
        check = self.signature_check
        if check is not None:
            self._follow_clock(check)
        messages: list[Any] = []
        for _ in range(_MAX_READS):
            try:
                data = self.conn.recv(_READ_CHUNK)
            except OSError as exc:
                log.debug("%s: read failed: %s", self.name, exc)
                break
            if not data:
                break
            if self.conn.first_byte:
                self.conn.auto_mavlink_version(data)
            parsed = self.parser.parse(data)
            if self._tlog is not None:
                for msg in parsed:
                    self._record(msg)
            messages += parsed
        if check is not None:
            self._catch_up(check)
        self.received += len(messages)
        return messages

    def send(self, msg: Any) -> bool:
        """Pack and send one message object; returns False (and counts) on failure."""
        if self.signature_check is not None:
            self._follow_clock(self.signature_check)
        try:
            self.conn.mav.send(msg)
        except Exception as exc:  # a send must never take the control loop down
            self._send_failed(exc)
            return False
        self.sent += 1
        return True

    def _send_failed(self, exc: Exception) -> None:
        """Count a failed send; warn at most once a second per link (a dead peer would
        otherwise flood the log at the output rate)."""
        self.send_errors += 1
        now = time.monotonic()
        if now - self._warned_s >= SEND_WARNING_PERIOD_S:
            self._warned_s = now
            log.warning("%s: send failed (%d so far): %s", self.name, self.send_errors, exc)

    def send_rc_override(self, target_system: int, target_component: int,
                         channels: list[int]) -> None:
        """RC_CHANNELS_OVERRIDE with the 18 ``chanN_raw`` fields, packed by the fast codec
        (pymavlink when the link signs); never raises."""
        packet = encode_rc_override(self.conn.mav, target_system, target_component, channels)
        if packet is None:
            self.send(self.conn.mav.rc_channels_override_encode(
                target_system, target_component, *channels))
            return
        try:
            self.conn.write(packet)
        except Exception as exc:  # a send must never take the control loop down
            self._send_failed(exc)
            return
        self.sent += 1
        if self._tlog is not None:
            with contextlib.suppress(OSError, ValueError):
                self._tlog.write(_TLOG_STAMP.pack(int(time.time() * 1e6)) + packet)

    def close(self, *, linger_s: float = 0.0) -> None:
        """Close the connection; idempotent.

        With ``linger_s`` what was written last reaches the peer and is read before the link
        goes: a serial port waits until its output is sent (``flush``); a TCP socket keeps the
        connection open for ``linger_s`` seconds, reading and dropping what the peer still
        sends, then sends its end-of-stream and closes. A peer that sees the connection end
        while the last bytes are still in its buffers may drop them: measured with ArduPilot
        SITL, the companion's channel release sent right before ``close()`` never took effect.
        Draining also keeps unread data from turning the close into a reset.
        """
        with contextlib.suppress(OSError, ValueError):
            if linger_s > 0.0:
                self._flush_out(linger_s)
        with contextlib.suppress(OSError):
            self.conn.close()

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


def follow(selector: selectors.BaseSelector, link: Link, fd: int, data: object = None) -> int:
    """Keep ``selector`` watching ``link`` whose descriptor was ``fd``; the current one.

    A ``tcpin`` link swaps its descriptor when a client connects: re-register it then."""
    new_fd = link.fileno()
    if new_fd != fd:
        selector.unregister(fd)
        selector.register(new_fd, selectors.EVENT_READ, data)
    return new_fd


def open_link(url: str, *, source_system: int, source_component: int, name: str,
              signing_key: bytes | None = None) -> Link:
    """Open a :class:`Link`; raises ``OSError``/``ValueError`` with the URL on failure."""
    try:
        return Link(url, source_system=source_system, source_component=source_component,
                    name=name, signing_key=signing_key)
    except (OSError, ValueError) as exc:
        raise type(exc)(f"cannot open {name} link {url!r}: {exc}") from exc
