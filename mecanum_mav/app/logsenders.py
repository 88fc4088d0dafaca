"""Who sent what in a tlog: the vehicle (:func:`vehicle_of`), senders that share a system and
component id told apart (:class:`Senders`), and whose an RC_CHANNELS_OVERRIDE is
(:func:`override_from_pilot`).

Two senders can share a system and component id: the companion and its flight controller are
both 1/1 by default, the companion's flight-controller link and a Mission Planner-like ground
station both 255/190, and a tlog has no link tag. Such senders are told apart by their
sequence numbers (each sender counts its own packets): a packet continues the sender whose
last sequence number is closest below its own. A sender that sends ODOMETRY is the companion,
one that sends MANUAL_CONTROL, COMMAND_LONG, SET_MODE or mission uploads a ground station; the
vehicle's modes come from the companion's HEARTBEATs only.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from mecanum_mav.config.params import Params
from mecanum_mav.control.core import FC_LINK_COMPID
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.io.tlog import TlogEntry
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.rcoverride import LEAVE, field_action

__all__ = ["GCS_ANCHORS", "MAX_SENDERS", "MAX_SEQ_GAP", "VEHICLE_ANCHORS", "Senders",
           "override_from_pilot", "sent_by", "vehicle_of"]

MAX_SEQ_GAP = 16
"""A packet continues a sender whose last sequence number is at most this far below (lost
packets); farther, it is a new sender."""
MAX_SENDERS = 4
"""Senders kept apart per system and component id."""
VEHICLE_ANCHORS = frozenset({"ODOMETRY"})
"""Messages only the companion sends: their sender is the vehicle."""
GCS_ANCHORS = frozenset({"MANUAL_CONTROL", "COMMAND_LONG", "COMMAND_INT", "SET_MODE",
                         "MISSION_COUNT", "PARAM_SET", "SET_POSITION_TARGET_LOCAL_NED"})
"""Messages only a ground station sends."""
_NOT_VEHICLES = frozenset({mavlink.MAV_TYPE_GCS, mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
                           mavlink.MAV_TYPE_GIMBAL, mavlink.MAV_TYPE_ADSB,
                           mavlink.MAV_TYPE_CAMERA})
_WHEEL_CHANNELS = frozenset(PwmMap.from_params(Params()).channels)
"""The channels the companion's overrides set by default (MOT_FL_CH ... MOT_RR_CH)."""


def override_from_pilot(msg: Any, channels: Sequence[int],
                        vehicle: tuple[int, int] | None) -> bool:
    """Whether an RC_CHANNELS_OVERRIDE (``channels``: its 18 ``chanN_raw``) is the pilot's
    stick input (a ground station's, e.g. MAVProxy's ``rc 3 1700``, sent to the vehicle)
    rather than the companion's PWM output (sent from its flight-controller link, system
    FC_GCS_SYSID (255) component 190, to the flight controller). In order:

    1. sent to another system than ``vehicle``'s (target not 0): the companion's, to its
       flight controller (whose FC_SYSID is not the companion's SYSID_THISMAV);
    2. sent from another component than 190: the pilot's (MAVProxy sends as component 0
       or 230, and the companion's flight-controller link is always 190; the system id
       does not tell, ground stations send as 255 too and FC_GCS_SYSID may be set to
       another);
    3. else (sender and target alike, as a Mission Planner-like 255/190 pilot and the
       companion by default): the companion's if it sets or releases exactly the default
       wheel channels (MOT_x_CH: 1-4) and leaves every other, the pilot's otherwise
       (MAVProxy's ``rc`` sets its channels and releases the rest of 1-8).
    """
    target = msg.target_system
    if vehicle is not None and target not in (0, vehicle[0]):
        return False
    if msg.get_srcComponent() != FC_LINK_COMPID:
        return True
    touched = {n for n, raw in enumerate(channels, start=1) if field_action(n, raw) != LEAVE}
    return touched != _WHEEL_CHANNELS


def vehicle_of(entries: Sequence[TlogEntry]) -> tuple[int, int] | None:
    """The vehicle (system, component): the sender of the first ODOMETRY or MISSION_CURRENT,
    else of the most HEARTBEATs of a vehicle type from an autopilot; None if none."""
    beats: Counter[tuple[int, int]] = Counter()
    for e in entries:
        kind = e.msg.get_type()
        if kind in ("ODOMETRY", "MISSION_CURRENT"):
            return e.msg.get_srcSystem(), e.msg.get_srcComponent()
        if (kind == "HEARTBEAT" and e.msg.type not in _NOT_VEHICLES
                and e.msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID):
            beats[(e.msg.get_srcSystem(), e.msg.get_srcComponent())] += 1
    return beats.most_common(1)[0][0] if beats else None


def sent_by(msg: Any, who: tuple[int, int] | None) -> bool:
    """Whether ``msg`` comes from the system of ``who`` (system, component); True for None (no
    vehicle found: every message counts)."""
    return who is None or msg.get_srcSystem() == who[0]


# ---------------------------------------------------------------------- senders sharing an id


@dataclass
class _Chain:
    """One sender's packets so far."""

    number: int
    last_seq: int
    last_index: int
    kinds: set[str] = field(default_factory=set)


class Senders:
    """Tells apart senders sharing a system and component id (see the module docstring).

    A packet continues the sender whose last sequence number is closest below its own; where
    two are equally close (their counts met), the one that has sent this message before, then
    the one silent longest.
    """

    def __init__(self) -> None:
        self._chains: dict[tuple[int, int], list[_Chain]] = defaultdict(list)
        self._anchors: dict[int, list[tuple[int, str]]] = defaultdict(list)
        self._siblings: dict[int, list[int]] = {}
        """chain number -> the numbers of every chain of its id."""
        self.chain_of: list[int] = []
        self._count = 0

    def add(self, index: int, msg: Any) -> None:
        """Assign message number ``index`` to a sender."""
        seq, kind = msg.get_seq(), msg.get_type()
        chains = self._chains[(msg.get_srcSystem(), msg.get_srcComponent())]
        best: _Chain | None = None
        best_rank = (MAX_SEQ_GAP + 1, False, 0)
        for chain in chains:
            rank = ((seq - chain.last_seq - 1) % 256, kind not in chain.kinds, chain.last_index)
            if rank < best_rank:
                best, best_rank = chain, rank
        if best is None:
            best = _Chain(self._count, seq, index)
            self._count += 1
            chains.append(best)
            siblings = self._siblings.get(chains[0].number, [])
            siblings.append(best.number)
            self._siblings[best.number] = siblings
            if len(chains) > MAX_SENDERS:  # forget the one silent longest
                chains.remove(min(chains, key=lambda c: c.last_index))
        best.last_seq, best.last_index = seq, index
        best.kinds.add(kind)
        self.chain_of.append(best.number)
        if kind in VEHICLE_ANCHORS:
            self._anchor(chains, best.number, index, "vehicle")
        elif kind in GCS_ANCHORS:
            self._anchor(chains, best.number, index, "gcs")

    def _anchor(self, chains: list[_Chain], chain: int, index: int, role: str) -> None:
        """``chain`` has ``role`` from message ``index`` on; a sender of the same id that had
        it (the two were confused where their sequence numbers met) no longer has."""
        for other in chains:
            anchors = self._anchors[other.number]
            if other.number == chain:
                if not anchors or anchors[-1][1] != role:
                    anchors.append((index, role))
            elif anchors and anchors[-1][1] == role:
                anchors.append((index, "other"))

    def role(self, index: int) -> str | None:
        """The role of message ``index``'s sender: "vehicle", "gcs", "other" or None
        (unknown): the sender's last anchor before it; before its first anchor, that anchor's
        role unless another sender of its id had that role then."""
        chain = self.chain_of[index]
        before = self._role_before(chain, index)
        if before is not None:
            return before
        anchors = self._anchors.get(chain)
        if not anchors:
            return None
        role = anchors[0][1]
        taken = any(self._role_before(other, index) == role
                    for other in self._siblings[chain] if other != chain)
        return None if taken else role

    def _role_before(self, chain: int, index: int) -> str | None:
        role = None
        for at, kind in self._anchors.get(chain, ()):
            if at > index:
                break
            role = kind
        return role
