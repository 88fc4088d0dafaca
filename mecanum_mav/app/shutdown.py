"""Clean termination of foreground processes: SIGINT (Ctrl-C) and SIGTERM call a stop function."""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Callable, Iterator
from types import FrameType

__all__ = ["on_termination"]


@contextlib.contextmanager
def on_termination(stop: Callable[[], None]) -> Iterator[None]:
    """Call ``stop()`` on SIGINT and SIGTERM while inside; the old handlers come back after.

    ``stop`` must only signal the loop to end (set an event, write a wake-up byte): the loop
    itself then shuts down in order. Use from the main thread.
    """

    def handler(signum: int, frame: FrameType | None) -> None:
        stop()

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
