"""The loop's poller (mecanum_mav/io/poller.py): a selector whose wait gives each ready
descriptor's registered data (the latest, after a modify) with its epoll events, waits at
least the time asked when nothing is ready (epoll's milliseconds rounded up), goes on waiting
through a signal, and reports nothing for a descriptor it no longer watches."""

from __future__ import annotations

import gc
import select
import selectors
import signal
import socket
import threading
import time
import weakref

import pytest

from mecanum_mav.io.poller import READABLE, Poller


def test_wait_gives_the_data_of_the_latest_registration_or_modify_with_its_events():
    a, b = socket.socketpair()
    with Poller() as poller, a, b:
        poller.register(a, selectors.EVENT_READ, "reading")
        assert poller.wait(0.0) == []  # nothing to read
        poller.modify(a, selectors.EVENT_READ | selectors.EVENT_WRITE, "writing too")
        [(data, events)] = poller.wait(0.0)
        assert data == "writing too" and events & select.EPOLLOUT and not events & READABLE
        b.send(b"x")
        [(data, events)] = poller.wait(0.0)
        assert events & select.EPOLLIN and events & select.EPOLLOUT
        poller.unregister(a)
        assert poller.wait(0.0) == []


def test_the_selector_keys_hold_the_data_of_the_latest_registration_or_modify():
    """(links.follow and the loop read keys as from any selector.)"""
    a, b = socket.socketpair()
    with Poller() as poller, a, b:
        assert poller.register(a, selectors.EVENT_READ, "reading").data == "reading"
        key = poller.modify(a, selectors.EVENT_WRITE, "writing")
        assert key.data == "writing" and poller.get_key(a).data == "writing"
        assert poller.unregister(a).data == "writing"


def test_the_poller_keeps_nothing_of_a_descriptor_it_no_longer_watches():
    """A tcpin link's clients come and go for days: their links must not live on in it."""

    class Data:
        pass

    a, b = socket.socketpair()
    with Poller() as poller, a, b:
        data = Data()
        gone = weakref.ref(data)
        poller.register(a, selectors.EVENT_READ, data)
        poller.modify(a, selectors.EVENT_READ, data)
        poller.unregister(a)
        del data
        gc.collect()
        assert gone() is None


def test_an_idle_wait_lasts_at_least_the_time_asked():
    with Poller() as poller:
        for timeout_s in (0.0004, 0.0101):  # (under a millisecond; between two)
            started = time.monotonic()
            assert poller.wait(timeout_s) == []
            assert time.monotonic() - started >= timeout_s


class _RecordingEpoll:
    """An epoll that is never ready and notes the timeout of each poll (seconds)."""

    def __init__(self) -> None:
        self.timeouts: list[float] = []

    def poll(self, timeout: float, maxevents: int = -1) -> list[tuple[int, int]]:
        self.timeouts.append(timeout)
        return []


def test_a_wait_is_rounded_up_to_the_next_millisecond_and_no_further():
    """epoll counts in milliseconds: the time asked is rounded up to a whole one (a timer's
    wake never comes early), never by more (nor late: each ms late is a stick's latency)."""
    with Poller() as poller:
        epoll = _RecordingEpoll()
        poller._epoll = epoll
        for timeout_s in (0.0004, 0.02, 0.0201, 0.25, 0.0, -1.0):
            poller.wait(timeout_s)
        assert epoll.timeouts == pytest.approx([0.001, 0.02, 0.021, 0.25, 0.0, 0.0],
                                               abs=1e-12)


def test_a_signal_during_a_wait_does_not_cut_it_short():
    """(A handled SIGUSR1 — the companion's status request — arrives mid-wait.)"""
    got: list[int] = []
    previous = signal.signal(signal.SIGUSR1, lambda signum, frame: got.append(signum))
    main = threading.main_thread().ident
    assert main is not None
    timer = threading.Timer(0.05, lambda: signal.pthread_kill(main, signal.SIGUSR1))
    try:
        with Poller() as poller:
            started = time.monotonic()
            timer.start()
            assert poller.wait(0.2) == []
            assert time.monotonic() - started >= 0.2
    finally:
        timer.cancel()
        signal.signal(signal.SIGUSR1, previous)
    assert got == [signal.SIGUSR1]
