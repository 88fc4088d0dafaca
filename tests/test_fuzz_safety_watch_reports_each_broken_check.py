"""The fuzzing's checks can fail (mecanum_mav.sim.fuzz.SafetyWatch, used by the fuzz tests and
tools/fuzz.py): an override that is neither neutral nor the release, a gap between the rover's
HEARTBEATs of MAX_HEARTBEAT_GAP_S or more (up to the end of watching too), a STATUSTEXT saying
an exception forced neutral, and a non-finite ODOMETRY or LOCAL_POSITION_NED field (NaN
covariances excepted: the protocol's "unknown") are each reported in words, with the first
five examples; a watch that saw none reports nothing."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from mecanum_mav.config.params import Params
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.rcoverride import override_fields, release_fields
from mecanum_mav.sim.fuzz import MAX_HEARTBEAT_GAP_S, SafetyWatch

ROVER = mavlink.MAVLink(None, srcSystem=1, srcComponent=191)
NAN_FIRST = [math.nan] + [0.0] * 20
"""A covariance the protocol calls unknown."""


def from_rover(build: str, *args: Any) -> Any:
    """A message of the rover's as the ground station receives it (packed, parsed)."""
    data = getattr(ROVER, f"{build}_encode")(*args).pack(ROVER)
    return mavlink.MAVLink(None).decode(bytearray(data))


def heartbeat() -> Any:
    return from_rover("heartbeat", mavlink.MAV_TYPE_GROUND_ROVER,
                      mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4)


def odometry(x: float, covariance: list[float]) -> Any:
    return from_rover("odometry", 0, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_BODY_FRD,
                      x, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                      covariance, covariance, 0, mavlink.MAV_ESTIMATOR_TYPE_VIO, 100)


def local_position(x: float) -> Any:
    return from_rover("local_position_ned", 0, x, 0.0, 0.0, 0.0, 0.0, 0.0)


def statustext(text: str) -> Any:
    return from_rover("statustext", mavlink.MAV_SEVERITY_CRITICAL, text.encode())


def watch_that_saw(messages: list[tuple[float, Any]], overrides: Sequence[list[int]] = (),
                   end_s: float = 1.0) -> SafetyWatch:
    watch = SafetyWatch(Params(), 0.0)
    for fields in overrides:
        watch.on_override(fields)
    for t, msg in messages:
        watch.on_gcs_message(msg, t)
    watch.finish(end_s)
    return watch


def test_neutral_overrides_releases_steady_heartbeats_and_finite_telemetry_report_nothing():
    pwm = PwmMap.from_params(Params())
    watch = watch_that_saw(
        [(0.5, heartbeat()), (0.6, odometry(1.0, NAN_FIRST)), (0.7, local_position(1.0)),
         (0.8, statustext("Mode HOLD"))],
        overrides=[override_fields(pwm.channels, pwm.neutral()), release_fields(pwm.channels)])
    assert watch.problems() == []
    assert (watch.overrides, watch.heartbeats, watch.telemetry) == (2, 1, 2)


def test_an_override_neither_neutral_nor_the_release_is_reported_with_its_fields():
    pwm = PwmMap.from_params(Params())
    moving = override_fields(pwm.channels, [1600, 1500, 1500, 1500])
    watch = watch_that_saw([(0.5, heartbeat())], overrides=[moving])
    assert watch.problems() == ["1 of 1 overrides neither neutral nor released",
                                f"override {moving}"]


def test_a_heartbeat_gap_is_reported_between_beats_and_up_to_the_end_of_watching():
    gap = MAX_HEARTBEAT_GAP_S + 0.25
    between = watch_that_saw([(0.5, heartbeat()), (0.5 + gap, heartbeat())], end_s=0.5 + gap)
    assert between.problems() == [f"heartbeat gap {gap:.3f} s"]
    at_the_end = watch_that_saw([(0.5, heartbeat())], end_s=0.5 + gap)
    assert at_the_end.problems() == [f"heartbeat gap {gap:.3f} s"]
    just_under = watch_that_saw([(0.5, heartbeat())], end_s=0.5 + MAX_HEARTBEAT_GAP_S - 0.01)
    assert just_under.problems() == []


def test_a_statustext_saying_an_exception_forced_neutral_is_reported():
    text = "Error handling MANUAL_CONTROL: neutral"
    watch = watch_that_saw([(0.5, heartbeat()), (0.6, statustext(text))])
    assert watch.problems() == ["1 exceptions caught by the core", text]


def test_non_finite_telemetry_is_reported_but_an_unknown_covariance_is_not():
    bad = [odometry(math.nan, NAN_FIRST), local_position(math.inf)]
    watch = watch_that_saw([(0.5, heartbeat()), (0.6, odometry(0.0, NAN_FIRST)),
                            *((0.7, msg) for msg in bad)])
    problems = watch.problems()
    assert problems[0] == "2 of 3 ODOMETRY/LOCAL_POSITION_NED not finite"
    assert len(problems) == 3 and problems[1].startswith("ODOMETRY")
    assert problems[2].startswith("LOCAL_POSITION_NED")


def test_only_the_first_five_examples_are_kept():
    statustexts = [(0.5 + k / 100, statustext(f"Error computing output {k}")) for k in range(8)]
    watch = watch_that_saw([(0.5, heartbeat()), *statustexts])
    assert watch.problems() == ["8 exceptions caught by the core",
                                *(f"Error computing output {k}" for k in range(5))]
