"""The MAVLink parameter protocol against a real pymavlink ground station."""

from __future__ import annotations

import time

import numpy as np
import pytest
from mavpeers import flight_controller, ground_station

from mecanum_mav.app.companion import Companion
from mecanum_mav.io.links import mavlink
from mecanum_mav.params import SCHEMA, load

REAL32, INT32 = mavlink.MAV_PARAM_TYPE_REAL32, mavlink.MAV_PARAM_TYPE_INT32


def param_values(rig, since: int, count: int, timeout_s: float = 3.0) -> dict:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        got = {m.param_id: m for m in rig.gcs.messages[since:] if m.get_type() == "PARAM_VALUE"}
        if len(got) >= count:
            return got
        rig.gcs.pump(0.05)
    return {m.param_id: m for m in rig.gcs.messages[since:] if m.get_type() == "PARAM_VALUE"}


def set_param(rig, name: str, value: float, ptype: int = REAL32):
    since = rig.gcs.mark()
    rig.gcs.mav.param_set_send(1, 1, name.encode(), value, ptype)
    return rig.gcs.wait("PARAM_VALUE", lambda m: m.param_id == name, 1.0, since)


def test_param_request_list_sends_every_parameter_with_index_and_count(rig):
    since = rig.gcs.mark()
    rig.gcs.mav.param_request_list_send(1, 1)
    got = param_values(rig, since, len(SCHEMA))
    assert set(got) == {spec.name for spec in SCHEMA}
    for index, spec in enumerate(SCHEMA):
        msg = got[spec.name]
        assert (msg.param_index, msg.param_count) == (index, len(SCHEMA))
        assert msg.param_type == (INT32 if spec.kind is int else REAL32)
        assert msg.param_value == float(np.float32(spec.default))  # travels as float32


def test_param_request_read_by_name_and_by_index(rig):
    since = rig.gcs.mark()
    rig.gcs.mav.param_request_read_send(1, 1, b"WHL_MAX_SPD", -1)
    by_name = rig.gcs.wait("PARAM_VALUE", lambda m: m.param_id == "WHL_MAX_SPD", 1.0, since)
    assert by_name is not None and by_name.param_value == 1.0
    rig.gcs.mav.param_request_read_send(1, 1, b"", 0)
    by_index = rig.gcs.wait("PARAM_VALUE", lambda m: m.param_index == 0, 1.0, since)
    assert by_index.param_id == SCHEMA[0].name


def test_unknown_parameter_names_get_no_answer(rig):
    since = rig.gcs.mark()
    rig.gcs.mav.param_request_read_send(1, 1, b"NOT_A_PARAM", -1)
    rig.gcs.mav.param_set_send(1, 1, b"NOT_A_PARAM", 1.0, REAL32)
    assert rig.gcs.wait("PARAM_VALUE", timeout_s=0.5, since=since) is None


def test_param_set_in_range_is_stored_and_announced(rig):
    reply = set_param(rig, "INP_EXPO", 0.25)
    assert reply is not None and abs(reply.param_value - 0.25) < 1e-7
    assert rig.companion.core.params["INP_EXPO"] == 0.25


def test_param_set_out_of_range_answers_the_unchanged_value_and_says_why(rig):
    since = rig.gcs.mark()
    reply = set_param(rig, "WHL_MAX_SPD", 500.0)
    assert reply is not None and reply.param_value == 1.0
    text = rig.gcs.wait("STATUSTEXT", lambda m: "WHL_MAX_SPD" in m.text, 1.0, since)
    assert text is not None and "outside" in text.text


def test_param_set_non_finite_is_refused(rig):
    reply = set_param(rig, "INP_DEADBAND", float("nan"))
    assert reply is not None and abs(reply.param_value - 0.05) < 1e-7


def test_a_changed_mixing_parameter_takes_effect_without_a_restart(rig):
    rig.arm()
    assert set_param(rig, "MOT_FL_REV", 1.0, INT32).param_value == 1.0
    deadline = time.monotonic() + 2.0
    seen = None
    while seen is None and time.monotonic() < deadline:
        since = rig.sticks(1000)
        seen = rig.wait_override(lambda ch: ch[:4] == [1000, 2000, 2000, 2000], since, 0.1)
    assert seen is not None


def test_an_identity_change_is_stored_and_flagged_for_a_restart(rig):
    since = rig.gcs.mark()
    assert set_param(rig, "SYSID_THISMAV", 7.0, INT32).param_value == 7.0
    assert rig.gcs.wait("STATUSTEXT", lambda m: "after a restart" in m.text, 1.0, since)
    assert rig.gcs.wait("HEARTBEAT", lambda m: m.get_srcSystem() == 1, 2.0, since)


def test_accepted_sets_are_saved_to_the_parameter_file(tmp_path):
    path = tmp_path / "robot.parm"
    path.write_text("INP_EXPO 0.1\n")
    params = load(path)
    gcs, fc = ground_station(), flight_controller()
    companion = Companion(params, gcs.url, fc.url, param_path=path)
    companion.start()
    try:
        assert gcs.wait("HEARTBEAT", timeout_s=3.0)
        since = gcs.mark()
        gcs.mav.param_set_send(1, 1, b"INP_EXPO", 0.3, REAL32)
        assert gcs.wait("PARAM_VALUE", lambda m: m.param_id == "INP_EXPO", 1.0, since)
        deadline = time.monotonic() + 2.0
        while load(path)["INP_EXPO"] != 0.3 and time.monotonic() < deadline:
            gcs.pump(0.05)
        assert load(path)["INP_EXPO"] == 0.3
        assert not list(tmp_path.glob("*.tmp*"))
    finally:
        companion.close()
        gcs.close()
        fc.close()


def test_parameter_messages_for_another_system_are_ignored(rig):
    since = rig.gcs.mark()
    rig.gcs.mav.param_request_list_send(9, 1)
    rig.gcs.mav.param_set_send(9, 1, b"INP_EXPO", 0.5, REAL32)
    assert rig.gcs.wait("PARAM_VALUE", timeout_s=0.5, since=since) is None
    assert rig.companion.core.params["INP_EXPO"] == 0.0


def test_a_geometry_change_is_stored_and_flagged_for_a_restart(rig):
    since = rig.gcs.mark()
    assert set_param(rig, "GEO_HALF_LEN", 0.2).param_value == pytest.approx(0.2)
    assert rig.gcs.wait("STATUSTEXT", lambda m: "GEO_HALF_LEN takes effect after a restart"
                        in m.text, 1.0, since)
