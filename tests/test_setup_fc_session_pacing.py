"""How ``setup-fc`` talks to the board (mecanum_mav.app.setupfc.FcSession and the --apply
report), on a simulated clock: what each PARAM_SET, COMMAND_LONG and REQUEST_MESSAGE
carries, when each is sent again, when it gives up, and how it tells that the board rebooted.

The board here answers in-process (10 ms after a message, on the session's clock), so the
pace of every message is exact: a rule of the MAVLink parameter and command protocols, or of
the module's constants (``REPEAT_S``, ``WINDOW``, ``ACK_TIMEOUT_S``, ``WRITE_DEADLINE_S``), is
stated as the times it was sent at.
"""

from __future__ import annotations

import io
from itertools import pairwise
from typing import Any

import pytest
from fcsim import INT16, LATENCY_S, REAL32, START_S, Board, Clock, session_on, use_clock

from mecanum_mav.app import setupfc
from mecanum_mav.config.params import Params
from mecanum_mav.config.spec import float32_of
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.paramread import REPEAT_S, WINDOW


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> Clock:
    return use_clock(monkeypatch)


# --------------------------------------------------------------------------- PARAM_REQUEST_READ


def test_each_setting_is_read_by_its_name(clock: Clock) -> None:
    """MAVLink's PARAM_REQUEST_READ: param_index -1 reads by name (else the name is ignored)."""
    board = Board(clock, params={"ARMING_RUDDER": (0.0, REAL32), "RC1_DZ": (30.0, REAL32),
                                 "RC2_DZ": (20.0, REAL32)})
    reading = session_on(board).read([("RC2_DZ",), ("RC1_DZ",)])
    assert reading.values == {"RC2_DZ": 20.0, "RC1_DZ": 30.0} and reading.missing == []
    assert {m.param_index for _, m in board.sent("PARAM_REQUEST_READ")} == {-1}


def test_a_read_not_answered_is_asked_again_repeat_s_later(clock: Clock) -> None:
    board = Board(clock, params={"RC1_DZ": (30.0, REAL32)}, drop_reads={"RC1_DZ": 1})
    assert session_on(board).read([("RC1_DZ",)]).values == {"RC1_DZ": 30.0}
    first, second = board.times("PARAM_REQUEST_READ")
    assert REPEAT_S <= second - first <= REPEAT_S + 0.01


# --------------------------------------------------------------------------- PARAM_SET


def test_no_more_than_window_settings_wait_unconfirmed_at_once(clock: Clock) -> None:
    names = [f"RC{ch}_DZ" for ch in range(1, WINDOW + 5)]
    board = Board(clock, drop_sets={n: 1 for n in names})  # nothing echoed the first time
    session_on(board).write({n: 0.0 for n in names})
    first = [m.param_id for t, m in board.sent("PARAM_SET") if t == START_S]
    assert first == names[:WINDOW]
    assert {m.param_id for _, m in board.sent("PARAM_SET")} == set(names)


def test_a_setting_not_echoed_is_sent_again_after_repeat_s_and_then_confirmed(
        clock: Clock) -> None:
    board = Board(clock, params={"RC1_DZ": (30.0, REAL32)}, drop_sets={"RC1_DZ": 2})
    echoed = session_on(board).write({"RC1_DZ": 0.0})
    assert echoed == {"RC1_DZ": 0.0}
    first, second, third = board.times("PARAM_SET")
    for before, after in ((first, second), (second, third)):
        assert REPEAT_S <= after - before <= REPEAT_S + 0.1 + 1e-6


def test_each_setting_is_set_as_the_type_the_board_reported_and_an_unread_one_as_a_float(
        clock: Clock) -> None:
    """MAVLink's PARAM_SET carries the parameter's type (PARAM_VALUE's, when it was read)."""
    board = Board(clock, params={"RC1_MIN": (1100.0, INT16), "RC1_DZ": (30.0, INT16)})
    session = session_on(board)
    reading = session.read([("RC1_MIN",)])
    assert reading.values == {"RC1_MIN": 1100.0} and reading.missing == []
    assert session.write({"RC1_MIN": 1000.0, "RC1_DZ": 0.0}) == {"RC1_MIN": 1000.0,
                                                                "RC1_DZ": 0.0}
    kinds = {m.param_id: m.param_type for _, m in board.sent("PARAM_SET")}
    assert kinds == {"RC1_MIN": INT16, "RC1_DZ": REAL32}
    values = {m.param_id: m.param_value for _, m in board.sent("PARAM_SET")}
    assert values == {"RC1_MIN": 1000.0, "RC1_DZ": 0.0}
    assert {m.target_system for _, m in board.sent("PARAM_SET")} == {1}


def test_a_value_the_board_keeps_otherwise_is_sent_again_until_the_deadline(
        clock: Clock) -> None:
    board = Board(clock, params={"RC1_MIN": (1100.0, REAL32)}, keeps={"RC1_MIN": 1001.0})
    assert session_on(board).write({"RC1_MIN": 1000.0}) == {"RC1_MIN": 1001.0}
    times = board.times("PARAM_SET")
    assert len(times) == round(setupfc.WRITE_DEADLINE_S / REPEAT_S)
    assert times[-1] < setupfc.WRITE_DEADLINE_S <= clock.now - START_S


def test_a_float_echoed_as_the_float32_the_wire_carries_is_confirmed_at_once(
        clock: Clock) -> None:
    board = Board(clock, params={"RC_OVERRIDE_TIME": (3.0, REAL32)},
                  extra=[Board(clock).mav.heartbeat_encode(10, 3, 0, 0, 3)])
    echoed = session_on(board).write({"RC_OVERRIDE_TIME": 0.6})
    assert echoed == {"RC_OVERRIDE_TIME": float32_of(0.6)} != {"RC_OVERRIDE_TIME": 0.6}
    assert len(board.times("PARAM_SET")) == 1  # (a HEARTBEAT came with the echo)


def test_writing_gives_up_on_a_board_that_never_echoes_after_write_deadline_s(
        clock: Clock) -> None:
    board = Board(clock, drop_sets={"RC1_DZ": 1000})
    assert session_on(board).write({"RC1_DZ": 0.0}) == {}
    assert setupfc.WRITE_DEADLINE_S <= clock.now - START_S <= setupfc.WRITE_DEADLINE_S + 0.1


# --------------------------------------------------------------------------- SYSTEM_TIME


def test_the_time_since_boot_is_requested_again_every_ack_timeout_until_the_timeout(
        clock: Clock) -> None:
    board = Board(clock, tells_time=False)
    assert session_on(board).boot_ms(3.0) is None
    assert clock.now == START_S + 3.0  # not a moment longer
    asks = board.sent("COMMAND_LONG", command=mavlink.MAV_CMD_REQUEST_MESSAGE)
    assert [round(t - START_S, 6) for t, _ in asks] == [0.0, 1.0, 2.0]
    for _, ask in asks:  # MAVLink's REQUEST_MESSAGE: the message id, nothing else
        assert (ask.target_system, ask.target_component, ask.confirmation) == (1, 1, 0)
        assert [ask.param1, ask.param2, ask.param3, ask.param4, ask.param5, ask.param6,
                ask.param7] == [mavlink.MAVLINK_MSG_ID_SYSTEM_TIME, 0, 0, 0, 0, 0, 0]


def test_a_short_wait_for_the_time_since_boot_ends_on_time(clock: Clock) -> None:
    board = Board(clock, tells_time=False)
    assert session_on(board).boot_ms(0.5) is None
    assert clock.now == START_S + 0.5


def test_the_time_since_boot_is_the_boards_answer(clock: Clock) -> None:
    board = Board(clock, booted_s=START_S - 12.5)
    assert session_on(board).boot_ms() == 12_500  # (asked at once)


# --------------------------------------------------------------------------- the reboot


def _reboots(board: Board) -> list[tuple[float, Any]]:
    return board.sent("COMMAND_LONG", command=mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN)


def test_the_reboot_asks_the_autopilot_alone_to_reboot(clock: Clock) -> None:
    """MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN: param1 1 reboots the autopilot; param2 is the
    onboard computer's (the companion's own), 0: do nothing."""
    board = Board(clock, down_s=2.0)
    assert session_on(board).reboot(10.0) is None
    (_, command), = _reboots(board)
    assert (command.target_system, command.target_component, command.confirmation) == (1, 1, 0)
    assert [command.param1, command.param2, command.param3, command.param4, command.param5,
            command.param6, command.param7] == [1, 0, 0, 0, 0, 0, 0]


def test_an_unanswered_reboot_is_sent_three_times_each_a_confirmation_of_the_first(
        clock: Clock) -> None:
    board = Board(clock, reboot_ack=None)
    assert session_on(board).reboot(10.0) == "no answer to MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN"
    sent = _reboots(board)
    assert [m.confirmation for _, m in sent] == [0, 1, 2]
    first = sent[0][0]
    assert [round(t - first, 6) for t, _ in sent] == [0.0, setupfc.ACK_TIMEOUT_S,
                                                      2 * setupfc.ACK_TIMEOUT_S]
    assert clock.now == first + 3 * setupfc.ACK_TIMEOUT_S


def test_a_board_rebooted_seconds_after_it_booted_is_seen_back(clock: Clock) -> None:
    board = Board(clock, booted_s=START_S - 2.0, down_s=3.0)
    assert session_on(board).reboot(10.0) is None
    assert clock.now < START_S + 5.0  # back at 3 s after the reboot command


def test_a_board_silent_for_seconds_while_it_reboots_is_waited_for(clock: Clock) -> None:
    board = Board(clock, down_s=5.0)
    assert session_on(board).reboot(10.0) is None
    asks = board.times("COMMAND_LONG", command=mavlink.MAV_CMD_REQUEST_MESSAGE)
    assert asks[-1] >= 5.0  # asked until the board answered again
    assert all(round(b - a, 6) == setupfc.ACK_TIMEOUT_S for a, b in pairwise(asks[1:]))


def test_a_board_not_back_is_given_up_when_the_timeout_is_over_not_later(clock: Clock) -> None:
    board = Board(clock, down_s=100.0)
    session = session_on(board)
    assert session.reboot(4.0) == "the board was not back within 4 s"
    acked = _reboots(board)[0][0] + LATENCY_S
    assert acked <= clock.now - 4.0 <= acked + 1e-5


def test_a_board_that_runs_on_after_acknowledging_is_not_taken_as_rebooted(
        clock: Clock) -> None:
    board = Board(clock, reboots=False)
    assert session_on(board).reboot(3.0) == "the board was not back within 3 s"


def test_a_board_that_did_not_tell_its_time_before_the_reboot_is_back_at_its_first_answer(
        clock: Clock) -> None:
    board = Board(clock, down_s=2.0, silent_until_reboot=True)
    assert session_on(board).reboot(10.0) is None
    assert board.boots == 1
    acked = _reboots(board)[0][0]
    # its first answer, once up again (asked every ACK_TIMEOUT_S)
    assert acked + 2.0 < clock.now <= acked + 2.0 + setupfc.ACK_TIMEOUT_S + 2 * LATENCY_S


# --------------------------------------------------------------------------- --apply


def test_apply_reports_how_many_settings_the_board_took_and_names_those_it_did_not(
        clock: Clock) -> None:
    board = Board(clock, keeps={"RC2_DZ": 30.0, "RC1_DZ": 30.0})
    out = io.StringIO()
    setup = setupfc._Setup(session_on(board), Params(), out)
    wanted = setupfc.safe_settings(Params(), {})
    have = {n: float(v) + 7 for n, v in wanted.items()}  # each one wrong
    changed = setup.apply(setupfc.Reading(have, []))
    assert {"RC1_DZ", "RC2_DZ", "RC3_DZ"} <= changed
    n = len(changed)
    line = out.getvalue().strip("\n")
    assert line == (f"wrote {n - 2} of {n} settings ({n} changed, 0 stored by writing a "
                    "neighbour first); not accepted: RC1_DZ, RC2_DZ")


def test_apply_that_the_board_took_whole_reports_it_in_one_line(clock: Clock) -> None:
    board = Board(clock)
    out = io.StringIO()
    setup = setupfc._Setup(session_on(board), Params(), out)
    wanted = setupfc.safe_settings(Params(), {})
    changed = setup.apply(setupfc.Reading({"RC1_DZ": 30.0}, []))
    assert changed == set(wanted)
    n = len(wanted)
    assert out.getvalue() == (f"\nwrote {n} of {n} settings ({n} changed, 0 stored by writing "
                              "a neighbour first)\n")
