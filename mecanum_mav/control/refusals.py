"""What the rover refused from its links, by kind: counted, and said sparingly.

Every input the rover turns down is one of the kinds of :class:`Refusal`. Each refusal is
counted (the status line of ``mecanum-mav run`` and SYS_STATUS ``errors_comm`` /
``drop_rate_comm`` report the counts) and its reason is said in a STATUSTEXT, at most once a
second per kind: a radio spewing a thousand bad sticks a second costs the ground station one
message a second, not a thousand. Packets that never became messages (bad CRC, truncated) are
counted by the links, not here; messages addressed to other systems are not refusals (shared
links carry them normally) and are ignored silently.
"""

from __future__ import annotations

import math
from enum import Enum

from mecanum_mav.protocol.signing import Check

__all__ = ["FC_SIGNATURE_REFUSED", "REFUSAL_REPEAT_S", "Refusal", "RefusalLog"]

REFUSAL_REPEAT_S = 1.0
"""The reason for a refusal of one kind is said at most once per this many seconds."""
FC_SIGNATURE_REFUSED = {
    Check.UNSIGNED: "FC sent unsigned: board has no signing key",
    Check.BAD_SIGNATURE: "FC bad signature: wrong --fc-signing-key?",
    Check.REPLAYED: "FC replayed signed packet refused",
    Check.TOO_OLD: "FC signed packet refused: timestamp too old",
}
"""What a refused packet from the flight-controller link says (``--fc-signing-key``), per
kind: unsigned packets from it mean the board has no key (SETUP_SIGNING was never sent to it).
The ground station's are :data:`mecanum_mav.protocol.signing.REFUSED_TEXTS`."""


class Refusal(Enum):
    """The kinds of input the rover refuses (the value names it in the status line)."""

    STICK = "stick"
    """MANUAL_CONTROL or a ground station's RC override with a value out of range."""
    SETPOINT = "setpoint"
    """SET_POSITION_TARGET_LOCAL_NED outside GUIDED, non-finite, or with an unusable mask."""
    PARAM = "param"
    """PARAM_SET with a non-finite, out-of-range or inconsistent value."""
    COMMAND = "command"
    """A command (COMMAND_LONG/INT, SET_MODE) with parameters it cannot take."""
    ARM = "arm"
    """An arm request a pre-arm check turned down."""
    MODE = "mode"
    """A mode that is unknown, unavailable, or cannot start now."""
    MISSION = "mission"
    """A mission upload or item the mission protocol turned down."""
    ORIGIN = "origin"
    """SET_GPS_GLOBAL_ORIGIN with an impossible position."""
    SIGNATURE = "signature"
    """A packet a link with a signing key dropped: unsigned, badly signed, replayed, or too
    old (:class:`~mecanum_mav.protocol.signing.Check`)."""
    SENSOR = "sensor"
    """WHEEL_DISTANCE or ATTITUDE from the flight controller that is not finite or not
    physically possible (the estimator does not use it)."""


class RefusalLog:
    """Counts refusals per kind and decides when a refusal's reason is said again."""

    def __init__(self) -> None:
        self.counts: dict[Refusal, int] = dict.fromkeys(Refusal, 0)
        self._said_s: dict[Refusal, float] = dict.fromkeys(Refusal, -math.inf)

    def add(self, kind: Refusal, now_s: float, count: int = 1) -> bool:
        """Count ``count`` refusals of ``kind`` at ``now_s`` (s); whether its reason is due to
        be said (not said for this kind within the last :data:`REFUSAL_REPEAT_S`)."""
        self.counts[kind] += count
        if now_s - self._said_s[kind] < REFUSAL_REPEAT_S:
            return False
        self._said_s[kind] = now_s
        return True

    @property
    def total(self) -> int:
        """Refusals of every kind so far."""
        return sum(self.counts.values())

    def summary(self) -> str:
        """``"stick 3, param 1"`` (kinds with a count, in declaration order) or ``"none"``."""
        parts = [f"{kind.value} {n}" for kind, n in self.counts.items() if n]
        return ", ".join(parts) or "none"
