"""The sample drive (mecanum_mav.sim.sampledrive), as its docstring promises it: the mission
upload, arming, MANUAL sticks (forward, right, turning clockwise), the "Manual input lost"
failsafe, AUTO, the "GCS link lost" failsafe half-way through the mission, AUTO again, the
mission's end in HOLD and disarming, all recorded to the tlog; what it returns (the true path
every TRUTH_PERIOD_S, when each mode began, the end); its parameters; and a drive that cannot
finish naming the step that failed (its ``Raises``).

Each test runs its own drive (a fraction of a second): what the ground station sent is read
back from the tlog, what the vehicle answered from the harness's ground station.
"""

from __future__ import annotations

import io
import itertools
import math
import re
from collections.abc import Callable
from typing import Any

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.io.tlog import parse_tlog
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.groundstation import GCS_SYSID
from mecanum_mav.sim.lockstep import TLOG_EPOCH_S, Lockstep
from mecanum_mav.sim.sampledrive import (
    MANUAL_SEGMENTS,
    STICK_PERIOD_S,
    TRUTH_PERIOD_S,
    SampleDrive,
    sample_drive,
    square_mission,
)

ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
SAME_TIME_S = 1e-6
"""Two virtual times from the same step (a tlog stamp is whole microseconds)."""


Timed = list[tuple[float, Any]]
"""(virtual time, message), oldest first."""


def run(params: Params | None = None, **options: Any) -> tuple[SampleDrive, Timed]:
    """A sample drive; and what its tlog holds, as (virtual time, message)."""
    buf = io.BytesIO()
    result = sample_drive(buf, params, **options)
    entries = parse_tlog(buf.getvalue()).entries
    return result, [(e.time_s - TLOG_EPOCH_S, e.msg) for e in entries]


def sent(tlog: Timed, kind: str) -> Timed:
    """What the ground station sent of ``kind``, as the tlog recorded it."""
    return [(t, m) for t, m in tlog if m.get_type() == kind and m.get_srcSystem() == GCS_SYSID]


def seen(result: SampleDrive, kind: str,
         predicate: Callable[[Any], bool] = lambda m: True) -> Timed:
    """What the ground station received of ``kind`` (matching ``predicate``), with when."""
    gcs = result.harness.gcs
    return [(t, m) for m, t in zip(gcs.messages, gcs.arrived_s, strict=True)
            if m.get_type() == kind and predicate(m)]


def first_text(result: SampleDrive, text: str) -> float:
    return next(t for t, m in seen(result, "STATUSTEXT") if m.text.startswith(text))


def accepted(result: SampleDrive, command: int) -> list[float]:
    return [t for t, m in seen(result, "COMMAND_ACK")
            if m.command == command and m.result == ACCEPTED]


def test_the_sample_drive_runs_its_phases_in_order_and_says_when_each_mode_began() -> None:
    result, tlog = run()
    h = result.harness
    assert isinstance(h, Lockstep) and result.end_s == h.now_s
    assert tlog[-1][0] <= result.end_s + SAME_TIME_S
    # The mission: a square of side_m (1.5 m by default) from the origin, uploaded and kept.
    square = [(it.seq, it.frame, it.command, it.x, it.y) for it in square_mission(1.5)]
    assert [(it.seq, it.frame, it.command, it.x, it.y) for it in result.items] == square
    assert [(m.seq, m.frame, m.command, m.x, m.y)
            for _, m in sent(tlog, "MISSION_ITEM_INT")] == square
    ((mission_ack, ack),) = seen(result, "MISSION_ACK")
    assert ack.type == mavlink.MAV_MISSION_ACCEPTED
    # Arming, once the flight controller's link is up: the drive starts in MANUAL.
    link_up = first_text(result, "Flight controller link up")
    arms = [(t, m) for t, m in sent(tlog, "COMMAND_LONG") if m.command == ARM]
    assert arms[0][0] >= max(link_up, mission_ack) - SAME_TIME_S
    assert [m.param1 for _, m in arms[:-1]] == [1.0] * (len(arms) - 1)
    armed, auto_acks = accepted(result, ARM)[0], accepted(result, mavlink.MAV_CMD_DO_SET_MODE)
    assert [m for _, m in result.mode_starts] == [
        Mode.MANUAL, Mode.AUTO, Mode.HOLD, Mode.AUTO, Mode.HOLD]
    assert result.mode_starts[0][0] == armed
    # MANUAL: the sticks forward, right, then turning clockwise, each for its time; then
    # centred, then no more sticks: the "Manual input lost" failsafe, before AUTO.
    sticks = sent(tlog, "MANUAL_CONTROL")
    assert {(m.target, m.z, m.buttons) for _, m in sticks} == {(1, 500, 0)}  # z mid-travel
    positions = [(m.x, m.y, m.r) for _, m in sticks]
    runs = [(xyr, len(list(group))) for xyr, group in itertools.groupby(positions)]
    assert [xyr for xyr, _ in runs if xyr != (0, 0, 0)] == [s[:3] for s in MANUAL_SEGMENTS]
    assert [n * STICK_PERIOD_S for xyr, n in runs if xyr != (0, 0, 0)] == pytest.approx(
        [s[3] for s in MANUAL_SEGMENTS], abs=STICK_PERIOD_S)
    assert positions[-1] == (0, 0, 0)
    assert armed - SAME_TIME_S <= sticks[0][0]
    input_lost = first_text(result, "Manual input lost")
    assert sticks[-1][0] < input_lost < auto_acks[0]
    # AUTO; the ground station's heartbeats stop after item 2 (half-way): the GCS failsafe's
    # HOLD, before item 3; heartbeats back, AUTO again, the mission's end.
    reached = {m.seq: t for t, m in seen(result, "MISSION_ITEM_REACHED")}
    assert sorted(reached) == [1, 2, 3, 4]
    beats = [t for t, _ in sent(tlog, "HEARTBEAT")]
    gap = max(itertools.pairwise(beats), key=lambda p: p[1] - p[0])
    gcs_lost = first_text(result, "GCS link lost: failsafe")
    assert auto_acks[0] < reached[2] <= gap[0] < gcs_lost < gap[1] < auto_acks[1] < reached[3]
    assert reached[3] < reached[4]
    # When each mode began: the COMMAND_ACK, the failsafe's STATUSTEXT, the first HEARTBEAT
    # that showed HOLD after the last item.
    end_hold = next(t for t, m in seen(result, "HEARTBEAT", lambda m: m.custom_mode == Mode.HOLD)
                    if t >= reached[4])
    assert [t for t, _ in result.mode_starts] == pytest.approx(
        [armed, auto_acks[0], gcs_lost, auto_acks[1], end_hold], abs=SAME_TIME_S)
    # Disarming ends it: accepted, and the vehicle's last HEARTBEAT says disarmed.
    assert arms[-1][1].param1 == 0.0 and accepted(result, ARM)[-1] > end_hold
    last_beat = seen(result, "HEARTBEAT")[-1][1]
    assert not last_beat.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    assert result.end_s > accepted(result, ARM)[-1]


def test_the_true_path_is_sampled_every_truth_period_at_the_step_asked_for() -> None:
    """``true_path``: (time, north m, east m) every TRUTH_PERIOD_S, from the start; here with
    a step of half of it, so each sample falls on a step."""
    dt_s = TRUTH_PERIOD_S / 2
    result, _ = run(dt_s=dt_s)
    assert result.harness.dt_s == dt_s
    times = [p[0] for p in result.true_path]
    assert times[0] == pytest.approx(dt_s)  # the first step, due at 0
    assert times[1] == pytest.approx(TRUTH_PERIOD_S, abs=1e-12)  # the step it falls on
    late = [t - TRUTH_PERIOD_S * k for k, t in enumerate(times)][1:]
    assert min(late) > -1e-9 and max(late) < dt_s + 1e-9  # the first step at or after it
    assert times[-1] > result.end_s - TRUTH_PERIOD_S - dt_s
    pose = result.harness.truth().pose
    assert result.true_path[-1][1:] == pytest.approx((pose.x_m, pose.y_m), abs=1e-3)
    assert max(math.hypot(n, e) for _, n, e in result.true_path) > 1.5  # the square's corner


@pytest.mark.parametrize(("values", "options", "step"), [
    ({}, {"side_m": 150_000.0}, "upload refused"),  # beyond the 100 km a local item may be
    ({"FS_INPUT_TMO": 10.0}, {}, "no input failsafe"),
    ({"WP_SPEED": 0.05}, {}, "item 2 not reached"),
    ({"FS_GCS_TMO": 60.0}, {}, "no GCS failsafe"),
    ({"FS_GCS_ACTION": 1}, {}, "mission unfinished"),  # the GCS failsafe disarms
], ids=["upload", "input-failsafe", "item-2", "gcs-failsafe", "mission-end"])
def test_a_drive_that_cannot_finish_raises_naming_the_step_that_failed(
        values: dict[str, float], options: dict[str, Any], step: str) -> None:
    params = Params()
    params.update(values)
    with pytest.raises(RuntimeError, match=f"^sample drive: {re.escape(step)}$"):
        sample_drive(io.BytesIO(), params, **options)
