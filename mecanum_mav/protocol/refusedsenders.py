"""Who a link with a signing key refused, so they can be told why: few, recent, sparingly.

A ground station without the key (MAVProxy before ``signing key``, a pymavlink script) that
talks to a ``udpin:`` link with a signing key is never made a peer: it would wait for a
HEARTBEAT forever with no hint why. :class:`RefusedSenders` keeps the addresses whose
well-formed MAVLink packets the signature check refused (unsigned, badly signed, replayed,
too old), with the latest refusal's kind, so that the link can send each of them a signed
HEARTBEAT and the reason (:data:`~mecanum_mav.protocol.signing.REFUSED_TEXTS`) once per
heartbeat, and nothing else.

Bounded so a flood of forged source addresses costs neither memory nor traffic: at most
:data:`MAX_REFUSED_SENDERS` addresses (the longest silent is dropped for a new one), each
forgotten after :data:`REFUSED_TIMEOUT_S` of silence, and each told at most once per
:data:`HINT_MIN_INTERVAL_S` whatever calls :meth:`RefusedSenders.due`. An address that is
heard correctly signed is a peer: :meth:`RefusedSenders.forget` it.

Pure: the caller passes the time (monotonic seconds); addresses are whatever the socket gives
(``(host, port)`` tuples), compared by equality.
"""

from __future__ import annotations

import math
from collections.abc import Hashable

from mecanum_mav.protocol.signing import Check

__all__ = ["HINT_MIN_INTERVAL_S", "MAX_REFUSED_SENDERS", "REFUSED_TIMEOUT_S",
           "RefusedSenders"]

MAX_REFUSED_SENDERS = 8
"""At most this many refused addresses are kept (the longest silent goes first)."""
REFUSED_TIMEOUT_S = 10.0
"""A refused address silent for this long (seconds) is forgotten, as a silent peer is."""
HINT_MIN_INTERVAL_S = 0.5
"""An address is told at most once per this many seconds (the hints ride the 1 Hz heartbeat,
which may come up to half an output refresh early or late: 0.5 s keeps one per heartbeat)."""


class RefusedSenders:
    """The addresses whose packets were refused lately, and when each was last told why.

    Args:
        limit: how many addresses are kept.
        timeout_s: how long (s) a silent address is kept.
    """

    def __init__(self, limit: int = MAX_REFUSED_SENDERS,
                 timeout_s: float = REFUSED_TIMEOUT_S) -> None:
        self.limit = limit
        self.timeout_s = timeout_s
        self._heard: dict[Hashable, tuple[float, Check]] = {}  # least recently heard first
        self._told_s: dict[Hashable, float] = {}

    def __len__(self) -> int:
        return len(self._heard)

    def __contains__(self, address: object) -> bool:
        return address in self._heard

    def refused(self, address: Hashable, kind: Check, now_s: float) -> None:
        """A packet from ``address`` was refused as ``kind`` at ``now_s``."""
        heard = self._heard
        if heard.pop(address, None) is None and len(heard) >= self.limit:
            oldest = next(iter(heard))
            del heard[oldest]
            self._told_s.pop(oldest, None)
        heard[address] = (now_s, kind)

    def forget(self, address: Hashable) -> None:
        """``address`` is a peer now (it was heard correctly signed): no more hints."""
        if self._heard.pop(address, None) is not None:
            self._told_s.pop(address, None)

    def due(self, now_s: float) -> list[tuple[Hashable, Check]]:
        """The addresses to tell now, each with its latest refusal's kind; they count as told
        at ``now_s``. Addresses silent for :attr:`timeout_s` are forgotten first."""
        heard, told = self._heard, self._told_s
        for address in [a for a, (seen_s, _) in heard.items()
                        if now_s - seen_s > self.timeout_s]:
            del heard[address]
            told.pop(address, None)
        due = []
        for address, (_, kind) in heard.items():
            if now_s - told.get(address, -math.inf) >= HINT_MIN_INTERVAL_S:
                told[address] = now_s
                due.append((address, kind))
        return due
