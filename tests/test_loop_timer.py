"""The shell's slow timer on the loop (:meth:`~mecanum_mav.runtime.loop.ControlLoop.set_timer`,
the progress line): "call ``action(now_s)`` on the next pass and then whenever the time it
returned has come", as the lockstep harness steps the companion's pass."""

from __future__ import annotations

import itertools
import math
import time
from typing import Any

import pytest
from conftest import lockstep
from support import wait_until

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.groundstation import udp_ground_station


def _watch_waits(h: Any) -> list[float]:
    """The timeouts the loop gives its poller from now on."""
    timeouts: list[float] = []
    wait = h.loop.poller.wait

    def watched_wait(timeout_s: float) -> list[tuple[Any, int]]:
        timeouts.append(timeout_s)
        return wait(timeout_s)

    h.loop.poller.wait = watched_wait
    return timeouts


def test_a_timer_runs_on_the_next_pass_without_a_wait_and_then_each_time_it_asked_for():
    h = lockstep()
    h.run_for(0.3)
    calls: list[float] = []

    def progress(now_s: float) -> float:
        calls.append(now_s)
        return now_s + 0.25

    timeouts = _watch_waits(h)
    h.loop.set_timer(progress)
    h.step()
    assert calls == [h.now_s]  # in the very next step,
    assert timeouts[0] <= 0.0  # and its pass did not wait for anything to arrive first
    h.run_for(1.0)
    assert len(calls) == 5  # then every 0.25 s as it asked: at +0.25, +0.5, +0.75, +1.0
    gaps = [b - a for a, b in itertools.pairwise(calls)]
    assert all(0.25 <= gap < 0.25 + 2 * h.dt_s for gap in gaps), gaps


def test_a_timer_set_while_sticks_come_in_their_lane_runs_on_the_next_pass_not_after_them():
    """After a stick the lane answered, the next pass would wait for the next stick until the
    timers that pass saw; a timer set then is due at once and is not kept waiting."""
    h = lockstep()
    h.gcs.arm()
    h.gcs.sticks(500)
    h.run_for(0.2)  # driving: the lane is open
    pilot = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    for i in range(100):  # until the next pass may be a stick alone
        h.inject(bytes(pilot.manual_control_encode(1, 400 + i, 0, 500, 0, 0).pack(pilot)))
        h.step()
        if h.loop._sticks_until_s > -math.inf:
            break
    assert h.loop._sticks_until_s > -math.inf
    calls: list[float] = []
    timeouts = _watch_waits(h)
    h.loop.set_timer(lambda now_s: calls.append(now_s) or math.inf)
    h.step()
    assert calls == [pytest.approx(h.now_s)]
    assert timeouts[0] <= 0.0  # (the companion's epoll would have slept until a stick came)


def test_a_timer_set_on_a_running_companion_runs_on_its_next_pass_and_then_when_asked():
    """(The companion's own thread runs the loop; the timer is set from another one, while
    the loop waits: it runs on the loop's next pass.)"""
    _, port = udp_ground_station()
    companion = Companion(Params(), port.url, "udpout:127.0.0.1:9")
    calls: list[float] = []

    def action(now_s: float) -> float:
        calls.append(time.monotonic())
        return now_s + 0.1

    try:
        companion.start()
        assert wait_until(lambda: companion.loop is not None, 5.0)
        set_at = time.monotonic()
        companion.set_timer(action)
        assert wait_until(lambda: len(calls) >= 3, 5.0), calls
    finally:
        companion.close()
        port.close()
    assert calls[0] - set_at < 0.5  # (the next pass: 14-43 ms after, measured)
    assert all(later - earlier >= 0.09 for earlier, later in itertools.pairwise(calls))
