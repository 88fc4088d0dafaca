"""SIGINT and SIGTERM for the companion (``mecanum_mav.app.shutdown.Termination``), as its
docstring promises, without a process: while it starts the first signal abandons the
start-up; once running, the first one stops the loop and none after it does anything more."""

from __future__ import annotations

import pytest

from mecanum_mav.app.shutdown import Termination


def test_a_signal_during_start_up_abandons_it_and_one_more_is_only_noted():
    termination = Termination()
    with pytest.raises(KeyboardInterrupt):
        termination.signalled()
    termination.signalled()  # (a second Ctrl-C while the start-up unwinds: no second raise)
    assert termination.requested


def test_once_running_the_first_signal_stops_the_loop_and_later_ones_do_nothing_more():
    stops: list[int] = []
    termination = Termination()
    termination.running(lambda: stops.append(1))
    assert stops == [] and not termination.requested
    termination.signalled()
    termination.signalled()
    assert stops == [1] and termination.requested


def test_a_loop_handed_over_after_a_signal_came_is_stopped_at_once():
    stops: list[int] = []
    termination = Termination()
    with pytest.raises(KeyboardInterrupt):
        termination.signalled()
    termination.running(lambda: stops.append(1))
    assert stops == [1]
