"""The parameter schema's defaults keep every cross-parameter rule, checked when the rules
module is imported (mecanum_mav.config.rules: "defaults that break a rule raise"): a rule the
defaults break is refused there, naming the first problem, rather than leave a store that
refuses its own defaults."""

from __future__ import annotations

import re

import pytest

from mecanum_mav.config.rules import (
    RULES,
    DistinctChannels,
    ModeNumbers,
    Rule,
    _check_defaults,
)


def test_the_shipped_rules_hold_for_the_defaults() -> None:
    _check_defaults(RULES)  # (as at import: nothing raised)


@pytest.mark.parametrize(("rule", "problem"), [
    (DistinctChannels(("MOT_FR_CH", "MOT_FL_CH", "RCMAP_STEER"), "one function each"),
     "MOT_FL_CH and RCMAP_STEER share RC channel 1; one function each"),
    (ModeNumbers(("MODE1", "MOT_FR_CH")),
     "MOT_FR_CH 2 is not a mode: one of 0 MANUAL, 4 HOLD, 10 AUTO, 15 GUIDED"),
], ids=["shared channel", "not a mode"])
def test_a_rule_the_defaults_break_is_refused_naming_the_first_problem(
        rule: Rule, problem: str) -> None:
    with pytest.raises(ValueError, match="^" + re.escape(
            f"parameter schema: defaults break a rule: {problem}") + "$"):
        _check_defaults([*RULES, rule])
