"""A parameter's schema entry (config/spec.py) is checked when it is defined, and each
problem is said exactly, for the rover builder who adds one: the name (GROUP_NAME, at most
the 16 characters of MAVLink's param_id), the kind, the range, float32 exactness (the
parameter protocol carries float32), one sentence, enumerations. Also the messages that
name a parameter or a number for the user."""

from __future__ import annotations

import re

import pytest

from mecanum_mav.config.params import ParamError, parse_assignment, unknown_name
from mecanum_mav.config.rules import DistinctChannels, _check_rules
from mecanum_mav.config.spec import NAME_MAX_LEN, ParamSpec, show_number

GOOD = {"name": "MIX_ALGO", "kind": int, "default": 0, "minimum": 0, "maximum": 3,
        "units": "", "description": "Fine.", "values": dict.fromkeys(range(4), "x")}


def refused(**changes: object) -> str:
    """The message a schema entry with ``changes`` is refused with."""
    with pytest.raises(ValueError) as caught:
        ParamSpec(**{**GOOD, **changes})  # type: ignore[arg-type]
    return str(caught.value)


@pytest.mark.parametrize(("changes", "problem"), [
    ({"kind": str}, "kind must be int or float"),
    ({"default": 4}, "default must lie within minimum .. maximum"),
    ({"kind": float, "default": 0.1000000001, "minimum": 0.0, "maximum": 1.0, "values": None},
     "default, minimum and maximum must be exact as float32 (float32_canonical)"),
    ({"minimum": -(2 ** 24) - 1, "values": None},
     "int range must be exact as float32 (within +-2**24)"),
    ({"description": "Two sentences. Without a stop"},
     "description must be one sentence ending with a full stop"),
    ({"kind": float, "default": 0.0, "minimum": 0.0, "maximum": 3.0},
     "an enumeration must be of kind int"),
    ({"values": {0: "a", 1: "b", 2: "c"}},
     "enumeration labels must cover minimum .. maximum exactly"),
])
def test_each_problem_of_a_schema_entry_is_said_with_the_parameters_name(changes, problem):
    name = changes.get("name", GOOD["name"])
    assert refused(**changes) == f"parameter schema: {name}: {problem}"


def test_a_name_of_16_characters_is_the_longest_a_parameter_can_have():
    assert NAME_MAX_LEN == 16  # MAVLink's param_id
    ParamSpec(**{**GOOD, "name": "MIX_" + "A" * 12})  # type: ignore[arg-type]
    assert refused(name="MIX_" + "A" * 13) == (
        "parameter schema: MIX_AAAAAAAAAAAAA: name must be GROUP_NAME in upper case, at most "
        "16 characters")


def test_an_int_range_reaching_2_to_the_24_exactly_is_carried_by_float32():
    ParamSpec(**{**GOOD, "minimum": -(2 ** 24), "maximum": 2 ** 24,  # type: ignore[arg-type]
                 "values": None})
    assert "within +-2**24" in refused(maximum=2 ** 24 + 1, values=None)


def test_an_enumeration_from_1_is_labelled_1_to_its_maximum():
    spec = ParamSpec(**{**GOOD, "default": 1, "minimum": 1,  # type: ignore[arg-type]
                        "values": {1: "a", 2: "b", 3: "c"}})
    assert dict(spec.values or {}) == {1: "a", 2: "b", 3: "c"}
    with pytest.raises(TypeError):
        spec.values[4] = "d"  # type: ignore[index]  # labels are read-only once defined


@pytest.mark.parametrize(("number", "shown"), [
    (3.0, "3"), (-2.0, "-2"), (-0.0, "0"), (7, "7"), (2.5, "2.5"),
    (999_999_999_999_999.0, "999999999999999"), (1e15, "1000000000000000"),
    (2.0 ** 53, "9007199254740992"), (1e16, "1e+16"), (1.5e300, "1.5e+300"),
    (float("inf"), "inf"), (float("nan"), "nan")])
def test_numbers_in_messages_are_written_without_decimals_when_they_are_whole(number, shown):
    assert show_number(number) == shown


def test_an_unknown_name_far_from_every_parameter_gets_no_guess():
    assert unknown_name("QQQQ") == "unknown parameter 'QQQQ'"


def test_an_assignment_splits_at_its_first_equals_sign():
    with pytest.raises(ParamError) as caught:
        parse_assignment("MIX_ALGO=1=2")
    assert "unknown parameter" not in str(caught.value) and "MIX_ALGO" in str(caught.value)


def test_a_rule_reading_a_parameter_the_schema_lacks_is_refused_naming_it():
    _check_rules([DistinctChannels(("MOT_FL_CH", "MOT_FL_CH"), "one motor each")])
    with pytest.raises(ValueError, match=re.escape(
            "parameter schema: a rule reads unknown parameter MOT_XX_CH")):
        _check_rules([DistinctChannels(("MOT_FL_CH", "MOT_XX_CH"), "one motor each")])
