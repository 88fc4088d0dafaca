"""Reading named parameters from a flight controller, paced to what ArduPilot accepts.

Pure bookkeeping, no I/O, time passed in: :class:`ParamReader` says which names to ask for
(PARAM_REQUEST_READ by name) and when, takes the PARAM_VALUE answers, and says when the read
is over and what was never answered. The companion's run-time check
(:mod:`mecanum_mav.control.fccheck`) and ``mecanum-mav setup-fc``
(:mod:`mecanum_mav.app.setupfc`) both read through it.

What ArduPilot does with PARAM_REQUEST_READ (``libraries/GCS_MAVLink/GCS_Param.cpp``, and
measured with ArduPilot Rover SITL of July 2025):

- Requests wait in ONE queue of 20 shared by every MAVLink port of the board
  (``param_requests(20)``); a request that finds it full is dropped without an answer. Its IO
  thread moves one request at a time into a reply queue of 5, and each port sends at most 5
  replies per update. A burst of 40 requests got about 20 answers; the rest were lost.
- A name the firmware does not have is never answered (no error either).

So the reader keeps at most :data:`WINDOW` requests unanswered at once (a ground station
reading parameters through the board at the same time still finds room), asks again for a
name not answered within :data:`REPEAT_S`, and ends at :data:`DEADLINE_S`: the names never
answered by then are :meth:`ParamReader.missing`, which is not the same as a wrong value. A
board that has answered nothing by :data:`SILENT_S` answers no parameters at all: the read ends
then.
Measured on the SITL over UDP with this pacing: the 42 names of the default setup check, all
answered, in 0.1-0.3 s.

A *group* of names is one setting known by several names (``MAV_GCS_SYSID`` in current
ArduPilot, ``SYSID_MYGCS`` in older firmware): an answer to any of them answers the group.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Sequence

__all__ = ["DEADLINE_S", "REPEAT_S", "SILENT_S", "WINDOW", "ParamReader"]

WINDOW = 8
"""Requests unanswered at once: well inside ArduPilot's shared queue of 20."""
REPEAT_S = 0.5
"""A name not answered within this long is asked for again (ArduPilot answers a request it
kept within tens of milliseconds; one it dropped is never answered)."""
DEADLINE_S = 10.0
"""The read ends this long after it started, answered or not."""
SILENT_S = 3.0
"""A board that answered nothing at all by then answers no parameters (a firmware without
them, a signing board the link cannot talk to): the read ends, with nothing answered."""


class ParamReader:
    """One read of a set of named parameters (see the module docstring).

    Args:
        groups: the settings to read, each a sequence of the names it may have (one name
            for most).
        now_s: when the read starts, monotonic seconds.
        optional: names whose absence does not count as :meth:`missing` (informational).
        deadline_s: how long the read may take.
    """

    def __init__(self, groups: Iterable[Sequence[str]], now_s: float, *,
                 optional: Iterable[str] = (), deadline_s: float = DEADLINE_S) -> None:
        self.groups: list[tuple[str, ...]] = [tuple(g) for g in groups if g]
        self._group_of = {name: group for group in self.groups for name in group}
        self._optional = frozenset(optional)
        self.values: dict[str, float] = {}
        """Every name answered so far, with its value."""
        self.types: dict[str, int] = {}
        """The MAV_PARAM_TYPE of each name answered (for a PARAM_SET of it)."""
        self._answered: set[tuple[str, ...]] = set()
        self._queue: deque[str] = deque(self._group_of)
        self._asked: dict[str, float] = {}  # name -> when asked, unanswered (insertion order)
        self.started_s = now_s
        self.deadline_s = now_s + deadline_s
        self.over = not self.groups
        """The read has ended: every group answered, or the deadline passed."""

    @property
    def answered(self) -> int:
        """How many of the groups have been answered."""
        return len(self._answered)

    def on_value(self, name: str, value: float, param_type: int | None = None) -> bool:
        """A PARAM_VALUE arrived; whether it answered one of the names read.

        ``value`` is kept as the setting's value even after the read ended (a later change
        the board announces); call :meth:`requests` next, a slot may have opened."""
        group = self._group_of.get(name)
        if group is None:
            return False
        self.values[name] = value
        if param_type is not None:
            self.types[name] = param_type
        if group not in self._answered:
            self._answered.add(group)
            for other in group:
                self._asked.pop(other, None)
            if len(self._answered) == len(self.groups):
                self.over = True
        return True

    def requests(self, now_s: float) -> list[str]:
        """The names to send a PARAM_REQUEST_READ for now (possibly none)."""
        if self.over:
            return []
        if now_s >= self.deadline_s or (not self._answered
                                         and now_s >= self.started_s + SILENT_S):
            self.over = True
            self._asked.clear()
            return []
        expired = []
        for name, asked_s in self._asked.items():
            if now_s - asked_s < REPEAT_S:
                break  # (oldest first)
            expired.append(name)
        for name in expired:
            del self._asked[name]
        self._queue.extendleft(reversed(expired))  # asked again before the names not yet asked
        out = []
        while self._queue and len(self._asked) < WINDOW:
            name = self._queue.popleft()
            if self._group_of[name] in self._answered:
                continue
            self._asked[name] = now_s
            out.append(name)
        return out

    def next_due_s(self) -> float:
        """When :meth:`requests` next has something to do (inf once the read is over)."""
        if self.over:
            return math.inf
        oldest = next(iter(self._asked.values()), math.inf)
        end_s = self.deadline_s if self._answered else self.started_s + SILENT_S
        return min(oldest + REPEAT_S, end_s)

    def missing(self) -> list[str]:
        """Each required setting not answered (its first name), in the order given."""
        return [g[0] for g in self.groups
                if g not in self._answered and not self._optional.intersection(g)]
