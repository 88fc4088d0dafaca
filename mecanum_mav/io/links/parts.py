"""Parts any link can take: MAVLink 2 signing (:class:`Signing`) and tlog recording
(:class:`Recorder`).

A :class:`~mecanum_mav.io.links.base.Link` holds each as an attribute that is None when the
link has none (``link.signing``, ``link.recorder``); the hot paths look at the attribute and
skip the call without one. Times here follow the wall clock (``time.time``): signing
timestamps in the 10 us ticks of MAVLink 2 signing since 2015-01-01, tlog stamps in Unix
microseconds. (A link's timers follow its own monotonic clock, seconds.)
"""

from __future__ import annotations

import contextlib
import time
from typing import Any, BinaryIO

from mecanum_mav.io.tlog import tlog_record
from mecanum_mav.protocol.signing import SignatureCheck, ticks_from_unix

__all__ = ["Recorder", "Signing"]


class Signing:
    """A link's MAVLink 2 signing: everything sent signed, only correctly signed packets read.

    Everything sent is signed (link id 0; the timestamp starts at the wall clock, follows it
    and the newest timestamp of the verified packets received, and never goes backwards) and
    only correctly signed, fresh packets are read (:attr:`check`, a
    :class:`~mecanum_mav.protocol.signing.SignatureCheck`); the others are dropped and counted
    (``Link.take_rejections``). Taking the peer's timestamp is what the MAVLink C library and
    pymavlink do; ArduPilot relies on it: it drops a new stream more than a minute behind its
    own timestamp, which starts a minute ahead of the one it stored
    (tests/test_sitl_signing.py).

    pymavlink checks signatures itself when its parser holds the key, recording a stream's
    timestamp before verifying it (pymavlink issue #961): the link parses keyless and lets
    :attr:`check` decide.

    Args:
        conn: the pymavlink connection whose ``mav`` signs what is sent.
        key: the 32-byte signing key.
    """

    def __init__(self, conn: Any, key: bytes) -> None:
        now = ticks_from_unix(time.time())
        conn.setup_signing(key, sign_outgoing=True, link_id=0, initial_timestamp=now)
        self._conn = conn
        self.check = SignatureCheck(key, now)
        """Decides which packets received are kept."""

    def follow_clock(self) -> None:
        """Before a send: the signing timestamps follow the wall clock (10 us ticks) and the
        newest verified packet's, never going back."""
        check = self.check
        check.advance(ticks_from_unix(time.time()))
        self.catch_up()

    def catch_up(self) -> None:
        """After a read: what is sent next is signed no earlier than the local timestamp (the
        clock, or the newest verified packet's if that is later)."""
        signing = self._conn.mav.signing
        check = self.check
        if signing.timestamp < check.timestamp:
            signing.timestamp = check.timestamp


class Recorder:
    """Records every message a link receives and sends to a tlog, in the telemetry-log format
    MAVProxy and Mission Planner read: 8-byte big-endian Unix microseconds, raw packet.
    A failed write is dropped (the control loop never stops for its log)."""

    def __init__(self, tlog: BinaryIO) -> None:
        self.tlog = tlog

    def packet(self, packet: bytes) -> None:
        """Record one raw packet, stamped now."""
        with contextlib.suppress(OSError, ValueError):
            self.tlog.write(tlog_record(int(time.time() * 1e6), packet))

    def message(self, msg: Any) -> None:
        """Record one pymavlink message (its packed bytes); pymavlink's send callback."""
        self.packet(msg.get_msgbuf())

    def messages(self, messages: list[Any]) -> None:
        """Record each of ``messages``, in order."""
        for msg in messages:
            self.packet(msg.get_msgbuf())
