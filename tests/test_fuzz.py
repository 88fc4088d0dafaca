"""Bad input from either link never crashes the companion and never moves a wheel (issue 11.1).

The short CI version of ``tools/fuzz.py``: the same generator
(:class:`mecanum_mav.sim.fuzz.DatagramFuzzer`) with a fixed seed and the same checks
(:class:`mecanum_mav.sim.fuzz.SafetyWatch`). In the lockstep harness (virtual time, exact) the
datagrams go straight into the core's parsers as raw bytes: 30,000 on the ground-station link
while disarmed, 10,000 on the flight-controller link while armed in HOLD, ten per 2 ms step
(5,000 a second of virtual time); then 10,000 shaped like the pilot's stick at the stick lane
while the pilot drives in MANUAL, one per step. Then one short run of the tool itself against
the real process.
"""

from __future__ import annotations

import logging
import math
import re
import subprocess
import sys
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from conftest import lockstep

from mecanum_mav.control.refusals import Refusal
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim import Lockstep
from mecanum_mav.sim.fuzz import MESSAGE_IDS, DatagramFuzzer, SafetyWatch

SEED = 20240611
GCS_COUNT = 30_000
FC_COUNT = 10_000
LANE_COUNT = 10_000
PER_STEP = 10
TOOL = Path(__file__).resolve().parent.parent / "tools" / "fuzz.py"


def fuzz(h: Lockstep, make: Callable[[], bytes], count: int, *, from_fc: bool) -> SafetyWatch:
    """``count`` datagrams from ``make`` into the core, watched; the watch."""
    watch = SafetyWatch(h.params, h.now_s)
    overrides, messages = len(h.overrides), len(h.gcs.messages)
    sent = 0
    while sent < count:
        for _ in range(min(PER_STEP, count - sent)):
            h.inject(make(), from_fc=from_fc)
        sent += PER_STEP
        h.step()
    h.run_for(1.0)  # what it caused comes out; the heartbeat goes on
    for seen in h.overrides[overrides:]:
        watch.on_override(seen.channels)
    for msg, t in zip(h.gcs.messages[messages:], h.gcs.arrived_s[messages:], strict=True):
        watch.on_gcs_message(msg, t)
    watch.finish(h.now_s)
    return watch


def drives_after(h: Lockstep) -> bool:
    """A normal disarm, MANUAL, arm, and a stick forward: the wheels move."""
    disarm = h.gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    assert disarm is not None and disarm.result == mavlink.MAV_RESULT_ACCEPTED
    assert h.gcs.set_mode(Mode.MANUAL) == mavlink.MAV_RESULT_ACCEPTED
    h.gcs.sticks(0, 0, 0)
    h.gcs.arm()
    start = h.now_s
    stop = h.every(0.05, lambda now: h.gcs.sticks(500, 0, 0))
    h.run_for(0.5)
    stop()
    trim = h.core.pwm.neutral()
    return any(tuple(o.channels[c - 1] for c in h.core.pwm.channels) != trim
               for o in h.overrides_since(start))


@pytest.fixture
def errors(caplog: pytest.LogCaptureFixture) -> Callable[[], list[str]]:
    """Exceptions the core caught and logged (it would have said 'Error handling ...')."""
    caplog.set_level(logging.ERROR)
    return lambda: [r.getMessage() for r in caplog.records if r.levelno >= logging.ERROR]


def test_the_generator_covers_every_message_id_of_the_dialect_and_repeats_for_a_seed() -> None:
    a, b = DatagramFuzzer(SEED), DatagramFuzzer(SEED)
    frames = [a.random_frame() for _ in MESSAGE_IDS]
    assert frames == [b.random_frame() for _ in MESSAGE_IDS]
    ids = {f[7] | f[8] << 8 | f[9] << 16 for f in frames}
    assert ids == set(MESSAGE_IDS) and len(ids) > 250
    assert DatagramFuzzer(SEED + 1).random_frame() != frames[0]


def decoded(datagram: bytes) -> Any:
    """The one message in ``datagram``, as pymavlink decodes it."""
    (msg,) = mavlink.MAVLink(None).parse_buffer(datagram) or []
    return msg


def test_fc_sensor_datagrams_are_wheel_distance_or_attitude_from_the_flight_controller() -> None:
    fuzzer = DatagramFuzzer(SEED, fc_sysid=7, fc_compid=9)
    msgs = [decoded(fuzzer.fc_sensors()) for _ in range(1000)]
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in msgs} == {(7, 9)}
    wheels = [m for m in msgs if m.get_type() == "WHEEL_DISTANCE"]
    assert {m.get_type() for m in msgs} == {"WHEEL_DISTANCE", "ATTITUDE"}
    assert 400 < len(wheels) < 600  # half each
    counts = Counter(m.count for m in wheels)
    assert set(counts) == {0, 1, 3, 4, 16, 255}
    assert counts.most_common(1)[0][0] == 4  # the four wheels mostly
    distances = [d for m in wheels for d in m.distance]
    # hostile doubles (those of a double only too: 1e308, 5e-324) among plausible distances
    assert {1e308, -1e308, 5e-324, math.inf} <= set(distances)
    assert any(math.isnan(d) for d in distances)
    assert any(0.001 < abs(d) <= 1000.0 and d not in (1.0, -1.0) for d in distances)


@pytest.mark.parametrize("fc_sysid", [1, 255])
def test_foreign_heartbeats_come_from_any_system_but_the_flight_controller(fc_sysid: int
                                                                           ) -> None:
    fuzzer = DatagramFuzzer(SEED, fc_sysid=fc_sysid)
    msgs = [decoded(fuzzer.fc_foreign_heartbeat()) for _ in range(3000)]
    assert {m.get_type() for m in msgs} == {"HEARTBEAT"}
    sysids = {m.get_srcSystem() for m in msgs}
    assert fc_sysid not in sysids
    assert len(sysids) > 200  # (of the 255 others)


def test_fuzzed_ground_station_datagrams_while_disarmed_never_move_a_wheel(
        errors: Callable[[], list[str]]) -> None:
    h = Lockstep()
    h.run_for(0.5)
    fuzzer = DatagramFuzzer(SEED, rover_sysid=1)
    watch = fuzz(h, fuzzer.gcs_datagram, GCS_COUNT, from_fc=False)
    assert watch.problems() == []
    assert watch.overrides > 100 and watch.heartbeats >= 6 and watch.telemetry > 100
    assert watch.worst_gap_s < 1.5
    assert not h.core.vehicle.armed
    assert errors() == []
    assert set(fuzzer.counts) == {"random_bytes", "random_frame", "manual_control",
                                  "hostile_values", "truncated", "mavlink1", "signed_garbage",
                                  "several"}
    refused = h.core.refusals.counts
    assert all(refused[kind] > 0 for kind in (Refusal.STICK, Refusal.SETPOINT, Refusal.PARAM,
                                              Refusal.COMMAND, Refusal.MISSION))
    assert h.params.changed() == []  # no NaN, inf or huge value was taken
    assert drives_after(h)


def test_fuzzed_flight_controller_datagrams_while_armed_in_hold_never_move_a_wheel(
        errors: Callable[[], list[str]]) -> None:
    h = Lockstep()
    h.run_for(0.5)
    assert h.gcs.set_mode(Mode.HOLD) == mavlink.MAV_RESULT_ACCEPTED
    h.gcs.arm()
    fuzzer = DatagramFuzzer(SEED, fc_sysid=int(h.params["FC_SYSID"]),
                            fc_compid=int(h.params["FC_COMPID"]))
    watch = fuzz(h, fuzzer.fc_datagram, FC_COUNT, from_fc=True)
    assert watch.problems() == []
    assert watch.overrides > 20 and watch.heartbeats >= 2 and watch.telemetry > 50
    assert h.core.vehicle.armed and h.core.vehicle.mode is Mode.HOLD
    assert errors() == []
    assert h.core.refusals.counts[Refusal.SENSOR] > 0
    pose = h.core.estimator.pose
    assert all(math.isfinite(v) and abs(v) < 1e6 for v in pose)
    assert drives_after(h)


def test_hostile_sticks_in_the_lane_while_the_pilot_drives_never_move_a_wheel(
        errors: Callable[[], list[str]], monkeypatch: pytest.MonkeyPatch) -> None:
    h = lockstep({"SYSID_MYGCS": 255})  # only the pilot (the harness's ground station) drives
    h.run_for(0.5)
    h.gcs.sticks(0, 0, 0)
    h.gcs.arm()
    assert h.core.vehicle.mode is Mode.MANUAL and h.core.vehicle.armed
    answered: list[bytes] = []  # what the lane answered
    lane = h.core.stick_lane

    def watched(datagram: bytes, now_s: float, seq: int) -> bytes | None:
        packet = lane(datagram, now_s, seq)
        if packet is not None:
            answered.append(datagram)
        return packet

    monkeypatch.setattr(h.core, "stick_lane", watched)
    fuzzer = DatagramFuzzer(SEED, rover_sysid=1, gcs_sysid=255)
    watch = SafetyWatch(h.params, h.now_s)
    start, messages = h.now_s, len(h.gcs.messages)
    pilot_mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    pilot: set[bytes] = set()
    for step in range(LANE_COUNT):  # one datagram a step, alone on the wire: the lane sees it
        if step % 10 == 0:  # the pilot, centred, at 50 Hz
            stick = pilot_mav.manual_control_encode(1, 0, 0, 500, 0, 0).pack(pilot_mav)
            pilot.add(stick)
            h.inject(stick)
        else:
            h.inject(fuzzer.lane_datagram())
        h.step()
    for seen in h.overrides_since(start):
        watch.on_override(seen.channels)
    for msg, t in zip(h.gcs.messages[messages:], h.gcs.arrived_s[messages:], strict=True):
        watch.on_gcs_message(msg, t)
    watch.finish(h.now_s)
    assert watch.problems() == []
    assert watch.overrides > 900 and watch.heartbeats >= 15
    assert h.core.vehicle.armed and h.core.vehicle.mode is Mode.MANUAL
    assert not h.core.vehicle.input_stale
    assert all(datagram in pilot for datagram in answered)  # the lane answered the pilot only,
    assert len(answered) > 0.9 * LANE_COUNT / 10  # ... nearly every stick of the pilot's
    assert errors() == []
    assert set(fuzzer.counts) == {"stranger_stick", "stick_elsewhere", "stick_out_of_range",
                                  "stick_corrupted", "stick_truncated", "random_bytes"}
    assert h.core.refusals.counts[Refusal.STICK] > 0
    assert drives_after(h)


@pytest.mark.slow
def test_the_fuzz_tool_passes_against_the_real_process_with_a_fixed_seed() -> None:
    done = subprocess.run([sys.executable, str(TOOL), "--seed", str(SEED), "--gcs-count",
                           "3000", "--fc-count", "1000", "--lane-count", "3000"],
                          capture_output=True, text=True, timeout=120)
    out = done.stdout
    assert done.returncode == 0, out + done.stderr
    assert "FAIL" not in out, out
    for check in ("gcs: the companion process is alive", "fc: the companion process is alive",
                  "lane: the companion process is alive",
                  "still armed in MANUAL after the stick lane's fuzz",
                  "afterwards: MANUAL_CONTROL x=500 drives", "SIGTERM: exit status 0"):
        assert f"PASS  {check}" in out, out
    for phase in ("gcs", "fc", "lane"):
        for check in (r"[1-9][\d,]* overrides, 0 neither neutral nor released",
                      r"[1-9]\d* HEARTBEATs, worst gap [01]\.\d+ s \(< 1\.5 s\)",
                      r"[1-9][\d,]* ODOMETRY/LOCAL_POSITION_NED, 0 not finite",
                      r"0 exceptions caught by the core, 0 tracebacks logged"):
            assert re.search(rf"^PASS  {phase}: ({check})", out, re.MULTILINE), (check, out)
    assert out.rstrip().endswith("PASS"), out
