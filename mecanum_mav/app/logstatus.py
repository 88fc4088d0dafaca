"""A tlog's STATUSTEXTs: long texts joined from their chunks (:class:`StatusChunks`), and which
texts start a failsafe (:func:`is_failsafe`).

A long text's chunks (MAVLink 2 ``id`` != 0, ``chunk_seq`` 0, 1, ...) are joined into one text
per sender and ``id``, at its first chunk's time.
"""

from __future__ import annotations

import re
from typing import Any

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.statustext import STATUSTEXT_LEN

__all__ = ["StatusChunks", "is_failsafe"]

_FAILSAFE_TEXT = re.compile(r"fail\s*-?safe|\blost\b", re.IGNORECASE)
_REFUSAL_TEXT = re.compile(r"^\s*(?:pre\s*-?arm|arm)\s*:", re.IGNORECASE)
_CLEARED_TEXT = re.compile(
    r"\b(?:cleared|restored|regained|resumed|recovered|reconnected|link\s+up|ok)\b",
    re.IGNORECASE)
_ACTION_TEXT = re.compile(r"^\s*disarmed\b", re.IGNORECASE)


def is_failsafe(severity: int, text: str) -> bool:
    """Whether a STATUSTEXT (``severity`` MAV_SEVERITY, whole ``text``) starts a failsafe.

    A failsafe is an event that starts one: a text that says "failsafe" or "lost", or any
    text of severity CRITICAL or worse, unless it is one of these, which are not:

    - a pre-arm or arming refusal: the text begins "PreArm:" or "Arm:" (ArduPilot sends
      them at CRITICAL, e.g. "PreArm: Radio failsafe on"; the companion words its refusals
      the same way, e.g. "PreArm: radio failsafe (receiver)");
    - a clearance: the text says "cleared", "restored", "regained", "resumed",
      "recovered", "reconnected", "link up" or "OK" (ArduPilot's "Radio Failsafe Cleared",
      "GCS Failsafe Cleared"; the companion's "GCS link regained, mode HOLD", "Manual input
      resumed", "Flight controller link up", "Radio receiver OK, mode MANUAL", "... link
      reconnected");
    - a failsafe's action, not its start: the text begins "Disarmed" (the companion's
      "Disarmed: GCS failsafe" follows its "GCS link lost: failsafe").

    So ArduPilot's "Radio Failsafe" and "GCS Failsafe", and the companion's "GCS link lost:
    failsafe" (CRITICAL), "Flight controller link lost" (CRITICAL), "Radio failsafe: ..."
    (CRITICAL) and "Manual input lost: wheels neutral" (WARNING) are failsafes.
    """
    if _REFUSAL_TEXT.match(text) or _CLEARED_TEXT.search(text) or _ACTION_TEXT.match(text):
        return False
    return severity <= mavlink.MAV_SEVERITY_CRITICAL or bool(_FAILSAFE_TEXT.search(text))


class StatusChunks:
    """Joins the chunks of long STATUSTEXTs (see the module docstring).

    A chunk (``id`` != 0) opens or continues the text of its sender and ``id``; a chunk whose
    text is shorter than :data:`~mecanum_mav.protocol.statustext.STATUSTEXT_LEN` bytes
    (NUL-terminated) ends it, and so does a chunk_seq already held (the ``id`` reused for a new
    text). Texts still open at the log's end are given as they are.
    """

    def __init__(self) -> None:
        self._open: dict[tuple[int, int, int], tuple[float, int, dict[int, str]]] = {}

    def add(self, t: float, msg: Any) -> list[tuple[float, int, str]]:
        """The (time, severity, text) completed by one STATUSTEXT at ``t``."""
        text = str(msg.text).split("\x00", 1)[0]
        ident = getattr(msg, "id", 0) or 0
        if not ident:
            return [(t, msg.severity, text)]
        key = (msg.get_srcSystem(), msg.get_srcComponent(), ident)
        seq = getattr(msg, "chunk_seq", 0) or 0
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
