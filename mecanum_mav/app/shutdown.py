"""Signals for foreground processes: SIGINT (Ctrl-C) and SIGTERM stop, SIGUSR1 asks for status."""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Callable, Iterable, Iterator
from types import FrameType

__all__ = ["on_signals", "on_termination"]


@contextlib.contextmanager
def on_signals(signals: Iterable[signal.Signals], action: Callable[[], None]) -> Iterator[None]:
    """Call ``action()`` on each of ``signals`` while inside; the old handlers come back after.

    Use from the main thread. ``action`` runs in the main thread between two bytecodes of
    whatever it was doing: keep it short (set an event, write a wake-up byte, print a line).
    """

    def handler(signum: int, frame: FrameType | None) -> None:
        action()

    previous = {sig: signal.signal(sig, handler) for sig in signals}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def on_termination(stop: Callable[[], None]) -> contextlib.AbstractContextManager[None]:
    """Call ``stop()`` on SIGINT and SIGTERM while inside (see :func:`on_signals`).

    ``stop`` must only signal the loop to end (set an event, write a wake-up byte): the loop
    itself then shuts down in order.
    """
    return on_signals((signal.SIGINT, signal.SIGTERM), stop)
