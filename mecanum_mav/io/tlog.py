"""Reading telemetry logs (tlogs): what ``--tlog``, MAVProxy and Mission Planner record.

A tlog is a sequence of records, each an 8-byte big-endian timestamp (Unix microseconds) and
one raw MAVLink packet (MAVLink 1 or 2, signed or not), with nothing between them and no
header. :func:`parse_tlog` reads one from bytes, never raising: a record whose timestamp is
implausible (before 1995 or after 2100) or whose packet does not check (bad start byte, bad
CRC, a length that runs past the end) is not MAVLink; the reader then looks for the next
position where a valid record starts (a plausible timestamp and a packet whose CRC checks) and
goes on from there, reporting the bytes it skipped, e.g. ``mav.tlog: bytes 1234-1299 not
MAVLink (skipped)``. A last record cut short is reported as ``truncated at byte N``. Packets
of message ids the ArduPilot dialect does not know (another dialect's) cannot be checked by
their CRC; they are counted and skipped, not reported as damage.

Each packet (its length from its header) goes through the companion's codec first
(:func:`~mecanum_mav.protocol.codec.decode_datagram`: the same message object as
pymavlink's, in about half the time); what it does not take (an unknown id, an odd flag,
damage) goes through pymavlink's ``decode``, which decides as it always did.

:func:`read_tlog` reads a file; the result holds every message with its time, and the problems
as text. An unreadable file gives no messages and one problem.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mecanum_mav.protocol.codec import decode_datagram
from mecanum_mav.protocol.dialect import mavlink

__all__ = ["TlogEntry", "TlogRead", "parse_tlog", "read_tlog", "tlog_record"]

_STAMP = struct.Struct(">Q")
STAMP_LEN = 8
"""Bytes of a record's timestamp."""
EARLIEST_US = 788_918_400 * 1_000_000
"""1995-01-01: a record stamped earlier is not a tlog record."""
LATEST_US = 4_102_444_800 * 1_000_000
"""2100-01-01: nor one stamped later."""
_V1, _V2 = 0xFE, 0xFD


def _plausible(stamp_us: int) -> bool:
    """Whether a record's timestamp (Unix us) could be one: from 1995 to 2100, both included."""
    return EARLIEST_US <= stamp_us <= LATEST_US


def tlog_record(unix_us: int, packet: bytes | bytearray) -> bytes:
    """One tlog record: ``packet`` stamped with ``unix_us`` (Unix microseconds), as ``--tlog``
    writes it and :func:`parse_tlog` reads it."""
    return _STAMP.pack(unix_us) + packet
_SIGNATURE_LEN = 13


@dataclass(frozen=True)
class TlogEntry:
    """One message of a tlog.

    Attributes:
        time_s: the record's timestamp, Unix seconds.
        offset: byte offset of the record (its timestamp) in the file.
        msg: the pymavlink message.
    """

    time_s: float
    offset: int
    msg: Any


@dataclass
class TlogRead:
    """What :func:`parse_tlog` found.

    Attributes:
        name: the file's name, as the problems quote it.
        size: bytes read.
        entries: every message, in file order.
        problems: one line per damaged part (byte ranges), in file order.
        unknown: packets with message ids this dialect does not know (skipped).
    """

    name: str
    size: int
    entries: list[TlogEntry] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    unknown: int = 0


def _packet_len(data: bytes | bytearray, start: int) -> int | None:
    """Length of the MAVLink packet starting at ``start`` (inside ``data``), from its header;
    None if no packet starts there (or its header is cut off)."""
    magic = data[start]
    if magic == _V2:
        if start + 3 > len(data):
            return None
        signed = data[start + 2] & mavlink.MAVLINK_IFLAG_SIGNED
        return 12 + data[start + 1] + (_SIGNATURE_LEN if signed else 0)
    if magic == _V1:
        if start + 2 > len(data):
            return None
        return 8 + data[start + 1]
    return None


class _Decoder:
    def __init__(self) -> None:
        self.mav = mavlink.MAVLink(None)

    def record(self, data: bytes, at: int) -> tuple[int, float, Any] | None:
        """The record at ``at``: (its length, Unix time s, message or None for an unknown
        id); None if no valid record starts there (including one cut off by the end)."""
        if at + STAMP_LEN >= len(data):
            return None
        stamp = _STAMP.unpack_from(data, at)[0]
        if not _plausible(stamp):
            return None
        length = _packet_len(data, at + STAMP_LEN)
        if length is None:
            return None
        end = at + STAMP_LEN + length
        if end > len(data):
            return None
        packet = data[at + STAMP_LEN:end]
        fast = decode_datagram(packet)
        if fast is not None:  # the companion's codec: the same message, faster
            return STAMP_LEN + length, stamp / 1e6, fast[0]
        try:
            msg = self.mav.decode(bytearray(packet))
        except Exception:  # pymavlink raises MAVError, struct.error, ... on bad packets
            return None
        known = not isinstance(msg, mavlink.MAVLink_unknown)
        return STAMP_LEN + length, stamp / 1e6, msg if known else None

    def truncated(self, data: bytes, at: int) -> bool:
        """True if a record starts at ``at`` (inside ``data``) but the data ends inside it: in
        its timestamp, or after a plausible one in its packet's header or body."""
        if at + STAMP_LEN > len(data):
            return True
        if not _plausible(_STAMP.unpack_from(data, at)[0]):
            return False
        start = at + STAMP_LEN
        if start >= len(data):
            return True
        if data[start] not in (_V1, _V2):
            return False
        length = _packet_len(data, start)
        return length is None or start + length > len(data)


def parse_tlog(data: bytes, name: str = "tlog") -> TlogRead:
    """Every message of the tlog ``data`` (see the module docstring); never raises."""
    out = TlogRead(name, len(data))
    decoder = _Decoder()
    at = 0
    size = len(data)
    while at < size:
        found = decoder.record(data, at)
        if found is not None:
            length, time_s, msg = found
            if msg is None:
                out.unknown += 1
            else:
                out.entries.append(TlogEntry(time_s, at, msg))
            at += length
            continue
        resume = _resync(decoder, data, at + 1)
        if resume is None and decoder.truncated(data, at):
            out.problems.append(f"{name}: truncated at byte {at} (last record incomplete, "
                                f"{size - at} bytes)")
            break
        end = size if resume is None else resume
        out.problems.append(f"{name}: bytes {at}-{end - 1} not MAVLink (skipped)")
        at = end
    return out


def _resync(decoder: _Decoder, data: bytes, start: int) -> int | None:
    """The first offset at or after ``start`` where a valid record begins, or None."""
    at = start
    while True:
        # A record's packet starts with a MAVLink start byte 8 bytes after the record.
        v2 = data.find(b"\xfd", at + STAMP_LEN)
        v1 = data.find(b"\xfe", at + STAMP_LEN)
        hits = [h for h in (v1, v2) if h != -1]
        if not hits:
            return None
        candidate = min(hits) - STAMP_LEN  # (its start byte is inside the data)
        if decoder.record(data, candidate) is not None:
            return candidate
        at = candidate + 1


def read_tlog(path: Path) -> TlogRead:
    """Read the tlog at ``path``; an unreadable file gives no entries and one problem."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        return TlogRead(str(path), 0, problems=[f"{path}: cannot read: {exc.strerror or exc}"])
    return parse_tlog(data, str(path))
