"""The flight-controller setup rules (protocol/fcsetup.py): what makes a board unsafe."""

from __future__ import annotations

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.control.fccheck import DECIDE_S, RETRY_S, FcSetupCheck
from mecanum_mav.protocol.fcsetup import check, safe_settings, wanted_names

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
    assert {"RC_OVERRIDE_TIME", "ARMING_RUDDER"} <= found
    assert "MAV_GCS_SYSID" not in found and "SERVO1_FUNCTION" not in found


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
    ({"SERVO3_FUNCTION": 73}, "SERVO3_FUNCTION"),      # throttle, not pass-through (and
    ({"SERVO3_FUNCTION": 53}, "SERVO_RC_FS_MSK bit 2"),  # plain RCIN3: holds when it dies)
    ({"SERVO3_TRIM": 1520}, "SERVO3_TRIM"),            # scaled: the pulse would move
    ({"RC_OVERRIDE_TIME": -1}, "RC_OVERRIDE_TIME"),    # never times out
    ({"RCMAP_THROTTLE": 7}, "RCMAP_THROTTLE"),         # the failsafe would never fire
    ({"FS_THR_ENABLE": 0}, "FS_THR_ENABLE"),
])
def test_each_way_a_safe_board_can_become_unsafe_is_found(change, hazard):
    safe = {**PLAIN_PASSTHROUGH, **safe_settings(Params(), PLAIN_PASSTHROUGH)}
    found = hazards({**safe, **change})
    assert hazard in found and found <= {hazard, "SERVO_RC_FS_MSK bit 2"}


def test_older_firmware_names_the_ground_station_id_sysid_mygcs():
    values = {k: v for k, v in PLAIN_PASSTHROUGH.items() if k != "MAV_GCS_SYSID"}
    values["SYSID_MYGCS"] = 255
    assert "SYSID_MYGCS" not in hazards(values)
    assert "SYSID_MYGCS" in safe_settings(Params(), values)


def test_a_board_without_the_parameters_is_unsafe_not_silently_fine():
    assert {"MAV_GCS_SYSID", "SERVO1_FUNCTION", "RC_OVERRIDE_TIME"} <= hazards({})


def test_the_wheel_channels_decide_which_parameters_are_read():
    params = Params()
    params.update({"MOT_FL_CH": 9, "MOT_RR_CH": 12})
    names = wanted_names(params)
    assert "SERVO9_FUNCTION" in names and "RC12_DZ" in names and "SERVO1_FUNCTION" not in names


# --------------------------------------------------------------------------- the run-time check


def test_the_companions_own_check_asks_again_for_missing_answers_then_reports_each_hazard():
    params, check_ = Params(), FcSetupCheck()
    asked = check_.start(params, 10.0)
    assert set(asked) == set(wanted_names(params))
    for name, value in list(PLAIN_PASSTHROUGH.items())[:5]:
        check_.on_value(name, value)
    assert check_.tick(params, 10.0 + RETRY_S - 0.01) == ((), None)  # not due yet
    again, verdict = check_.tick(params, 10.0 + RETRY_S)
    assert verdict is None and set(again) == set(asked) - set(list(PLAIN_PASSTHROUGH)[:5])
    for name, value in PLAIN_PASSTHROUGH.items():
        check_.on_value(name, value)
    again, verdict = check_.tick(params, 10.0 + DECIDE_S)
    assert again == () and verdict.startswith("FC setup unsafe (6): ")
    assert "SERVO_RC_FS_MSK bit 0" in verdict and "ARMING_RUDDER" in verdict
    assert check_.checked and {f.name for f in check_.hazards} >= {"RC_OVERRIDE_TIME"}
    assert check_.next_due_s == float("inf")


def test_a_board_that_answers_no_parameter_is_not_checked_and_blocks_nothing():
    params, check_ = Params(), FcSetupCheck()
    check_.start(params, 0.0)
    check_.tick(params, RETRY_S)
    _, verdict = check_.tick(params, DECIDE_S)
    assert verdict == "FC setup not checked: no parameters from the flight controller"
    assert not check_.checked and check_.hazards == []


def test_setup_fc_puts_wheels_on_9_to_12_through_scaled_pass_through_with_a_wheel_throttle():
    params = Params()
    params.update({"MOT_FL_CH": 9, "MOT_FR_CH": 10, "MOT_RL_CH": 11, "MOT_RR_CH": 12,
                   "RCIN_ENABLE": 1})
    out = safe_settings(params, {"RCMAP_THROTTLE": 3.0})
    assert [out[f"SERVO{ch}_FUNCTION"] for ch in (9, 10, 11, 12)] == [148, 149, 150, 151]
    assert out["SERVO_RC_FS_MSK"] == 0b1111 << 8
    assert out["RCMAP_THROTTLE"] == 9  # the board's radio failsafe watches a wheel channel
    assert not [f for f in check(params, out) if f.hazard]
