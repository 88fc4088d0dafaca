"""A tlog's STATUSTEXTs: which texts start a failsafe (:func:`is_failsafe`). Long texts are
joined from their chunks by :class:`~mecanum_mav.protocol.statustext.StatusChunks`.
"""

from __future__ import annotations

import re

from mecanum_mav.protocol.dialect import mavlink

__all__ = ["is_failsafe"]

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
