"""STATUSTEXT: the text length, the severities and the chunking of long texts.

A STATUSTEXT carries at most :data:`STATUSTEXT_LEN` (50) bytes of text, read from the
dialect's own message definition. A longer text goes out as several messages (MAVLink 2's
extension fields): each carries a 50-byte chunk, the same non-zero ``id`` and ``chunk_seq``
0, 1, 2, ...; a text that fits goes out whole with ``id`` 0 ("the only chunk"). The messages
are pymavlink message objects, built without a link: whoever owns a link sends them
(``link.mav.send(msg)``) with its own sequence number, source ids and signing.
:class:`StatusChunks` joins received chunks back into texts.
"""

from __future__ import annotations

from enum import IntEnum
from typing import Any, Final

from mecanum_mav.protocol.dialect import mavlink

__all__ = ["STATUSTEXT_LEN", "Severity", "StatusChunks", "statustext_messages"]

_STATUSTEXT = mavlink.MAVLink_statustext_message

STATUSTEXT_LEN: Final[int] = dict(
    zip(_STATUSTEXT.ordered_fieldnames, _STATUSTEXT.array_lengths, strict=True)
)["text"]
"""Bytes of text one STATUSTEXT carries (50): the dialect's ``char text[50]``."""


class Severity(IntEnum):
    """MAVLink ``MAV_SEVERITY`` of a STATUSTEXT (tests/test_statustext.py checks the numbers
    against pymavlink's)."""

    EMERGENCY = 0
    ALERT = 1
    CRITICAL = 2
    ERROR = 3
    WARNING = 4
    NOTICE = 5
    INFO = 6


def _chunk_id(text: str) -> int:
    """A non-zero 15-bit id for the chunks of ``text`` (stable within one process)."""
    return (hash(text) & 0x7FFF) or 1


def statustext_messages(
    severity: int, text: str, *, chunk_id: int | None = None
) -> list[Any]:
    """The STATUSTEXT messages (pymavlink message objects) that say ``text``.

    Args:
        severity: a :class:`Severity` (MAV_SEVERITY, 0..7).
        text: the text; encoded as UTF-8 (unencodable characters become ``?``).
        chunk_id: the ``id`` of the chunks of a long text, 1..65535; None derives one from
            the text (non-zero, below 32768). Unused when the text fits one message.

    Returns:
        One message with ``id`` 0 and ``chunk_seq`` 0 when the encoded text has at most
        :data:`STATUSTEXT_LEN` bytes (an empty text included); else one message per
        :data:`STATUSTEXT_LEN`-byte chunk, in order, each with ``id`` = ``chunk_id`` and
        ``chunk_seq`` 0, 1, 2, ... A chunk boundary may fall inside a multi-byte character.
    """
    data = text.encode("utf-8", "replace")
    if len(data) <= STATUSTEXT_LEN:
        return [_STATUSTEXT(int(severity), data)]
    ident = _chunk_id(text) if chunk_id is None else chunk_id
    if not 1 <= ident <= 0xFFFF:
        raise ValueError(f"STATUSTEXT chunk id must be 1..65535, got {ident}")
    return [
        _STATUSTEXT(int(severity), data[start:start + STATUSTEXT_LEN], ident, seq)
        for seq, start in enumerate(range(0, len(data), STATUSTEXT_LEN))
    ]


class StatusChunks:
    """Joins the chunks of long STATUSTEXTs as they are received (what
    :func:`statustext_messages` splits): per sender and ``id``, at the first chunk's time.

    A chunk (MAVLink 2 ``id`` != 0, ``chunk_seq`` 0, 1, ...) opens or continues the text of
    its sender and ``id``; a chunk whose text is shorter than :data:`STATUSTEXT_LEN` bytes
    (NUL-terminated) ends it, and so does a chunk_seq already held (the ``id`` reused for a new
    text). Texts still open at the end are given as they are (:meth:`flush`).
    """

    def __init__(self) -> None:
        self._open: dict[tuple[int, int, int], tuple[float, int, dict[int, str]]] = {}

    def add(self, t: float, msg: Any) -> list[tuple[float, int, str]]:
        """The (time, severity, text) completed by one STATUSTEXT at ``t`` (a pymavlink
        message: its ``text`` ends at the first NUL; a MAVLink 1 one has ``id`` 0)."""
        text, ident, seq = msg.text, msg.id, msg.chunk_seq
        if not ident:
            return [(t, msg.severity, text)]
        key = (msg.get_srcSystem(), msg.get_srcComponent(), ident)
        done = []
        if key in self._open and seq in self._open[key][2]:
            done.append(self._close(key))
        chunks = self._open.setdefault(key, (t, msg.severity, {}))[2]
        chunks[seq] = text
        if len(text.encode("utf-8", "replace")) < STATUSTEXT_LEN:
            done.append(self._close(key))
        return done

    def flush(self) -> list[tuple[float, int, str]]:
        """The texts still open (their last chunk not in the log)."""
        return [self._close(key) for key in list(self._open)]

    def _close(self, key: tuple[int, int, int]) -> tuple[float, int, str]:
        t, severity, chunks = self._open.pop(key)
        return t, severity, "".join(chunks[seq] for seq in sorted(chunks))
