"""The schema's data: which parameters wait for a restart, and the cross-parameter rules."""

from __future__ import annotations

from mecanum_mav.config.params import (
    RULES,
    SCHEMA,
    SPECS,
    DistinctChannels,
    OrderedTriple,
    consistency_problems,
)
from mecanum_mav.protocol.paramservice import RESTART_REQUIRED

DEFAULTS = {spec.name: spec.default for spec in SCHEMA}


def test_reboot_required_is_identity_geometry_and_the_simulator():
    expected = {"SYSID_THISMAV", "GEO_HALF_LEN", "GEO_HALF_WID", "WHL_STRAFE_EFF"} | {
        spec.name for spec in SCHEMA if spec.name.startswith("SIM_")}
    assert {spec.name for spec in SCHEMA if spec.reboot_required} == expected
    # 4 + the 13 SIM_ (issue 25 added the strafe efficiency, which the kinematics are built
    # from as from GEO_*, and 5 SIM_ for the MuJoCo chassis; issue 26 the simulated board's
    # heading bias and position rate, SIM_YAW_BIAS and SIM_POS_RATE)
    assert len(expected) == 17


def test_the_parameter_service_reads_reboot_required_from_the_schema():
    assert {spec.name for spec in SCHEMA if spec.reboot_required} == RESTART_REQUIRED
    assert isinstance(RESTART_REQUIRED, frozenset)


def test_rules_are_the_pwm_triples_and_the_channel_groups():
    triples = [r.prefix for r in RULES if isinstance(r, OrderedTriple)]
    groups = [(r.names, r.purpose) for r in RULES if isinstance(r, DistinctChannels)]
    assert triples == ["MOT_FL", "MOT_FR", "MOT_RL", "MOT_RR", "RCIN"]
    assert groups == [
        (("MOT_FL_CH", "MOT_FR_CH", "MOT_RL_CH", "MOT_RR_CH"), "one motor each"),
        (("RCMAP_STEER", "RCMAP_THROTTLE", "RCMAP_LATERAL"), "one stick axis each"),
    ]
    assert all(name in SPECS for rule in RULES for name in rule.names)


def test_defaults_keep_every_rule():
    assert consistency_problems(DEFAULTS) == []


def test_problems_come_in_rule_order_with_the_names_involved():
    values = {**DEFAULTS, "MOT_RR_MIN": 1600, "RCIN_MAX": 1500, "MOT_FL_CH": 4, "MOT_FR_CH": 4,
              "MOT_RL_CH": 4, "RCMAP_LATERAL": 1}
    assert consistency_problems(values) == [
        ("MOT_RR: need MIN < TRIM < MAX, got MOT_RR_MIN 1600, MOT_RR_TRIM 1500, "
         "MOT_RR_MAX 2000 us", ("MOT_RR_MIN", "MOT_RR_TRIM", "MOT_RR_MAX")),
        ("RCIN: need MIN < TRIM < MAX, got RCIN_MIN 1000, RCIN_TRIM 1500, RCIN_MAX 1500 us",
         ("RCIN_MIN", "RCIN_TRIM", "RCIN_MAX")),
        ("MOT_FL_CH, MOT_FR_CH, MOT_RL_CH and MOT_RR_CH share RC channel 4; one motor each",
         ("MOT_FL_CH", "MOT_FR_CH", "MOT_RL_CH", "MOT_RR_CH")),
        ("RCMAP_STEER and RCMAP_LATERAL share RC channel 1; one stick axis each",
         ("RCMAP_STEER", "RCMAP_LATERAL")),
    ]
