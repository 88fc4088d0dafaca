"""The companion's behaviour towards a ground station and a flight controller, exactly.

Everything here but the last test runs in the lockstep harness (the rover core, a simulated
ArduPilot board and a scripted ground station in virtual time, every message packed and
parsed on a virtual wire), so every timing below is exact to one step (``h.dt_s``, 2 ms).

Timing rules of the harness the assertions rely on:

- a message the test sends between steps reaches the core in the next step
  (:func:`arrival`); one sent by an :meth:`Lockstep.every` action reaches it in that step;
- the core's answers (COMMAND_ACK, STATUSTEXT, the RC override) go out in the step the
  message arrived, so an override *at* a stick's arrival time is the answer to that stick;
- :meth:`ScriptedGroundStation.wait` returns in the step its message arrived
  (``h.now_s`` is then the arrival time).

One test stays on real UDP sockets: the companion shell's own datagram parsing and link
counters (:class:`~mecanum_mav.io.links.Link`), which the virtual wire does not exercise.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from itertools import pairwise

import pytest
from conftest import lockstep
from missionitems import local_wp, renumber
from support import junk_packets, status_texts, wait_until

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.control.refusals import REFUSAL_REPEAT_S, Refusal
from mecanum_mav.io.links import mavlink, open_link
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.rcoverride import override_fields, release_fields
from mecanum_mav.protocol.statustext import Severity
from mecanum_mav.sim.groundstation import udp_ground_station
from mecanum_mav.sim.lockstep import Lockstep, OverrideSeen
from mecanum_mav.sim.simfc import SimFlightController

ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
SET_MODE = mavlink.MAV_CMD_DO_SET_MODE
CUSTOM = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
ARMED_FLAG = mavlink.MAV_MODE_FLAG_SAFETY_ARMED
ACCEPTED, DENIED = mavlink.MAV_RESULT_ACCEPTED, mavlink.MAV_RESULT_DENIED
WHEELS = (1, 2, 3, 4)
"""RC channels of FL, FR, RL, RR (the default MOT_*_CH)."""
NEUTRAL = [1500, 1500, 1500, 1500]
FORWARD = [2000, 2000, 2000, 2000]
PERIOD_S = 1.0 / 20.0
"""The override refresh period at the default OUT_RATE (20 Hz)."""
EPS = 1e-9
"""Float slack on virtual times (sums of steps)."""
STICK_PERIOD_S = 0.05
"""A ground station streaming MANUAL_CONTROL at 20 Hz."""
HEARTBEAT_WAIT_S = 1.1
"""Long enough for the next 1 Hz heartbeat."""

JUNK_SETS = 5
"""How many times each kind of junk is sent."""


# --------------------------------------------------------------------------- helpers


def arrival(h: Lockstep) -> float:
    """The virtual time at which a message sent now (between steps) reaches the core."""
    return h.now_s + h.dt_s


def stick(h: Lockstep, x: int = 0, y: int = 0, r: int = 0, target: int | None = None) -> float:
    """Send one MANUAL_CONTROL now; the time it reaches the core."""
    h.gcs.sticks(x, y, r, target=target)
    return arrival(h)


def answer_at(h: Lockstep, t: float) -> OverrideSeen | None:
    """The override the board received at exactly ``t`` (at most one), or None."""
    at = [o for o in h.overrides_since(t) if o.time_s == t]
    assert len(at) <= 1, at
    return at[0] if at else None


def drive(h: Lockstep, x: int = 0, y: int = 0, r: int = 0, target: int | None = None
          ) -> OverrideSeen | None:
    """Send one MANUAL_CONTROL and step once: the override sent in answer to it (in the step
    it reached the core), or None if none went out in that step."""
    t = stick(h, x, y, r, target)
    h.step()
    return answer_at(h, t)


def stream(h: Lockstep, x: int = 0, y: int = 0, r: int = 0, target: int = 1
           ) -> tuple[list[float], Callable[[], None]]:
    """Stream MANUAL_CONTROL at 20 Hz from now on; (the times they reached the core, stop)."""
    sent: list[float] = []

    def send(now_s: float) -> None:
        h.gcs.mav.manual_control_send(target, x, y, 500, r, 0)
        # the first goes out now, between steps (it arrives in the next step); the rest at
        # the start of a step, and arrive in it
        sent.append(now_s if sent else arrival(h))

    stop = h.every(STICK_PERIOD_S, send)
    return sent, stop


def wheels(o: OverrideSeen) -> list[int]:
    return o.channels[:4]


def gaps(seen: list[OverrideSeen]) -> list[float]:
    """Virtual seconds between consecutive overrides."""
    return [b.time_s - a.time_s for a, b in pairwise(seen)]


def command(h: Lockstep, cmd: int, *params: float, target: tuple[int, int] = (1, 1)) -> int:
    """COMMAND_LONG now; the index of the ground station's messages from before it."""
    p = [*params, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0][:7]
    since = h.gcs.mark()
    h.gcs.mav.command_long_send(*target, cmd, 0, *p)
    return since


def statustext(h: Lockstep, fragment: str, since: int, timeout_s: float = 1.0):
    """The first STATUSTEXT containing ``fragment`` from index ``since``, waiting up to
    ``timeout_s``; ``h.now_s`` is then the step it arrived in (if it arrived while waiting)."""
    return h.gcs.wait("STATUSTEXT", lambda m: fragment in m.text, timeout_s, since)


def heartbeat(h: Lockstep, predicate=lambda m: True, timeout_s: float = HEARTBEAT_WAIT_S):
    """The next HEARTBEAT matching ``predicate`` sent from now on (``mark`` first: a wait
    from "now" would also take what arrived earlier and is still in the port's inbox)."""
    return h.gcs.wait("HEARTBEAT", predicate, timeout_s, h.gcs.mark())


def armed(h: Lockstep) -> Lockstep:
    h.gcs.arm()
    assert h.core.vehicle.armed
    return h


def junk(h: Lockstep) -> list[bytes]:
    """Random bytes and truncated packets (one datagram each), as a broken radio delivers."""
    good = h.gcs.mav.command_long_encode(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
    return junk_packets(bytes(good.pack(h.gcs.mav))) * JUNK_SETS


def full(pulses: list[int]) -> list[int]:
    """All 18 override fields for pulses on the default wheel channels."""
    return override_fields(WHEELS, pulses)


# --------------------------------------------------------------------------- identity


def test_heartbeat_shows_a_disarmed_ardupilot_rover_in_manual(harness):
    hb = heartbeat(harness)
    assert hb.get_srcSystem() == 1 and hb.get_srcComponent() == 1
    assert hb.type == mavlink.MAV_TYPE_GROUND_ROVER
    assert hb.autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    assert hb.base_mode & CUSTOM and not hb.base_mode & ARMED_FLAG
    assert hb.custom_mode == 0 and hb.system_status == mavlink.MAV_STATE_ACTIVE  # (Rover's)
    assert hb.get_msgbuf()[0] == 0xFD  # MAVLink 2


@pytest.mark.parametrize(("mode", "flags"), [
    (Mode.MANUAL, mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED),
    (Mode.HOLD, 0),
    (Mode.GUIDED, mavlink.MAV_MODE_FLAG_GUIDED_ENABLED),
    (Mode.AUTO, mavlink.MAV_MODE_FLAG_GUIDED_ENABLED),
])
def test_heartbeat_base_mode_flags_are_ardupilot_rovers_in_each_mode(mode, flags):
    """ArduPilot Rover's base_mode (Rover/GCS_Mavlink.cpp, STICK_MIXING 0): custom mode
    always, manual input for a mode the sticks drive, guided for an autopilot mode (AUTO
    too: Rover never sets AUTO_ENABLED), safety armed when armed."""
    h = lockstep(mission=renumber([local_wp(0, 0.0, 0.0), local_wp(0, 1.0, 0.0)]))
    h.gcs.arm()
    assert h.gcs.set_mode(mode) == ACCEPTED
    hb = heartbeat(h, lambda m: m.custom_mode == mode)
    assert hb.base_mode == CUSTOM | ARMED_FLAG | flags
    # (Rover/GCS_Mavlink.cpp vehicle_system_status: STANDBY in HOLD, ACTIVE otherwise)
    assert hb.system_status == (mavlink.MAV_STATE_STANDBY if mode is Mode.HOLD
                                else mavlink.MAV_STATE_ACTIVE)


def test_companion_heartbeats_the_flight_controller_as_a_ground_station(harness):
    h = harness
    before = len(h.fc_received)
    h.run_for(2.5)
    beats = [m for m in h.fc_received[before:] if m.get_type() == "HEARTBEAT"]
    assert len(beats) >= 2  # 1 Hz
    for hb in beats:
        assert hb.type == mavlink.MAV_TYPE_GCS
        assert (hb.get_srcSystem(), hb.get_srcComponent()) == (255, 190)


# --------------------------------------------------------------------------- commands


def test_arm_is_acknowledged_in_the_step_it_arrives_and_reported(harness):
    h = harness
    since = command(h, ARM, 1)
    h.step()  # the command reaches the core in this step: the answer goes out in it too
    h.gcs.mark()
    acks = h.gcs.received("COMMAND_ACK", since)
    assert len(acks) == 1
    ack = acks[0]
    assert (ack.command, ack.result) == (ARM, ACCEPTED)
    assert (ack.target_system, ack.target_component) == (255, 190)
    assert any(t.startswith("Armed") for t in status_texts(h, since))  # reported in the same step
    hb = heartbeat(h, lambda m: m.base_mode & ARMED_FLAG)
    assert hb.system_status == mavlink.MAV_STATE_ACTIVE
    assert hb.base_mode & mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
    h.run_for(1.0)
    assert len(h.gcs.received("COMMAND_ACK", since)) == 1  # one command, one answer


def test_repeated_arm_and_disarm_commands_are_harmless(harness):
    h = harness
    for _ in range(2):
        assert h.gcs.command(ARM, 1).result == ACCEPTED
        assert h.core.vehicle.armed
    for _ in range(2):
        assert h.gcs.command(ARM, 0).result == ACCEPTED
        assert not h.core.vehicle.armed
    assert heartbeat(h, lambda m: not m.base_mode & ARMED_FLAG)


def test_nan_in_unused_command_params_is_accepted(harness):
    ack = harness.gcs.command(ARM, 1, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan)
    assert ack.result == ACCEPTED and harness.core.vehicle.armed


def test_broadcast_target_is_accepted(harness):
    h = harness
    since = command(h, ARM, 1, target=(0, 0))
    assert h.gcs.wait("COMMAND_ACK", lambda m: m.command == ARM, 1.0, since).result == ACCEPTED
    assert h.core.vehicle.armed


def test_commands_for_another_system_get_no_answer(harness):
    h = harness
    since = command(h, ARM, 1, target=(7, 1))
    h.run_for(1.0)
    h.gcs.mark()
    assert h.gcs.received("COMMAND_ACK", since) == []
    assert not h.core.vehicle.armed


def test_command_int_arms_too(harness):
    h = harness
    since = h.gcs.mark()
    h.gcs.mav.command_int_send(1, 1, 0, ARM, 0, 0, 1, 0, 0, 0, 0, 0, 0)
    assert h.gcs.wait("COMMAND_ACK", lambda m: m.command == ARM, 1.0, since).result == ACCEPTED
    assert h.core.vehicle.armed


def test_set_mode_hold_by_command_and_by_message(harness):
    h = harness
    assert h.gcs.set_mode(Mode.HOLD) == ACCEPTED
    assert heartbeat(h, lambda m: m.custom_mode == Mode.HOLD)
    since = h.gcs.mark()
    h.gcs.mav.set_mode_send(1, CUSTOM, int(Mode.MANUAL))
    ack = h.gcs.wait("COMMAND_ACK", lambda m: m.command == mavlink.MAVLINK_MSG_ID_SET_MODE,
                     1.0, since)
    assert ack is not None and ack.result == ACCEPTED
    # (as ArduPilot: no progress, no result detail, addressed to the sender)
    assert (ack.progress, ack.result_param2) == (0, 0)
    assert (ack.target_system, ack.target_component) == (h.gcs.mav.srcSystem,
                                                         h.gcs.mav.srcComponent)
    assert heartbeat(h, lambda m: m.custom_mode == Mode.MANUAL)


def test_set_mode_auto_by_message_starts_the_mission_as_the_command_does():
    h = armed(lockstep(mission=renumber([local_wp(0, 0.0, 0.0), local_wp(0, 1.0, 0.0)])))
    since = h.gcs.mark()
    h.gcs.mav.set_mode_send(1, CUSTOM, int(Mode.AUTO))
    ack = h.gcs.wait("COMMAND_ACK", lambda m: m.command == mavlink.MAVLINK_MSG_ID_SET_MODE,
                     1.0, since)
    assert ack is not None and ack.result == ACCEPTED
    assert h.gcs.wait("MISSION_ITEM_REACHED", lambda m: m.seq == 1, 10.0, since)
    assert not h.core.faulted


@pytest.mark.parametrize(("sender", "target"), [(200, 1), (255, 7)],
                         ids=["not the pilot's ground station", "for another system"])
def test_set_mode_from_another_ground_station_or_for_another_system_is_ignored(
        sender: int, target: int) -> None:
    h = lockstep({"SYSID_MYGCS": 255})
    h.gcs.mav.srcSystem = sender
    since = h.gcs.mark()
    h.gcs.mav.set_mode_send(target, CUSTOM, int(Mode.HOLD))
    h.run_for(0.5)
    h.gcs.mark()
    assert h.gcs.received("COMMAND_ACK", since) == []
    assert h.core.vehicle.mode is Mode.MANUAL


@pytest.mark.parametrize(("mode", "name"), [(int(Mode.AUTO), "AUTO"), (3, "3")])
def test_auto_without_a_mission_and_unknown_modes_are_denied_with_a_reason(harness, mode, name):
    h = harness
    since = h.gcs.mark()
    assert h.gcs.command(SET_MODE, CUSTOM, mode).result == DENIED
    assert any(name in t for t in status_texts(h, since))
    assert h.core.vehicle.mode is Mode.MANUAL


def test_unknown_command_is_unsupported(harness):
    assert harness.gcs.command(31999).result == mavlink.MAV_RESULT_UNSUPPORTED


def test_arming_with_the_sticks_deflected_is_refused_as_ardupilot_words_it(harness):
    h = harness
    _, stop = stream(h, x=500)  # the pilot holds the stick forward
    h.run_for(0.2)
    ack = h.gcs.command(ARM, 1)
    assert ack is not None and ack.result == DENIED
    assert statustext(h, "PreArm: sticks not centred (x +0.50)", 0) is not None
    assert not h.core.vehicle.armed
    stop()
    _, stop = stream(h)  # centred: arms
    h.run_for(0.2)
    ack = h.gcs.command(ARM, 1)
    stop()
    assert ack is not None and ack.result == ACCEPTED and h.core.vehicle.armed


def test_forced_arming_and_arming_check_0_skip_the_pre_arm_checks(harness):
    h = harness
    _, stop = stream(h, y=800)
    h.run_for(0.2)
    ack = h.gcs.command(ARM, 1, 21196)  # MAV_CMD_COMPONENT_ARM_DISARM param2: force
    assert ack is not None and ack.result == ACCEPTED and h.core.vehicle.armed
    assert h.gcs.command(ARM, 0).result == ACCEPTED
    h.gcs.mav.param_set_send(1, 1, b"ARMING_CHECK", 0, mavlink.MAV_PARAM_TYPE_INT32)
    h.run_for(0.1)
    ack = h.gcs.command(ARM, 1)
    stop()
    assert ack is not None and ack.result == ACCEPTED


def test_arming_without_the_flight_controller_is_refused_as_a_pre_arm_check():
    h = Lockstep()  # the board's first heartbeat has not been heard yet
    since = h.gcs.mark()
    h.gcs.mav.command_long_send(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
    ack = h.gcs.wait("COMMAND_ACK", timeout_s=0.01, since=since)
    assert ack is not None and ack.result == DENIED
    assert statustext(h, "PreArm: flight controller link down", since) is not None


def test_arm_with_a_bad_param1_is_denied(harness):
    assert harness.gcs.command(ARM, math.nan).result == DENIED
    assert not harness.core.vehicle.armed


# --------------------------------------------------------------------------- manual driving


@pytest.mark.parametrize(
    ("x", "y", "r", "pwm"),
    [(1000, 0, 0, [2000, 2000, 2000, 2000]),       # forward: every wheel forward
     (0, 1000, 0, [2000, 1000, 1000, 2000]),       # strafe right
     (0, 0, 1000, [2000, 1000, 2000, 1000]),       # clockwise
     (1000, 1000, 0, [2000, 1500, 1500, 2000]),    # diagonal forward-right
     (-1000, 0, 0, [1000, 1000, 1000, 1000])],     # backward
)
def test_sticks_drive_the_right_pwm_pattern_on_the_right_channels(harness, x, y, r, pwm):
    h = armed(harness)
    o = drive(h, x, y, r)
    assert o is not None, "no override in answer to the stick"
    assert o.source_system == 255, "ArduPilot drops overrides not from its GCS id"
    assert o.channels[:4] == pwm
    assert o.channels[4:8] == [65535] * 4  # channels it does not own: left alone
    assert o.channels[8:] == [0] * 10
    board = h.truth()  # the board obeyed it (right target, right sender)
    assert board.overrides_ignored == 0
    assert board.channel_pwm == dict(zip(WHEELS, pwm, strict=True))


def test_sticks_while_disarmed_leave_the_wheels_at_neutral(harness):
    h = harness
    t0 = arrival(h)
    sent, stop = stream(h, 1000)
    h.run_for(1.0)
    stop()
    seen = h.overrides_since(t0)
    assert len(sent) >= 20
    for t in sent:  # every stick was answered at once, with neutral
        o = answer_at(h, t)
        assert o is not None and wheels(o) == NEUTRAL, (t, o)
    assert all(wheels(o) == NEUTRAL for o in seen)
    assert h.truth().wheel_commands == (0.0, 0.0, 0.0, 0.0)


def test_hold_mode_keeps_neutral_while_armed(harness):
    h = armed(harness)
    assert h.gcs.set_mode(Mode.HOLD) == ACCEPTED
    t0 = arrival(h)
    sent, stop = stream(h, 1000)
    h.run_for(1.0)
    stop()
    for t in sent:
        o = answer_at(h, t)
        assert o is not None and wheels(o) == NEUTRAL, (t, o)
    assert all(wheels(o) == NEUTRAL for o in h.overrides_since(t0))
    assert h.truth().wheel_commands == (0.0, 0.0, 0.0, 0.0)


def test_reverse_and_channel_map_parameters_move_the_output():
    h = armed(lockstep({"MOT_FR_REV": 1, "MOT_FL_CH": 6, "MOT_RR_CH": 12}))
    o = drive(h, 1000)
    assert o is not None
    # FL on 6, FR reversed on 2, RL on 3, RR on 12; 1 and 4 now free: left alone
    want = [65535, 1000, 2000, 65535, 65535, 2000, 65535, 65535] + [0] * 10
    want[11] = 2000
    assert o.channels == want


def test_invalid_axis_reads_as_zero(harness):
    h = armed(harness)
    o = drive(h, 0x7FFF, 1000, 0x7FFF)
    assert o is not None and wheels(o) == [2000, 1000, 1000, 2000]  # a pure strafe


def test_out_of_range_stick_is_rejected_and_never_moves_the_robot(harness):
    h = armed(harness)
    since = h.gcs.mark()
    t0 = arrival(h)
    _, stop = stream(h, 1500)
    h.run_for(1.0)
    stop()
    said = status_texts(h, since)
    assert said.count("Rejected: MANUAL_CONTROL x=1500 not in +-1000") == 1  # once a second
    seen = h.overrides_since(t0)
    assert seen and all(wheels(o) == NEUTRAL for o in seen)
    # rejected whole: none of them was even answered (only the 20 Hz refresh went out)
    assert all(g > PERIOD_S - EPS for g in gaps(seen))
    assert h.truth().wheel_commands == (0.0, 0.0, 0.0, 0.0)
    assert h.truth().pose.x_m == 0.0


def test_manual_control_for_another_system_is_ignored(harness):
    h = armed(harness)
    t0 = arrival(h)
    _, stop = stream(h, 1000, target=9)
    h.run_for(1.0)
    stop()
    seen = h.overrides_since(t0)
    assert seen and all(wheels(o) == NEUTRAL for o in seen)
    assert all(g > PERIOD_S - EPS for g in gaps(seen))
    assert h.core.stick == (0.0, 0.0, 0.0)


def test_a_restricted_ground_station_id_ignores_other_senders():
    h = lockstep({"SYSID_MYGCS": 200})
    since = command(h, ARM, 1)  # from 255
    h.run_for(1.0)
    h.gcs.mark()
    assert h.gcs.received("COMMAND_ACK", since) == []
    assert not h.core.vehicle.armed
    h.gcs.mav.srcSystem = 200  # the permitted ground station is obeyed
    assert h.gcs.command(ARM, 1).result == ACCEPTED


def test_ground_station_rc_override_drives_like_a_stick(harness):
    h = armed(harness)
    t = arrival(h)
    # MAVProxy "rc 3 2000": throttle (forward) channel 3, everything else left alone.
    h.gcs.mav.rc_channels_override_send(1, 1, 65535, 65535, 2000, 65535, 65535, 65535, 65535,
                                        65535)
    h.step()
    o = answer_at(h, t)
    assert o is not None and wheels(o) == FORWARD
    t = arrival(h)
    h.gcs.mav.rc_channels_override_send(1, 1, 65535, 65535, 0, 65535, 65535, 65535, 65535,
                                        65535)  # release throttle -> centre
    h.step()
    o = answer_at(h, t)
    assert o is not None and wheels(o) == NEUTRAL


@pytest.mark.parametrize(("pulse", "expected"), [(2200, FORWARD), (800, [1000] * 4)])
def test_ground_station_rc_override_at_the_ends_of_the_valid_range_drives(
        harness, pulse: int, expected: list[int]) -> None:
    """800 and 2200 us are pulses (RC_CHANNELS_OVERRIDE's valid range, as ArduPilot's): full
    deflection, clamped beyond RCIN_MIN/MAX."""
    h = armed(harness)
    t = arrival(h)
    h.gcs.mav.rc_channels_override_send(1, 1, 65535, 65535, pulse, 65535, 65535, 65535, 65535,
                                        65535)
    h.step()
    o = answer_at(h, t)
    assert o is not None and wheels(o) == expected


def test_ground_station_rc_override_with_an_absurd_pulse_is_rejected(harness):
    h = armed(harness)
    since = h.gcs.mark()
    t0 = arrival(h)
    h.gcs.mav.rc_channels_override_send(1, 1, 65535, 65535, 40000, 65535, 65535, 65535,
                                        65535, 65535)
    h.step()
    assert status_texts(h, since) == ["Rejected: RC ch3=40000 not in 800..2200 us"]
    assert answer_at(h, t0) is None  # nothing applied
    h.run_for(0.5)
    assert all(wheels(o) == NEUTRAL for o in h.overrides_since(t0))


# --------------------------------------------------------------------------- output timing


def test_overrides_are_refreshed_at_out_rate_while_idle_so_the_fc_timeout_never_lapses(harness):
    h = harness
    t0 = h.now_s
    h.run_for(10.0)
    seen = h.overrides_since(t0)
    # every 50 ms, late by at most one step (float virtual time: a deadline ``now + period``
    # may fall a hair after the 25th step and cost one more)
    assert all(PERIOD_S - EPS <= g <= PERIOD_S + h.dt_s + EPS for g in gaps(seen))
    for second in range(10):
        start = t0 + second
        count = sum(1 for o in seen if start <= o.time_s < start + 1.0)
        assert count in (19, 20), (second, count)
    assert all(o.channels == full(NEUTRAL) for o in seen)
    # the board's own override timeout (SIM_RC_TMO 0.5 s) never lapsed
    assert h.truth().channel_pwm == dict.fromkeys(WHEELS, 1500)


def test_overrides_are_refreshed_exactly_every_period_when_the_step_divides_it(harness_exact):
    h = harness_exact
    t0 = h.now_s
    h.run_for(10.0)
    seen = h.overrides_since(t0)
    assert set(gaps(seen)) == {1.0 / 16.0}
    for second in range(10):
        assert sum(1 for o in seen if t0 + second <= o.time_s < t0 + second + 1.0) == 16


@pytest.fixture
def harness_exact() -> Lockstep:
    """OUT_RATE 16 Hz and a step of 2**-9 s: every virtual time is a binary fraction, so the
    float sums are exact and a period is exactly 32 steps."""
    return lockstep({"OUT_RATE": 16.0}, dt_s=2.0 ** -9)


# --------------------------------------------------------------------------- failsafes


def test_stale_manual_control_returns_wheels_to_neutral_at_the_timeout_and_resumes():
    timeout_s = 0.3
    h = armed(lockstep({"FS_INPUT_TMO": timeout_s}))
    since = h.gcs.mark()
    sent, stop = stream(h, 1000)
    h.run_for(0.5)
    stop()
    last = sent[-1]
    assert wheels(answer_at(h, last)) == FORWARD

    def first_neutral():
        return next((o for o in h.overrides_since(last) if wheels(o) == NEUTRAL), None)

    o = h.run_until(first_neutral, 2.0)
    assert o is not None
    assert timeout_s < o.time_s - last <= timeout_s + h.dt_s + EPS, o.time_s - last
    assert all(wheels(d) == FORWARD for d in h.overrides_since(last) if d.time_s < o.time_s)
    lost = statustext(h, "Manual input lost", since)
    assert lost is not None and lost.severity == Severity.WARNING
    resumed = drive(h, 1000)
    assert resumed is not None and wheels(resumed) == FORWARD
    assert "Manual input resumed" in status_texts(h, since)


@pytest.mark.parametrize(("action", "armed_after"), [(0, True), (1, False)])
def test_ground_station_loss_triggers_the_failsafe_action_at_the_timeout(action, armed_after):
    timeout_s = 1.0
    h = armed(lockstep({"FS_GCS_TMO": timeout_s, "FS_GCS_ACTION": action}))
    sent, stop = stream(h, 1000)
    h.run_for(0.2)
    assert wheels(answer_at(h, sent[-1])) == FORWARD
    h.gcs.beating = False
    last_beat = h.core.vehicle.gcs_seen_s
    since = h.gcs.mark()
    text = statustext(h, "GCS link lost", since, 3.0)
    fired = h.now_s  # the step the text arrived in
    assert text is not None and text.severity == mavlink.MAV_SEVERITY_CRITICAL
    assert timeout_s < fired - last_beat <= timeout_s + h.dt_s + EPS
    before = [o for o in h.overrides if o.time_s < fired]
    assert wheels(before[-1]) == FORWARD  # driving until then
    assert wheels(answer_at(h, fired)) == NEUTRAL  # neutral in the same step
    # the sticks keep coming: each is answered at once, with neutral, for the next second
    h.run_for(1.0)
    stop()
    after = [t for t in sent if t > fired]
    assert len(after) >= 19
    for t in after:
        o = answer_at(h, t)
        assert o is not None and wheels(o) == NEUTRAL, (t, o)
    assert all(wheels(o) == NEUTRAL for o in h.overrides_since(fired))
    hb = heartbeat(h)
    assert hb.system_status == mavlink.MAV_STATE_CRITICAL
    assert bool(hb.base_mode & ARMED_FLAG) == armed_after
    if armed_after:
        assert hb.custom_mode == Mode.HOLD


def test_flight_controller_loss_disarms_reports_and_refuses_to_arm():
    timeout_s = 1.0
    h = armed(lockstep({"FS_FC_TMO": timeout_s}))
    since = h.gcs.mark()
    h.board.beating = False
    last_beat = h.core.vehicle.fc_seen_s
    assert statustext(h, "Flight controller link lost", since, 3.0)
    fired = h.now_s
    assert timeout_s < fired - last_beat <= timeout_s + h.dt_s + EPS
    assert "Disarmed: flight controller link lost" in status_texts(h, since)  # in the same step
    assert not h.core.vehicle.armed
    assert heartbeat(h).system_status == mavlink.MAV_STATE_CRITICAL
    since = h.gcs.mark()
    assert h.gcs.command(ARM, 1).result == DENIED
    assert any("flight controller link down" in t for t in status_texts(h, since))
    h.board.beating = True
    assert statustext(h, "Flight controller link up", since, 1.0 + 2 * h.dt_s)
    # the board is read again (it may have rebooted with other settings): arm once it was
    assert statustext(h, "FC setup checked: safe", since, 1.0)
    assert h.gcs.command(ARM, 1).result == ACCEPTED


# --------------------------------------------------------------------------- robustness


def test_random_bytes_and_truncated_packets_on_both_links_do_not_crash_it(harness):
    h = harness
    blobs = junk(h)
    for from_fc in (False, True):
        before = h.core.link_counts().malformed
        for blob in blobs:
            h.inject(blob, from_fc=from_fc)
        h.step()
        # each datagram counted at least once (a truncated packet, bad bytes, a bad CRC)
        assert h.core.link_counts().malformed - before >= len(blobs), from_fc
    assert not h.core.faulted
    assert h.gcs.command(ARM, 1).result == ACCEPTED
    o = drive(h, 1000)
    assert o is not None and wheels(o) == FORWARD


def test_clean_shutdown_sends_neutral_then_releases_the_channels(harness):
    h = armed(harness)
    assert wheels(drive(h, 1000)) == FORWARD
    last = h.core.shutdown()
    assert len(last) == 3
    hold, again, release = last
    for o in (hold, again):
        assert (o.target_system, o.target_component) == (1, 1)
        assert o.channels == full(NEUTRAL)
    assert (release.target_system, release.target_component) == (1, 1)
    assert release.channels == release_fields(WHEELS)
    assert release.channels[:4] == [0, 0, 0, 0] and release.channels[4:8] == [65535] * 4
    assert release.channels[8:] == [0] * 10
    assert h.core.pulses_us == tuple(NEUTRAL)


def broken(*args, **kwargs):
    raise RuntimeError("bug")


def test_an_exception_in_the_control_path_ends_at_neutral_and_latches(monkeypatch):
    h = armed(lockstep({"FS_INPUT_TMO": 5.0}))  # the stick stays fresh: only the latch holds
    assert wheels(drive(h, 1000)) == FORWARD
    with monkeypatch.context() as patch:
        patch.setattr("mecanum_mav.control.chain.wheels_from_stick", broken)
        patch.setattr(h.core, "_lane", broken)  # (the stick lane, which mixes inline, too)
        since = h.gcs.mark()
        o = drive(h, 1000)
        assert o is not None and wheels(o) == NEUTRAL  # in answer to the stick
        h.gcs.mark()
        error = [m for m in h.gcs.received("STATUSTEXT", since) if m.text.startswith("Error")]
        assert [m.text for m in error] == ["Error computing output: neutral"]
        assert error[0].severity == Severity.ERROR
        assert h.core.faulted
    # The mixer works again, but the output stays neutral (latched) until a valid stick.
    t0 = arrival(h)
    h.run_for(1.0)
    seen = h.overrides_since(t0)
    assert len(seen) >= 19 and all(wheels(o) == NEUTRAL for o in seen)
    o = drive(h, 1000)
    assert o is not None and wheels(o) == FORWARD
    assert not h.core.faulted


def test_a_stick_lane_that_raises_leaves_the_stick_to_the_general_path(monkeypatch):
    h = armed(lockstep())
    monkeypatch.setattr(h.core, "_lane", broken)
    o = drive(h, 1000)
    assert o is not None and wheels(o) == FORWARD  # answered the long way, in its step
    assert not h.core.faulted


def test_an_exception_in_a_message_handler_latches_neutral_until_the_next_valid_stick(
        monkeypatch, caplog):
    from mecanum_mav.control import gcsinput

    h = armed(lockstep({"FS_INPUT_TMO": 5.0}))
    assert wheels(drive(h, 1000)) == FORWARD
    real = gcsinput.stick_from_manual_control
    calls = []

    def once(*args, **kwargs):
        calls.append(args)
        if len(calls) == 1:
            raise RuntimeError("bug")
        return real(*args, **kwargs)

    monkeypatch.setattr(gcsinput, "stick_from_manual_control", once)
    monkeypatch.setattr(h.core, "_lane", broken)  # (the stick lane decodes inline: fails too)
    since = h.gcs.mark()
    with caplog.at_level("ERROR", logger="mecanum_mav"):
        o = drive(h, 1000)
    assert o is not None and wheels(o) == NEUTRAL  # at once, in the step it arrived
    # the log names the message and keeps the traceback, for the bug report
    [record] = [r for r in caplog.records if r.getMessage().startswith("error handling")]
    assert record.levelname == "ERROR" and record.getMessage() == "error handling MANUAL_CONTROL"
    assert record.exc_info is not None and str(record.exc_info[1]) == "bug"
    h.gcs.mark()
    error = [m for m in h.gcs.received("STATUSTEXT", since) if m.text.startswith("Error")]
    assert [m.text for m in error] == ["Error handling MANUAL_CONTROL: neutral"]
    assert error[0].severity == Severity.ERROR
    assert h.core.faulted
    t0 = arrival(h)
    h.run_for(1.0)  # the earlier stick is still fresh (5 s), but the latch holds
    seen = h.overrides_since(t0)
    assert len(seen) >= 19 and all(wheels(o) == NEUTRAL for o in seen)
    o = drive(h, 1000)
    assert o is not None and wheels(o) == FORWARD
    assert not h.core.faulted and len(calls) == 2


def test_a_mode_change_clears_the_exception_latch(monkeypatch):
    h = armed(lockstep({"FS_INPUT_TMO": 5.0}))
    assert wheels(drive(h, 1000)) == FORWARD
    with monkeypatch.context() as patch:
        patch.setattr("mecanum_mav.control.chain.wheels_from_stick", broken)
        patch.setattr(h.core, "_lane", broken)  # (the stick lane, which mixes inline, too)
        assert wheels(drive(h, 1000)) == NEUTRAL
    h.run_for(0.5)
    assert h.core.faulted and all(wheels(o) == NEUTRAL for o in h.overrides[-5:])
    assert h.gcs.set_mode(Mode.HOLD) == ACCEPTED
    assert not h.core.faulted
    t = arrival(h)
    assert h.gcs.set_mode(Mode.MANUAL) == ACCEPTED
    # no new stick: back in MANUAL the last (still fresh) stick drives again at once
    o = answer_at(h, t)
    assert o is not None and wheels(o) == FORWARD


def test_a_flood_of_distinct_bad_sticks_is_said_once_a_second_and_counted_whole():
    h = armed(lockstep())
    since = h.gcs.mark()
    xs = range(1001, 1251)  # 250 distinct rejections in 0.05 s
    for x in xs:
        h.gcs.mav.manual_control_send(1, x, 0, 500, 0, 0)
        if x % 10 == 0:
            h.step()
    h.step()
    assert [t for t in status_texts(h, since) if t.startswith("Rejected")] == [
        "Rejected: MANUAL_CONTROL x=1001 not in +-1000"]
    assert h.core.refusals.counts[Refusal.STICK] == len(xs)
    h.run_for(REFUSAL_REPEAT_S)
    since = h.gcs.mark()
    h.gcs.mav.manual_control_send(1, 1300, 0, 500, 0, 0)
    h.step()
    # a second on
    assert status_texts(h, since) == ["Rejected: MANUAL_CONTROL x=1300 not in +-1000"]


def test_each_kind_of_refusal_is_said_on_its_own_clock_and_named_in_the_status_line():
    h = armed(lockstep())
    assert h.core.status_line().endswith("refused 0 (none)")
    since = h.gcs.mark()
    h.gcs.mav.manual_control_send(1, 2000, 0, 500, 0, 0)
    h.gcs.mav.param_set_send(1, 1, b"OUT_RATE", math.nan, mavlink.MAV_PARAM_TYPE_REAL32)
    h.gcs.mav.command_long_send(1, 1, ARM, 0, 7, 0, 0, 0, 0, 0, 0)
    h.gcs.mav.set_mode_send(1, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 99)
    h.run_for(0.1)
    said = status_texts(h, since)
    assert said[:1] == ["Rejected: MANUAL_CONTROL x=2000 not in +-1000"]
    assert any(t.startswith("Param refused: OUT_RATE") for t in said), said
    assert "Arm/disarm: param1 must be 0 or 1, got 7.0" in said
    assert "Mode 99 unknown" in said
    counts = h.core.refusals.counts
    assert [counts[k] for k in (Refusal.STICK, Refusal.PARAM, Refusal.COMMAND, Refusal.MODE)] == [
        1, 1, 1, 1]
    assert h.core.refusals.total == 4
    assert h.core.status_line().endswith("refused 4 (stick 1, param 1, command 1, mode 1)")


def test_sys_status_counts_refusals_in_errors_comm_and_their_recent_share_in_drop_rate(harness):
    h = armed(harness)
    h.run_for(1.0)  # a heartbeat period without refusals: the drop rate starts at 0
    assert h.core.link_counts().received > 0
    status = h.gcs.wait("SYS_STATUS", timeout_s=1.0)
    assert status is not None and status.errors_comm == 0 and status.drop_rate_comm == 0
    for _ in range(20):
        h.gcs.mav.manual_control_send(1, 1500, 0, 500, 0, 0)
        h.step()
    h.run_for(1.0)
    # a heartbeat period later: 20 refused of the messages that arrived in it
    status = h.gcs.wait("SYS_STATUS", timeout_s=1.0)
    assert status is not None and status.errors_comm == 20
    assert 0 < status.drop_rate_comm < 10_000
    h.run_for(2.5)  # two clean heartbeat periods: the rate falls back, the count stays
    status = h.gcs.wait("SYS_STATUS", timeout_s=1.0)
    assert status.errors_comm == 20 and status.drop_rate_comm == 0


def test_sys_status_errors_comm_counts_malformed_packets(harness):
    h = harness
    blobs = junk(h)
    for blob in blobs:
        h.inject(blob)
        h.inject(blob, from_fc=True)
    h.step()
    bad = h.core.link_counts().malformed
    assert bad >= 2 * len(blobs)
    since = command(h, mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_SYS_STATUS)
    h.step()
    h.gcs.mark()
    assert [a.result for a in h.gcs.received("COMMAND_ACK", since)] == [ACCEPTED]
    status = h.gcs.received("SYS_STATUS", since)  # answered in the same step
    assert len(status) == 1 and status[0].errors_comm == bad
    streamed = h.gcs.wait("SYS_STATUS", timeout_s=1.0)  # TLM_EXT_RATE 2 Hz
    assert streamed is not None and streamed.errors_comm == bad


# --------------------------------------------------------------------------- real sockets


def test_the_companion_shell_counts_junk_datagrams_per_link_and_keeps_driving():
    """The shell's own I/O: real datagrams through Link.read, counted per link, in SYS_STATUS."""
    gcs, port = udp_ground_station()
    sim = SimFlightController("udpin:127.0.0.1:0", Params())
    sim.start()
    companion = Companion(Params(), port.url, f"udpout:127.0.0.1:{sim.local_port}")
    companion.start()
    try:
        # (two 1 Hz heartbeats meet: the board learns the companion from its first, and the
        # link is up at the board's next one; on a loaded machine that took over 5 s once)
        assert gcs.wait("STATUSTEXT", lambda m: "Flight controller link up" in m.text, 20.0)
        good = gcs.mav.command_long_encode(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
        blobs = junk_packets(bytes(good.pack(mavlink.MAVLink(None, 255, 190)))) * JUNK_SETS
        # From each peer's own socket: a udpout link's socket is connected to its peer, and
        # the kernel drops a stranger's datagrams (tests/test_links.py).
        for peer, link in ((port.link, companion.gcs), (sim._link, companion.fc)):
            for blob in blobs:
                peer.conn.port.sendto(blob, ("127.0.0.1", link.local_port))
        c = companion
        wait_until(lambda: c.gcs.bad >= len(blobs) and c.fc.bad >= len(blobs), 5.0,
                   pump=gcs.pump)
        assert c.gcs.bad >= len(blobs) and c.fc.bad >= len(blobs), (c.gcs.bad, c.fc.bad)
        since = gcs.mark()
        ack = gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_SYS_STATUS)
        assert ack is not None and ack.result == ACCEPTED
        status = gcs.wait("SYS_STATUS", timeout_s=1.0, since=since)
        # both links' counters, through the shell's link_errors
        assert status.errors_comm == c.gcs.bad + c.fc.bad + c.gcs.send_errors + c.fc.send_errors
        gcs.arm()

        def forward() -> object:
            gcs.sticks(1000)
            return sim.wait_for(lambda s: [s.channel_pwm.get(ch) for ch in (1, 2, 3, 4)]
                                == FORWARD, 0.1)

        assert wait_until(forward, 2.0) is not None
    finally:
        companion.close()
        sim.stop()
        port.close()


def test_sticks_answered_in_their_lane_every_step_still_leave_telemetry_and_heartbeats_on_time():
    h = armed(lockstep({}))
    h.dt_s = 0.001  # a stick in every 1 ms step: every pass is a lane pass
    since = h.gcs.mark()
    t0 = h.now_s
    for i in range(2000):
        o = drive(h, 300 + i % 400)
        assert o is not None  # each stick answered in the step it arrived
    seconds = h.now_s - t0
    odometry = h.gcs.received("ODOMETRY", since)
    beats = h.gcs.received("HEARTBEAT", since)
    assert len(odometry) >= int(10 * seconds) - 1  # TLM_POS_RATE 10 Hz
    assert len(beats) >= int(seconds) - 1  # 1 Hz
    assert h.core.estimator.pose.x_m > 0.1  # the lane took the odometry of every stick


def test_a_stick_every_step_stops_driving_the_step_the_flight_controller_times_out():
    timeout_s = 1.0
    h = armed(lockstep({"FS_FC_TMO": timeout_s}))
    h.dt_s = 0.001  # a stick in every step, each one a candidate for the lane
    h.board.beating = False
    last_beat = h.core.vehicle.fc_seen_s
    driving = []
    for _ in range(int(1.5 * timeout_s / h.dt_s)):
        o = drive(h, 600)
        if o is not None and wheels(o) != NEUTRAL:
            driving.append(o.time_s)
    assert driving  # it drove until the timeout...
    assert max(driving) <= last_beat + timeout_s + EPS  # ...and not one step after it


def test_sticks_keep_their_lane_while_telemetry_and_heartbeats_fall_due(monkeypatch):
    h = armed(lockstep({}))
    h.dt_s = 0.001  # a stick in every step
    drive(h, 300)
    long_way, others = [], set()
    real_handle = h.core.handle

    def handle(msg, now_s, **kwargs):
        if msg.get_type() == "MANUAL_CONTROL":
            long_way.append(now_s)
        elif not kwargs.get("from_fc"):
            others.add(now_s)  # (the ground station's heartbeat: with it, no stick is alone)
        return real_handle(msg, now_s, **kwargs)

    monkeypatch.setattr(h.core, "handle", handle)
    since = h.gcs.mark()
    for i in range(1500):
        o = drive(h, 300 + i % 300)
        assert o is not None and wheels(o) != NEUTRAL  # every stick answered in its step
    assert len(h.gcs.received("ODOMETRY", since)) >= 14  # 10 Hz
    assert h.gcs.received("HEARTBEAT", since)
    # Not one stick that came alone waited for the telemetry's turn.
    assert [t for t in long_way if t not in others] == []


def test_close_waits_for_a_loop_run_in_the_callers_own_thread_which_ends_released():
    """``run()`` in a thread of the caller's (not :meth:`Companion.start`), ``close()`` from
    another: close waits for the loop's end, so its last overrides go out on an open link
    and the loop never reads a closed wake pipe."""
    fc = open_link("udpin:127.0.0.1:0", source_system=1, source_component=1, name="test-fc")
    companion = Companion(Params(), "udpin:127.0.0.1:0", f"udpout:127.0.0.1:{fc.local_port}")
    crashed: list[BaseException | None] = []
    loop = threading.Thread(target=companion.run)
    previous, threading.excepthook = threading.excepthook, lambda a: crashed.append(a.exc_value)
    overrides: list[list[int]] = []

    released = release_fields(companion.core.pwm.channels)

    def read_overrides() -> list[list[int]]:
        overrides.extend([getattr(m, f"chan{i}_raw") for i in range(1, 19)]
                         for m in fc.read() if m.get_type() == "RC_CHANNELS_OVERRIDE")
        return overrides

    try:
        loop.start()
        wait_until(read_overrides, 2.0)  # the loop runs: the refresh comes
        assert overrides
        companion.close()
        assert not loop.is_alive()  # close() waited for the loop
        wait_until(lambda: read_overrides()[-1] == released, 2.0)
        assert overrides[-1] == released
        assert crashed == []
    finally:
        threading.excepthook = previous
        companion.close()
        loop.join(5.0)
        fc.close()
