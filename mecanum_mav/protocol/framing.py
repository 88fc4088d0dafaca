"""Received bytes -> MAVLink messages, never raising: the parsing every link shares.

:class:`MessageParser` wraps a pymavlink ``MAVLink`` parser (robust parsing, MAVLink 2). On
datagram links (UDP) the fast codec goes first, so the control path never waits on pymavlink's
pure-Python parser: a datagram holding exactly one MANUAL_CONTROL is decoded by
:func:`~mecanum_mav.protocol.codec.decode_manual_control`, any other datagram of whole, good
packets of known messages by :func:`~mecanum_mav.protocol.codec.decode_datagram` (the same
message objects pymavlink would return); anything else goes through pymavlink. A MAVLink
packet never spans UDP datagrams, so on datagram links a leftover partial packet is dropped
(and counted) instead of swallowing the start of the next datagram. Malformed bytes, bad CRCs
and truncated packets are counted in :attr:`MessageParser.bad`.

With a :class:`~mecanum_mav.protocol.signing.SignatureCheck` (a link with a signing key) every
message, from the fast path or pymavlink's, is kept only if its packet is correctly signed and
not replayed; the others are dropped and counted in the check (per kind). pymavlink's own
check is not used (its parser object holds no key): it records a stream's timestamp before
verifying the signature (ArduPilot/pymavlink issue #961).
"""

from __future__ import annotations

import logging
from typing import Any

from mecanum_mav.protocol.codec import decode_datagram, decode_manual_control
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.signing import Check, SignatureCheck

log = logging.getLogger(__name__)

__all__ = ["MessageParser"]

_ACCEPTED = Check.ACCEPTED


class MessageParser:
    """Parses what one link receives.

    Args:
        mav: the link's pymavlink ``MAVLink`` object (its parser state, version detection).
        datagrams: True on datagram links (UDP): each chunk is one datagram.
        name: short name for logs.
        check: keep only correctly signed, fresh packets (a link with a signing key), or None.
            ``mav`` must then hold no key (its signing is for sending).
    """

    def __init__(self, mav: Any, *, datagrams: bool, name: str = "",
                 check: SignatureCheck | None = None) -> None:
        self.mav = mav
        self.mav.robust_parsing = True
        self.datagrams = datagrams
        self.name = name
        self.check = check
        self.bad = 0
        """Malformed, truncated or bad-CRC packets seen (never raised)."""

    def parse(self, data: bytes) -> list[Any]:
        """Every complete message in ``data`` (and what earlier chunks left), oldest first;
        with a signature check, only the accepted ones."""
        check = self.check
        if self.datagrams:
            fast = decode_manual_control(data)
            if fast is not None:
                if check is None or check.check(data) is _ACCEPTED:
                    return [fast]
                return []
            mav = self.mav
            # what pymavlink's parser would return, unless it would call back or check keys
            messages = (decode_datagram(data) if mav.callback is None
                        and mav.signing.secret_key is None else None)
            if messages is None:
                messages = self._parse_general(data)
        else:
            messages = self._parse_general(data)
        if check is None or not messages:
            return messages
        return [m for m in messages if check.check(m.get_msgbuf()) is _ACCEPTED]

    def _parse_general(self, data: bytes) -> list[Any]:
        try:
            parsed = self._parse(data)
        except Exception as exc:  # pymavlink raises MAVError (and worse) on some garbage
            self.bad += 1
            log.debug("%s: unparseable bytes: %s", self.name, exc)
            self.reset()
            return []
        if self.datagrams and self.mav.buf_len() > 0:
            self.bad += 1  # a truncated packet
            self.reset()
        messages = []
        for msg in parsed:
            if msg.get_type() == "BAD_DATA":
                self.bad += 1
            else:
                messages.append(msg)
        return messages

    def _parse(self, data: bytes) -> list[Any]:
        """``parse_buffer`` without its extra empty pass when the buffer is already empty
        (one message per datagram is the common case on the hot path)."""
        mav = self.mav
        msg = mav.parse_char(data)
        parsed = []
        while msg is not None:
            parsed.append(msg)
            if mav.buf_len() == 0:
                break
            msg = mav.parse_char(b"")
        return parsed

    def reset(self) -> None:
        """Forget a partial packet."""
        mav = self.mav
        mav.buf = bytearray()
        mav.buf_index = 0
        mav.expected_length = mavlink.HEADER_LEN_V1 + 2
        mav.have_prefix_error = False
