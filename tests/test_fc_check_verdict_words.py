"""What the companion's check of the flight controller's setup says (control/fccheck.py's
module docstring): every hazard and every unanswered setting named, how far a read has got
while an arm attempt waits for it, a verdict said again when the link comes up again, and
values the check does not read left alone."""

from __future__ import annotations

from test_fcsetup import SAFE_BOARD, QueuedBoard, run_check

from mecanum_mav.config.params import Params
from mecanum_mav.control.fccheck import FcCheckState, FcSetupCheck
from mecanum_mav.protocol.fcsetup import wanted_groups

SAFE = "FC setup checked: safe for the companion"


def test_an_unsafe_verdict_counts_and_names_every_hazard() -> None:
    board = QueuedBoard({**SAFE_BOARD, "RC2_DZ": 30, "RC3_DZ": 40})
    verdicts = run_check(board, FcSetupCheck(), Params())
    assert [v for _, v in verdicts] == [
        "FC setup unsafe (2): RC2_DZ, RC3_DZ; run mecanum-mav setup-fc --apply"]


def test_a_not_confirmed_verdict_names_every_setting_without_an_answer() -> None:
    values = {k: v for k, v in SAFE_BOARD.items() if k not in ("RC3_DZ", "RC4_DZ")}
    check = FcSetupCheck()
    verdicts = run_check(QueuedBoard(values), check, Params())
    assert [v for _, v in verdicts] == [
        "FC setup not confirmed: no answer for RC3_DZ, RC4_DZ; asked again when arming"]
    assert check.missing == ["RC3_DZ", "RC4_DZ"]
    assert check.arm_problem(20.0)[0] == (
        "FC setup not confirmed: no answer for RC3_DZ, RC4_DZ; reading again")


def test_an_arm_attempt_during_a_read_is_told_how_many_settings_have_answered() -> None:
    params = Params()
    check = FcSetupCheck()
    asked = check.start(params, 0.0)
    total = len(wanted_groups(params))
    assert check.arm_problem(0.0) == (
        f"FC setup not confirmed: reading the flight controller (0 of {total})", [])
    check.on_value(asked[0], SAFE_BOARD[asked[0]], 0.01)
    assert check.arm_problem(0.01)[0] == (
        f"FC setup not confirmed: reading the flight controller (1 of {total})")
    assert check.state is FcCheckState.READING and not check.checked


def test_the_verdict_is_said_again_when_the_link_comes_up_again() -> None:
    check = FcSetupCheck()
    first = run_check(QueuedBoard(SAFE_BOARD), check, Params())
    again = run_check(QueuedBoard(SAFE_BOARD), check, Params(), start_s=20.0, until_s=35.0)
    assert [v for _, v in first] == [v for _, v in again] == [SAFE]
    assert check.checked and check.hazards == [] and check.missing == []


def test_a_value_of_a_setting_the_check_does_not_read_is_ignored() -> None:
    check = FcSetupCheck()
    run_check(QueuedBoard(SAFE_BOARD), check, Params())
    assert check.on_value("BATT_CAPACITY", 3300.0, 16.0) == []
    assert "BATT_CAPACITY" not in check.values
    assert check.state is FcCheckState.SAFE and check.next_due_s == float("inf")



def test_before_the_link_comes_up_the_check_blocks_nothing_and_ignores_values() -> None:
    check = FcSetupCheck()
    assert check.state is FcCheckState.IDLE and not check.checked
    assert (check.hazards, check.missing, check.values) == ([], [], {})
    assert check.on_value("RC2_DZ", 30.0, 0.0) == [] and check.values == {}
    assert check.arm_problem(0.0) == (None, []) and check.next_due_s == float("inf")


def test_a_board_that_answers_nothing_is_in_the_not_checked_state() -> None:
    check = FcSetupCheck()
    run_check(QueuedBoard({}), check, Params())
    assert check.state is FcCheckState.NOT_CHECKED and check.state.value == "not checked"
