"""A selector for the companion's loop: selectors' epoll, with a lean wait.

:class:`Poller` is a :class:`selectors.EpollSelector` (so :func:`~mecanum_mav.io.links.follow`
registers and modifies links on it as on any selector) whose :meth:`Poller.wait` skips what
``select()`` does on every wake (a key object per ready descriptor, event translation): it
returns each ready descriptor's registered ``data`` and raw epoll event mask. On an idle
rover every wake is a timer's, and on the control path every microsecond of a wake counts.
"""

from __future__ import annotations

import math
import os
import select
import selectors
from typing import Any

__all__ = ["READABLE", "Poller"]

_sched_yield = getattr(os, "sched_yield", lambda: None)

READABLE = ~select.EPOLLOUT
"""A mask of the epoll events that mean "read it": all but writable (an error or a hang-up
is found by reading), as ``selectors`` reads them."""


class Poller(selectors.EpollSelector):
    """An epoll selector whose :meth:`wait` returns ``(data, epoll events)`` pairs."""

    def __init__(self) -> None:
        super().__init__()
        self._data: dict[int, Any] = {}
        self._epoll: Any = self._selector  # type: ignore[attr-defined]

    def register(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        key = super().register(fileobj, events, data)
        self._data[key.fd] = data
        return key

    def unregister(self, fileobj: Any) -> selectors.SelectorKey:
        key = super().unregister(fileobj)
        self._data.pop(key.fd, None)
        return key

    def modify(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        key = super().modify(fileobj, events, data)
        self._data[key.fd] = data
        return key

    def yield_cpu(self) -> None:
        """Give the CPU to whatever is runnable here (``sched_yield``): a write to a pty is
        delivered by a kernel worker that runs on the writer's CPU only when the writer
        sleeps or yields, so the loop yields after a stick's write before the long part of a
        pass (housekeeping: a few hundred microseconds). About a microsecond when nothing
        waits; elsewhere than Linux, nothing."""
        _sched_yield()

    def wait(self, timeout_s: float) -> list[tuple[Any, int]]:
        """Wait up to ``timeout_s`` seconds (at least that long when nothing is ready: epoll
        counts in milliseconds, so it is rounded up); the ready descriptors' data and events."""
        timeout = math.ceil(timeout_s * 1e3) * 1e-3 if timeout_s > 0.0 else 0.0
        data = self._data  # (every registered descriptor's: epoll reports no other)
        # (A signal during the wait: Python retries it with the time left, PEP 475.)
        ready = self._epoll.poll(timeout, len(data) or 1)
        out = []
        for fd, events in ready:  # (a loop, not a comprehension: no frame of its own in 3.11)
            out.append((data[fd], events))
        return out
