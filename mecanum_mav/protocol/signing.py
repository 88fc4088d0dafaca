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

import hmac
import string
from enum import Enum
from hashlib import sha256

__all__ = [
    "EPOCH_2015_UNIX_S",
    "IFLAG_SIGNED",
    "KEY_LEN",
    "NEW_STREAM_WINDOW_TICKS",
    "REFUSED_TEXTS",
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
    return sha256(body.encode("utf-8")).digest()


def signature(key: bytes, signed_part: bytes | bytearray) -> bytes:
    """The 6-byte signature of ``signed_part``: the packet up to and including the link id
    and timestamp."""
    return sha256(key + signed_part).digest()[:6]


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

    On the control path (one check per MANUAL_CONTROL) it costs the SHA-256 and little else:
    plain integers for the stream key and the tallies (hashing an Enum runs Python code).

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
        self.streams: dict[int, int] = {}
        """The last accepted timestamp per stream (:meth:`last_timestamp`)."""
        self.accepted = 0
        self._rejected = [0] * len(_REJECTIONS)
        self._reported = [0] * len(_REJECTIONS)
        self.new_rejections = 0
        """Packets refused since :meth:`take_rejections` last ran (a cheap test for the loop)."""
        self.last_rejection: Check | None = None
        """The kind of the latest packet refused (None before the first)."""

    @property
    def counts(self) -> dict[Check, int]:
        """Packets checked so far, per outcome."""
        return {Check.ACCEPTED: self.accepted, **dict(zip(_REJECTIONS, self._rejected,
                                                          strict=True))}

    def last_timestamp(self, link_id: int, system: int, component: int) -> int | None:
        """The last accepted timestamp of a stream, or None if none was accepted."""
        return self.streams.get(link_id | system << 8 | component << 16)

    def advance(self, now_ticks: int) -> None:
        """The clock moved on: the local timestamp never goes backwards."""
        if now_ticks > self.timestamp:
            self.timestamp = now_ticks

    def check(self, packet: bytes | bytearray) -> Check:
        """Decide on one whole received packet (its bytes as they arrived); counted."""
        if (len(packet) < _MIN_SIGNED_LEN or packet[0] != 0xFD
                or not packet[2] & IFLAG_SIGNED):
            return self._reject(_UNSIGNED)
        if not hmac.compare_digest(signature(self.key, packet[:-6]), packet[-6:]):
            return self._reject(_BAD_SIGNATURE)
        timestamp = int.from_bytes(packet[-12:-6], "little")
        stream = packet[-13] | packet[5] << 8 | packet[6] << 16  # link id, system, component
        streams = self.streams
        last = streams.get(stream)
        if last is not None:
            if timestamp <= last:
                return self._reject(_REPLAYED)
        elif timestamp + NEW_STREAM_WINDOW_TICKS < self.timestamp:
            return self._reject(_TOO_OLD)
        # only now, with the signature verified, does the packet move any timestamp
        streams[stream] = timestamp
        if timestamp > self.timestamp:
            self.timestamp = min(timestamp, _MAX_TIMESTAMP)
        self.accepted += 1
        return _ACCEPTED

    def _reject(self, index: int) -> Check:
        self._rejected[index] += 1
        self.new_rejections += 1
        kind = self.last_rejection = _REJECTIONS[index]
        return kind

    def take_rejections(self) -> dict[Check, int]:
        """The refusals per kind since the last call (kinds with a count only)."""
        taken = {kind: now - before for kind, now, before
                 in zip(_REJECTIONS, self._rejected, self._reported, strict=True) if now > before}
        self._reported = list(self._rejected)
        self.new_rejections = 0
        return taken

    def summary(self) -> str:
        """``"unsigned 3, bad signature 1"`` (rejections with a count) or ``"none"``."""
        parts = [f"{kind.value} {n}" for kind, n in zip(_REJECTIONS, self._rejected, strict=True)
                 if n]
        return ", ".join(parts) or "none"


REFUSED_TEXTS = {
    Check.UNSIGNED: "Unsigned packet refused: signing required",
    Check.BAD_SIGNATURE: "Bad signature: packet refused (wrong key?)",
    Check.REPLAYED: "Replayed signed packet refused",
    Check.TOO_OLD: "Signed packet refused: timestamp too old",
}
"""What a ground station is told (at most once a second) when a link with a signing key drops
a packet; each under 50 characters, one STATUSTEXT."""

_ACCEPTED = Check.ACCEPTED
_REJECTIONS = (Check.UNSIGNED, Check.BAD_SIGNATURE, Check.REPLAYED, Check.TOO_OLD)
_UNSIGNED, _BAD_SIGNATURE, _REPLAYED, _TOO_OLD = range(len(_REJECTIONS))
_MIN_SIGNED_LEN = _HEADER_LEN + 2 + SIGNATURE_BLOCK_LEN
