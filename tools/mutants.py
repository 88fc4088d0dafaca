#!/usr/bin/env python3
"""Mutation check: the safety rules and decisions that mutmut cannot reach, broken once,
must fail a test.

What
    The package's mutation testing is mutmut's (``tools/mutation.py``: every mutant of every
    function, run against the tests that reach it). :data:`MUTATIONS` holds only what mutmut
    cannot reach, and CI's quick subset:

    - code mutmut does not mutate: module-level constants and tables (the roller signs, the
      RC override's field limits, the layer rules' imports), decorated functions (properties,
      context managers; mutmut 3 skips every decorator but ``staticmethod`` and
      ``classmethod``), and tools outside the package (the bench and calibration scripts);
    - rules that live across a process boundary, which mutmut's in-process trace cannot see:
      a companion or firmware process ending with its parent, signing and the lane between
      real processes, the twin's truth and view (their tests are marked ``slow`` or ``sitl``);
    - ``fast``: one mutant per safety rule CI runs on every change (``--fast``): neutral on
      every way out, the failsafes, the pre-arm checks, the RC override's fields, signing.

    Each entry names the rule it breaks, the file, an exact ``old`` snippet (which must occur
    exactly once in that file, else the entry is STALE: a refactor must update the list), its
    ``new`` text, and the tests that should fail when it is applied (targeted node ids, a few
    seconds each). Entries mutmut covers were removed (issue 36); git history keeps them.

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
MJ = T + "test_mujoco_chassis.py::"
PC = T + "test_shaping_pwm.py::"
PL = T + "test_plant_calibration.py::"
TW = T + "test_twin.py::"

MUTATIONS: tuple[Mutation, ...] = (
    # ---------------------------------------------------------------- neutral on every way out
    M("core-shutdown-neutral", "shutdown sends neutral (each wheel's trim) before releasing",
      PKG + "control/output.py",
      "neutral = self.pwm.neutral()\n        self.pulses_us = neutral\n",
      "neutral = self.pulses_us\n",
      CO + "test_clean_shutdown_sends_neutral_then_releases_the_channels",
      fast=True),
    M("core-handler-neutral", "an exception in a message handler sends neutral at once",
      PKG + "control/core.py",
      'f"Error handling {kind}: neutral")\n        return self._override(self.pwm.neutral(), '
      "now_s)",
      'f"Error handling {kind}: neutral")\n        return self._override(self.pulses_us, now_s)',
      CO + ""
      "test_an_exception_in_a_message_handler_latches_neutral_until_the_next_valid_stick",
      fast=True),
    M("vehicle-driving-armed", "disarmed never drives", PKG + "control/vehicle.py",
      "self.armed and self.mode is Mode.MANUAL and not self.input_stale",
      "self.mode is Mode.MANUAL and not self.input_stale",
      CO + "test_sticks_while_disarmed_leave_the_wheels_at_neutral",
      fast=True),
    M("guided-setpoint-lapse", "a GUIDED velocity setpoint not renewed within GUID_TMO stops",
      PKG + "control/guided.py",
      "lapsed = sp is not None and now_s - sp.time_s > c.timeout_s",
      "lapsed = sp is not None and now_s - sp.time_s > 2 * c.timeout_s",
      T + "test_guided.py::test_a_velocity_setpoint_lapses_and_the_rover_stops", fast=True),
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
    M("vehicle-gcs-timeout", "FS_GCS_TMO: no GCS heartbeat for the timeout is the failsafe",
      PKG + "control/vehicle.py",
      "now_s - self.gcs_seen_s > c.gcs_timeout_s", "now_s - self.gcs_seen_s > 2 * c.gcs_timeout_s",
      CO + "test_ground_station_loss_triggers_the_failsafe_action_at_the_timeout",
      fast=True),
    # ---------------------------------------------------------------- pre-arm checks
    M("prearm-fc-link", "arming is refused while the FC link is down",
      PKG + "control/vehicle.py",
      'if self.fc_lost:\n            return self._refuse("PreArm: flight controller link down"',
      'if False:\n            return self._refuse("PreArm: flight controller link down"',
      CO + "test_arming_without_the_flight_controller_is_refused_as_a_pre_arm_check",
      fast=True),
    M("prearm-fc-unsafe", "an unsafe FC setup refuses arming", PKG + "control/fccheck.py",
      "if state is FcCheckState.UNSAFE:", "if False:",
      FCS + "test_a_board_whose_setup_is_wrong_is_unsafe_and_blocks_arming",
      fast=True),
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
    # ---------------------------------------------------------------- stick input
    M("stick-pulse-range", "a GCS RC override pulse outside 800..2200 us is refused whole",
      PKG + "control/sticks.py",
      "PULSE_RANGE_US = (800, 2200)", "PULSE_RANGE_US = (1, 65533)",
      CO + "test_ground_station_rc_override_with_an_absurd_pulse_is_rejected"),
    # ---------------------------------------------------------------- the stick lane
    M("lane-target", "the lane refuses a stick addressed to another vehicle",
      PKG + "control/lane.py",
      "if (to and to != sysid) or (pilot and datagram[5] != pilot):",
      "if (pilot and datagram[5] != pilot):",
      T + "test_lane.py", fast=True),
    M("lane-axis-range", "the lane refuses an axis outside +-1000",
      PKG + "control/lane.py",
      "if not (-1000 <= x <= 1000 and -1000 <= y <= 1000 and -1000 <= r <= 1000):",
      "if False:",
      T + "test_lane.py", fast=True),
    # ---------------------------------------------------------------- signing
    M("sign-bad-signature", "a packet signed with another key (or altered) is refused",
      PKG + "protocol/signing.py",
      "if not hmac.compare_digest(signature(self.key, packet[:-6]), packet[-6:]):", "if False:",
      T + "test_signing.py", fast=True),
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
    # ---------------------------------------------------------------- mixing and kinematics
    M("wheels-lateral-signs", "the roller signs of the X arrangement", PKG + "mecanum/wheels.py",
      "LATERAL_SIGNS: tuple[float, float, float, float] = (1.0, -1.0, -1.0, 1.0)",
      "LATERAL_SIGNS: tuple[float, float, float, float] = (1.0, -1.0, 1.0, -1.0)",
      T + "test_wheels.py", T + "test_kinematics.py"),
    # ---------------------------------------------------------------- processes
    M("child-dies-with-parent", "a companion process ends when its parent is killed",
      PKG + "sim/process.py", "preexec_fn=dies_with_this_thread(signal.SIGTERM)",
      "preexec_fn=None", T + "test_process_cleanup.py"),
    M("firmware-dies-with-parent", "the firmware ends when its parent is killed",
      PKG + "sim/firmware.py", "preexec_fn=dies_with_this_thread(signal.SIGKILL)",
      "preexec_fn=None", T + "test_process_cleanup.py"),
    # ---------------------------------------------------------------- the links' timers
    M("link-reopen-period", "a broken serial or TCP link tries to reopen every 0.5 s",
      PKG + "io/links/base.py", "REOPEN_PERIOD_S = 0.5", "REOPEN_PERIOD_S = 1.0",
      T + "test_link_timing.py"),
    M("link-override-newest-wins", "a waiting override is replaced by a newer one (stream)",
      PKG + "io/links/stream.py",
      "        if replace:\n            self._override = (target_system, target_component, "
      "channels)",
      "        if False:\n            self._override = (target_system, target_component, "
      "channels)",
      T + "test_link_timing.py", T + "test_serial_pacing.py", T + "test_links.py"),
    # ---------------------------------------------------------------- ESC dead band, strafe
    M("pwm-dead-band-live", "commands of at most a microsecond are not lifted (a held "
      "position does not hunt)",
      PKG + "control/pwm.py", "DEAD_BAND_LIVE = 0.002", "DEAD_BAND_LIVE = 0.0",
      PC + "test_with_a_dead_band_zero_and_commands_of_at_most_a_microsecond_stay_inside_it",
      PL + "test_a_held_position_on_the_mujoco_chassis_with_its_esc_dead_band_does_not_"
      "oscillate"),
    M("guided-yaw-lead", "the body velocity is for the heading one motor lag ahead (0.09 s)",
      PKG + "config/schema.py", '"GUID_YAW_LEAD", float, default=0.09,',
      '"GUID_YAW_LEAD", float, default=0.12,',
      T + "test_bench_control.py::"
      "test_strafing_while_turning_half_a_turn_keeps_the_kinematic_rover_on_its_line"),
    M("bench-dz-type", "bench_control sets MOT_DZ_TYPE jump (the MuJoCo ESC's kind)",
      "tools/bench_control.py", '"MOT_DZ_TYPE": 1.0}', '"MOT_DZ_TYPE": 0.0}',
      PL + "test_the_square_on_the_mujoco_chassis_at_1_m_s_finishes_within_its_goals"),
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
    M("mujoco-encoder-wheel", "encoders count what the wheel rolled, not the ground",
      PKG + "sim/mujocochassis.py",
      "        fl, fr, rl, rr = ((float(self.data.qpos[i]) - zero) * r\n"
      "                          for i, zero in zip(self._wheel_q, self._wheel_zero, "
      "strict=True))\n",
      "        fl = fr = rl = rr = math.hypot(self.pose.x_m, self.pose.y_m) + 0.0 * r\n",
      MJ + "test_a_hard_brake_from_1_m_s_slides_further_than_the_wheels_roll"),
    M("mujoco-yaw-sign", "the chassis's yaw is clockwise from north (MuJoCo's is counter-"
      "clockwise)",
      PKG + "sim/mujocochassis.py",
      "return Pose2d(float(x), -float(y), _wrap(-yaw_up))",
      "return Pose2d(float(x), -float(y), _wrap(yaw_up))",
      MJ + "test_forward_moves_along_the_heading_in_ned"),
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
    # The Rerun view (mecanum_mav/app/rerunview.py, app/view.py; issue 27). VW: test_view.py.
    # The tlog reader's fast path (io/tlog.py through protocol/codec.py decode_datagram; issue 27).
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
    # The twin's truth in the view (sim/truthsender.py, issue 27 item 3). TW: test_twin.py.
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
