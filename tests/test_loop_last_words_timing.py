""":meth:`~mecanum_mav.runtime.loop.ControlLoop.shutdown` in virtual time: the neutral overrides
stand :data:`~mecanum_mav.runtime.loop.NEUTRAL_HOLD_S` before the release (ArduPilot reads
its RC input once per 20 ms pass), and meanwhile what waits in a slow stream link is handed
over as it goes, not once per neutral."""

from __future__ import annotations

import itertools
from typing import Any

import pytest
from conftest import lockstep

from mecanum_mav.runtime import loop as loop_module
from mecanum_mav.runtime.loop import NEUTRAL_HOLD_S


class VirtualTime:
    """``time.monotonic`` and ``time.sleep`` for the loop: a sleep moves the clock on."""

    def __init__(self) -> None:
        self.now = 1000.0
        self.sleeps = 0

    def monotonic(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        assert seconds >= 0.0
        self.sleeps += 1
        assert self.sleeps < 10_000, "the hold never ends"
        self.now += seconds


@pytest.fixture
def shutdown_seen(monkeypatch: pytest.MonkeyPatch) -> tuple[list[Any], list[float]]:
    """(Each override the shutdown sent: (time, channels, replace); each hand-over's time)."""
    h = lockstep()
    h.gcs.arm()
    h.gcs.sticks(800)
    h.run_for(0.3)
    clock = VirtualTime()
    monkeypatch.setattr(loop_module, "time", clock)
    sent: list[Any] = []
    flushes: list[float] = []
    fc = h.loop.fc
    fc.send_rc_override = lambda _sys, _comp, channels, *, replace=True: sent.append(
        (clock.now, list(channels), replace))
    fc.flush = lambda: flushes.append(clock.now)
    h.loop.shutdown()
    return sent, flushes


def test_two_neutrals_then_the_release_the_release_a_neutral_hold_after_the_first(
        shutdown_seen):
    sent, _ = shutdown_seen
    assert len(sent) == 3
    (t0, first, _), (t1, second, _), (t2, release, _) = sent
    assert first[:4] == second[:4] == [1500] * 4 and release[:4] == [0] * 4
    assert t0 < t1 < t2
    assert t2 - t0 == pytest.approx(NEUTRAL_HOLD_S, abs=1e-9)
    assert t1 - t0 == pytest.approx(NEUTRAL_HOLD_S / 2, abs=1e-9)  # spread over the hold


def test_each_of_the_last_words_the_release_included_is_sent_as_a_last_word(shutdown_seen):
    """``replace=False``: the link queues it behind the words before it, no later override
    replaces it, and closing waits for the wire to carry it (StreamLink.send_rc_override). A
    release sent as a newest-wins override could overtake the neutrals still on a slow wire."""
    sent, _ = shutdown_seen
    assert [replace for _, _, replace in sent] == [False, False, False]


def test_while_the_neutrals_stand_a_slow_link_hands_over_what_waits_every_few_milliseconds(
        shutdown_seen):
    """At 2400 baud an override is 0.2 s on the wire: a link handed its turn only when the
    next neutral is queued would leave the wire idle for most of each 50 ms."""
    sent, flushes = shutdown_seen
    start, end = sent[0][0], sent[-1][0]
    during = [start, *(t for t in flushes if start <= t <= end), end]
    gaps = [b - a for a, b in itertools.pairwise(during)]
    assert max(gaps) <= 0.010, gaps
