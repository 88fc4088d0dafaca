"""The MAVLink parameter protocol, in the lockstep harness (virtual time, exact: every answer
goes out in the step its request reaches the core)."""

from __future__ import annotations

import errno
from collections.abc import Sequence

import numpy as np
import pytest
from conftest import lockstep
from support import status_texts

from mecanum_mav.config.params import Params
from mecanum_mav.io.links import mavlink
from mecanum_mav.io.storage import FileStorage
from mecanum_mav.params import SCHEMA, load
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.sim.lockstep import Lockstep

REAL32, INT32 = mavlink.MAV_PARAM_TYPE_REAL32, mavlink.MAV_PARAM_TYPE_INT32


def answers(h: Lockstep, since: int) -> list:
    """Step once (the request reaches the core): the PARAM_VALUEs received from ``since``."""
    h.step()
    h.gcs.mark()
    return h.gcs.received("PARAM_VALUE", since)


def set_param(h: Lockstep, name: str, value: float, ptype: int = REAL32):
    """PARAM_SET; the one PARAM_VALUE answering it, in the step it arrived (or None)."""
    since = h.gcs.mark()
    h.gcs.mav.param_set_send(1, 1, name.encode(), value, ptype)
    got = answers(h, since)
    assert len(got) <= 1, got
    assert all(m.param_id == name for m in got)
    return got[0] if got else None


class MemoryStorage:
    """Keeps what the core saves; ``fail`` makes every save raise as a full disk would."""

    def __init__(self, fail: bool = False) -> None:
        self.fail = fail
        self.saved: list[dict[str, float]] = []

    def save_params(self, params: Params) -> None:
        if self.fail:
            raise OSError(errno.ENOSPC, "No space left on device")
        self.saved.append({spec.name: params[spec.name] for spec in SCHEMA})

    def save_mission(self, items: Sequence[MissionItem]) -> None:
        raise AssertionError("no mission here")


def test_param_request_list_sends_every_parameter_with_index_and_count(harness):
    h = harness
    since = h.gcs.mark()
    h.gcs.mav.param_request_list_send(1, 1)
    values = answers(h, since)  # all of them in the step the request arrived
    assert [m.param_id for m in values] == [spec.name for spec in SCHEMA]  # in index order
    for index, (spec, msg) in enumerate(zip(SCHEMA, values, strict=True)):
        assert (msg.param_index, msg.param_count) == (index, len(SCHEMA))
        assert msg.param_type == (INT32 if spec.kind is int else REAL32)
        assert msg.param_value == float(np.float32(spec.default))  # travels as float32


def test_param_request_read_by_name_and_by_index(harness):
    h = harness
    since = h.gcs.mark()
    h.gcs.mav.param_request_read_send(1, 1, b"WHL_MAX_SPD", -1)
    by_name = answers(h, since)
    assert [(m.param_id, m.param_value) for m in by_name] == [("WHL_MAX_SPD", 1.0)]
    since = h.gcs.mark()
    h.gcs.mav.param_request_read_send(1, 1, b"", 0)
    by_index = answers(h, since)
    assert [(m.param_id, m.param_index) for m in by_index] == [(SCHEMA[0].name, 0)]


def test_a_read_by_the_last_index_answers_and_one_past_it_gets_no_answer(harness):
    h = harness
    last = len(SCHEMA) - 1
    since = h.gcs.mark()
    for index in (last, last + 1, 32767):
        h.gcs.mav.param_request_read_send(1, 1, b"", index)
    h.run_for(1.0)
    h.gcs.mark()
    got = h.gcs.received("PARAM_VALUE", since)
    assert [(m.param_id, m.param_index) for m in got] == [(SCHEMA[last].name, last)]
    assert status_texts(h, since) == []  # a request like any other, not an error
    assert not h.core.faulted


def test_unknown_parameter_names_get_no_answer(harness):
    h = harness
    since = h.gcs.mark()
    h.gcs.mav.param_request_read_send(1, 1, b"NOT_A_PARAM", -1)
    h.gcs.mav.param_set_send(1, 1, b"NOT_A_PARAM", 1.0, REAL32)
    h.run_for(1.0)
    h.gcs.mark()
    assert h.gcs.received("PARAM_VALUE", since) == []


def test_param_set_in_range_is_stored_and_announced(harness):
    reply = set_param(harness, "INP_EXPO", 0.25)
    assert reply is not None and abs(reply.param_value - 0.25) < 1e-7
    assert harness.core.params["INP_EXPO"] == 0.25
    assert harness.core.input.expo == 0.25  # and in force


def test_param_set_out_of_range_answers_the_unchanged_value_and_says_why(harness):
    h = harness
    since = h.gcs.mark()
    reply = set_param(h, "WHL_MAX_SPD", 500.0)
    assert reply is not None and reply.param_value == 1.0
    said = [t for t in status_texts(h, since) if "WHL_MAX_SPD" in t]  # in the same step
    assert len(said) == 1 and "outside" in said[0]
    assert h.core.params["WHL_MAX_SPD"] == 1.0


def test_param_set_non_finite_is_refused(harness):
    reply = set_param(harness, "INP_DEADBAND", float("nan"))
    assert reply is not None and abs(reply.param_value - 0.05) < 1e-7
    assert harness.core.params["INP_DEADBAND"] == 0.05


def test_a_changed_mixing_parameter_takes_effect_without_a_restart(harness):
    h = harness
    h.gcs.arm()
    assert set_param(h, "MOT_FL_REV", 1.0, INT32).param_value == 1.0
    t = h.now_s + h.dt_s  # the stick reaches the core in the next step
    h.gcs.sticks(1000)
    h.step()
    answer = [o for o in h.overrides_since(t) if o.time_s == t]
    assert len(answer) == 1 and answer[0].channels[:4] == [1000, 2000, 2000, 2000]


def test_an_identity_change_is_stored_and_flagged_for_a_restart(harness):
    h = harness
    since = h.gcs.mark()
    assert set_param(h, "SYSID_THISMAV", 7.0, INT32).param_value == 7.0
    assert h.core.params["SYSID_THISMAV"] == 7
    assert "SYSID_THISMAV takes effect after a restart" in status_texts(h, since)
    hb = h.gcs.wait("HEARTBEAT", timeout_s=1.1, since=h.gcs.mark())
    assert hb is not None and hb.get_srcSystem() == 1  # the link keeps its id (the harness's)


def test_after_an_identity_change_the_rover_still_answers_to_its_running_id(harness):
    h = harness
    assert set_param(h, "SYSID_THISMAV", 7.0, INT32).param_value == 7.0
    ack = h.gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)  # to system 1, as heartbeated
    assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED


def test_accepted_sets_are_saved_to_the_parameter_file(tmp_path):
    path = tmp_path / "robot.parm"
    path.write_text("INP_EXPO 0.1\n")
    h = lockstep(load(path), storage=FileStorage(path))
    assert set_param(h, "INP_EXPO", 0.3) is not None
    assert load(path)["INP_EXPO"] == 0.3  # written in the step the set arrived
    assert not list(tmp_path.glob("*.tmp*"))
    assert set_param(h, "INP_EXPO", 5.0).param_value == pytest.approx(0.3)  # refused
    assert load(path)["INP_EXPO"] == 0.3


def test_only_accepted_sets_are_saved_and_a_failed_save_is_reported():
    storage = MemoryStorage()
    h = lockstep(None, storage=storage)
    set_param(h, "INP_EXPO", 0.3)
    set_param(h, "INP_EXPO", 5.0)  # out of range: refused
    set_param(h, "INP_DEADBAND", float("nan"))  # refused
    h.gcs.mav.param_set_send(1, 1, b"NOT_A_PARAM", 1.0, REAL32)
    h.step()
    assert [saved["INP_EXPO"] for saved in storage.saved] == [0.3]
    storage.fail = True
    since = h.gcs.mark()
    reply = set_param(h, "INP_EXPO", 0.4)
    assert reply is not None and reply.param_value == pytest.approx(0.4)
    assert h.core.params["INP_EXPO"] == 0.4  # in force, only not kept
    assert "Param save failed: No space left on device" in status_texts(h, since)


@pytest.mark.parametrize(("system", "component"), [(9, 1), (1, 5)],
                         ids=["another system", "another component"])
def test_parameter_messages_for_another_system_or_component_are_ignored(
        harness, system: int, component: int) -> None:
    h = harness
    since = h.gcs.mark()
    h.gcs.mav.param_request_list_send(system, component)
    h.gcs.mav.param_request_read_send(system, component, b"INP_EXPO", -1)
    h.gcs.mav.param_set_send(system, component, b"INP_EXPO", 0.5, REAL32)
    h.run_for(1.0)
    h.gcs.mark()
    assert h.gcs.received("PARAM_VALUE", since) == []
    assert h.core.params["INP_EXPO"] == 0.0


def test_parameter_messages_to_every_component_are_answered(harness):
    """(target_component 0: all components, as MAVProxy's param fetch sends it.)"""
    h = harness
    since = h.gcs.mark()
    h.gcs.mav.param_request_read_send(1, 0, b"INP_EXPO", -1)
    h.gcs.mav.param_set_send(1, 0, b"INP_EXPO", 0.5, REAL32)
    got = answers(h, since)
    assert [(m.param_id, m.param_value) for m in got] == [("INP_EXPO", 0.0), ("INP_EXPO", 0.5)]


def test_a_parameter_set_from_another_ground_station_is_ignored():
    h = lockstep({"SYSID_MYGCS": 255})
    h.gcs.mav.srcSystem = 200
    since = h.gcs.mark()
    h.gcs.mav.param_set_send(1, 1, b"INP_EXPO", 0.5, REAL32)
    h.run_for(1.0)
    h.gcs.mark()
    assert h.gcs.received("PARAM_VALUE", since) == []
    assert h.core.params["INP_EXPO"] == 0.0


def test_a_geometry_change_is_stored_and_flagged_for_a_restart(harness):
    h = harness
    since = h.gcs.mark()
    assert set_param(h, "GEO_HALF_LEN", 0.2).param_value == pytest.approx(0.2)
    assert h.core.params["GEO_HALF_LEN"] == pytest.approx(0.2)
    assert "GEO_HALF_LEN takes effect after a restart" in status_texts(h, since)
