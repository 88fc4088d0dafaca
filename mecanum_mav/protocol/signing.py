"""MAVLink 2 message signing: the key, the signature, and the check of incoming packets.

A signed MAVLink 2 packet (incompat flag 0x01) ends in a 13-byte block: the link id (1 byte),
a timestamp (6 bytes, little-endian, in 10 us units since 1 January 2015 00:00 UTC) and the
first 6 bytes of SHA-256(secret key + every byte of the packet before the signature). See the
MAVLink specification, "Message signing".

:class:`SignatureCheck` decides which incoming packets to accept, per the specification:
correctly signed, and newer than the last accepted packet of the same stream (link id,
system, component), or, for a stream not seen yet, not more than a minute behind the local
timestamp. Unlike pymavlink's generated ``check_signature`` (ArduPilot/pymavlink issue #961),
it records a stream's timestamp only *after* the signature verified: one forged packet with a
genuine stream's ids and a timestamp far in the future cannot make the genuine packets that
follow look old. The local timestamp too moves only with the clock and with verified packets.

Pure: the caller passes the time (:func:`ticks_from_unix`) and the packet bytes.
"""

from __future__ import annotations

import hashlib
import hmac
import string
from enum import Enum

__all__ = [
    "EPOCH_2015_UNIX_S",
    "IFLAG_SIGNED",
    "KEY_LEN",
    "NEW_STREAM_WINDOW_TICKS",
    "SIGNATURE_BLOCK_LEN",
    "TICKS_PER_S",
    "Check",
    "SignatureCheck",
    "SigningKeyError",
    "key_from_text",
    "signature",
    "signature_block",
    "ticks_from_unix",
]

EPOCH_2015_UNIX_S = 1_420_070_400
"""1 January 2015 00:00 UTC in Unix seconds: the signing timestamp's epoch."""
TICKS_PER_S = 100_000
"""Signing timestamps count 10 us ticks."""
NEW_STREAM_WINDOW_TICKS = 60 * TICKS_PER_S
"""A new stream is accepted only if its timestamp is at most a minute behind the local one."""
KEY_LEN = 32
SIGNATURE_BLOCK_LEN = 13
"""Link id (1) + timestamp (6) + signature (6)."""
IFLAG_SIGNED = 0x01
_HEADER_LEN = 10
_MAX_TIMESTAMP = (1 << 48) - 1


def ticks_from_unix(unix_s: float) -> int:
    """A signing timestamp (10 us ticks since 2015) from Unix time in seconds."""
    return max(0, int((unix_s - EPOCH_2015_UNIX_S) * TICKS_PER_S))


class SigningKeyError(ValueError):
    """A key file's contents are not a key (the message says why)."""


def key_from_text(text: str) -> bytes:
    """The 32-byte secret key from a key file's text.

    The text (one trailing newline stripped) is either 64 hex digits, the key itself, or a
    passphrase, whose key is SHA-256 of its UTF-8 bytes: how MAVProxy's ``signing setup`` and
    ``signing key`` derive it from the same passphrase.

    Raises:
        SigningKeyError: empty, several lines, or hex digits only but not 64 of them (a key that
            was cut short or pasted twice is not silently taken for a passphrase).
    """
    body = text[:-1] if text.endswith("\n") else text
    body = body[:-1] if body.endswith("\r") else body
    if not body.strip():
        raise SigningKeyError("empty: expected 64 hex digits or a passphrase")
    if "\n" in body or "\r" in body:
        raise SigningKeyError("more than one line: expected 64 hex digits or a passphrase")
    if all(c in string.hexdigits for c in body):
        if len(body) != 2 * KEY_LEN:
            raise SigningKeyError(f"{len(body)} hex digits: a key is exactly {2 * KEY_LEN}")
        return bytes.fromhex(body)
    return hashlib.sha256(body.encode("utf-8")).digest()


def signature(key: bytes, signed_part: bytes) -> bytes:
    """The 6-byte signature of ``signed_part``: the packet up to and including the link id
    and timestamp."""
    return hashlib.sha256(key + signed_part).digest()[:6]


def signature_block(key: bytes, packet: bytes, link_id: int, timestamp: int) -> bytes:
    """The 13 bytes to append to ``packet`` (header with the signed flag set, payload, CRC)."""
    tail = bytes((link_id,)) + timestamp.to_bytes(6, "little")
    return tail + signature(key, packet + tail)


class Check(Enum):
    """What :meth:`SignatureCheck.check` made of a packet (counted per kind)."""

    ACCEPTED = "accepted"
    UNSIGNED = "unsigned"
    """No signature (MAVLink 1, or MAVLink 2 without the signed flag)."""
    BAD_SIGNATURE = "bad signature"
    """Signed with another key, or altered."""
    REPLAYED = "replayed"
    """Correctly signed, but not newer than the last packet of its stream (a replay)."""
    TOO_OLD = "too old"
    """A new stream whose timestamp is more than a minute behind the local one."""


class SignatureCheck:
    """Accepts incoming packets that are correctly signed with ``key`` and not replayed.

    Args:
        key: the 32-byte secret key.
        now_ticks: the local timestamp to start from (:func:`ticks_from_unix` of the clock).
    """

    def __init__(self, key: bytes, now_ticks: int) -> None:
        if len(key) != KEY_LEN:
            raise ValueError(f"a signing key is {KEY_LEN} bytes, got {len(key)}")
        self.key = key
        self.timestamp = now_ticks
        """The local timestamp: the clock, or the newest verified packet's if that is later."""
        self.streams: dict[tuple[int, int, int], int] = {}
        """The last accepted timestamp per (link id, system, component)."""
        self.counts: dict[Check, int] = dict.fromkeys(Check, 0)
        self._reported: dict[Check, int] = {}
        self.new_rejections = 0
        """Packets refused since :meth:`take_rejections` last ran (a cheap test for the loop)."""

    def advance(self, now_ticks: int) -> None:
        """The clock moved on: the local timestamp never goes backwards."""
        if now_ticks > self.timestamp:
            self.timestamp = now_ticks

    def check(self, packet: bytes | bytearray) -> Check:
        """Decide on one whole received packet (its bytes as they arrived); counted."""
        result = self._check(packet)
        self.counts[result] += 1
        if result is not Check.ACCEPTED:
            self.new_rejections += 1
        return result

    def take_rejections(self) -> dict[Check, int]:
        """The refusals per kind since the last call (kinds with a count only)."""
        taken: dict[Check, int] = {
            kind: n - self._reported.get(kind, 0) for kind, n in self.counts.items()
            if kind is not Check.ACCEPTED and n > self._reported.get(kind, 0)}
        self._reported = dict(self.counts)
        self.new_rejections = 0
        return taken

    def _check(self, packet: bytes | bytearray) -> Check:
        if (len(packet) < _HEADER_LEN + 2 + SIGNATURE_BLOCK_LEN or packet[0] != 0xFD
                or not packet[2] & IFLAG_SIGNED):
            return Check.UNSIGNED
        link_id = packet[-13]
        timestamp = int.from_bytes(packet[-12:-6], "little")
        if not hmac.compare_digest(signature(self.key, bytes(packet[:-6])), bytes(packet[-6:])):
            return Check.BAD_SIGNATURE
        stream = (link_id, packet[5], packet[6])
        last = self.streams.get(stream)
        if last is not None:
            if timestamp <= last:
                return Check.REPLAYED
        elif timestamp + NEW_STREAM_WINDOW_TICKS < self.timestamp:
            return Check.TOO_OLD
        # only now, with the signature verified, does the packet move any timestamp
        self.streams[stream] = timestamp
        if timestamp > self.timestamp:
            self.timestamp = min(timestamp, _MAX_TIMESTAMP)
        return Check.ACCEPTED

    def summary(self) -> str:
        """``"unsigned 3, bad signature 1"`` (rejections with a count) or ``"none"``."""
        parts = [f"{c.value} {n}" for c, n in self.counts.items() if n and c is not Check.ACCEPTED]
        return ", ".join(parts) or "none"
