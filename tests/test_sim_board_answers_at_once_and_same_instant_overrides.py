"""The simulated board's timing rules (mecanum_mav.sim.board): a parameter asked for is
answered at the next turn, without waiting for the next physics step or telemetry message
(``next_due_s`` is due at once meanwhile); overrides take effect from the moment they arrive,
so of two arriving at one instant the later is in force and no physics time passes. The board
alone, time passed in."""

from __future__ import annotations

from typing import Any

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.outbox import MessageOutbox
from mecanum_mav.sim.board import SimBoard

GCS = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)


def received(build: str, *args: Any) -> Any:
    """A message from the ground station's system as the board receives it (packed, parsed)."""
    data = getattr(GCS, f"{build}_encode")(*args).pack(GCS)
    return mavlink.MAVLink(None).decode(bytearray(data))


def override(pulse: int) -> Any:
    """RC_CHANNELS_OVERRIDE of channels 1-4 (the wheels by default) to ``pulse``."""
    return received("rc_channels_override", 1, 1, pulse, pulse, pulse, pulse,
                    *([65535] * 4))


def test_a_parameter_request_makes_the_board_due_at_once_and_is_answered_then():
    board, outbox = SimBoard(Params(), 0.0), MessageOutbox()
    board.on_time(0.0, outbox)
    outbox.take()
    idle_due_s = board.next_due_s()
    assert idle_due_s > 0.0
    board.receive([received("param_request_read", 1, 1, b"RC_OVERRIDE_TIME", -1)], 0.001)
    assert board.next_due_s() <= 0.001 < idle_due_s  # due now, not at the next step
    board.on_time(0.001, outbox)
    answers = [m for m in outbox.take() if m.get_type() == "PARAM_VALUE"]
    assert [(m.param_id, m.param_value) for m in answers] == [
        ("RC_OVERRIDE_TIME", pytest.approx(board.parameters["RC_OVERRIDE_TIME"]))]
    assert board.next_due_s() > 0.001  # answered: nothing more due now


def test_a_parameter_the_board_does_not_have_is_not_answered_and_nothing_is_due():
    board, outbox = SimBoard(Params(), 0.0), MessageOutbox()
    board.on_time(0.0, outbox)
    outbox.take()
    idle_due_s = board.next_due_s()
    board.receive([received("param_request_read", 1, 1, b"NO_SUCH_PARAM", -1)], 0.001)
    assert board.next_due_s() == idle_due_s
    board.on_time(0.001, outbox)
    assert [m for m in outbox.take() if m.get_type() == "PARAM_VALUE"] == []


def test_of_two_overrides_arriving_at_one_instant_the_later_is_in_force_and_no_time_passes():
    board = SimBoard(Params(), 0.0)
    board.receive([override(1700)], 0.05)
    first = board.state()
    board.receive([override(1300)], 0.05)
    second = board.state()
    assert second.time_s == first.time_s == pytest.approx(0.05)
    assert second.pose == first.pose and second.wheel_speeds_mps == first.wheel_speeds_mps
    assert {ch: second.channel_pwm[ch] for ch in (1, 2, 3, 4)} == dict.fromkeys((1, 2, 3, 4),
                                                                                 1300)
    assert all(c < 0.0 for c in second.wheel_commands)  # below trim: the wheels roll back


def test_a_board_held_up_for_seconds_sends_each_message_once_then_keeps_its_rate():
    """A late board (a starved process) does not burst out the messages it missed: one of
    each, and the next a whole period later, as a real board's scheduler does."""
    board, outbox = SimBoard(Params(), 0.0), MessageOutbox()
    board.on_time(0.0, outbox)
    outbox.take()
    board.on_time(5.0, outbox)  # 5 s late: HEARTBEAT is 1 Hz
    late = [m.get_type() for m in outbox.take()]
    assert late.count("HEARTBEAT") == 1
    board.on_time(5.5, outbox)
    assert "HEARTBEAT" not in [m.get_type() for m in outbox.take()]
    board.on_time(6.0, outbox)
    assert [m.get_type() for m in outbox.take()].count("HEARTBEAT") == 1
