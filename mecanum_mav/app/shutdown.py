"""Signals for foreground processes: SIGINT (Ctrl-C) and SIGTERM stop, SIGUSR1 asks for status.

:func:`terminate_in_order` is the companion's: however many SIGINT/SIGTERM come and however
fast, the first one ends it in order and the rest are ignored (:class:`Termination`)."""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Callable, Iterable, Iterator
from types import FrameType

__all__ = ["Termination", "on_signals", "on_termination", "terminate_in_order"]


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


class Termination:
    """SIGINT and SIGTERM for a process that must end in order (the companion): while it
    starts, the first one raises :class:`KeyboardInterrupt` (start-up is abandoned, what was
    opened is closed on the way out); once :meth:`running` handed it the loop's ``stop``, the
    first one calls ``stop()``. Every further signal only sets :attr:`requested` again: it can
    never cut the shutdown short (neutral, the release, the links' linger), which takes
    milliseconds. Install it with :func:`terminate_in_order`."""

    def __init__(self) -> None:
        self.requested = False
        """A SIGINT or SIGTERM came."""
        self._stop: Callable[[], None] | None = None

    def running(self, stop: Callable[[], None]) -> None:
        """The loop runs from now on: the first signal calls ``stop()`` (at once, if one came
        already)."""
        self._stop = stop
        if self.requested:
            stop()

    def signalled(self) -> None:
        """A SIGINT or SIGTERM (the handler's action)."""
        first, self.requested = not self.requested, True
        if not first:
            return
        if self._stop is None:
            raise KeyboardInterrupt
        self._stop()


@contextlib.contextmanager
def terminate_in_order() -> Iterator[Termination]:
    """A :class:`Termination` handling SIGINT and SIGTERM while inside (main thread only).
    The old handlers come back after, unless one of the signals came: the process is then on
    its way out, and further ones are ignored (a Ctrl-C more must not turn a clean stop into
    death by signal)."""
    termination = Termination()
    try:
        with on_termination(termination.signalled):
            yield termination
    finally:
        if termination.requested:
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, signal.SIG_IGN)
