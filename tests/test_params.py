"""The parameter schema, the validated store and parameter files (mecanum_mav.config.params)."""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import pickle
import re
import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mecanum_mav.config.params import MODE_NUMBERS, RETIRED, _index
from mecanum_mav.io.paramfile import main as _main
from mecanum_mav.io.paramfile import save_keeping_layout
from mecanum_mav.io.storage import FileStorage
from mecanum_mav.params import (
    DEFAULTS_FILE_HEADER,
    SCHEMA,
    SPECS,
    WHEELS,
    ParamError,
    ParamFileError,
    Params,
    ParamSpec,
    float32_canonical,
    format_text,
    load,
    markdown_table,
    parse_assignment,
    parse_text,
    save,
)

PARAMS_DIR = Path(__file__).resolve().parent.parent / "params"
DEFAULT_FILE = PARAMS_DIR / "default.parm"
EXAMPLE_FILE = PARAMS_DIR / "example_400x300_97mm_wheels.parm"


def to_float32(x: float) -> float:
    """What a MAVLink float32 field carries for ``x``."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


def file_errors(text: str) -> list[str]:
    """The errors parse_text reports for ``text`` (which must be rejected)."""
    with pytest.raises(ParamFileError) as caught:
        parse_text(text, source="bad.parm")
    return caught.value.errors


# --- the schema ------------------------------------------------------------------------------


def test_the_schema_has_exactly_the_parameters_the_rest_of_the_code_reads():
    motor = [
        f"MOT_{w}_{f}"
        for w in ("FL", "FR", "RL", "RR")
        for f in ("CH", "MIN", "TRIM", "MAX", "REV")
    ]
    assert list(SPECS) == [
        "MIX_ALGO",
        "MIX_DESAT",
        "INP_DEADBAND",
        "INP_EXPO",
        "INP_CIRCLE",
        "GEO_HALF_LEN",
        "GEO_HALF_WID",
        "WHL_MAX_SPD",
        "WHL_STRAFE_EFF",
        "MOT_DZ",
        "MOT_DZ_TYPE",
        *motor,
        "SYSID_THISMAV", "SYSID_MYGCS", "FC_SYSID", "FC_COMPID", "FC_GCS_SYSID", "OUT_RATE",
        "FS_INPUT_TMO", "FS_GCS_TMO", "FS_GCS_ACTION", "FS_FC_TMO", "FS_THR_ENABLE",
        "FS_THR_VALUE", "FS_RC_ACTION", "ARMING_CHECK",
        "RCMAP_STEER", "RCMAP_THROTTLE", "RCMAP_LATERAL", "RCIN_MIN", "RCIN_TRIM", "RCIN_MAX",
        "RCIN_ENABLE", "RCIN_ARM_CH", "MODE_CH", "MODE1", "MODE2", "MODE3", "MODE4", "MODE5",
        "MODE6",
        "MAN_Z_SCALE", "CTL_RATE", "GUID_SPD_MAX", "GUID_ACC_MAX", "GUID_YAW_RATE",
        "GUID_POS_P", "GUID_YAW_P", "GUID_YAW_LEAD", "GUID_TIMEOUT", "WP_SPEED", "WP_ACCEL",
        "WP_RADIUS", "WP_POS_P", "WP_OVERSHOOT", "WP_YAW_BEHAVIOR", "ORIGIN_LAT", "ORIGIN_LON",
        "ODOM_SRC",
        "ODOM_CMD_TAU", "ODOM_CMD_GAIN",
        "ODOM_YAW_SRC", "ODOM_YAW_BIAS", "ODOM_POS_TAU",
        "TLM_POS_RATE",
        "TLM_EXT_RATE",
        "SIM_MOTOR_TAU", "SIM_SLIP", "SIM_RC_TMO", "SIM_GCS_SYSID", "SIM_RATE", "SIM_SEED",
        "SIM_FRICTION", "SIM_MASS", "SIM_WHL_RAD", "SIM_MOT_TORQUE", "SIM_ESC_DZ",
        "SIM_YAW_BIAS", "SIM_POS_RATE",
    ]
    assert [s.name for s in SCHEMA] == list(SPECS)
    assert SPECS["MIX_ALGO"].values == {
        0: "cartesian",
        1: "polar_2011",
        2: "max_speed_scaled",
        3: "holonomic_2010",
    }
    assert SPECS["MIX_DESAT"].values == {
        0: "proportional",
        1: "rotation_priority",
        2: "translation_priority",
    }
    assert [SPECS[f"MOT_{w}_CH"].default for w in WHEELS] == [1, 2, 3, 4]


@pytest.mark.parametrize("spec", SCHEMA, ids=lambda s: s.name)
def test_every_name_is_an_upper_case_group_name_of_at_most_16_characters(spec):
    assert len(spec.name) <= 16
    # (ArduPilot Rover's mode-switch names have no group: MODE1 .. MODE6)
    assert re.fullmatch(r"[A-Z][A-Z0-9]*(_[A-Z0-9]+)+|MODE[1-6]", spec.name)


@pytest.mark.parametrize("spec", SCHEMA, ids=lambda s: s.name)
def test_every_default_lies_in_its_range_and_has_its_kind(spec):
    assert spec.minimum <= spec.default <= spec.maximum
    for number in (spec.default, spec.minimum, spec.maximum):
        assert type(number) is spec.kind
    assert spec.description.endswith(".")
    assert spec.units in ("", "m", "m/s", "us", "s", "Hz", "m/s/s", "deg/s", "1/s", "deg",
                          "kg", "N.m")


@pytest.mark.parametrize("spec", [s for s in SCHEMA if s.values], ids=lambda s: s.name)
def test_every_enumeration_labels_its_whole_range_including_the_default(spec):
    assert spec.kind is int
    assert spec.default in spec.values
    assert sorted(spec.values) == list(range(spec.minimum, spec.maximum + 1))


@pytest.mark.parametrize("spec", SCHEMA, ids=lambda s: s.name)
def test_every_default_and_bound_survives_a_float32_round_trip(spec):
    for number in (spec.default, spec.minimum, spec.maximum):
        assert float32_canonical(to_float32(number)) == number


@pytest.mark.parametrize(
    ("changes", "complaint"),
    [
        ({"name": "MOT_FRONT_LEFT_TRIM"}, "at most 16"),
        ({"name": "mix_algo"}, "upper case"),
        ({"name": "MIXALGO"}, "GROUP_NAME"),
        ({"default": 9}, "within minimum"),
        ({"default": 1.0}, "of kind int"),
        ({"kind": str}, "int or float"),
        ({"description": "no full stop"}, "sentence"),
        ({"values": {0: "a", 1: "b"}}, "cover"),
    ],
)
def test_a_bad_schema_entry_raises_when_it_is_defined(changes, complaint):
    entry = {
        "name": "MIX_ALGO",
        "kind": int,
        "default": 0,
        "minimum": 0,
        "maximum": 3,
        "units": "",
        "description": "Fine.",
        "values": dict.fromkeys(range(4), "x"),
    }
    ParamSpec(**entry)
    with pytest.raises(ValueError, match=complaint):
        ParamSpec(**{**entry, **changes})


def test_a_float_bound_that_float32_cannot_carry_is_rejected():
    with pytest.raises(ValueError, match="float32"):
        ParamSpec(
            "GEO_X",
            float,
            default=0.5,
            minimum=0.1000000001,
            maximum=1.0,
            units="m",
            description="Too precise.",
        )


def test_a_schema_listing_a_name_twice_is_rejected():
    with pytest.raises(ValueError, match="MIX_ALGO is listed twice"):
        _index([SPECS["MIX_ALGO"], SPECS["INP_EXPO"], SPECS["MIX_ALGO"]])


def test_a_schema_entry_whose_group_has_no_title_is_rejected():
    untitled = dataclasses.replace(SPECS["MIX_ALGO"], name="ZZZ_ALGO")
    with pytest.raises(ValueError, match="ZZZ_ALGO: group ZZZ has no title"):
        _index([SPECS["MIX_ALGO"], untitled])


def test_parameter_specs_are_hashable_and_their_labels_read_only():
    spec = SPECS["MIX_ALGO"]
    assert hash(spec) == hash(SPECS["MIX_ALGO"])
    with pytest.raises(TypeError):
        spec.values[9] = "new"  # type: ignore[index]


# --- the store -------------------------------------------------------------------------------


def test_a_new_store_holds_the_schema_defaults_with_their_kinds():
    params = Params()
    assert params.as_dict() == {s.name: s.default for s in SCHEMA}
    assert params.names() == tuple(SPECS)
    assert type(params["MIX_ALGO"]) is int
    assert type(params["GEO_HALF_LEN"]) is float
    assert params.changed() == []
    assert params.check_consistency() == []
    assert len(params) == len(SCHEMA)
    assert "MIX_ALGO" in params
    assert "NOPE" not in params


def test_set_stores_ints_as_int_and_floats_float32_canonical():
    params = Params()
    assert params.set("MIX_ALGO", 2.0) == 2
    assert type(params["MIX_ALGO"]) is int
    assert params.set("GEO_HALF_LEN", 0.15000000000000002) == 0.15
    assert params.set("GUID_YAW_LEAD", to_float32(0.0485)) == 0.0485
    assert params.set("WHL_MAX_SPD", 1) == 1.0
    assert type(params["WHL_MAX_SPD"]) is float
    assert params.changed() == ["MIX_ALGO", "GUID_YAW_LEAD"]


@pytest.mark.parametrize(
    ("name", "value", "message"),
    [
        ("MIX_ALOG", 1, "unknown parameter 'MIX_ALOG'; did you mean MIX_ALGO?"),
        ("XYZZY", 1, "unknown parameter 'XYZZY'"),
        ("INP_EXPO", math.nan, "INP_EXPO: value must be finite, got nan"),
        ("INP_EXPO", -math.inf, "INP_EXPO: value must be finite, got -inf"),
        ("GEO_HALF_LEN", 9, "GEO_HALF_LEN: 9 m is outside the range 0.02 .. 5 m"),
        ("MOT_FL_TRIM", 700, "MOT_FL_TRIM: 700 us is outside the range 800 .. 2200 us"),
        ("INP_DEADBAND", 0.7, "INP_DEADBAND: 0.7 is outside the range 0 .. 0.5"),
        ("MIX_ALGO", 4, "MIX_ALGO: 4 is not one of 0 = cartesian, 1 = polar_2011, "),
        ("MOT_FL_CH", 1.5, "MOT_FL_CH: 1.5 is not an integer"),
        ("MOT_FL_CH", 10**400, "MOT_FL_CH: 1000"),
        ("INP_EXPO", "0.3", "INP_EXPO: expected a number, got '0.3'"),
        ("INP_CIRCLE", True, "INP_CIRCLE: expected a number, got True"),
        ("MOT_FL_CH", 2, "MOT_FL_CH = 2 rejected: MOT_FL_CH and MOT_FR_CH share RC channel 2"),
        ("MOT_RR_MIN", 1500, "MOT_RR_MIN = 1500 rejected: MOT_RR: need MIN < TRIM < MAX, got "),
        ("MOT_RR_MAX", 1400, "MOT_RR_MAX = 1400 rejected: MOT_RR: need MIN < TRIM < MAX"),
    ],
)
def test_set_rejects_a_bad_value_with_a_clear_message_and_keeps_the_old_one(name, value, message):
    params = Params()
    with pytest.raises(ParamError) as caught:
        params.set(name, value)
    assert str(caught.value).startswith(message)
    assert params == Params()


def test_a_suggestion_lists_up_to_three_close_names():
    with pytest.raises(ParamError, match=r"did you mean MOT_FL_\w+, MOT_FL_\w+ or MOT_FL_\w+\?"):
        Params().set("MOT_FL", 1)


def test_reading_an_unknown_name_raises_key_error_with_a_suggestion():
    with pytest.raises(KeyError, match="did you mean INP_EXPO"):
        Params()["INP_EXP"]
    assert Params().get("INP_EXP") is None


def test_set_accepts_a_change_that_stays_consistent_step_by_step():
    params = Params()
    params.set("MOT_FL_MAX", 1900)
    params.set("MOT_FL_TRIM", 1450)
    params.set("MOT_FL_MIN", 1100)
    params.set("MOT_FL_CH", 9)
    params.set("MOT_FR_CH", 1)
    assert params.check_consistency() == []
    assert [params[f"MOT_FL_{f}"] for f in ("MIN", "TRIM", "MAX", "CH")] == [1100, 1450, 1900, 9]


def test_update_applies_a_channel_swap_at_once_or_nothing():
    params = Params()
    params.update({"MOT_FR_CH": 3, "MOT_RL_CH": 2})
    assert (params["MOT_FR_CH"], params["MOT_RL_CH"]) == (3, 2)
    with pytest.raises(ParamError, match="share RC channel 3"):
        params.update({"INP_EXPO": 0.5, "MOT_FL_CH": 3})
    assert params["INP_EXPO"] == 0.0
    with pytest.raises(ParamError, match="INP_EXPO"):
        params.update({"MIX_ALGO": 1, "INP_EXPO": 2})
    assert params["MIX_ALGO"] == 0


def test_the_constructor_validates_the_values_it_is_given():
    assert Params({"MIX_ALGO": 3})["MIX_ALGO"] == 3
    with pytest.raises(ParamError, match="did you mean MIX_ALGO"):
        Params({"MIX_ALGOR": 3})
    with pytest.raises(ParamError, match="share RC channel 1"):
        Params({"MOT_RR_CH": 1})


def test_a_copy_is_independent_of_its_original():
    params = Params({"INP_EXPO": 0.25})
    clone = params.copy()
    clone.set("INP_EXPO", 0.5)
    assert params["INP_EXPO"] == 0.25
    assert clone == Params({"INP_EXPO": 0.5})
    assert repr(clone) == "Params({'INP_EXPO': 0.5})"


# --- parameter files -------------------------------------------------------------------------


def test_the_committed_default_file_is_generated_from_the_schema_defaults():
    expected = format_text(Params(), header=DEFAULTS_FILE_HEADER)
    assert DEFAULT_FILE.read_text(encoding="utf-8") == expected, (
        "params/default.parm is stale: python -m mecanum_mav.params "
        "--write-defaults params/default.parm"
    )
    assert load(DEFAULT_FILE) == Params()


def test_the_example_robot_file_loads_and_lists_only_what_differs():
    params = load(EXAMPLE_FILE)
    listed = [
        line.split()[0]
        for line in EXAMPLE_FILE.read_text().splitlines()
        if line.strip() and not line.startswith("#")
    ]
    assert sorted(params.changed()) == sorted(listed)
    assert (params["GEO_HALF_LEN"], params["GEO_HALF_WID"]) == (0.2, 0.15)
    assert params["WHL_MAX_SPD"] == 1.2
    assert (params["MOT_FR_REV"], params["MOT_RR_REV"]) == (1, 1)
    assert [params[f"MOT_{w}_CH"] for w in WHEELS] == [1, 3, 2, 4]


def test_a_file_with_several_mistakes_reports_every_one_with_file_and_line():
    text = "\n".join(
        [
            "# a file with a mistake on almost every line",  # 1
            "MIX_ALOG 1",  # 2
            "INP_DEADBAND 0.7",  # 3
            "INP_EXPO abc",  # 4
            "GEO_HALF_LEN nan",  # 5
            "GEO_HALF_WID inf",  # 6
            "MOT_FL_CH 1.5",  # 7
            "WHL_MAX_SPD",  # 8
            "MIX_ALGO 1",  # 9
            "MIX_ALGO 2",  # 10
            "MIX_DESAT 1 2",  # 11
            "WP_RADIUS 1,5",  # 12
            "INP_CIRCLE 0x1",  # 13
            "MIX_DESAT 7",  # 14
        ]
    )
    assert file_errors(text) == [
        "bad.parm:2: unknown parameter 'MIX_ALOG'; did you mean MIX_ALGO?",
        "bad.parm:3: INP_DEADBAND: 0.7 is outside the range 0 .. 0.5",
        "bad.parm:4: INP_EXPO: 'abc' is not a number",
        "bad.parm:5: GEO_HALF_LEN: value must be finite, got nan",
        "bad.parm:6: GEO_HALF_WID: value must be finite, got inf",
        "bad.parm:7: MOT_FL_CH: 1.5 is not an integer; this parameter is an int",
        "bad.parm:8: WHL_MAX_SPD: missing value",
        "bad.parm:10: MIX_ALGO: duplicate, already set on line 9",
        "bad.parm:11: MIX_DESAT: unexpected text after the value: ['2']",
        "bad.parm:12: WP_RADIUS: unexpected text after the value: ['5']",
        "bad.parm:13: INP_CIRCLE: '0x1' is not a number",
        "bad.parm:14: MIX_DESAT: duplicate, already set on line 11",
        "bad.parm:14: MIX_DESAT: 7 is not one of 0 = proportional, 1 = rotation_priority, "
        "2 = translation_priority",
    ]


def test_a_rejected_file_applies_nothing(tmp_path):
    path = tmp_path / "robot.parm"
    path.write_text("INP_EXPO 0.5\nMIX_ALGO 1\nGEO_HALF_LEN 99\n")
    base = Params({"INP_EXPO": 0.25})
    with pytest.raises(ParamFileError) as caught:
        load(path, base=base)
    assert caught.value.errors == [f"{path}:3: GEO_HALF_LEN: 99 m is outside the range 0.02 .. 5 m"]
    assert base == Params({"INP_EXPO": 0.25})


def test_the_file_error_message_lists_every_error_and_survives_pickling():
    error = ParamFileError(["a.parm:1: one", "a.parm:2: two"])
    assert str(error) == (
        "parameter file rejected, nothing applied (2 errors):\n  a.parm:1: one\n  a.parm:2: two"
    )
    assert pickle.loads(pickle.dumps(error)).errors == error.errors


def test_a_file_applies_on_top_of_a_base_without_changing_it():
    base = Params({"INP_EXPO": 0.25, "MIX_ALGO": 2})
    params = parse_text("MIX_ALGO 1\n", base=base)
    assert (params["INP_EXPO"], params["MIX_ALGO"]) == (0.25, 1)
    assert base["MIX_ALGO"] == 2
    assert parse_text("") == Params()


def test_a_file_loaded_on_top_of_a_base_keeps_what_it_does_not_set(tmp_path):
    """(``mecanum-mav params --params FILE``: the file on top of the rover's parameters.)"""
    path = tmp_path / "more.parm"
    path.write_text("MIX_ALGO 1\n", encoding="utf-8")
    params = load(path, base=Params({"INP_EXPO": 0.25, "MIX_ALGO": 2}))
    assert (params["INP_EXPO"], params["MIX_ALGO"]) == (0.25, 1)


def test_text_given_without_a_source_names_its_lines_as_string():
    with pytest.raises(ParamFileError) as caught:
        parse_text("MIX_ALGO 1\nNO_SUCH_PARAM 1\n")
    assert caught.value.errors[0].startswith("<string>:2: ")


def test_commas_whitespace_trailing_comments_and_number_styles_are_accepted():
    text = (
        "\ufeff# Mission Planner style\r\n"
        "MIX_ALGO,1\r\n"
        "MIX_DESAT , 2   # translation priority\r\n"
        "\tINP_EXPO\t\t.25\r\n"
        "\r\n"
        "MOT_FL_MIN 1e3  # = 1000\n"
        "MOT_FL_TRIM 1.5E3\n"
        "MOT_FL_MAX +2000.0\n"
        "GEO_HALF_LEN 2.5e-1\n"
        "   # indented comment\n"
    )
    params = parse_text(text.removeprefix("\ufeff"))
    assert params.as_dict() == {
        **Params().as_dict(),
        "MIX_ALGO": 1,
        "MIX_DESAT": 2,
        "INP_EXPO": 0.25,
        "GEO_HALF_LEN": 0.25,
    }


def test_a_byte_order_mark_is_ignored_when_loading(tmp_path):
    path = tmp_path / "windows.parm"
    path.write_bytes(b"\xef\xbb\xbfMIX_ALGO,3\r\n")
    assert load(path)["MIX_ALGO"] == 3


def test_the_order_of_lines_in_a_file_does_not_matter():
    params = parse_text(
        "MOT_RL_MIN 1600\nMOT_RL_MAX 1900\nMOT_RL_TRIM 1700\nMOT_FL_CH 2\nMOT_FR_CH 1\n"
    )
    assert [params[f"MOT_RL_{f}"] for f in ("MIN", "TRIM", "MAX")] == [1600, 1700, 1900]
    assert (params["MOT_FL_CH"], params["MOT_FR_CH"]) == (2, 1)


def test_min_trim_max_order_is_checked_and_cited_at_the_last_involved_line():
    errors = file_errors("MOT_RL_TRIM 1000\nINP_EXPO 0.5\nMOT_RL_MIN 1200\n")
    assert errors == [
        "bad.parm:3: MOT_RL: need MIN < TRIM < MAX, got MOT_RL_MIN 1200, MOT_RL_TRIM 1000, "
        "MOT_RL_MAX 2000 us"
    ]
    assert file_errors("MOT_FR_MAX 1500\n") == [
        "bad.parm:1: MOT_FR: need MIN < TRIM < MAX, got MOT_FR_MIN 1000, MOT_FR_TRIM 1500, "
        "MOT_FR_MAX 1500 us"
    ]


def test_duplicate_channels_are_caught():
    assert file_errors("MOT_RR_CH 1\n# comment\nMOT_FR_CH 1\n") == [
        "bad.parm:3: MOT_FL_CH, MOT_FR_CH and MOT_RR_CH share RC channel 1; one motor each"
    ]


# --- saving ----------------------------------------------------------------------------------


def test_save_writes_every_parameter_as_name_value_lines_mavproxy_can_read(tmp_path):
    path = tmp_path / "robot.parm"
    save(Params({"WP_RADIUS": 0.0485, "MOT_FR_REV": 1}), path, header="My robot\nline two")
    lines = path.read_text().splitlines()
    assert lines[:2] == ["# My robot", "# line two"]
    data = [line.split() for line in lines if line and not line.startswith("#")]
    assert [name for name, _ in data] == list(SPECS)
    assert all(len(fields) == 2 for fields in data)  # no trailing comments: MAVProxy rejects them
    values = dict(data)
    assert values["WP_RADIUS"] == "0.0485"
    assert values["MOT_FR_REV"] == "1"
    assert values["WHL_MAX_SPD"] == "1.0"
    assert values["MOT_FL_TRIM"] == "1500"


def test_save_gives_a_new_file_0644_and_keeps_an_existing_files_mode(tmp_path):
    path = tmp_path / "robot.parm"
    save(Params(), path)
    assert path.stat().st_mode & 0o777 == 0o644
    path.chmod(0o600)
    save(Params(), path)
    assert path.stat().st_mode & 0o777 == 0o600


@pytest.mark.parametrize("failing", ["fsync", "replace"])
def test_a_save_that_fails_midway_leaves_the_original_file_and_no_temp_file(
    tmp_path, monkeypatch, failing
):
    path = tmp_path / "robot.parm"
    path.write_text("MIX_ALGO 1\n")

    def fail(*args, **kwargs):
        raise OSError(f"simulated {failing} failure")

    if failing == "fsync":
        monkeypatch.setattr(os, "fsync", fail)
    else:
        monkeypatch.setattr(Path, "replace", fail)
    with pytest.raises(OSError, match="simulated"):
        save(Params({"MIX_ALGO": 3}), path)
    assert path.read_text() == "MIX_ALGO 1\n"
    assert list(tmp_path.iterdir()) == [path]


@st.composite
def valid_params(draw: st.DrawFn) -> Params:
    """Any consistent store: every value within its range, the motor rules kept."""
    values: dict[str, float] = {}
    for spec in SCHEMA:
        if spec.kind is int:
            values[spec.name] = draw(st.integers(spec.minimum, spec.maximum))
        else:
            values[spec.name] = draw(st.floats(spec.minimum, spec.maximum))
    # wheels, sticks, mode and arm switch on channels of their own (a switch may be off: 0)
    channels = draw(st.lists(st.integers(1, 16), min_size=9, max_size=9, unique=True))
    values["MODE_CH"] = channels[7] if draw(st.booleans()) else 0
    values["RCIN_ARM_CH"] = channels[8] if draw(st.booleans()) else 0
    for i in range(1, 7):
        values[f"MODE{i}"] = draw(st.sampled_from(sorted(MODE_NUMBERS)))
    for prefix in (*(f"MOT_{w}" for w in WHEELS), "RCIN"):
        pwm = sorted(draw(st.lists(st.integers(800, 2200), min_size=3, max_size=3, unique=True)))
        values.update(
            {f"{prefix}_{f}": v for f, v in zip(("MIN", "TRIM", "MAX"), pwm, strict=True)}
        )
    for wheel, channel in zip(WHEELS, channels[:4], strict=True):
        values[f"MOT_{wheel}_CH"] = channel
    for name, channel in zip(("RCMAP_STEER", "RCMAP_THROTTLE", "RCMAP_LATERAL"),
                             channels[4:7], strict=True):
        values[name] = channel
    return Params(values)


@settings(max_examples=60, deadline=None)
@given(params=valid_params())
def test_save_then_load_round_trips_every_value_exactly(tmp_path_factory, params):
    path = tmp_path_factory.mktemp("round_trip") / "robot.parm"
    save(params, path)
    loaded = load(path)
    assert loaded.as_dict() == params.as_dict()
    assert all(type(loaded[n]) is type(params[n]) for n in params)


@given(params=valid_params())
def test_every_stored_value_survives_the_float32_trip_of_the_mavlink_parameter_protocol(params):
    for name, value in params.items():
        received = Params(params).set(name, to_float32(value))
        assert received == value
        assert type(received) is type(value)


@given(st.floats(-1e38, 1e38) | st.floats(0.005, 20.0))
def test_float32_canonical_is_the_shortest_decimal_of_the_float32(x):
    canonical = float32_canonical(x)
    assert to_float32(canonical) == to_float32(x)
    assert float32_canonical(canonical) == canonical
    assert canonical == float(str(np.float32(x)))  # numpy's shortest float32 repr (Dragon4)


# --- command line and README -----------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("MIX_ALGO=1", ("MIX_ALGO", 1)),
        (" INP_EXPO = 0.3 ", ("INP_EXPO", 0.3)),
        ("MOT_FL_MAX=2e3", ("MOT_FL_MAX", 2000)),
        ("GEO_HALF_LEN=0.15000000000000002", ("GEO_HALF_LEN", 0.15)),
    ],
)
def test_parse_assignment_returns_the_name_and_the_validated_value(text, expected):
    assert parse_assignment(text) == expected
    assert type(parse_assignment(text)[1]) is SPECS[expected[0]].kind


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("MIX_ALGO", "expected NAME=VALUE, got 'MIX_ALGO'"),
        ("=1", "expected NAME=VALUE, got '=1'"),
        ("MIX_ALGO=", "MIX_ALGO: missing value"),
        ("MIX_ALOG=1", "unknown parameter 'MIX_ALOG'; did you mean MIX_ALGO?"),
        ("INP_EXPO=fast", "INP_EXPO: 'fast' is not a number"),
        ("INP_EXPO=nan", "INP_EXPO: value must be finite, got nan"),
        ("MIX_ALGO=1.5", "MIX_ALGO: 1.5 is not an integer"),
        ("WHL_MAX_SPD=30", "WHL_MAX_SPD: 30 m/s is outside the range 0.01 .. 20 m/s"),
        ("WHL_MAX_SPD=1e39", "WHL_MAX_SPD: 1e+39 m/s is outside the range 0.01 .. 20 m/s"),
        ("WHL_MAX_SPD=20.0000001", None),
    ],
)
def test_parse_assignment_rejects_a_bad_assignment_clearly(text, message):
    if message is None:  # within float32 rounding of a bound: that bound
        assert parse_assignment(text) == ("WHL_MAX_SPD", 20.0)
        return
    with pytest.raises(ParamError) as caught:
        parse_assignment(text)
    assert str(caught.value).startswith(message)


def test_the_markdown_table_has_a_row_per_parameter_with_enumerations_spelled_out():
    lines = markdown_table().splitlines()
    assert lines[0] == "| Name | Default | Range / values | Units | Description |"
    rows = {line.split(" | ")[0].strip("| `"): line for line in lines[2:]}
    assert list(rows) == list(SPECS)
    assert rows["MIX_ALGO"].startswith(
        "| `MIX_ALGO` | 0 (cartesian) | 0 = cartesian, 1 = polar_2011, 2 = max_speed_scaled, "
        "3 = holonomic_2010 |  | "
    )
    assert rows["GEO_HALF_LEN"].startswith("| `GEO_HALF_LEN` | 0.15 | 0.02 .. 5 | m | ")
    assert all(line.count(" | ") == 4 for line in lines)


def test_the_module_command_prints_the_table_and_writes_the_defaults_file(tmp_path, capsys):
    assert _main(["--table", "--write-defaults", str(tmp_path / "d.parm")]) == 0
    assert capsys.readouterr().out == markdown_table()
    assert (tmp_path / "d.parm").read_text() == DEFAULT_FILE.read_text()


def test_ground_station_stick_channels_must_be_distinct_and_range_ordered():
    errors = file_errors("RCMAP_LATERAL 3\nRCIN_TRIM 2100\n")
    assert any("RCMAP_THROTTLE and RCMAP_LATERAL share RC channel 3" in e for e in errors)
    assert any("RCIN: need MIN < TRIM < MAX" in e for e in errors)


def test_a_retired_parameter_in_a_file_is_ignored_with_a_warning_naming_its_line(caplog):
    with caplog.at_level("WARNING"):
        params = parse_text("GEO_HALF_LEN 0.2\nGEO_WHEEL_RAD 0.0485\nINP_EXPO 0.3\n",
                            source="old.parm")
    assert params["GEO_HALF_LEN"] == 0.2 and "GEO_WHEEL_RAD" not in params
    assert params["INP_EXPO"] == 0.3  # the lines after it still apply
    assert caplog.messages == [f"old.parm:2: GEO_WHEEL_RAD is no longer a parameter "
                               f"({RETIRED['GEO_WHEEL_RAD']}); line ignored"]


def test_wheel_channels_17_and_18_which_ardupilot_never_reads_are_refused():
    with pytest.raises(ParamError, match=r"MOT_FL_CH: 17 is outside the range 1 \.\. 16"):
        Params().set("MOT_FL_CH", 17)


# --------------------------------------------------------------------------- saving in place

HAND_WRITTEN = """# my rover: measured 2026-11-20
GEO_HALF_LEN   0.2     # wheelbase 400 mm
MIX_ALGO,1
# motors
MOT_FR_REV 1
"""


def test_saving_a_changed_parameter_changes_only_its_line_and_keeps_the_old_file(tmp_path):
    path = tmp_path / "rover.parm"
    path.write_text(HAND_WRITTEN)
    params = load(path)
    params.set("GEO_HALF_LEN", 0.25)
    save_keeping_layout(params, path)
    old, new = HAND_WRITTEN.splitlines(), path.read_text().splitlines()
    changed = [(a, b) for a, b in zip(old, new, strict=True) if a != b]
    assert changed == [("GEO_HALF_LEN   0.2     # wheelbase 400 mm",
                        "GEO_HALF_LEN   0.25     # wheelbase 400 mm")]
    assert (tmp_path / "rover.parm.bak").read_text() == HAND_WRITTEN
    assert load(path).as_dict() == params.as_dict()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rover.parm", "rover.parm.bak"]


def test_a_parameter_that_was_not_in_the_file_is_appended(tmp_path):
    path = tmp_path / "rover.parm"
    path.write_text(HAND_WRITTEN)
    params = load(path)
    params.set("INP_EXPO", 0.3)
    save_keeping_layout(params, path)
    assert path.read_text() == HAND_WRITTEN + "INP_EXPO 0.3\n"
    assert load(path)["INP_EXPO"] == 0.3


def test_saving_unchanged_parameters_writes_nothing(tmp_path):
    path = tmp_path / "rover.parm"
    path.write_text(HAND_WRITTEN)
    save_keeping_layout(load(path), path)
    assert path.read_text() == HAND_WRITTEN and not (tmp_path / "rover.parm.bak").exists()


def test_opening_the_storage_removes_temporaries_a_killed_save_left_and_nothing_else(
        tmp_path, caplog):
    path = tmp_path / "rover.parm"
    path.write_text("OUT_RATE 25\n")
    left = [tmp_path / ".rover.parm.k3j9x_2a.tmp", tmp_path / ".rover.parm.bak.q0w9e8r7.tmp",
            tmp_path / ".rover.waypoints.a1b2c3d4.tmp"]
    kept = [tmp_path / ".other.parm.a1b2c3d4.tmp", tmp_path / "rover.parm.tmp", path]
    for stray in left + kept[:2]:
        stray.write_text("half a fi")
    with caplog.at_level(logging.WARNING):
        FileStorage(path)
    assert sorted(tmp_path.iterdir()) == sorted(kept)
    assert sum("cut short" in r.getMessage() for r in caplog.records) == len(left)
