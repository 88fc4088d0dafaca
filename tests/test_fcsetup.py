"""The flight-controller setup rules (protocol/fcsetup.py): what makes a board unsafe."""

from __future__ import annotations

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.control.fccheck import FcCheckState, FcSetupCheck
from mecanum_mav.protocol.fcsetup import (
    check,
    safe_settings,
    store_nudge,
    wanted_groups,
    wanted_names,
)
from mecanum_mav.protocol.paramread import DEADLINE_S, REPEAT_S, SILENT_S, WINDOW, ParamReader

PLAIN_PASSTHROUGH = {  # what the README recommended before: RCIN1..4, receiver-less board
    "MAV_GCS_SYSID": 255, "SERVO_RC_FS_MSK": 0, "RC_OVERRIDE_TIME": 3.0, "ARMING_RUDDER": 2,
    "RCMAP_THROTTLE": 3, "FS_THR_ENABLE": 1,
    **{f"SERVO{ch}_FUNCTION": 50 + ch for ch in (1, 2, 3, 4)},
    **{f"{kind}{ch}_{part}": value for ch in (1, 2, 3, 4) for kind in ("RC", "SERVO")
       for part, value in (("MIN", 1100), ("TRIM", 1500), ("MAX", 1900))},
    **{f"RC{ch}_DZ": 30 for ch in (1, 2, 3, 4)},
}


def hazards(values, params=None):
    return {f.name for f in check(params or Params(), values) if f.hazard}


def test_plain_passthrough_holds_the_last_command_after_the_companion_dies():
    found = hazards(PLAIN_PASSTHROUGH)
    assert {f"SERVO_RC_FS_MSK bit {b}" for b in range(4)} <= found
    assert {f"SERVO{ch}_FUNCTION" for ch in (1, 2, 3, 4)} <= found  # RCINn, not RCINnScaled
    assert {"RC_OVERRIDE_TIME", "ARMING_RUDDER"} <= found
    assert "MAV_GCS_SYSID" not in found


def test_every_value_that_differs_from_what_the_companion_needs_is_a_hazard_before_apply():
    """The check without --apply: a board not yet on the scaled pass-through still has every
    wrong range and dead zone marked (it used to mark them ok until the functions changed)."""
    found = hazards(PLAIN_PASSTHROUGH)
    assert {"RC2_MIN", "SERVO2_MIN", "RC2_MAX", "SERVO2_MAX", "RC1_DZ", "RC4_DZ"} <= found
    assert "RC1_TRIM" not in found and "SERVO3_TRIM" not in found  # 1500 is what is needed


def test_the_safe_settings_leave_no_hazard_and_pass_pulses_unchanged():
    params = Params()
    settings = safe_settings(params, PLAIN_PASSTHROUGH)
    assert hazards({**PLAIN_PASSTHROUGH, **settings}) == set()
    assert settings["SERVO1_FUNCTION"] == 140 and settings["SERVO4_FUNCTION"] == 143
    assert settings["SERVO_RC_FS_MSK"] == 0b1111
    assert (settings["RC2_MIN"], settings["SERVO2_MAX"], settings["RC2_DZ"]) == (1000, 2000, 0)
    assert settings["RC_OVERRIDE_TIME"] == 0.5 and settings["ARMING_RUDDER"] == 0
    assert "RCMAP_THROTTLE" not in settings  # channel 3 is already a wheel channel


@pytest.mark.parametrize(("change", "hazard"), [
    ({"MAV_GCS_SYSID": 254}, "MAV_GCS_SYSID"),
    ({"SERVO3_FUNCTION": 73}, "SERVO3_FUNCTION"),      # throttle, not pass-through
    ({"SERVO3_FUNCTION": 53}, "SERVO3_FUNCTION"),      # plain RCIN3: holds when it dies
    ({"SERVO_RC_FS_MSK": 0b1011}, "SERVO_RC_FS_MSK bit 2"),
    ({"SERVO3_TRIM": 1520}, "SERVO3_TRIM"),            # the pulse would move
    ({"RC2_DZ": 30}, "RC2_DZ"),
    ({"RC_OVERRIDE_TIME": -1}, "RC_OVERRIDE_TIME"),    # never times out
    ({"RC_OVERRIDE_TIME": 0}, "RC_OVERRIDE_TIME"),     # every override ignored
    ({"RCMAP_THROTTLE": 7}, "RCMAP_THROTTLE"),         # the failsafe would never fire
    ({"FS_THR_ENABLE": 0}, "FS_THR_ENABLE"),
    ({"ARMING_RUDDER": 1}, "ARMING_RUDDER"),
])
def test_each_way_a_safe_board_can_become_unsafe_is_found(change, hazard):
    safe = {**PLAIN_PASSTHROUGH, **safe_settings(Params(), PLAIN_PASSTHROUGH)}
    assert hazards({**safe, **change}) == {hazard}


def test_older_firmware_names_the_ground_station_id_sysid_mygcs():
    values = {k: v for k, v in PLAIN_PASSTHROUGH.items() if k != "MAV_GCS_SYSID"}
    values["SYSID_MYGCS"] = 255
    assert "SYSID_MYGCS" not in hazards(values)
    assert "SYSID_MYGCS" in safe_settings(Params(), values)
    assert ("MAV_GCS_SYSID", "SYSID_MYGCS") in wanted_groups(Params())  # either answers


def test_a_setting_the_board_did_not_answer_is_unknown_not_a_hazard():
    findings = {f.name: f for f in check(Params(), {})}
    assert not any(f.hazard for f in findings.values())
    assert findings["RC4_DZ"].value is None and findings["SERVO_RC_FS_MSK bit 0"].value is None


def test_the_wheel_channels_decide_which_parameters_are_read():
    params = Params()
    params.update({"MOT_FL_CH": 9, "MOT_RR_CH": 12})
    names = wanted_names(params)
    assert "SERVO9_FUNCTION" in names and "RC12_DZ" in names and "SERVO1_FUNCTION" not in names


def test_only_pulse_widths_dead_zones_and_the_override_time_are_nudged_to_be_stored():
    assert store_nudge("RC9_DZ", 0) == 1 and store_nudge("SERVO10_TRIM", 1500) == 1501
    assert store_nudge("RC1_MIN", 1000) == 1001
    # (s: a neighbour, not a new timeout: the override falls back at most 0.2 s later while
    # it is being set)
    assert 0.5 < store_nudge("RC_OVERRIDE_TIME", 0.5) <= 0.7
    for name in ("SERVO1_FUNCTION", "MAV_GCS_SYSID", "SERVO_RC_FS_MSK", "RCMAP_THROTTLE",
                 "FS_THR_ENABLE", "ARMING_RUDDER", "RC9_OPTION"):
        assert store_nudge(name, 1) is None


# --------------------------------------------------------------------------- the run-time check


class QueuedBoard:
    """ArduPilot's parameter service as GCS_Param.cpp has it: PARAM_REQUEST_READ waits in one
    queue of 20 (a request that finds it full is dropped), one is answered per IO tick (the
    SITL answered about 50 a second), a name it does not have is never answered, and a
    PARAM_SET is announced to every link."""

    QUEUE = 20
    ANSWER_PERIOD_S = 0.02

    def __init__(self, values):
        self.values = dict(values)
        self.queue: list[str] = []
        self.dropped = 0
        self._next_answer_s = 0.0

    def request(self, name):
        if len(self.queue) >= self.QUEUE:
            self.dropped += 1
        else:
            self.queue.append(name)

    def answers(self, now_s):
        out = []
        while self.queue and now_s >= self._next_answer_s:
            name = self.queue.pop(0)
            self._next_answer_s = max(self._next_answer_s, now_s - self.ANSWER_PERIOD_S) + \
                self.ANSWER_PERIOD_S
            if name in self.values:
                out.append((name, self.values[name]))
        return out


SAFE_BOARD = {**PLAIN_PASSTHROUGH, **safe_settings(Params(), PLAIN_PASSTHROUGH),
              "RC_PROTOCOLS": 1}


def run_check(board, check_, params, start_s=0.0, until_s=15.0, step_s=0.005,
              announce=None):
    """Step the check and the board in virtual time; the verdicts said, with when."""
    verdicts = []
    for name in check_.start(params, start_s):
        board.request(name)
    now = start_s
    while now < until_s:
        now += step_s
        if announce is not None and announce[0] <= now:
            name, value = announce[1:]
            board.values[name] = value
            for n in check_.on_value(name, value, now):
                board.request(n)
            announce = None
        for name, value in board.answers(now):
            for n in check_.on_value(name, value, now):
                board.request(n)
        if now >= check_.next_due_s:
            again, verdict = check_.tick(params, now)
            for n in again:
                board.request(n)
            if verdict is not None:
                verdicts.append((now, verdict))
    return verdicts


def test_a_burst_of_every_request_loses_half_of_them_on_ardupilot():
    """What the companion used to do (every name at once): the board model drops what its
    queue cannot hold, as the SITL did (40 asked, about 20 answered)."""
    board = QueuedBoard(SAFE_BOARD)
    for name in wanted_names(Params()):
        board.request(name)
    assert board.dropped == len(wanted_names(Params())) - QueuedBoard.QUEUE


def test_the_reader_keeps_at_most_a_window_of_requests_unanswered_and_asks_again_later():
    reader = ParamReader([("A",), ("B", "B_OLD"), *[(f"P{i}",) for i in range(20)]], 0.0)
    first = reader.requests(0.0)
    assert len(first) == WINDOW and first[:3] == ["A", "B", "B_OLD"]
    assert reader.requests(0.1) == []  # the window is full, nothing is due
    assert reader.on_value("B_OLD", 255.0) and not reader.on_value("OTHER", 1.0)
    assert reader.requests(0.1) == ["P5", "P6"]  # B answered by B_OLD: both slots open
    again = reader.requests(REPEAT_S)
    assert "A" in again and "B" not in again  # not answered in time: asked again
    assert reader.values == {"B_OLD": 255.0}  # the old name answered the group
    assert reader.requests(DEADLINE_S) == [] and reader.over
    assert reader.missing()[0] == "A" and "B" not in reader.missing()


def test_a_setting_answered_again_by_its_other_name_updates_it_and_counts_once():
    singles = [(f"P{i}",) for i in range(WINDOW - 1)]
    reader = ParamReader([*singles, ("B", "B_OLD"), ("C",)], 0.0)
    assert reader.requests(0.0)[-1] == "B"  # the window is full: B_OLD and C wait
    assert reader.on_value("B", 1.0)
    assert reader.on_value("B_OLD", 2.0)  # (an older firmware's name, or a later announce)
    assert reader.answered == 1 and not reader.over
    assert reader.values == {"B": 1.0, "B_OLD": 2.0}
    assert reader.requests(0.1) == ["C"]  # B_OLD's group is answered: never asked for


def test_the_companions_check_reads_every_setting_of_a_board_that_drops_bursts():
    board, check_ = QueuedBoard(SAFE_BOARD), FcSetupCheck()
    verdicts = run_check(board, check_, Params())
    assert verdicts and verdicts[0][1] == "FC setup checked: safe for the companion"
    assert verdicts[0][0] < 2.0 and board.dropped == 0
    assert check_.state is FcCheckState.SAFE and check_.arm_problem(20.0) == (None, [])


def test_a_setting_never_answered_is_not_confirmed_and_read_again_at_the_next_arm_attempt():
    values = {k: v for k, v in SAFE_BOARD.items() if k != "RC4_DZ"}
    board, check_ = QueuedBoard(values), FcSetupCheck()
    verdicts = run_check(board, check_, Params())
    assert [v for _, v in verdicts] == [
        "FC setup not confirmed: no answer for RC4_DZ; asked again when arming"]
    assert verdicts[0][0] >= DEADLINE_S and check_.hazards == []
    problem, ask = check_.arm_problem(20.0)
    assert problem == "FC setup not confirmed: no answer for RC4_DZ; reading again"
    assert ask  # the board is read again
    problem, ask = check_.arm_problem(20.1)
    assert problem is not None and problem.startswith(
        "FC setup not confirmed: reading the flight controller (")


def test_a_board_whose_setup_is_wrong_is_unsafe_and_blocks_arming():
    board, check_ = QueuedBoard(PLAIN_PASSTHROUGH), FcSetupCheck()
    verdicts = run_check(board, check_, Params())
    assert len(verdicts) == 1 and verdicts[0][1].startswith("FC setup unsafe (")
    assert "SERVO_RC_FS_MSK bit 0" in verdicts[0][1] and "ARMING_RUDDER" in verdicts[0][1]
    problem, _ = check_.arm_problem(20.0)
    assert problem is not None and problem.startswith("FC setup unsafe: ")


def test_a_setting_changed_on_the_board_is_read_again_and_arming_waits_for_it():
    """ArduPilot announces a PARAM_SET to every link: the check reads the board again."""
    board, check_ = QueuedBoard(SAFE_BOARD), FcSetupCheck()
    verdicts = run_check(board, check_, Params(), until_s=5.0, announce=(3.0, "RC2_DZ", 30))
    assert verdicts[0][1] == "FC setup checked: safe for the companion"
    assert verdicts[1][0] > 3.0 and verdicts[1][1] == "FC setup unsafe (1): RC2_DZ; run " \
        "mecanum-mav setup-fc --apply"
    assert check_.arm_problem(5.0)[0] == "FC setup unsafe: RC2_DZ (mecanum-mav setup-fc)"


def test_arming_waits_while_the_board_is_read_again_after_a_change():
    board, check_ = QueuedBoard(SAFE_BOARD), FcSetupCheck()
    run_check(board, check_, Params(), until_s=3.0)
    assert check_.on_value("RC2_DZ", 0.0, 3.0) == []  # the same value: nothing to do
    assert check_.on_value("RC2_DZ", 5.0, 3.0)         # changed: asked for again
    problem, _ = check_.arm_problem(3.01)
    assert problem is not None and "reading the flight controller" in problem


def test_a_board_that_answers_no_parameter_is_not_checked_and_blocks_nothing():
    board, check_ = QueuedBoard({}), FcSetupCheck()
    verdicts = run_check(board, check_, Params())
    assert [v for _, v in verdicts] == [
        "FC setup not checked: no parameters from the flight controller"]
    assert SILENT_S <= verdicts[0][0] < SILENT_S + 0.1  # not the whole deadline
    assert not check_.checked and check_.hazards == [] and check_.arm_problem(20.0) == (None, [])


def test_setup_fc_puts_wheels_on_9_to_12_through_scaled_pass_through_with_a_wheel_throttle():
    params = Params()
    params.update({"MOT_FL_CH": 9, "MOT_FR_CH": 10, "MOT_RL_CH": 11, "MOT_RR_CH": 12,
                   "RCIN_ENABLE": 1})
    out = safe_settings(params, {"RCMAP_THROTTLE": 3.0})
    assert [out[f"SERVO{ch}_FUNCTION"] for ch in (9, 10, 11, 12)] == [148, 149, 150, 151]
    assert out["SERVO_RC_FS_MSK"] == 0b1111 << 8
    assert out["RCMAP_THROTTLE"] == 9  # the board's radio failsafe watches a wheel channel
    assert not [f for f in check(params, out) if f.hazard]
