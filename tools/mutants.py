#!/usr/bin/env python3
"""Mutation check: every safety rule and protocol decision, broken once, must fail a test.

What
    :data:`MUTATIONS` is a curated list of small changes to the product, one or more per rule
    (neutral on every way out, failsafes, pre-arm checks, the RC override's field rules,
    signing, the stick lane's refusals, the layer rule, parameter validation, setup-fc's
    hazards, mixing and kinematics signs, the PWM edge, mission protocol decisions). Each names
    the rule it breaks, the file, an exact ``old`` snippet (which must occur exactly once in
    that file, else the entry is STALE: a refactor must update the list), its ``new`` text,
    and the tests that should fail when it is applied (targeted node ids, a few seconds each).

How
    The package and its tests are copied into a temporary folder per worker (no .git, no
    .venv, no byte code). Each mutation is written into the copy's file, the tests run there
    (the same interpreter, ``PYTHONPATH`` and the working directory the copy, so that pytest
    AND the subprocesses the tests start, ``python -m mecanum_mav ...``, import the mutated
    package, not the editable install; checked by a canary at start), and the file is put
    back. First the baseline: the union of the selected tests must pass on the unmutated copy.

    A mutant is killed when pytest fails a test; a failure to collect or import is reported
    as "killed (error)" (a mutation that only breaks an import proves little: keep mutations
    importable). The table gives the first failing test's node id (from the JUnit XML).

Usage
    python tools/mutants.py                 # the whole list, 2 workers
    python tools/mutants.py --fast          # the CI subset (flagged fast in the list)
    python tools/mutants.py --only ID ...   # some entries
    python tools/mutants.py --list          # the list, nothing run
    python tools/mutants.py -j 1            # one worker

Exit status: 0 when every selected mutant was killed; 1 on a survivor, a stale entry, a
broken baseline or a copy that does not import from itself.

Adding a mutation: append a :class:`Mutation` to :data:`MUTATIONS` with a new short id, the
rule in one line, ``old`` copied from the file (enough context to be unique) and the tests
that name the behaviour; run ``python tools/mutants.py --only ID``. A survivor is a missing
test: write the test (its commit names the mutation), keep the entry.
"""

from __future__ import annotations

import argparse
import os
import queue
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
COPIED = ("mecanum_mav", "tests", "tools", "params", "docs", "pyproject.toml", "README.md",
          "mkdocs.yml", ".ci")
"""What a worker's copy holds (the tests read the README, the docs and the parameter files)."""
IGNORED = shutil.ignore_patterns("__pycache__", "*.pyc", ".pytest_cache", ".hypothesis",
                                 "*.egg-info")
PYTEST = ("-x", "-q", "-p", "no:cacheprovider", "-o", "addopts=", "--tb=no")
TIMEOUT_S = 120.0
"""A mutant whose tests run longer than this is reported as killed (timeout)."""


@dataclass(frozen=True)
class Mutation:
    """One change to the product and the tests that must notice it.

    Attributes:
        id: short and stable (``--only`` takes it).
        rule: the rule the change breaks, one line.
        file: the file, relative to the repository root.
        old: text that occurs exactly once in ``file``.
        new: what replaces it.
        tests: pytest node ids or files (relative to the root) that must fail.
        fast: one of the CI subset (``--fast``).
    """

    id: str
    rule: str
    file: str
    old: str
    new: str
    tests: tuple[str, ...]
    fast: bool = False


def M(id: str, rule: str, file: str, old: str, new: str, *tests: str,
      fast: bool = False) -> Mutation:
    """A :class:`Mutation` (short to write in the list)."""
    return Mutation(id, rule, file, old, new, tests, fast)


PKG = "mecanum_mav/"
T = "tests/"
CO = T + "test_companion.py::"
FCS = T + "test_fcsetup.py::"
PAR = T + "test_params.py::"
AU = T + "test_auto.py::"
AR = T + "test_auto_arrival.py::"
MJ = T + "test_mujoco_chassis.py::"
PC = T + "test_shaping_pwm.py::"
PL = T + "test_plant_calibration.py::"
VW = T + "test_view.py::"
TF = T + "test_tlog_fast.py::"
TW = T + "test_twin.py::"
HB = T + "test_estimator_heading_bias.py::"
HS = T + "test_heading_bias.py::"
OG = T + "test_estimator_gain.py::"
BG = T + "test_heading_bias_bend.py::"

MUTATIONS: tuple[Mutation, ...] = (
    # ---------------------------------------------------------------- neutral on every way out
    M("core-shutdown-neutral", "shutdown sends neutral (each wheel's trim) before releasing",
      PKG + "control/output.py",
      "neutral = self.pwm.neutral()\n        self.pulses_us = neutral\n",
      "neutral = self.pulses_us\n",
      CO + "test_clean_shutdown_sends_neutral_then_releases_the_channels",
      fast=True),
    M("core-shutdown-release", "shutdown ends by releasing the wheel channels to the radio",
      PKG + "control/output.py",
      "return [hold, hold, RcOverride(*target, release_fields(self.pwm.channels))]",
      "return [hold, hold]",
      CO + "test_clean_shutdown_sends_neutral_then_releases_the_channels"),
    M("core-handler-neutral", "an exception in a message handler sends neutral at once",
      PKG + "control/core.py",
      'f"Error handling {kind}: neutral")\n        return self._override(self.pwm.neutral(), '
      "now_s)",
      'f"Error handling {kind}: neutral")\n        return self._override(self.pulses_us, now_s)',
      CO + ""
      "test_an_exception_in_a_message_handler_latches_neutral_until_the_next_valid_stick",
      fast=True),
    M("core-handler-latch", "after a handler's exception neutral stays latched",
      PKG + "control/core.py",
      "self.faulted = True\n        self.say(Severity.ERROR, f\"Error handling",
      "self.faulted = False\n        self.say(Severity.ERROR, f\"Error handling",
      CO + ""
      "test_an_exception_in_a_message_handler_latches_neutral_until_the_next_valid_stick"),
    M("core-output-exception", "an exception computing the output gives neutral",
      PKG + "control/core.py",
      "wheels, pulses = NEUTRAL_WHEELS, self.pwm.neutral()\n        self._output_wheels",
      "wheels, pulses = NEUTRAL_WHEELS, self.pulses_us\n        self._output_wheels",
      CO + "test_an_exception_in_the_control_path_ends_at_neutral_and_latches"),
    M("core-faulted-neutral", "a latched fault keeps the output neutral",
      PKG + "control/output.py",
      "if self.faulted:\n            self._autopilot_active = False",
      "if False:\n            self._autopilot_active = False",
      CO + "test_an_exception_in_the_control_path_ends_at_neutral_and_latches"),
    M("core-not-driving-neutral", "not driving (disarmed, HOLD, stale, failsafe) is neutral",
      PKG + "control/output.py",
      "if not vehicle.driving():\n            return NEUTRAL_WHEELS",
      "if False:\n            return NEUTRAL_WHEELS",
      CO + "test_sticks_while_disarmed_leave_the_wheels_at_neutral",
      CO + "test_hold_mode_keeps_neutral_while_armed"),
    M("core-fc-link-down", "a broken FC link fires the FC failsafe at once",
      PKG + "control/core.py",
      'if link == "fc":\n            self.vehicle.on_fc_link_down(now_s)',
      'if link == "fc":\n            pass',
      T + "test_link_drops.py"),
    M("vehicle-gcs-link-down", "a broken GCS link makes the stick stale at once",
      PKG + "control/vehicle.py",
      "self.input_s = None\n        if self.gcs_seen_s is not None:",
      "if self.gcs_seen_s is not None:",
      T + "test_vehicle_ways_out.py", T + "test_link_drops.py"),
    M("vehicle-driving-armed", "disarmed never drives", PKG + "control/vehicle.py",
      "self.armed and self.mode is Mode.MANUAL and not self.input_stale",
      "self.mode is Mode.MANUAL and not self.input_stale",
      CO + "test_sticks_while_disarmed_leave_the_wheels_at_neutral",
      fast=True),
    M("vehicle-driving-stale", "a stale stick never drives", PKG + "control/vehicle.py",
      "self.armed and self.mode is Mode.MANUAL and not self.input_stale",
      "self.armed and self.mode is Mode.MANUAL",
      CO + ""
      "test_stale_manual_control_returns_wheels_to_neutral_at_the_timeout_and_resumes",
      T + "test_vehicle_manual.py"),
    M("vehicle-driving-manual", "HOLD never drives", PKG + "control/vehicle.py",
      "self.armed and self.mode is Mode.MANUAL and not self.input_stale",
      "self.armed and not self.input_stale",
      CO + "test_hold_mode_keeps_neutral_while_armed"),
    M("vehicle-arm-waits-for-sticks", "after arming the wheels wait for a fresh stick",
      PKG + "control/vehicle.py",
      "self.input_stale = True  # the wheels wait for fresh sticks after arming",
      "pass",
      T + "test_vehicle_ways_out.py"),
    M("guided-setpoint-lapse", "a GUIDED velocity setpoint not renewed within GUID_TMO stops",
      PKG + "control/guided.py",
      "lapsed = sp is not None and now_s - sp.time_s > c.timeout_s",
      "lapsed = sp is not None and now_s - sp.time_s > 2 * c.timeout_s",
      T + "test_guided.py::test_a_velocity_setpoint_lapses_and_the_rover_stops", fast=True),
    M("guided-only-in-guided", "a setpoint outside GUIDED is refused", PKG + "control/gcsinput.py",
      "if self.vehicle.mode is not Mode.GUIDED:\n            self.refuse",
      "if False:\n            self.refuse",
      T + "test_guided.py::test_setpoints_outside_guided_are_refused_with_a_reason"),
    M("vehicle-autonomous-armed", "GUIDED and AUTO drive only while armed",
      PKG + "control/vehicle.py",
      "return self.armed and self.mode in _AUTONOMOUS and not (",
      "return self.mode in _AUTONOMOUS and not (",
      T + "test_guided_needs_arming.py", T + "test_guided.py"),
    M("auto-cannot-start-holds", "a mission that cannot start switches AUTO to HOLD",
      PKG + "control/core.py",
      'f"AUTO: {reason}: HOLD")\n                vehicle.request_mode(Mode.HOLD, now_s)',
      'f"AUTO: {reason}: HOLD")',
      T + "test_auto_that_cannot_start.py"),
    # ---- AUTO path following to the issue 25 standard (arrival, speed plan, heading)
    M("auto-speed-plan", "a pass-through waypoint is left slow enough to stop at the next stop",
      PKG + "control/pathfollow.py",
      "speed = min(arrive, corner_speed(legs[k - 1], legs[k], cruise, accel, overshoot_m))",
      "speed = corner_speed(legs[k - 1], legs[k], cruise, accel, overshoot_m)",
      AU + "test_pass_through_waypoints_plan_their_speed_so_the_rover_stops_at_the_next_stop",
      AU + "test_exit_speed_ahead_is_the_braking_speed_over_the_remaining_legs"),
    M("auto-pass-at-line", "a waypoint passed at speed is reached where the rover crosses it",
      PKG + "control/executor.py",
      "                if step.leg.errors(here)[0] + half_tick_m < step.leg.length_m:\n",
      "                if distance > step.radius and step.leg.errors(here)[0] < step.leg.length_m"
      ":\n",
      AR + "test_a_waypoint_passed_at_speed_is_reached_where_the_rover_crosses_it_not_at_the_"
      "radius"),
    M("auto-stop-settled", "a stop waypoint is reached once the rover has settled onto it",
      PKG + "control/executor.py",
      "            elif math.hypot(*velocity_ned) > SETTLED_MPS:\n",
      "            elif False:\n",
      AR + "test_a_stop_waypoint_is_reached_once_the_rover_has_settled_onto_it_inside_the_radius"),
    M("auto-stop-stalled", "a rover stalled inside a stop's radius goes on after a timeout",
      PKG + "control/executor.py",
      "if now_s - step.inside_s < SETTLE_TIMEOUT_S:",
      "if now_s - step.inside_s < 1e9 * SETTLE_TIMEOUT_S:",
      AR + "test_a_rover_stalled_inside_the_radius_of_a_stop_goes_on_after_the_settle_timeout"),
    M("auto-pose-lead", "between odometry steps the pose is carried forward by the commanded "
      "velocity", PKG + "control/autopilot.py",
      "lead = min(max(now_s - self._pose_seen_s, 0.0), MAX_POSE_LEAD_S)",
      "lead = 0.0 * MAX_POSE_LEAD_S",
      AR + "test_between_odometry_steps_the_pose_is_carried_forward_by_the_commanded_velocity"),
    M("auto-half-tick", "a waypoint passed at speed is reached at the tick nearest its line",
      PKG + "control/executor.py",
      "half_tick_m = self._follower.speed_along * tick_s / 2.0",
      "half_tick_m = 0.0 * tick_s",
      AR + "test_a_waypoint_passed_at_speed_is_reached_within_half_a_tick_of_its_line"),
    M("auto-yaw-schedule", "a waypoint's heading is turned along its leg, not commanded at once",
      PKG + "control/executor.py",
      "        if step.yaw_from is not None and self._yaw is not None:\n",
      "        if False:\n",
      AR + "test_a_waypoint_heading_is_turned_along_its_leg_and_held_as_the_rover_passes_it"),
    M("auto-yaw-feed-forward", "the heading schedule's rate is fed forward",
      PKG + "control/guided.py",
      "rate = feed_forward + c.yaw_gain * wrap_pi(target - pose.yaw_rad)",
      "rate = 0.0 * feed_forward + c.yaw_gain * wrap_pi(target - pose.yaw_rad)",
      AR + "test_a_yaw_rate_feed_forward_is_added_to_the_heading_controller",
      AR + "test_a_waypoint_heading_is_turned_along_its_leg_and_held_as_the_rover_passes_it"),
    M("auto-yaw-lead", "between gyro steps the heading is carried forward by the commanded rate",
      PKG + "control/autopilot.py",
      "wrap_pi(pose.yaw_rad + self.guided.yaw_rate * yaw_lead))",
      "wrap_pi(pose.yaw_rad + 0.0 * yaw_lead))",
      AR + "test_between_gyro_steps_the_heading_is_carried_forward_by_the_commanded_yaw_rate"),
    M("auto-corner-lead", "the turn onto the next leg begins before a waypoint passed at speed",
      PKG + "control/pathfollow.py",
      "share = min(1.0, 1.0 - max(remaining, 0.0) / lead_m)",
      "share = 0.0 * lead_m",
      AR + "test_the_turn_onto_the_next_leg_begins_early_so_the_path_stays_closer_to_the_polygon",
      AR + "test_corner_lead_moves_the_speed_onto_the_next_leg_as_the_waypoint_nears"),
    M("auto-disarm-neutral", "disarmed in AUTO or GUIDED the controllers never drive",
      PKG + "control/output.py",
      "if vehicle.autonomous():\n            self._autopilot_active = True",
      "if vehicle.mode in (Mode.GUIDED, Mode.AUTO):\n            self._autopilot_active = True",
      T + "test_missions.py::test_disarming_in_auto_sends_neutral_and_arming_resumes"),
    M("stick-rc-direction", "a GCS RC override above RCIN_TRIM is positive (forward, right, cw)",
      PKG + "control/sticks.py",
      "value = (pulse - trim) / span", "value = (trim - pulse) / span",
      CO + "test_ground_station_rc_override_drives_like_a_stick"),
    # ---------------------------------------------------------------- failsafes
    M("vehicle-stale-timeout", "FS_INPUT_TMO: no stick for the timeout is stale",
      PKG + "control/vehicle.py",
      "stale = self.input_s is None or now_s - self.input_s > c.input_timeout_s",
      "stale = self.input_s is None or now_s - self.input_s > 2 * c.input_timeout_s",
      CO + ""
      "test_stale_manual_control_returns_wheels_to_neutral_at_the_timeout_and_resumes",
      T + "test_vehicle_manual.py", fast=True),
    M("vehicle-fc-timeout", "FS_FC_TMO: no FC heartbeat for the timeout is FC loss",
      PKG + "control/vehicle.py",
      "now_s - self.fc_seen_s > c.fc_timeout_s", "now_s - self.fc_seen_s > 2 * c.fc_timeout_s",
      CO + "test_flight_controller_loss_disarms_reports_and_refuses_to_arm",
      fast=True),
    M("vehicle-fc-lost-disarms", "FC loss disarms", PKG + "control/vehicle.py",
      "if self.fc_lost and self.armed:", "if False:",
      CO + "test_flight_controller_loss_disarms_reports_and_refuses_to_arm"),
    M("vehicle-gcs-timeout", "FS_GCS_TMO: no GCS heartbeat for the timeout is the failsafe",
      PKG + "control/vehicle.py",
      "now_s - self.gcs_seen_s > c.gcs_timeout_s", "now_s - self.gcs_seen_s > 2 * c.gcs_timeout_s",
      CO + "test_ground_station_loss_triggers_the_failsafe_action_at_the_timeout",
      fast=True),
    M("vehicle-gcs-action", "FS_GCS_ACTION: 1 disarms, 0 switches to HOLD",
      PKG + "control/vehicle.py",
      "if c.gcs_action_disarm:", "if not c.gcs_action_disarm:",
      CO + "test_ground_station_loss_triggers_the_failsafe_action_at_the_timeout"),
    M("vehicle-rc-failsafe-action", "FS_RC_ACTION: a receiver failsafe holds or disarms",
      PKG + "control/vehicle.py",
      "if self.config.receiver_action_disarm:", "if not self.config.receiver_action_disarm:",
      T + "test_receiver.py"),
    M("vehicle-rc-timeout", "the receiver failsafe fires when RC_CHANNELS stop",
      PKG + "control/vehicle.py",
      "if rc_s is not None and now_s - rc_s > c.input_timeout_s and c.receiver_failsafe:",
      "if False:",
      T + "test_receiver.py"),
    # ---------------------------------------------------------------- pre-arm checks
    M("prearm-fc-link", "arming is refused while the FC link is down",
      PKG + "control/vehicle.py",
      'if self.fc_lost:\n            return self._refuse("PreArm: flight controller link down"',
      'if False:\n            return self._refuse("PreArm: flight controller link down"',
      CO + "test_arming_without_the_flight_controller_is_refused_as_a_pre_arm_check",
      fast=True),
    M("prearm-radio-failsafe", "arming is refused in the receiver failsafe",
      PKG + "control/vehicle.py",
      'if self.rc_failsafe:\n            return self._refuse("PreArm: radio failsafe',
      'if False:\n            return self._refuse("PreArm: radio failsafe',
      T + "test_receiver.py"),
    M("prearm-problems", "a failed pre-arm check refuses arming (unless forced)",
      PKG + "control/vehicle.py",
      "if problems and not force and self.config.arming_check:",
      "if problems and force and self.config.arming_check:",
      CO + "test_arming_with_the_sticks_deflected_is_refused_as_ardupilot_words_it",
      CO + "test_forced_arming_and_arming_check_0_skip_the_pre_arm_checks"),
    M("prearm-sticks-centred", "arming needs the sticks within the deadband",
      PKG + "control/context.py",
      "if abs(value) > self.input.deadband]", "if abs(value) > 1.0]",
      CO + "test_arming_with_the_sticks_deflected_is_refused_as_ardupilot_words_it"),
    M("prearm-fc-unsafe", "an unsafe FC setup refuses arming", PKG + "control/fccheck.py",
      "if state is FcCheckState.UNSAFE:", "if False:",
      FCS + "test_a_board_whose_setup_is_wrong_is_unsafe_and_blocks_arming",
      fast=True),
    M("prearm-fc-reading", "arming waits while the FC setup is read",
      PKG + "control/fccheck.py",
      "if state is FcCheckState.READING and self._reader is not None:", "if False:",
      FCS + "test_arming_waits_while_the_board_is_read_again_after_a_change"),
    M("prearm-fc-unconfirmed", "an unanswered FC setting refuses arming and is read again",
      PKG + "control/fccheck.py",
      "if state is FcCheckState.UNCONFIRMED:", "if False:",
      FCS + ""
      "test_a_setting_never_answered_is_not_confirmed_and_read_again_at_the_next_arm_attempt"),
    M("fccheck-reread-on-change", "a checked FC setting changed on the board is read again",
      PKG + "control/fccheck.py",
      "return self._read(now_s) if changed else []", "return []",
      FCS + "test_a_setting_changed_on_the_board_is_read_again_and_arming_waits_for_it"),
    M("fccheck-hazards", "a hazard found in the FC setup makes it unsafe",
      PKG + "control/fccheck.py",
      "if f.hazard]", "if f.hazard and f.value is None]",
      FCS + "test_a_board_whose_setup_is_wrong_is_unsafe_and_blocks_arming"),
    # ---------------------------------------------------------------- RC override fields
    M("rco-low-leave", "channels 1-8 not ours are 65535 (leave), never 0 (release)",
      PKG + "protocol/rcoverride.py",
      "_UNTOUCHED: Final = [LEAVE_LOW] * LOW_CHANNELS",
      "_UNTOUCHED: Final = [RELEASE_LOW] * LOW_CHANNELS",
      T + "test_rcoverride.py", fast=True),
    M("rco-high-leave", "channels 9-18 not ours are 0 (leave), never 65534 (release)",
      PKG + "protocol/rcoverride.py",
      "+ [LEAVE_HIGH] * (CHANNELS - LOW_CHANNELS)", "+ [RELEASE_HIGH] * (CHANNELS - LOW_CHANNELS)",
      T + "test_rcoverride.py"),
    M("rco-release-high", "releasing channels 9-18 writes 65534, not 0 (which leaves them)",
      PKG + "protocol/rcoverride.py",
      "RELEASE_LOW if channel <= LOW_CHANNELS else RELEASE_HIGH",
      "RELEASE_LOW if channel <= LOW_CHANNELS else RELEASE_LOW",
      T + "test_rcoverride.py", fast=True),
    M("rco-read-zero-low", "0 on channels 1-8 releases the channel",
      PKG + "protocol/rcoverride.py",
      "return RELEASE if raw == RELEASE_LOW else raw",
      "return LEAVE if raw == RELEASE_LOW else raw",
      T + "test_rcoverride.py"),
    M("rco-read-zero-high", "0 on channels 9-18 leaves the channel",
      PKG + "protocol/rcoverride.py",
      "if raw == LEAVE_HIGH:\n        return LEAVE",
      "if raw == LEAVE_HIGH:\n        return RELEASE",
      T + "test_rcoverride.py"),
    M("rco-read-65534", "65534 on channels 9-18 releases the channel",
      PKG + "protocol/rcoverride.py",
      "return RELEASE if raw == RELEASE_HIGH else raw", "return raw",
      T + "test_rcoverride.py"),
    M("rco-boundary", "channel 8 follows the channels 1-8 convention",
      PKG + "protocol/rcoverride.py",
      "if channel <= LOW_CHANNELS:\n        return RELEASE",
      "if channel < LOW_CHANNELS:\n        return RELEASE",
      T + "test_rcoverride.py"),
    M("rco-65535-high", "65535 leaves channels 9-18 alone too", PKG + "protocol/rcoverride.py",
      "if raw == LEAVE_LOW:\n        return LEAVE",
      "if raw == LEAVE_LOW and channel <= LOW_CHANNELS:\n        return LEAVE",
      T + "test_rcoverride.py"),
    M("rco-channel-slot", "channel n is field chan{n}_raw", PKG + "protocol/rcoverride.py",
      "fields[channel - 1] = int(pulse)", "fields[channel % CHANNELS] = int(pulse)",
      T + "test_rcoverride.py"),
    # ---------------------------------------------------------------- stick input
    M("stick-pulse-range", "a GCS RC override pulse outside 800..2200 us is refused whole",
      PKG + "control/sticks.py",
      "PULSE_RANGE_US = (800, 2200)", "PULSE_RANGE_US = (1, 65533)",
      CO + "test_ground_station_rc_override_with_an_absurd_pulse_is_rejected"),
    M("stick-axis-range", "a MANUAL_CONTROL axis outside +-1000 is refused, never clamped",
      PKG + "control/sticks.py",
      "if not -1000 <= value <= 1000:", "if not -32768 <= value <= 32767:",
      CO + "test_out_of_range_stick_is_rejected_and_never_moves_the_robot"),
    M("stick-invalid-axis", "0x7FFF marks an axis invalid: it reads 0",
      PKG + "control/sticks.py",
      "if value == INVALID_AXIS:\n        return 0.0", "if False:\n        return 0.0",
      CO + "test_invalid_axis_reads_as_zero"),
    M("stick-z-range", "MAN_Z_SCALE: z outside 0..1000 is refused (a negative z reverses)",
      PKG + "control/sticks.py",
      "if not 0 <= z <= 1000:", "if not -1000 <= z <= 1000:",
      T + "test_stick_decoding.py"),
    M("core-stick-target", "MANUAL_CONTROL for another system is ignored",
      PKG + "control/gcsinput.py",
      "if not (self._for_us(msg.target) and self._from_pilot(msg)):",
      "if not self._from_pilot(msg):",
      CO + "test_manual_control_for_another_system_is_ignored"),
    M("core-from-pilot", "SYSID_MYGCS restricts who may drive", PKG + "control/context.py",
      "return gcs == 0 or msg.get_srcSystem() == gcs", "return True",
      CO + "test_a_restricted_ground_station_id_ignores_other_senders"),
    # ---------------------------------------------------------------- the stick lane
    M("lane-target", "the lane refuses a stick addressed to another vehicle",
      PKG + "control/lane.py",
      "if (to and to != sysid) or (pilot and datagram[5] != pilot):",
      "if (pilot and datagram[5] != pilot):",
      T + "test_lane.py", fast=True),
    M("lane-pilot", "the lane refuses a stick from another sender than SYSID_MYGCS",
      PKG + "control/lane.py",
      "if (to and to != sysid) or (pilot and datagram[5] != pilot):",
      "if (to and to != sysid):",
      T + "test_lane.py"),
    M("lane-axis-range", "the lane refuses an axis outside +-1000",
      PKG + "control/lane.py",
      "if not (-1000 <= x <= 1000 and -1000 <= y <= 1000 and -1000 <= r <= 1000):",
      "if False:",
      T + "test_lane.py", fast=True),
    M("lane-z-range", "the lane refuses z outside 0..1000 with MAN_Z_SCALE",
      PKG + "control/lane.py",
      "if not 0 <= z <= 1000:\n                return None",
      "if False:\n                return None",
      T + "test_lane.py"),
    M("lane-one-message", "the lane answers only a datagram holding exactly one message",
      PKG + "control/lane.py",
      "if size != end + 2 or length", "if size < end + 2 or length",
      T + "test_lane.py"),
    M("lane-crc", "the lane refuses a bad CRC", PKG + "control/lane.py",
      "or length > manual_size or (", "or length > manual_size or False and (",
      T + "test_lane.py"),
    M("core-lane-gate", "the lane answers only while driving in MANUAL",
      PKG + "control/core.py",
      "if now_s >= self._lane_until_s or self.faulted or not self._lane_driving:",
      "if now_s >= self._lane_until_s or self.faulted:",
      T + "test_lane.py", T + "test_companion.py"),
    # ---------------------------------------------------------------- signing
    M("sign-bad-signature", "a packet signed with another key (or altered) is refused",
      PKG + "protocol/signing.py",
      "if not hmac.compare_digest(signature(self.key, packet[:-6]), packet[-6:]):", "if False:",
      T + "test_signing.py", fast=True),
    M("sign-unsigned", "an unsigned packet is refused where signing is required",
      PKG + "protocol/signing.py",
      "or not packet[2] & IFLAG_SIGNED):", "or False):",
      T + "test_signing_refusal_kinds.py", T + "test_signing.py"),
    M("sign-replay", "a signed packet not newer than its stream's last is a replay",
      PKG + "protocol/signing.py",
      "if timestamp <= last:", "if timestamp < last:",
      T + "test_signing.py"),
    M("sign-too-old", "a new stream more than a minute behind is refused",
      PKG + "protocol/signing.py",
      "elif timestamp + NEW_STREAM_WINDOW_TICKS < self.timestamp:", "elif False:",
      T + "test_signing.py"),
    M("sign-key-length", "a hex key that is not 64 digits is refused, not a passphrase",
      PKG + "protocol/signing.py",
      "if len(body) != 2 * KEY_LEN:", "if len(body) > 2 * KEY_LEN:",
      T + "test_signing.py"),
    M("link-signed-fast-stick", "a signing link drops an unsigned MANUAL_CONTROL (fast decode)",
      PKG + "protocol/framing.py",
      "if check is None or check.check(data) is _ACCEPTED:\n                    return [fast]",
      "if True:\n                    return [fast]",
      T + "test_signed_link_checks_every_datagram.py", T + "test_signing_process.py"),
    M("link-signed-messages", "a signing link keeps only correctly signed, fresh messages",
      PKG + "protocol/framing.py",
      "return [m for m in messages if check.check(m.get_msgbuf()) is _ACCEPTED]",
      "return messages",
      T + "test_signing_process.py", T + "test_signing.py"),
    M("link-signed-no-lane", "a signing link never hands datagrams to the unchecked stick lane",
      PKG + "io/links/base.py",
      "return self.signature_check is None and not self.conn.mav.signing.sign_outgoing",
      "return True",
      T + "test_signed_link_checks_every_datagram.py", T + "test_stream_lane.py"),
    M("prearm-force-magic", "only param2 21196 forces an arm past the pre-arm checks",
      PKG + "control/commands.py",
      "force=p[1] == FORCE_ARM_MAGIC))", "force=p[1] != 0))",
      T + "test_arming_rules.py"),
    M("core-fc-sysid", "on the FC link only the flight controller's own messages count",
      PKG + "control/core.py",
      "if msg.get_srcSystem() == self.identity.fc_sysid:", "if True:",
      T + "test_arming_rules.py"),
    M("heartbeat-armed-flag", "the HEARTBEAT says armed (SAFETY_ARMED) exactly when armed",
      PKG + "protocol/heartbeat.py",
      "if armed:\n        base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED",
      "if failsafe:\n        base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED",
      T + "test_companion.py"),
    M("heartbeat-critical", "a link failsafe shows as CRITICAL in the HEARTBEAT",
      PKG + "protocol/heartbeat.py",
      "if failsafe:\n        status = mavlink.MAV_STATE_CRITICAL", "if False:\n        status = 0",
      CO + "test_flight_controller_loss_disarms_reports_and_refuses_to_arm"),
    M("rcin-throttle-failsafe", "a receiver throttle below FS_THR_VALUE is the radio failsafe",
      PKG + "control/rcinput.py",
      "if channel == sticks.throttle_ch and pulse < config.throttle_fs_us:", "if False:",
      T + "test_receiver.py"),
    M("rcin-rssi", "a receiver reporting RSSI 0 is the radio failsafe", PKG + "control/rcinput.py",
      "if rssi == 0:", "if False:", T + "test_receiver.py"),
    M("rcin-no-pulse", "a stick channel without a pulse is the radio failsafe",
      PKG + "control/rcinput.py",
      "if not low <= pulse <= high:\n                return ReceiverFrame",
      "if False:\n                return ReceiverFrame", T + "test_receiver_frames.py"),
    M("lane-override-source", "overrides go out as FC_GCS_SYSID (ArduPilot obeys only its GCS id)",
      PKG + "control/lane.py",
      "source_system = identity.fc_gcs_sysid", "source_system = identity.sysid",
      T + "test_lane.py"),
    M("guided-absurd-speed", "a setpoint faster than 50 m/s is refused, not clamped",
      PKG + "protocol/limits.py",
      "MAX_SPEED_MPS: Final[float] = 50.0", "MAX_SPEED_MPS: Final[float] = 1000.0",
      T + "test_guided.py"),
    # ---------------------------------------------------------------- layers
    M("layer-upward-import", "a lower layer never imports a higher one (mecanum -> io)",
      PKG + "mecanum/geometry.py",
      "from __future__ import annotations\n",
      "from __future__ import annotations\n\nimport mecanum_mav.io.links  # noqa: F401\n",
      T + "test_architecture.py", fast=True),
    M("layer-relative-import", "a lower layer never imports a higher one, relative import too",
      PKG + "mecanum/geometry.py",
      "from __future__ import annotations\n",
      "from __future__ import annotations\n\nfrom ..io import links  # noqa: F401\n",
      T + "test_architecture.py"),
    M("layer-protocol-imports-control", "protocol never imports control",
      PKG + "protocol/rcoverride.py",
      "from typing import Final\n",
      "from typing import Final\n\nimport mecanum_mav.control.pwm  # noqa: F401\n",
      T + "test_architecture.py"),
    M("layer-core-socket", "the pure layers never import sockets", PKG + "control/vehicle.py",
      "import math\n", "import math\nimport socket  # noqa: F401\n",
      T + "test_architecture.py"),
    # ---------------------------------------------------------------- parameter validation
    M("param-range", "a parameter value outside its range is refused", PKG + "config/spec.py",
      "if not self.minimum <= x <= self.maximum:\n            raise ParamError",
      "if False:\n            raise ParamError",
      PAR + "test_set_rejects_a_bad_value_with_a_clear_message_and_keeps_the_old_one"),
    M("param-integer", "an int parameter refuses a fraction", PKG + "config/spec.py",
      "if self.kind is int and not x.is_integer():", "if False:",
      PAR + "test_set_rejects_a_bad_value_with_a_clear_message_and_keeps_the_old_one"),
    M("param-finite", "a parameter refuses NaN and infinity", PKG + "config/spec.py",
      "if not math.isfinite(x):\n            raise ParamError",
      "if False:\n            raise ParamError",
      PAR + "test_set_rejects_a_bad_value_with_a_clear_message_and_keeps_the_old_one"),
    M("param-min-trim-max", "MIN < TRIM < MAX for every pulse triple", PKG + "config/rules.py",
      "if low < trim < high:", "if low <= trim <= high:",
      PAR + "test_min_trim_max_order_is_checked_and_cited_at_the_last_involved_line",
      T + "test_param_rules.py"),
    M("param-distinct-channels", "two wheels never share an RC channel", PKG + "config/rules.py",
      "            if len(on_channel) > 1\n", "            if len(on_channel) > 2\n",
      T + "test_param_channel_sharing.py", PAR + "test_duplicate_channels_are_caught"),
    M("param-receiver-wheel", "with RCIN_ENABLE 1 no wheel is on a receiver channel",
      PKG + "config/rules.py",
      'if values["RCIN_ENABLE"] == 1:', 'if values["RCIN_ENABLE"] == 2:',
      T + "test_params.py", T + "test_param_rules.py", T + "test_receiver.py"),
    M("paramfile-typo", "a misspelt name in a parameter file is an error, not ignored",
      PKG + "io/paramfile.py",
      "if name not in SPECS:\n            errors.append(where + unknown_name(name))",
      "if name not in SPECS:\n            pass",
      PAR + "test_a_file_with_several_mistakes_reports_every_one_with_file_and_line"),
    M("paramfile-duplicate", "a parameter set twice in a file is an error", PKG + "io/paramfile.py",
      "if duplicate:\n            errors.append", "if False:\n            errors.append",
      PAR + "test_a_file_with_several_mistakes_reports_every_one_with_file_and_line"),
    M("paramfile-trailing-text", "text after the value is an error", PKG + "io/paramfile.py",
      "if len(rest) > 1:", "if len(rest) > 2:",
      PAR + "test_a_file_with_several_mistakes_reports_every_one_with_file_and_line"),
    M("paramfile-rules", "a parameter file that breaks a cross-parameter rule is refused",
      PKG + "io/paramfile.py",
      "for message, names in consistency_problems(candidate):", "for message, names in []:",
      PAR + "test_min_trim_max_order_is_checked_and_cited_at_the_last_involved_line"),
    M("cli-params-markdown", "params --markdown prints the parameter table",
      PKG + "app/cli.py",
      "if args.markdown:\n        print(markdown_table())",
      "if False:\n        print(markdown_table())",
      T + "test_cli.py::test_params_markdown_lists_every_parameter"),
    M("param-set-refused", "a refused PARAM_SET changes and saves nothing, and says why",
      PKG + "control/paramlink.py",
      "if problem:\n            self.refuse(Refusal.PARAM",
      "if False:\n            self.refuse(Refusal.PARAM",
      T + "test_param_protocol.py"),
    M("param-set-takes-effect", "an accepted PARAM_SET takes effect at once (no restart)",
      PKG + "control/paramlink.py",
      "self.reconfigure()\n        if name in RESTART_REQUIRED:",
      "if name in RESTART_REQUIRED:",
      T + "test_param_protocol.py"),
    M("param-set-for-us", "a PARAM_SET for another system is ignored", PKG + "control/paramlink.py",
      "validated, answered, applied and kept (module docstring).\"\"\"\n"
      "        if not (self._for_us(msg.target_system, msg.target_component) and "
      "self._from_pilot(msg)):",
      "validated, answered, applied and kept (module docstring).\"\"\"\n"
      "        if not self._from_pilot(msg):",
      T + "test_param_protocol.py"),
    # ---------------------------------------------------------------- setup-fc's hazards
    M("fcsetup-gcs-id", "MAV_GCS_SYSID must be the companion's FC_GCS_SYSID",
      PKG + "protocol/fcsetup.py", "gcs is not None and gcs != own))", "False))",
      T + "test_fcsetup.py"),
    M("fcsetup-plain-passthrough", "the plain RCINn pass-through holds the last command: unsafe",
      PKG + "protocol/fcsetup.py",
      "fn is not None and fn != scaled))", "fn is not None and fn != scaled and fn != 50 + ch))",
      FCS + "test_plain_passthrough_holds_the_last_command_after_the_companion_dies"),
    M("fcsetup-fs-mask", "each wheel channel's SERVO_RC_FS_MSK bit must be set",
      PKG + "protocol/fcsetup.py", "masked == 0.0))", "False))", T + "test_fcsetup.py"),
    M("fcsetup-ranges", "RC/SERVO MIN/TRIM/MAX must equal MOT_x's", PKG + "protocol/fcsetup.py",
      "value is not None and value != want))", "value is not None and abs(value - want) > 50))",
      T + "test_fcsetup.py"),
    M("fcsetup-dead-zone", "RCn_DZ must be 0", PKG + "protocol/fcsetup.py",
      "dz is not None and dz != 0))", "dz is not None and dz > 30))", T + "test_fcsetup.py"),
    M("fcsetup-override-time", "RC_OVERRIDE_TIME above 1 s is a hazard",
      PKG + "protocol/fcsetup.py",
      "not 0 < timeout <= OVERRIDE_TIME_MAX_S))", "not 0 < timeout <= 3 * OVERRIDE_TIME_MAX_S))",
      T + "test_fcsetup.py"),
    M("fcsetup-override-never", "RC_OVERRIDE_TIME 0 (ignore) or -1 (for ever) is a hazard",
      PKG + "protocol/fcsetup.py",
      "not 0 < timeout <= OVERRIDE_TIME_MAX_S))", "timeout > OVERRIDE_TIME_MAX_S))",
      T + "test_fcsetup.py"),
    M("fcsetup-throttle", "RCMAP_THROTTLE must be a wheel channel the companion refreshes",
      PKG + "protocol/fcsetup.py",
      "throttle is not None and throttle not in refreshed))", "False))", T + "test_fcsetup.py"),
    M("fcsetup-fs-thr", "FS_THR_ENABLE 0 is a hazard", PKG + "protocol/fcsetup.py",
      "fs_thr == 0))", "False))", T + "test_fcsetup.py"),
    M("fcsetup-rudder", "ARMING_RUDDER must be 0 (a diagonal drive would arm or disarm)",
      PKG + "protocol/fcsetup.py", "rudder is not None and rudder != 0))", "False))",
      T + "test_fcsetup.py"),
    M("fcsetup-apply-mask", "--apply sets each wheel channel's failsafe mask bit",
      PKG + "protocol/fcsetup.py", "mask |= 1 << (ch - 1)", "mask |= 1 << ch",
      T + "test_fcsetup.py"),
    M("fcsetup-apply-throttle", "--apply puts RCMAP_THROTTLE on a wheel channel",
      PKG + "protocol/fcsetup.py",
      'out["RCMAP_THROTTLE"] = wheels[0][1]', 'out["RCMAP_THROTTLE"] = 3',
      T + "test_fcsetup.py"),
    M("fcsetup-nudge", "only pulse widths, dead zones and the override time are nudged",
      PKG + "protocol/fcsetup.py",
      "if name == \"RC_OVERRIDE_TIME\":\n        return value + 0.1\n    return None",
      "if name == \"RC_OVERRIDE_TIME\":\n        return value + 0.1\n    return value + 1",
      T + "test_fcsetup.py"),
    M("setupfc-hazard-exit", "setup-fc exits 1 while a hazard remains", PKG + "app/setupfc.py",
      "if hazards:\n            out.write(", "if False:\n            out.write(",
      T + "test_setup_fc_verdict.py"),
    M("setupfc-unanswered-exit", "setup-fc never calls a board safe with a setting unanswered",
      PKG + "app/setupfc.py",
      "if reading.missing:\n            out.write(", "if False:\n            out.write(",
      T + "test_setup_fc_verdict.py"),
    M("setupfc-hazard-row", "setup-fc marks a hazard's row HAZARD", PKG + "app/setupfc.py",
      "if finding.hazard:", "if False:",
      T + "test_setup_fc_verdict.py"),
    M("setupfc-reads-the-board", "setup-fc judges the board's own values", PKG + "app/setupfc.py",
      "findings = check(self.params, reading.values)",
      "findings = check(self.params, safe_settings(self.params, reading.values))",
      T + "test_setup_fc_verdict.py"),
    # ---------------------------------------------------------------- mixing and kinematics
    M("mix-pattern", "FL = x+y+r, FR = x-y-r, RL = x-y+r, RR = x+y-r",
      PKG + "mecanum/desaturation.py",
      "return (a + r, b - r, b + r, a - r)", "return (a + r, b + r, b - r, a - r)",
      T + "test_mixing.py", T + "test_wheels.py"),
    M("mix-lateral", "y right: the FL/RR pair is x + y", PKG + "mecanum/scalarmix.py",
      "return mix_pairs(xs + ys, xs - ys, _clamp1(r), priority)",
      "return mix_pairs(xs - ys, xs + ys, _clamp1(r), priority)",
      T + "test_mixing.py", T + "test_wheels.py"),
    M("mix-desaturate", "wheel commands are desaturated to [-1, 1]",
      PKG + "mecanum/desaturation.py",
      "if t + ar > 1.0:", "if t + ar > 2.0:", T + "test_mixing.py"),
    M("mix-rotation-priority", "rotation priority keeps the rotation whole",
      PKG + "mecanum/desaturation.py",
      "k0, k1, k2, k3, o0, o1, o2, o3 = r0, r1, r2, r3, t0, t1, t2, t3",
      "k0, k1, k2, k3, o0, o1, o2, o3 = t0, t1, t2, t3, r0, r1, r2, r3",
      T + "test_mixing.py"),
    M("mix-nonfinite", "a non-finite input stops the wheels (never NaN)",
      PKG + "mecanum/desaturation.py",
      "if (w0 - w0) + (w1 - w1) + (w2 - w2) + (w3 - w3) != 0.0:  # a sum that overflowed",
      "if False:", T + "test_wheel_output_edges.py", T + "test_mixing.py"),
    M("wheels-lateral-signs", "the roller signs of the X arrangement", PKG + "mecanum/wheels.py",
      "LATERAL_SIGNS: tuple[float, float, float, float] = (1.0, -1.0, -1.0, 1.0)",
      "LATERAL_SIGNS: tuple[float, float, float, float] = (1.0, -1.0, 1.0, -1.0)",
      T + "test_wheels.py", T + "test_kinematics.py"),
    M("chassis-y-sign", "forward kinematics: y = (FL - FR - RL + RR) / 4",
      PKG + "mecanum/mixing.py",
      "(fl - fr - rl + rr) * 0.25", "(-fl + fr + rl - rr) * 0.25",
      T + "test_wheels.py", T + "test_mixing.py"),
    M("kin-rotation-sign", "a clockwise yaw rate speeds up the left wheels",
      PKG + "mecanum/kinematics.py",
      "fl = vxc + vyc + w * k_fl", "fl = vxc + vyc - w * k_fl",
      T + "test_kinematics.py"),
    M("kin-centre-of-rotation", "turning about an offset centre moves the robot centre",
      PKG + "mecanum/kinematics.py",
      "vyc = (float(vy) - w * float(cx)) * self._lateral_gain",
      "vyc = (float(vy) + w * float(cx)) * self._lateral_gain",
      T + "test_kinematics.py"),
    M("shaping-deadband", "a stick inside the deadband is zero", PKG + "mecanum/shaping.py",
      "if abs(v) <= deadband:", "if abs(v) < 0.0:", T + "test_shaping_pwm.py"),
    # ---------------------------------------------------------------- PWM edge
    M("pwm-reverse", "MOT_x_REV mirrors a wheel at the PWM edge", PKG + "control/pwm.py",
      "c = sign * command", "c = 1.0 * command",
      T + "test_shaping_pwm.py", CO + ""
      "test_reverse_and_channel_map_parameters_move_the_output"),
    M("pwm-limit", "a wheel command beyond +-1 is limited to MIN..MAX", PKG + "control/pwm.py",
      "                c = 1.0 if c > 0.0 else -1.0\n", "                pass\n",
      T + "test_shaping_pwm.py"),
    M("pwm-sides", "each side of trim spans to its own end (off-centre trim)",
      PKG + "control/pwm.py",
      "pulses.append(round(trim + c * (up if c >= 0.0 else down)))",
      "pulses.append(round(trim + c * up))", T + "test_shaping_pwm.py"),
    M("pwm-nonfinite", "a non-finite wheel command gives trim", PKG + "control/pwm.py",
      "if not math.isfinite(c):\n                    pulses.append(trim)",
      "if False:\n                    pulses.append(trim)", T + "test_shaping_pwm.py"),
    M("pwm-neutral-trim", "neutral is each wheel's own trim", PKG + "control/pwm.py",
      "(w[0].trim, w[1].trim, w[2].trim, w[3].trim)", "(w[0].trim, w[1].trim, w[2].trim, 1500)",
      T + "test_wheel_output_edges.py"),
    # ---------------------------------------------------------------- mission protocol
    M("mission-replace-at-end", "an upload replaces the mission only after its last item",
      PKG + "protocol/missionservice.py",
      "upload.items.append(item)\n",
      "upload.items.append(item)\n        self._replace(upload.items)\n",
      T + "test_mission_protocol.py"),
    M("mission-second-gcs", "a second ground station is denied mid-upload",
      PKG + "protocol/missionservice.py",
      "if upload.src != src:\n                self._error(\"Mission upload denied",
      "if False:\n                self._error(\"Mission upload denied",
      T + "test_mission_protocol.py"),
    M("mission-no-space", "more items than MAX_ITEMS get NO_SPACE",
      PKG + "protocol/missionservice.py", "if count > MAX_ITEMS:", "if count > MAX_ITEMS + 1:",
      T + "test_mission_protocol.py"),
    M("mission-retries", "an upload is cancelled after MAX_RETRIES requests",
      PKG + "protocol/missionservice.py",
      "if upload.retries >= MAX_RETRIES:", "if upload.retries > MAX_RETRIES:",
      T + "test_mission_protocol.py"),
    M("mission-item-check", "an invalid item aborts the upload with its result code",
      PKG + "protocol/missionservice.py",
      "            check_item(item, upload.count)\n", "",
      T + "test_mission_protocol.py"),
    M("mission-out-of-sequence", "an out-of-sequence item is dropped, the expected one asked",
      PKG + "protocol/missionservice.py",
      "if seq > upload.expected:", "if seq > upload.expected + 1:",
      T + "test_mission_protocol.py"),
    M("mission-download-range", "a download request past the end gets INVALID_SEQUENCE",
      PKG + "protocol/missionservice.py",
      "if not 0 <= seq < len(self.items):", "if not -1 <= seq < len(self.items):",
      T + "test_mission_protocol.py"),
    M("mission-fence-upload", "a fence or rally upload is unsupported (only missions stored)",
      PKG + "protocol/missionservice.py",
      "        if mission_type != _MISSION:\n            return [_ack(src, mavlink.MAV_MISSION_"
      "UNSUPPORTED, mission_type)]\n        upload = self._upload\n        if upload is not None:\n"
      "            if upload.src != src:",
      "        upload = self._upload\n        if upload is not None:\n"
      "            if upload.src != src:",
      T + "test_mission_protocol.py"),
    # ---------------------------------------------------------------- the loop (runtime/loop.py)
    M("loop-lane-unused", "the loop answers the pilot's stick datagram in the stick lane",
      PKG + "runtime/loop.py",
      "packet = (self.core.stick_lane(data, now, self._fc_mav.seq)\n"
      "                  if self._lane_links and (self._fc_datagrams or "
      "self.fc.takes_packet())\n"
      "                  else None)",
      "packet = None",
      T + "test_loop.py", T + "test_lane.py", T + "test_stream_lane.py"),
    M("loop-lane-asks-the-link", "the lane answers only when the FC link takes its packet at once",
      PKG + "runtime/loop.py",
      "(self._fc_datagrams or self.fc.takes_packet())", "True",
      T + "test_stream_lane.py"),
    M("loop-idle-follows-new-fd", "a settled pass still follows a stream link whose descriptor "
      "changed", PKG + "runtime/loop.py",
      " or link.wait_fd() != fd:", ":",
      T + "test_loop.py"),
    M("loop-idle-unwatches-write", "a settled pass stops watching a stream link for writing once "
      "nothing waits", PKG + "runtime/loop.py",
      "            if writing or link.pending", "            if link.pending",
      T + "test_loop.py"),
    M("loop-stick-pass-fc-busy", "a pass of sticks ends when the lane's write left the flight "
      "controller's stream link busy", PKG + "runtime/loop.py",
      "(self._fc_datagrams or (fc.up and not fc.pending))", "True",
      T + "test_loop.py"),
    M("loop-stick-pass-unused", "a stick right after a stick in its lane is the whole pass",
      PKG + "runtime/loop.py", "if self._next_stick(ready):", "if False:",
      T + "test_loop.py"),
    M("loop-stick-pass-rest", "what waits behind a stick a pass of sticks answered is read at "
      "once (the next wait, level-triggered, returns at once; the lockstep's step runs that "
      "pass)", PKG + "sim/lockstep.py",
      "            if not any(link.readable() for link in links):",
      "            if True:",
      T + "test_loop.py"),
    M("loop-stick-pass-bounded", "a pass of sticks waits no longer than the timers allow",
      PKG + "runtime/loop.py", "self._sticks_until_s = due  #",
      "self._sticks_until_s = math.inf  #",
      T + "test_stream_lane.py::test_after_the_pilots_last_stick_in_its_lane_the_refresh_and_"
      "the_input_timeout_still_come"),
    M("child-dies-with-parent", "a companion process ends when its parent is killed",
      PKG + "sim/process.py", "preexec_fn=dies_with_this_thread(signal.SIGTERM)",
      "preexec_fn=None", T + "test_process_cleanup.py"),
    M("firmware-dies-with-parent", "the firmware ends when its parent is killed",
      PKG + "sim/firmware.py", "preexec_fn=dies_with_this_thread(signal.SIGKILL)",
      "preexec_fn=None", T + "test_process_cleanup.py"),
    M("loop-yield-before-housekeeping", "a pass that answered a stick yields the CPU before "
      "its housekeeping (a pty's delivery of the override runs then)", PKG + "runtime/loop.py",
      "        if self._laned:  # (a pty", "        if False:  # (a pty",
      T + "test_loop.py::test_a_pass_that_answered_a_stick_yields_the_cpu_before_its_"
      "housekeeping_and_only_then"),
    M("loop-yield-stick-pass", "a pass of sticks that goes on to housekeeping counts its stick",
      PKG + "runtime/loop.py",
      "            return False\n        self._laned = True\n",
      "            return False\n",
      T + "test_loop.py::test_a_pass_that_answered_a_stick_yields_the_cpu_before_its_"
      "housekeeping_and_only_then"),
    M("loop-yield-only-after-stick", "a pass without a stick in the lane never yields",
      PKG + "runtime/loop.py", "self._laned |= self._answer_first(link, now)",
      "self._laned = True; self._answer_first(link, now)",
      T + "test_loop.py::test_a_pass_that_answered_a_stick_yields_the_cpu_before_its_"
      "housekeeping_and_only_then"),
    M("loop-stick-pass-settled", "a pass of sticks ends when the core has something to do",
      PKG + "runtime/loop.py",
      "return self.core.settled(now) and (self._fc_datagrams or (fc.up and not fc.pending))",
      "return True",
      T + "test_loop.py", T + "test_companion.py", T + "test_stream_lane.py"),
    M("loop-lane-signed", "the lane never answers on a signed link",
      PKG + "runtime/loop.py",
      "self._lane_links = gcs.unchecked and fc.unchecked",
      "self._lane_links = True",
      T + "test_signing.py", T + "test_signed_link_checks_every_datagram.py", T + "test_lane.py"),
    M("loop-answers-every-message", "every message read goes to the core, in order",
      PKG + "runtime/loop.py",
      "        for msg in messages:\n            out = handle(msg, now, from_fc=from_fc)",
      "        for msg in messages[-1:]:\n            out = handle(msg, now, from_fc=from_fc)",
      T + "test_companion.py", T + "test_mission_protocol.py"),
    M("loop-reports-a-break", "a stream link that broke is reported to the core when read",
      PKG + "runtime/loop.py",
      "        if not link.steady:\n            self._report(link, now)",
      "        if False:\n            self._report(link, now)",
      T + "test_link_drops.py"),
    M("loop-tells-link-up", "a link back up is told to the core (its first override neutral)",
      PKG + "runtime/loop.py",
      "        if up:\n            self._write(self.core.link_up(link.name, now))",
      "        if up:\n            pass",
      T + "test_link_drops.py"),
    M("loop-refusals-counted", "what a signature check dropped is counted and said",
      PKG + "runtime/loop.py",
      "            if rejected:  # unsigned",
      "            if False:  # unsigned",
      T + "test_signing.py"),
    M("loop-wakes-for-nothing", "a wake before anything is due, with nothing to read, does "
      "nothing", PKG + "runtime/loop.py",
      "        if not ready and now < due:\n            return",
      "        if False:\n            return",
      T + "test_loop.py"),
    M("loop-shutdown-order", "shutdown sends every override of the core's last words, in order",
      PKG + "runtime/loop.py",
      "        for override in neutral:", "        for override in neutral[:0]:",
      CO + "test_clean_shutdown_sends_neutral_then_releases_the_channels",
      T + "test_interrupts.py"),
    # ---------------------------------------------------------------- the links' timers
    M("link-reopen-period", "a broken serial or TCP link tries to reopen every 0.5 s",
      PKG + "io/links/base.py", "REOPEN_PERIOD_S = 0.5", "REOPEN_PERIOD_S = 1.0",
      T + "test_link_timing.py"),
    M("link-pacing-baud", "a serial link hands over no faster than its baud rate carries",
      PKG + "io/links/serialport.py",
      "            self._wire_free_s = max(self._wire_free_s, now) + n / rate",
      "            self._wire_free_s = max(self._wire_free_s, now) + n / rate / 4",
      T + "test_link_timing.py"),
    M("link-override-newest-wins", "a waiting override is replaced by a newer one (stream)",
      PKG + "io/links/stream.py",
      "        if replace:\n            self._override = (target_system, target_component, "
      "channels)",
      "        if False:\n            self._override = (target_system, target_component, "
      "channels)",
      T + "test_link_timing.py", T + "test_serial_pacing.py", T + "test_links.py"),
    M("link-lane-waits-its-turn", "a stream link never lets the lane's packet pass a waiting one",
      PKG + "io/links/stream.py",
      "        if self._head or self._override is not None or self._queue:\n"
      "            return False",
      "        if False:\n            return False",
      T + "test_stream_lane.py"),
    M("link-lane-paced", "a stream link takes the lane's packet only while the wire is free",
      PKG + "io/links/stream.py",
      "        return self._idle_and_open() and self._free_in_s(self.clock()) <= 0.0",
      "        return self._idle_and_open()",
      T + "test_stream_lane.py"),
    M("link-lane-follows-device", "after the lane's write a serial link learns the kernel's queue",
      PKG + "io/links/serialport.py",
      "            self._backlog_s(now)  # a device slower",
      "            pass  # a device slower",
      T + "test_stream_lane.py"),
    M("link-bcast-reply", "a udpbcast link sends to the address that answered it",
      PKG + "io/links/datagram.py", "        self.conn.last_address = address\n", "",
      T + "test_link_classes.py"),
    M("link-class-signed-udpin", "a signed udpin link told to is the one that tells refusals",
      PKG + "io/links/__init__.py", "        if signing_key is not None and tell_refused:",
      "        if False:", T + "test_link_classes.py", T + "test_refused_senders.py"),
    # ---------------------------------------------------------------- what is stored
    M("storage-atomic-save", "a saved file is complete old or complete new, never torn",
      PKG + "io/atomicfile.py",
      "        with os.fdopen(fd, \"wb\") as stream:\n            stream.write(data)\n"
      "            stream.flush()\n            os.fsync(stream.fileno())\n"
      "        tmp.chmod(mode)\n        tmp.replace(target)\n",
      "        os.close(fd)\n        tmp.unlink()\n"  # written in place
      "        with open(target, \"wb\") as stream:\n            stream.write(data)\n"
      "            stream.flush()\n            os.fsync(stream.fileno())\n",
      T + "test_kill_during_save.py"),
    M("storage-fsync", "a saved file's bytes are on disk before it replaces the old one",
      PKG + "io/atomicfile.py",
      "            os.fsync(stream.fileno())\n",
      "",
      T + "test_params.py", T + "test_kill_during_save.py"),
    # ---------------------------------------------------------------- the receiver's switches
    M("rcin-mode-switch", "the receiver's mode switch selects its FLTMODE",
      PKG + "control/rcinput.py",
      "            if position is not None:\n                mode = config.modes[position]",
      "            if False:\n                mode = config.modes[position]",
      T + "test_receiver.py"),
    M("vehicle-deadline-due", "the loop wakes at the failsafe deadlines (Vehicle.next_due_s)",
      PKG + "control/vehicle.py",
      "            due = self.fc_seen_s + c.fc_timeout_s\n",
      "            due = self.fc_seen_s + 2 * c.fc_timeout_s\n",
      T + "test_failsafe_deadlines.py"),
    # ---------------------------------------------------------------- ESC dead band, strafe
    M("pwm-dead-band-add", "a command past the threshold is lifted over the ESC dead band",
      PKG + "control/pwm.py", "c = lift + keep * c\n                    if c < band:",
      "c = c\n                    if False:",
      PC + "test_with_a_dead_band_a_small_command_jumps_over_it_and_full_stays_full",
      PL + "test_the_square_on_the_mujoco_chassis_at_1_m_s_finishes_within_its_goals"),
    M("pwm-dead-band-negative", "a negative command is lifted over the band towards minimum",
      PKG + "control/pwm.py", "c = keep * c - lift", "c = keep * c + lift",
      PC + "test_with_a_dead_band_a_small_command_jumps_over_it_and_full_stays_full"),
    M("pwm-dead-band-scale", "full command stays full with a dead band (scaled by 1 - dz)",
      PKG + "control/pwm.py",
      "(0.0, 1.0) if self.dead_band_jump else (band, 1.0 - band))",
      "(0.0, 1.0) if self.dead_band_jump else (band, 1.0))",
      PC + "test_with_a_dead_band_a_small_command_jumps_over_it_and_full_stays_full"),
    M("pwm-dead-band-zero", "a zero command stays neutral with a dead band",
      PKG + "control/pwm.py", "                if c > live:\n",
      "                if c >= 0.0:\n",
      PC + "test_with_a_dead_band_zero_and_commands_of_at_most_a_microsecond_stay_inside_it"),
    M("pwm-dead-band-live", "commands of at most a microsecond are not lifted (a held "
      "position does not hunt)",
      PKG + "control/pwm.py", "DEAD_BAND_LIVE = 0.002", "DEAD_BAND_LIVE = 0.0",
      PC + "test_with_a_dead_band_zero_and_commands_of_at_most_a_microsecond_stay_inside_it",
      PL + "test_a_held_position_on_the_mujoco_chassis_with_its_esc_dead_band_does_not_"
      "oscillate"),
    M("pwm-dead-band-array", "the vectorized PWM compensates the dead band as the scalar",
      PKG + "control/pwm.py", "np.sign(c) * np.maximum(lift + keep * size, band), c)",
      "c, c)", PC + "test_vector_pwm_matches_scalar_pwm_with_a_dead_band"),
    M("autopilot-idle-after-auto", "after AUTO or GUIDED the autopilot's ticks stop (no wake left)",
      PKG + "control/output.py",
      "        self.new_input = False\n        self._next_output_s",
      "        self.new_input = False\n        self._autopilot_active = False\n"
      "        self._next_output_s",
      T + "test_auto.py::"
      "test_after_a_mission_ends_in_hold_the_autopilot_has_no_timer_left_and_the_loop_sleeps"),
    M("guided-yaw-lead", "the body velocity is for the heading one motor lag ahead (0.09 s)",
      PKG + "config/schema.py", '"GUID_YAW_LEAD", float, default=0.09,',
      '"GUID_YAW_LEAD", float, default=0.12,',
      T + "test_bench_control.py::"
      "test_strafing_while_turning_half_a_turn_keeps_the_kinematic_rover_on_its_line"),
    M("pwm-dead-band-array-jump", "the vectorized PWM lifts a jump ESC's commands to the band",
      PKG + "control/pwm.py", "np.maximum(lift + keep * size, band)", "(lift + keep * size)",
      PC + "test_vector_pwm_matches_scalar_pwm_with_a_dead_band"),
    M("pwm-dead-band-jump", "a jump ESC's command inside the band is sent at its edge",
      PKG + "control/pwm.py", "if c < band:\n                        c = band",
      "if False:\n                        c = band",
      PC + "test_with_a_jump_dead_band_a_command_inside_it_goes_to_its_edge_one_past_it_"
      "as_it_is"),
    M("pwm-dead-band-type-param", "MOT_DZ_TYPE chooses the jump form",
      PKG + "control/pwm.py", 'bool(params["MOT_DZ_TYPE"])',
      'False and bool(params["MOT_DZ_TYPE"])',
      PC + "test_with_a_jump_dead_band_a_command_inside_it_goes_to_its_edge_one_past_it_"
      "as_it_is"),
    M("bench-dz-type", "bench_control sets MOT_DZ_TYPE jump (the MuJoCo ESC's kind)",
      "tools/bench_control.py", '"MOT_DZ_TYPE": 1.0}', '"MOT_DZ_TYPE": 0.0}',
      PL + "test_the_square_on_the_mujoco_chassis_at_1_m_s_finishes_within_its_goals"),
    M("pwm-dead-band-param", "MOT_DZ sets the PWM edge's dead band",
      PKG + "control/pwm.py", 'float(params["MOT_DZ"])', '0.0 * float(params["MOT_DZ"])',
      PC + "test_with_a_dead_band_a_small_command_jumps_over_it_and_full_stays_full",
      PL + "test_a_held_position_on_the_mujoco_chassis_with_its_esc_dead_band_does_not_"
      "oscillate"),
    M("lane-dead-band", "the stick lane compensates the dead band as the general path",
      PKG + "control/lane.py", "pulses_us = pwm.pulses_us",
      "pulses_us = type(pwm)(pwm.wheels).pulses_us",
      T + "test_lane.py::test_the_lane_answers_a_stick_exactly_as_the_general_path"),
    M("kin-strafe-eff-inverse", "the wheels are asked for vy / WHL_STRAFE_EFF (scalar path)",
      PKG + "mecanum/kinematics.py", "vyc = (float(vy) - w * float(cx)) * self._lateral_gain",
      "vyc = (float(vy) - w * float(cx)) * 1.0",
      PL + "test_the_wheels_are_asked_for_the_lateral_speed_over_the_strafe_efficiency"),
    M("kin-strafe-eff-matrix", "the kinematics matrix's lateral column is over the strafe "
      "efficiency (array path and odometry)",
      PKG + "mecanum/kinematics.py", "np.column_stack((np.ones(4), signs * self._lateral_gain, k))",
      "np.column_stack((np.ones(4), signs, k))",
      PL + "test_the_wheels_are_asked_for_the_lateral_speed_over_the_strafe_efficiency",
      PL + "test_the_odometry_counts_the_wheels_lateral_part_times_the_strafe_efficiency"),
    M("estimator-strafe-eff", "the estimator's kinematics take WHL_STRAFE_EFF",
      PKG + "control/estimator.py", 'strafe_efficiency=float(params["WHL_STRAFE_EFF"])',
      'strafe_efficiency=1.0 or float(params["WHL_STRAFE_EFF"])',
      PL + "test_the_estimator_counts_a_strafe_with_whl_strafe_eff"),
    M("bench-mot-dz", "bench_control sets MOT_DZ over SIM_ESC_DZ on the MuJoCo chassis",
      "tools/bench_control.py", 'chassis["MOT_DZ"] = min(', 'chassis["MOT_DZ"] = 0.0 * min(',
      PL + "test_the_square_on_the_mujoco_chassis_at_1_m_s_finishes_within_its_goals"),
    M("bench-strafe-eff", "bench_control sets the MuJoCo chassis's strafe efficiency",
      "tools/bench_control.py", '{"WHL_STRAFE_EFF": MUJOCO_STRAFE_EFF,',
      '{"WHL_STRAFE_EFF": 1.0,',
      PL + "test_the_square_on_the_mujoco_chassis_at_1_m_s_finishes_within_its_goals"),
    M("bench-strafe-eff-measured", "bench_control's MuJoCo strafe efficiency is the measured",
      "tools/bench_control.py", "MUJOCO_STRAFE_EFF = 0.988", "MUJOCO_STRAFE_EFF = 0.95",
      PL + "test_bench_controls_strafe_efficiency_is_what_the_mujoco_chassis_measures"),
    M("odomcal-ramp", "odometry_calibration's ramps accelerate at the given rate",
      "tools/odometry_calibration.py", "    step = accel * DT_S", "    step = 100.0 * DT_S",
      PL + "test_the_autonomous_accelerations_keep_traction_on_the_slippery_floor"),
    # ---------------------------------------------------------------- the MuJoCo chassis
    M("mujoco-roller-sense", "each wheel's rollers lie along (1, s_i) in FRD at the contact "
      "(the X pattern the kinematics assume)",
      PKG + "sim/mujocomodel.py",
      "ax, ay = 1.0 / math.sqrt(2.0), -lateral_sign / math.sqrt(2.0)",
      "ax, ay = 1.0 / math.sqrt(2.0), lateral_sign / math.sqrt(2.0)",
      MJ + "test_strafe_wheel_speeds_strafe_right_at_a_measured_efficiency",
      MJ + "test_the_model_has_four_wheels_of_twelve_rollers_at_45_degrees_in_the_x_pattern"),
    M("mujoco-friction", "the floor's friction is SIM_FRICTION",
      PKG + "sim/mujocomodel.py",
      'friction="{mu!r} 0.005 0.0001"',
      'friction="0.8 0.005 0.0001"',
      MJ + "test_the_floor_friction_is_sim_friction",
      MJ + "test_a_slippery_floor_slides_further_than_a_grippy_one"),
    M("mujoco-encoder-wheel", "encoders count what the wheel rolled, not the ground",
      PKG + "sim/mujocochassis.py",
      "        fl, fr, rl, rr = ((float(self.data.qpos[i]) - zero) * r\n"
      "                          for i, zero in zip(self._wheel_q, self._wheel_zero, "
      "strict=True))\n",
      "        fl = fr = rl = rr = math.hypot(self.pose.x_m, self.pose.y_m) + 0.0 * r\n",
      MJ + "test_a_hard_brake_from_1_m_s_slides_further_than_the_wheels_roll"),
    M("mujoco-dead-band", "a command inside the ESC dead band does not drive the wheel",
      PKG + "sim/mujocochassis.py",
      "if abs(c) < self.spec.esc_dead_band:",
      "if abs(c) < 0.0 * self.spec.esc_dead_band:",
      MJ + "test_a_command_inside_the_esc_dead_band_does_not_drive_the_wheels"),
    M("mujoco-yaw-sign", "the chassis's yaw is clockwise from north (MuJoCo's is counter-"
      "clockwise)",
      PKG + "sim/mujocochassis.py",
      "return Pose2d(float(x), -float(y), _wrap(-yaw_up))",
      "return Pose2d(float(x), -float(y), _wrap(yaw_up))",
      MJ + "test_forward_moves_along_the_heading_in_ned"),
    M("mujoco-same-instant", "the chassis's yaw, rates and velocity are of the state's instant "
      "(not MuJoCo's xmat, one timestep old)",
      PKG + "sim/mujocochassis.py",
      "mujoco.mju_quat2Mat(matrix, self.data.qpos[3:7])",
      "matrix = np.array(self.data.xmat[1])",
      MJ + "test_the_pose_and_rates_are_of_the_same_instant_as_the_wheel_distances"),
    M("mujoco-stiff-contact", "the roller-floor contact is as stiff as MuJoCo allows (2 steps): "
      "a soft one makes the wheels lag the ground and the odometry drift sideways in turns",
      PKG + "sim/mujocomodel.py",
      "CONTACT_STEPS = 2.0", "CONTACT_STEPS = 5.0",
      MJ + "test_translating_while_turning_the_wheels_odometry_stays_within_0_3_percent_"
      "sideways",
      MJ + "test_a_roller_passes_the_floor_in_at_least_one_and_a_half_integration_steps"),
    M("mujoco-short-step", "MuJoCo's step is 1 ms (room for the stiff contact)",
      PKG + "sim/mujocomodel.py",
      "TIMESTEP_S = 0.001", "TIMESTEP_S = 0.002",
      MJ + "test_translating_while_turning_the_wheels_odometry_stays_within_0_3_percent_"
      "sideways",
      MJ + "test_a_roller_passes_the_floor_in_at_least_one_and_a_half_integration_steps"),
    # The wheel contacts of the MuJoCo chassis in the view (issue 27).
    M("contacts-normal-force", "a wheel's contact force is the normal component",
      PKG + "sim/mujocochassis.py", "normal[wheel] += force[0]", "normal[wheel] += force[1]",
      MJ + "test_at_rest_the_wheels_normal_forces_sum_to_the_weight_and_are_about_equal"),
    M("contacts-slip", "a wheel whose contact slides over the floor slips",
      PKG + "sim/mujocochassis.py", "bool(s > SLIP_MPS)", "False",
      MJ + "test_a_full_command_launch_on_friction_0_4_slips_and_a_steady_cruise_does_not"),
    M("contacts-sent", "the board on the MuJoCo chassis sends the wheel contacts",
      PKG + "sim/board.py",
      "self._telemetry.append((_Every(CONTACTS_PERIOD_S, now_s), self._wheel_contacts))",
      "pass",
      T + "test_board_contacts.py::test_the_board_on_the_mujoco_chassis_sends_each_wheels_"
      "contact_at_10_hz"),
    M("contacts-from-fc-only", "contacts under the flight controller's ids from the companion "
      "are not the flight controller's",
      PKG + "app/rerunview.py",
      'or self._senders.role(self._index - 1) in ("vehicle", "gcs")):', "or False):",
      VW + "test_contacts_under_the_flight_controllers_ids_from_the_companion_are_not_mapped"),
    M("log-view-no-png", "log with a view draws the PNG only when --png is given",
      PKG + "app/logview.py", "    if png is not None or not viewing:", "    if True:",
      VW + "test_log_with_a_view_draws_the_png_only_when_asked"),
    # The Rerun view (mecanum_mav/app/rerunview.py, app/view.py; issue 27). VW: test_view.py.
    M("view-wheel-channel", "each wheel's PWM and command come from its own channel (MOT_<W>_CH)",
      PKG + "app/rerunview.py",
      "self._wheels(t, [channels[w.channel - 1] for w in self.pwm.wheels])",
      "self._wheels(t, [channels[w.channel % 4] for w in self.pwm.wheels])",
      VW + "test_the_wheel_commands_follow_the_x_roller_mixing_while_driving_right"),
    M("view-pwm-inverse", "wheel commands are the PWM read back through the PWM map's spans",
      PKG + "app/rerunview.py",
      "c = (p - wheel.trim) / np.where(span == 0, 1, span)",
      "c = (p - wheel.trim) / 400.0",
      VW + "test_the_wheel_commands_follow_the_x_roller_mixing_while_driving_right"),
    M("view-companion-modes", "the vehicle's modes come from the companion, not its flight "
      "controller sharing its ids",
      PKG + "app/rerunview.py",
      'or self._senders.role(self._index - 1) == "vehicle"', "or True",
      VW + "test_modes_arming_and_failsafes_are_on_the_timeline"),
    M("view-north-up", "the map draws north up (east, -north in Rerun's y-down 2D view)",
      PKG + "app/rerunview.py",
      "    return east_m, -north_m", "    return east_m, north_m",
      VW + "test_the_map_holds_the_planned_square_and_the_true_path_where_the_simulator_was"),
    M("view-last-rows", "the live view sends its last rows when it stops",
      PKG + "app/view.py",
      """                mapping.flush(recording)
                recording.flush()
            recording.disconnect()""",
      """                recording.flush()
            recording.disconnect()""",
      VW + "test_the_live_view_of_a_tlog_being_written_records_what_the_log_view_has"),
    # The tlog reader's fast path (io/tlog.py through protocol/codec.py decode_datagram; issue 27).
    M("tlog-fast-time", "a record read by the fast path has the time pymavlink's path gives it",
      PKG + "io/tlog.py", "return STAMP_LEN + length, stamp / 1e6, fast[0]",
      "return STAMP_LEN + length, stamp * 1e-6, fast[0]",
      TF + "test_the_fast_read_of_a_sample_drive_equals_pymavlinks_entry_for_entry"),
    M("tlog-fast-used", "a tlog's packets go through the companion's codec, not pymavlink's "
      "decode", PKG + "io/tlog.py", "fast = decode_datagram(packet)", "fast = None",
      TF + "test_only_what_the_codec_cannot_take_goes_through_pymavlinks_decode"),
    M("tlog-fast-signed", "a signed packet in a tlog is decoded by the fast path too",
      PKG + "io/tlog.py",
      "return 12 + data[start + 1] + (_SIGNATURE_LEN if signed else 0)",
      "return 12 + data[start + 1]",
      TF + "test_only_what_the_codec_cannot_take_goes_through_pymavlinks_decode"),
    M("tlog-fast-crc", "a damaged packet in a tlog is not MAVLink for the fast path either",
      PKG + "protocol/codec.py",
      "if crc != crc16(crc_extra, crc16(buf[pos + 1:crc_at], 0xFFFF)):", "if False:",
      TF + "test_a_damaged_tlog_reads_as_pymavlink_reads_it"),
    M("log-read-frozen", "the log command leaves what it read out of the collector's passes",
      PKG + "app/logview.py", "    with gc_paused(keep=True):", "    with gc_paused():",
      T + "test_log_open.py::test_the_log_command_leaves_what_it_read_out_of_the_collectors_"
      "later_passes"),
    M("gc-paused-keep", "gc_paused(keep=True) freezes what was made meanwhile",
      PKG + "app/view.py", """        if keep:
            gc.freeze()""", """        if False:
            gc.freeze()""",
      T + "test_log_open.py::test_the_log_command_leaves_what_it_read_out_of_the_collectors_"
      "later_passes"),
    M("log-plots-lazy", "a view of a log imports nothing of the PNG's",
      PKG + "app/logview.py", "from mecanum_mav.protocol.dialect import mavlink\n",
      "from mecanum_mav.protocol.dialect import mavlink\nimport mecanum_mav.app.plots\n",
      T + "test_log_open.py::test_a_view_of_a_log_imports_no_plotting"),
    M("odom-cmd-lag", "commanded wheel speeds pass the ODOM_CMD_TAU lag before they count",
      PKG + "control/estimator.py", "lagged = self.config.commanded_tau_s > 0.0",
      "lagged = False",
      T + "test_estimator_commanded.py::test_a_lagged_commanded_step_rolls_as_a_first_order_"
      "motor_does",
      T + "test_estimator_commanded.py::test_the_lagged_odometry_follows_the_simulated_"
      "chassis_wheel_for_wheel"),
    M("odom-yaw-carried", "the gyro yaw is carried to the update's moment at its rate",
      PKG + "control/estimator.py", "self._yaw_rate_gyro * max(age, 0.0)",
      "0.0 * self._yaw_rate_gyro * max(age, 0.0)",
      T + "test_estimator_commanded.py::test_the_gyro_yaw_is_carried_forward_at_its_rate_to_"
      "the_update"),
    M("odom-start-heading", "an ATTITUDE before the first update sets the starting heading",
      PKG + "control/estimator.py", "if first and self.config.yaw_from_gyro",
      "if False and first and self.config.yaw_from_gyro",
      T + "test_estimator_commanded.py::test_an_attitude_before_the_first_update_sets_the_"
      "starting_heading_itself"),
    M("twin-truth-by-wall-time", "a twin mission is graded with the truth at each look's wall time",
      PKG + "sim/twinmission.py", "if watch.look(due, truth.pose_at(due, origin), batch):",
      "if watch.look(due, truth.pose_at(end_s, origin), batch):",
      T + "test_twin_mission.py::test_the_arrival_is_graded_with_the_truth_at_the_wall_time_"
      "the_reached_message_arrived"),
    M("twin-origin-at-auto", "a twin mission is graded from where the rover stood at AUTO",
      PKG + "sim/twinmission.py", "origin = (home.north_m, home.east_m)", "origin = (0.0, 0.0)",
      T + "test_twin_mission.py::test_positions_are_graded_from_where_the_rover_stood_at_auto"),
    M("twin-periodic-looks", "the replay looks at least every WATCH_PERIOD_S between messages",
      PKG + "sim/twinmission.py", "due = min(now + period_s,", "due = min(now + math.inf,",
      T + "test_twin_mission.py::test_the_watch_looks_between_messages_so_the_cross_track_of_"
      "a_quiet_leg_counts"),
    M("twin-live-failure-wins", "a twin flight's own failure is the row's reason",
      PKG + "sim/twinmission.py",
      'return watch.run, record.failure or "the mission did not finish in time"',
      'return watch.run, "the mission did not finish in time"',
      T + "test_twin_mission.py::test_a_flight_without_its_end_says_so_and_the_live_failure_"
      "wins"),
    M("twin-record-after-ack", "a twin mission's record starts after the ACK accepting AUTO",
      PKG + "sim/twinmission.py", "return k + 1, gcs.arrived_s[k]", "return k, gcs.arrived_s[k]",
      T + "test_twin_mission.py::test_the_record_starts_after_the_ack_that_accepted_auto_not_"
      "with_what_came_with_it"),
    # The twin's truth in the view (sim/truthsender.py, issue 27 item 3). TW: test_twin.py.
    M("truth-newest-pose", "the twin's truth is the record's newest pose, north and east",
      PKG + "sim/truthsender.py",
      "send_sim_state(self.mav, self._origin, north, east, yaw, forward, right,",
      "send_sim_state(self.mav, self._origin, east, north, yaw, forward, right,",
      TW + "test_the_truth_publisher_sends_the_records_latest_pose_as_sim_state_from_its_own_"
      "sender"),
    M("truth-only-when-moved", "the twin's pose is sent again only when the physics moved on",
      PKG + "sim/truthsender.py", "if len(rows) and count != self._count:", "if len(rows):",
      TW + "test_the_truth_publisher_sends_the_records_latest_pose_as_sim_state_from_its_own_"
      "sender"),
    M("truth-rate", "the twin's pose goes out at 20 Hz",
      PKG + "sim/truthsender.py", "self._period_s = 1.0 / rate_hz",
      "self._period_s = 0.5 / rate_hz",
      TW + "test_the_truth_publisher_sends_each_new_pose_at_20_hz_while_the_physics_moves_on"),
    M("truth-contacts-once", "each contact reading of the bridge is sent once",
      PKG + "sim/truthsender.py", "if read is not None and read[0] != self._contacts_s:",
      "if read is not None:",
      TW + "test_the_truth_publisher_sends_each_contact_reading_once_as_the_boards_debug_vects"),
    M("bridge-contacts-period", "the bridge reads the contacts every 0.1 s of physics, not "
      "every frame", PKG + "sim/twinbridge.py",
      "self._contacts_due_s = self.chassis.time_s + CONTACTS_PERIOD_S",
      "self._contacts_due_s = self.chassis.time_s",
      TW + "test_the_bridge_records_the_wheel_contacts_every_tenth_of_a_second_carrying_the_"
      "weight"),
    M("view-twin-truth-only", "once the twin's truth came, only it is drawn as truth",
      PKG + "app/rerunview.py", "return twin or not self._twin_truth", "return True",
      VW + "test_once_the_twins_truth_came_the_true_path_and_contacts_are_its_alone"),
    M("view-twin-origin", "an origin guessed from another's truth gives way to the twin's",
      PKG + "app/rerunview.py",
      "self.origin = None if self._origin_derived else self.origin",
      "self.origin = self.origin",
      VW + "test_once_the_twins_truth_came_the_true_path_and_contacts_are_its_alone"),
    M("view-merge-in-time", "several sources are merged in time order",
      PKG + "app/view.py",
      "yield list(heapq.merge(*(next(s) for s in sources), key=lambda e: e[0]))",
      "yield [e for s in sources for e in next(s)]",
      VW + "test_several_sources_are_merged_in_time_order"),
    M("view-every-connect", "view follows every --connect",
      PKG + "app/view.py", "batches = merged(connects)", "batches = merged(connects[:1])",
      VW + "test_the_live_view_of_a_tlog_and_a_twins_truth_records_both"),
    M("twin-view-follows-truth", "twin --view's view follows the truth the twin sends",
      PKG + "app/cli.py", "also=[watch])", "also=[])",
      TW + "test_the_twin_command_with_view_serves_the_view_of_the_companions_links_and_ends_"
      "it"),
    M("twin-truth-on", "a twin with a truth URL publishes its truth there",
      PKG + "sim/twin.py", "        if self.truth_url is not None:\n",
      "        if False:\n",
      TW + "test_the_twins_truth_at_rest_has_each_wheels_contact_at_10_hz_carrying_its_weight"),
    M("omni-wheel-map", "ArduPilot's OMNIX motors land on the wheels our mixer drives alike",
      PKG + "sim/twinmission.py", "((4, 1.0), (1, 1.0), (3, 1.0), (2, 1.0))",
      "((1, 1.0), (4, 1.0), (3, 1.0), (2, 1.0))",
      T + "test_twin_mission.py::test_ardupilots_omni_x_motors_land_on_the_wheels_our_mixer_"
      "drives_the_same_way"),
    M("hb-sign", "the heading bias is the odometry's direction minus the flight controller's",
      PKG + "control/headingbias.py", "math.atan2(re_, rn) - math.atan2(fe, fn)",
      "math.atan2(fe, fn) - math.atan2(re_, rn)",
      HB + "test_a_straight_track_3_degrees_off_the_flight_controllers_gives_a_3_degree_bias",
      HS + "test_a_heading_2_5_deg_off_meets_the_square_arrival_and_heading_goals_only_when_"
      "estimated"),
    M("hb-straight-only", "the heading bias is measured on straight stretches only",
      PKG + "control/headingbias.py", "if chord < STRAIGHT_RATIO * path or fc_chord <",
      "if False or False and fc_chord <",
      HB + "test_a_curved_track_gives_no_estimate_its_lag_would_look_like_degrees",
      HB + "test_a_flight_controller_track_that_weaves_gives_no_estimate"),
    M("hb-straight-odometry", "the odometry's side of a window must be straight",
      PKG + "control/headingbias.py", "if chord < STRAIGHT_RATIO * path or fc_chord <",
      "if False or fc_chord <",
      HB + "test_an_odometry_track_that_weaves_gives_no_estimate"),
    M("hb-straight-fc", "the flight controller's side of a window must be straight",
      PKG + "control/headingbias.py", "or fc_chord < STRAIGHT_RATIO * (",
      "or 0.0 * fc_chord > STRAIGHT_RATIO * (",
      HB + "test_a_flight_controller_track_that_weaves_gives_no_estimate"),
    M("hb-steady-only", "the heading bias is measured only while the rover moves steadily",
      PKG + "control/headingbias.py",
      "if steady_only and least_step < STEADY_RATIO * path / steps:", "if False:",
      HB + "test_a_rover_that_keeps_speeding_up_and_slowing_down_gives_no_estimate"),
    M("hb-steady-gps", "GPS fixes are measured against from a standing start on",
      PKG + "control/headingbias.py",
      "if steady_only and least_step < STEADY_RATIO * path / steps:",
      "if least_step < STEADY_RATIO * path / steps:",
      HB + "test_gps_fixes_measure_the_bias_while_the_rover_speeds_up_from_rest"),
    M("stop-at-right-angle", "a turn of 90 degrees or more is a stop, for the executor and the "
      "bench alike", PKG + "control/pathfollow.py",
      "return a[0] * b[0] + a[1] * b[1] <= 0.0", "return a[0] * b[0] + a[1] * b[1] < -0.5",
      AU + "test_corner_speed_stops_for_right_angles_and_carries_speed_through_straight_ones"),
    M("bench-pass-crossing", "a waypoint passed at speed is graded where the rover crossed its "
      "line", PKG + "sim/missionrun.py", "        at = self._crossed or pose",
      "        at = pose",
      T + "test_bench_control.py::"
      "test_a_waypoint_passed_at_speed_is_arrived_at_where_the_rover_crossed_its_line_first"),
    M("hb-fix-lag", "a window that speeds up may find the late positions' chord short",
      PKG + "control/headingbias.py",
      "late_m = FIX_LAG_S * abs(", "late_m = 0.0 * abs(",
      HB + "test_gps_fixes_measure_the_bias_while_the_rover_speeds_up_from_rest"),
    M("hb-steady-ekf", "the EKF's position counts only over steady driving",
      PKG + "control/estimator.py", "follows_yaw=source == BIAS_FROM_EKF)",
      "follows_yaw=False)",
      HB + "test_from_a_standing_start_gps_fixes_correct_the_heading_within_0_6_m_and_an_ekf_not"),
    M("hb-bound", "a heading bias beyond 10 degrees is not corrected, and said",
      PKG + "control/headingbias.py", "if not abs(angle) <= MAX_BIAS_RAD:", "if False:",
      HB + "test_a_bias_beyond_10_degrees_is_not_corrected_and_said_once"),
    M("hb-outlier", "once settled, a measurement far from the estimate is an outlier",
      PKG + "control/headingbias.py",
      "and abs(angle - self.bias_rad) > OUTLIER_RAD:", "and False:",
      HB + "test_a_flight_controller_position_that_drifts_sideways_hardly_moves_a_settled_"
      "estimate"),
    M("hb-relearn", "outliers in a row mean the bias moved: it is learnt again",
      PKG + "control/headingbias.py", "self.measurements = self.outliers = 0",
      "self.outliers = 0",
      HB + "test_a_bias_that_moved_for_good_is_learnt_again"),
    M("hb-param-off", "ODOM_YAW_BIAS 0: the flight controller's position changes nothing",
      PKG + "control/estimator.py", "if self.config.yaw_bias != source or ", "if False or ",
      HB + "test_with_odom_yaw_bias_0_the_positions_change_nothing",
      HB + "test_with_odom_yaw_bias_1_the_ekfs_position_is_the_reference_and_the_gps_is_not"),
    M("hb-turn-until-settled", "once settled, a new correction turns only what comes after",
      PKG + "control/estimator.py", "self._correct(update.bias_rad, turn_track=not settled)",
      "self._correct(update.bias_rad, turn_track=True)",
      HB + "test_once_settled_a_new_correction_does_not_move_the_rover_on_the_map"),
    M("hb-carried", "the odometry is sampled where it is at the position's moment",
      PKG + "control/estimator.py", "north, east = body_to_ned(*self.velocity_body, pose.yaw_rad)",
      "north, east = 0.0, 0.0",
      HB + "test_a_position_fused_pulls_the_odometry_toward_the_fcs_track_at_its_time_constant"),
    M("fuse-gain", "a fused position pulls the odometry with 1 - exp(-dt / ODOM_POS_TAU)",
      PKG + "control/estimator.py",
      "gain = -math.expm1(-max(dt, 0.0) / self.config.position_tau_s)", "gain = 0.0",
      HB + "test_a_position_fused_pulls_the_odometry_toward_the_fcs_track_at_its_time_constant"),
    M("fuse-gate", "a position far from the odometry's is not fused",
      PKG + "control/estimator.py", "if not math.hypot(error_n, error_e) <= POSITION_GATE_M:",
      "if False:",
      HB + "test_a_fused_position_that_jumps_is_not_followed_until_it_stays"),
    M("fuse-not-a-step", "a fused position's pull is not a step the heading bias measures",
      PKG + "control/estimator.py",
      "self.heading_bias.shifted(gain * error_n, gain * error_e)",
      "self.heading_bias.follow(*self._carried(now_s))",
      HB + "test_a_fused_position_between_two_gps_fixes_leaves_the_heading_bias_its_steps"),
    M("gps-rtk-only", "only RTK GPS fixes, each once, are the heading bias's reference",
      PKG + "control/fclink.py",
      "if msg.fix_type < GPS_RTK_FIX or msg.time_usec == self._gps_fix_us:",
      "if msg.time_usec == self._gps_fix_us:",
      HS + "test_gps_fixes_without_an_rtk_fix_are_not_a_track"),
    M("hb-track-turned", "a new heading correction turns the track since the origin too",
      PKG + "mecanum/odometry.py",
      "Pose2d(about[0] + n, about[1] + e,",
      "Pose2d(self._pose.x_m, self._pose.y_m,",
      HB + "test_the_bias_is_taken_off_the_heading_and_the_track_since_the_origin_turned_back",
      HS + "test_a_heading_2_5_deg_off_meets_the_square_arrival_and_heading_goals_only_when_"
      "estimated"),
    M("hb-yaw-corrected", "the estimated bias is taken off every ATTITUDE yaw",
      PKG + "control/estimator.py", "yaw_rad -= self.yaw_correction", "yaw_rad -= 0.0",
      HB + "test_the_bias_is_taken_off_the_heading_and_the_track_since_the_origin_turned_back",
      HS + "test_a_heading_2_5_deg_off_meets_the_square_arrival_and_heading_goals_only_when_"
      "estimated"),
    M("hb-position-asked", "the companion asks the flight controller for LOCAL_POSITION_NED",
      PKG + "control/fclink.py", """(mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
                                         FC_POSITION_INTERVAL_US),""",
      """(mavlink.MAVLINK_MSG_ID_SYS_STATUS,
                                         FC_SYS_STATUS_INTERVAL_US),""",
      HS + "test_the_companion_asks_the_flight_controller_for_its_position_at_10_hz"),
    M("gps-asked", "the companion asks the flight controller for GPS_RAW_INT",
      PKG + "control/fclink.py", "(mavlink.MAVLINK_MSG_ID_GPS_RAW_INT,",
      "(mavlink.MAVLINK_MSG_ID_SYS_STATUS,",
      HS + "test_the_companion_asks_the_flight_controller_for_its_position_at_10_hz"),
    M("hb-bend-guard", "no heading-bias window while the raw track bends (late positions)",
      PKG + "control/headingbias.py", "        if self._bends(start, now):",
      "        if False:",
      BG + "test_a_bending_track_with_late_positions_moves_the_estimate_little"),
    M("odom-cmd-gain", "the commanded odometry counts each wheel's speed times ODOM_CMD_GAIN",
      PKG + "control/estimator.py",
      "self._commanded_mps = config.wheel_speed_max_mps * config.commanded_gain",
      "self._commanded_mps = config.wheel_speed_max_mps",
      OG + "test_a_commanded_gain_scales_the_distance_every_wheel_is_counted_to_roll",
      OG + "test_on_the_mujoco_chassis_the_measured_gain_takes_the_odometrys_over_reading_away"),
)

# ====================================================================== running


@dataclass
class Outcome:
    """What became of one mutant."""

    mutation: Mutation
    verdict: str
    """``killed``, ``killed (error)``, ``killed (timeout)``, ``SURVIVED``, ``STALE``,
    ``NO TESTS`` (its test ids match nothing), ``TOOL ERROR``."""
    by: str
    """The first failing test's node id, or why not."""
    seconds: float

    @property
    def ok(self) -> bool:
        return self.verdict.startswith("killed")


def stale_reason(m: Mutation) -> str | None:
    """Why ``m`` cannot be applied to this tree (None if it can)."""
    path = ROOT / m.file
    if not path.is_file():
        return f"{m.file} missing"
    count = path.read_text(encoding="utf-8").count(m.old)
    if count != 1:
        return f"old snippet found {count} times in {m.file}"
    if m.old == m.new:
        return "old == new"
    return None


def make_copy(into: Path) -> Path:
    """A copy of the repository's package, tests and data under ``into``; its root."""
    root = into / "repo"
    root.mkdir()
    for name in COPIED:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, root / name, ignore=IGNORED)
        elif src.is_file():
            shutil.copy2(src, root / name)
    return root


def environment(copy: Path) -> dict[str, str]:
    """The environment tests run in: the copy first on the import path, no byte code."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(copy), env.get("PYTHONPATH")]))
    env["PYTHONDONTWRITEBYTECODE"] = "1"  # a same-size mutation within a second: no stale .pyc
    env.pop("PYTEST_ADDOPTS", None)
    return env


def canary(copy: Path) -> str | None:
    """None if a subprocess started as the tests start them imports the copy's package; else
    what it imported."""
    probe = "import mecanum_mav, sys; sys.stdout.write(mecanum_mav.__file__)"
    for cwd in (copy, Path(tempfile.gettempdir())):
        out = subprocess.run([sys.executable, "-c", probe], cwd=cwd, env=environment(copy),
                             capture_output=True, text=True, timeout=60)
        where = out.stdout.strip()
        if out.returncode != 0 or not Path(where).resolve().is_relative_to(copy.resolve()):
            return f"from cwd {cwd}: {where or out.stderr.strip()[-300:]}"
    return None


def first_failure(junit: Path) -> tuple[str, bool] | None:
    """(node id, is a collection/import error) of the first failing test in a JUnit XML."""
    try:
        tree = ET.parse(junit)
    except (OSError, ET.ParseError):
        return None
    for case in tree.iter("testcase"):
        failure = case.find("failure")
        error = case.find("error")
        bad = failure if failure is not None else error
        if bad is None:
            continue
        classname, name = case.get("classname", ""), case.get("name", "")
        if not classname:  # a collection error: the name is the module
            return name, True
        parts = classname.split(".")
        module = "/".join(p for p in parts if not p[:1].isupper())
        classes = [p for p in parts if p[:1].isupper()]
        node = "::".join([f"{module}.py", *classes, name])
        message = (bad.get("message") or "").lower()
        return node, failure is None and "collect" in message
    return None


def run_tests(copy: Path, tests: tuple[str, ...], junit: Path) -> tuple[int, str, bool]:
    """pytest on ``tests`` in ``copy``: (exit code, the first failing node or a reason,
    the failure was a collection/import error)."""
    junit.unlink(missing_ok=True)
    cmd = [sys.executable, "-m", "pytest", *PYTEST, f"--junitxml={junit}", *tests]
    try:
        out = subprocess.run(cmd, cwd=copy, env=environment(copy), capture_output=True,
                             text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return -1, f"timeout after {TIMEOUT_S:.0f} s", False
    found = first_failure(junit)
    if found is not None:
        return out.returncode, found[0], found[1] or out.returncode == 2
    text = out.stdout + out.stderr
    lines = [line for line in text.strip().splitlines() if line.strip()]
    if out.returncode == 4 and "not found:" not in text:  # (a conftest that did not import)
        return 2, next((line for line in reversed(lines) if "Error" in line), lines[-1]), True
    return out.returncode, lines[-1] if lines else "", out.returncode == 2


def run_one(copy: Path, m: Mutation) -> Outcome:
    """Apply ``m`` to ``copy``, run its tests, put the file back."""
    start = time.monotonic()
    reason = stale_reason(m)
    if reason is not None:
        return Outcome(m, "STALE", reason, 0.0)
    target = copy / m.file
    original = (ROOT / m.file).read_text(encoding="utf-8")
    target.write_text(original.replace(m.old, m.new), encoding="utf-8")
    try:
        code, by, error = run_tests(copy, m.tests, copy.parent / f"junit-{m.id}.xml")
    finally:
        target.write_text(original, encoding="utf-8")
    seconds = time.monotonic() - start
    if code == -1:
        return Outcome(m, "killed (timeout)", by, seconds)
    if code == 0:
        return Outcome(m, "SURVIVED", "", seconds)
    if code in (4, 5):
        return Outcome(m, "NO TESTS", by, seconds)
    return Outcome(m, "killed (error)" if error else "killed", by, seconds)


def run_all(selected: list[Mutation], workers: int, show: bool) -> list[Outcome]:
    """Every mutant in ``selected`` on ``workers`` copies; exits on a broken baseline."""
    outcomes: dict[str, Outcome] = {}
    todo: queue.Queue[Mutation] = queue.Queue()
    runnable = []
    for m in selected:
        reason = stale_reason(m)
        if reason is None:
            runnable.append(m)
        else:
            outcomes[m.id] = Outcome(m, "STALE", reason, 0.0)
    with tempfile.TemporaryDirectory(prefix="mutants-") as tmp:
        copies = []
        for n in range(min(workers, len(runnable))):  # (none when every entry is stale)
            folder = Path(tmp) / f"w{n}"
            folder.mkdir()
            copies.append(make_copy(folder))
        if copies:
            problem = canary(copies[0])
            if problem is not None:
                sys.exit(f"mutants: the copy does not import itself ({problem}); the results "
                         f"would be about the installed package")
            union = tuple(dict.fromkeys(t for m in runnable for t in m.tests))
            start = time.monotonic()
            code, by, _ = run_tests(copies[0], union, copies[0].parent / "junit-baseline.xml")
            print(f"baseline: {len(union)} test selections, exit {code}, "
                  f"{time.monotonic() - start:.1f} s", flush=True)
            if code != 0:
                sys.exit(f"mutants: BROKEN BASELINE: {by}")
        for m in runnable:
            todo.put(m)
        lock = threading.Lock()

        def work(copy: Path) -> None:
            while True:
                try:
                    m = todo.get_nowait()
                except queue.Empty:
                    return
                try:
                    outcome = run_one(copy, m)
                except Exception as exc:  # (a tool failure, not a verdict: reported, not lost)
                    outcome = Outcome(m, "TOOL ERROR", repr(exc), 0.0)
                with lock:
                    outcomes[m.id] = outcome
                    if show:
                        print(f"  {m.id}: {outcome.verdict} {outcome.by} "
                              f"({outcome.seconds:.1f} s)", flush=True)

        threads = [threading.Thread(target=work, args=(c,), daemon=True) for c in copies]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    return [outcomes[m.id] for m in selected]


def table(outcomes: list[Outcome]) -> str:
    """The report: one row per mutant, then the totals."""
    rows = [("id", "rule", "killed by", "s")]
    for o in outcomes:
        by = o.by if o.verdict == "killed" else f"{o.verdict}: {o.by}".rstrip(": ")
        rows.append((o.mutation.id, o.mutation.rule, by, f"{o.seconds:.1f}"))
    widths = [max(len(r[i]) for r in rows) for i in range(2)]
    lines = [f"{r[0]:<{widths[0]}} | {r[1]:<{widths[1]}} | {r[2]} | {r[3]}" for r in rows]
    lines.insert(1, "-" * min(160, len(lines[0])))
    killed = sum(o.ok for o in outcomes)
    errors = sum(o.verdict != "killed" and o.ok for o in outcomes)
    bad = [o.mutation.id for o in outcomes if not o.ok]
    lines.append(f"\n{len(outcomes)} mutants: {killed} killed ({errors} by an error or timeout),"
                 f" {len(bad)} not: {' '.join(bad) or '-'}; "
                 f"{sum(o.seconds for o in outcomes):.0f} s of test time")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """The command line (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--fast", action="store_true", help="only the CI subset")
    parser.add_argument("--only", nargs="+", metavar="ID", help="only these ids")
    parser.add_argument("-j", "--jobs", type=int, default=2, help="workers (default 2)")
    parser.add_argument("--list", action="store_true", help="print the list and exit")
    parser.add_argument("-v", "--verbose", action="store_true", help="each result as it comes")
    args = parser.parse_args(argv)
    ids = [m.id for m in MUTATIONS]
    duplicates = {i for i in ids if ids.count(i) > 1}
    if duplicates:
        print(f"mutants: duplicate ids {sorted(duplicates)}", file=sys.stderr)
        return 1
    selected = [m for m in MUTATIONS if m.fast] if args.fast else list(MUTATIONS)
    if args.only:
        unknown = set(args.only) - set(ids)
        if unknown:
            print(f"mutants: unknown ids {sorted(unknown)}", file=sys.stderr)
            return 1
        selected = [m for m in selected if m.id in args.only]
    if args.list:
        for m in selected:
            flag = "*" if m.fast else " "
            stale = stale_reason(m)
            print(f"{flag} {m.id:<18} {m.file:<36} {m.rule}"
                  + (f"  [STALE: {stale}]" if stale else ""))
        print(f"{len(selected)} mutations ({sum(m.fast for m in selected)} in --fast, marked *)")
        return 0
    start = time.monotonic()
    outcomes = run_all(selected, args.jobs, args.verbose)
    print(table(outcomes))
    print(f"wall time {time.monotonic() - start:.0f} s with -j {args.jobs}")
    return 0 if all(o.ok for o in outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
