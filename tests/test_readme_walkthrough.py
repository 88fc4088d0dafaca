"""The README is the test plan: every user path it shows, run with its own commands.

Each test takes its commands from the README's code blocks (tests/readme_plan.py), runs them
as a user would (real processes, in an empty directory, MAVProxy typed at through a pipe,
real ArduPilot firmware as the flight controller), and checks what the user would see: the
rover's HEARTBEAT, its position and its answers, as a ground station receives them (through
MAVProxy's ``--out`` where MAVProxy is the ground station), and the firmware's outputs. A
command the walkthrough has no check for fails the test: the README cannot grow a step that
nobody ran. Only ports, the serial device and repository paths are changed
(:func:`readme_plan.localize`).
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time
import urllib.request
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import readme_plan as plan
from sitl import Rig, Sitl, find_sitl
from support import wait_until

from mecanum_mav.config.views import InputConfig
from mecanum_mav.control.chain import manual_output
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.io.paramfile import load
from mecanum_mav.mecanum.wheels import WHEEL_KEYS
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.groundstation import udp_ground_station
from mecanum_mav.sim.process import free_port

BIN = Path(sys.executable).parent
ARMED = mavlink.MAV_MODE_FLAG_SAFETY_ARMED
MODES = {m.name: int(m) for m in Mode}
INSTALL_STEPS = ("python3 -m venv .venv", ". .venv/bin/activate", "pip install -e ")
"""What .ci/run has done already in the clone the tests run in."""


def executable(name: str) -> str:
    """A README command's program, from this environment (where .ci/run installed it)."""
    found = shutil.which(name, path=str(BIN)) or shutil.which(name)
    if found is None:
        pytest.skip(f"{name} is not installed (pip install -e '.[test]')")
    return found


class Background:
    """A README command run in the background, in its own process group (killed on exit)."""

    def __init__(self, command: str, cwd: Path, log: Path) -> None:
        words = shlex.split(command)
        words[0] = executable(words[0])
        if words[0].endswith(".py"):
            words.insert(0, sys.executable)
        self.command = command
        self.log_path = log
        with log.open("wb") as out:
            self.proc = subprocess.Popen(words, cwd=cwd, stdin=subprocess.PIPE, stdout=out,
                                         stderr=subprocess.STDOUT, start_new_session=True)

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")[-4000:]

    def signal(self, sig: int) -> None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.proc.pid, sig)

    def close(self) -> int | None:
        if self.proc.poll() is None:
            self.signal(signal.SIGTERM)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.signal(signal.SIGKILL)
                self.proc.wait(10)
        return self.proc.returncode


class MavProxySession:
    """The README's MAVProxy command (with an ``--out`` to an observer and its state kept in
    a temporary folder), typed at through its standard input; the observer sees what the
    ground station sees."""

    def __init__(self, command: str, cwd: Path) -> None:
        self.observer, self._port = udp_ground_station()
        self.observer.beating = False  # only watches: MAVProxy is the ground station
        out = self._port.url.replace("udpout:", "--out=udpout:")
        self.lines: list[str] = []
        words = [*shlex.split(command), out, f"--state-basedir={cwd}"]
        words[0] = executable(words[0])
        self.proc = subprocess.Popen([sys.executable, *words], cwd=cwd, stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, bufsize=1, start_new_session=True)
        threading.Thread(target=self._read, daemon=True).start()
        self.attitude_yaw = 0.0
        self.last_item = -1
        """The last item of the mission MAVProxy loaded (``wp load``)."""
        self.position = (math.nan, math.nan)
        self.velocity = (0.0, 0.0)

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))

    def type(self, command: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()

    def printed(self, pattern: str, timeout_s: float = 20.0) -> bool:
        regex = re.compile(pattern)
        return bool(wait_until(lambda: any(regex.search(line) for line in self.lines),
                               timeout_s))

    def wait(self, kind: str, predicate: Callable[[Any], bool] = lambda m: True,
             timeout_s: float = 20.0) -> Any | None:
        """The first ``kind`` from now on that satisfies ``predicate`` (positions and yaw are
        tracked meanwhile), or None."""
        found: list[Any] = []

        def track(wait_s: float) -> None:
            for msg in self.observer.pump(wait_s):
                self._track(msg)
                if not found and msg.get_type() == kind and predicate(msg):
                    found.append(msg)

        return wait_until(lambda: found and found[0], timeout_s, pump=track, pump_s=0.1)

    def _track(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "LOCAL_POSITION_NED":
            self.position, self.velocity = (msg.x, msg.y), (msg.vx, msg.vy)
        elif kind == "ATTITUDE":
            self.attitude_yaw = msg.yaw

    def heartbeat(self, predicate: Callable[[Any], bool], timeout_s: float = 20.0) -> Any:
        return self.wait("HEARTBEAT", lambda m: m.get_srcComponent() == 1
                         and m.type == mavlink.MAV_TYPE_GROUND_ROVER and predicate(m), timeout_s)

    def settle(self, what: Callable[[], bool], timeout_s: float = 20.0) -> bool:
        """Pump the observer until ``what()`` holds (on the tracked state)."""
        return bool(wait_until(what, timeout_s, pump=lambda wait_s: self.wait(
            "LOCAL_POSITION_NED", timeout_s=wait_s), pump_s=0.2))

    def speed(self) -> float:
        return math.hypot(*self.velocity)

    def why(self) -> str:
        return "\n".join(self.lines[-40:])

    def close(self) -> None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.proc.pid, signal.SIGTERM)
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
        self._port.close()


def mavproxy_steps(session: MavProxySession, commands: list[str]) -> None:
    """Type each README command at MAVProxy's prompt and check what it did."""
    assert session.heartbeat(lambda m: True, 60.0), f"no rover through MAVProxy\n{session.why()}"
    # as the README says: type once MAVProxy has the parameters (param set needs them)
    assert session.printed(r"Received \d+ parameters", 60.0), session.why()
    for command in commands:
        start = session.position
        session.type(command)
        assert run_check(session, command.split(), start), (
            f"README step {command!r} did not do what it says\n{session.why()}")


def run_check(session: MavProxySession, words: list[str], start: tuple[float, float]) -> bool:
    """The check of one MAVProxy command (a command without one fails)."""
    match words:
        case ["param", "set", name, value]:
            return session.wait("PARAM_VALUE", lambda m: m.param_id == name
                                and math.isclose(m.param_value, float(value), rel_tol=1e-6))
        case ["arm", "throttle"]:
            return bool(session.heartbeat(lambda m: m.base_mode & ARMED))
        case ["disarm"]:
            return bool(session.heartbeat(lambda m: not m.base_mode & ARMED))
        case ["signing", "key", _]:
            return session.printed(r"[Ss]igning") or True  # (what it enables is checked next)
        case ["mode", name] if name.upper() in MODES:
            mode = MODES[name.upper()]
            if not session.heartbeat(lambda m: m.custom_mode == mode):
                return False
            if mode == Mode.AUTO:  # the mission runs to its last item
                return bool(session.wait("MISSION_ITEM_REACHED",
                                         lambda m: m.seq == session.last_item, 60.0))
            return True
        case ["rc", _, pulse]:
            if int(pulse) == 1500:
                return session.settle(lambda: session.speed() < 0.02)
            return session.settle(lambda: math.dist(session.position, start) > 0.2)
        case ["velocity", vx, vy, _]:
            wanted = math.hypot(float(vx), float(vy))
            if wanted == 0.0:
                return session.settle(lambda: session.speed() < 0.02)
            return session.settle(lambda: session.speed() > 0.8 * wanted)
        case ["position", x, y, _]:
            yaw = session.attitude_yaw  # body frame (BODY_NED): ahead is the heading
            north = start[0] + float(x) * math.cos(yaw) - float(y) * math.sin(yaw)
            east = start[1] + float(x) * math.sin(yaw) + float(y) * math.cos(yaw)
            return session.settle(lambda: math.dist(session.position, (north, east)) < 0.05
                                  and session.speed() < 0.02, 30.0)
        case ["wp", "load", path]:
            count = len([line for line in Path(path).read_text().splitlines()[1:]
                         if line.strip()])
            session.last_item = count - 1
            return session.printed(rf"Sent all {count} waypoints|Loaded {count} waypoints in")
    raise AssertionError(f"README MAVProxy command {' '.join(words)!r}: the walkthrough has "
                         "no check for it; add one")


# --------------------------------------------------------------------------- the paths


@pytest.fixture
def workdir(tmp_path: Path) -> Path:
    """An empty directory to run the README's commands in."""
    (tmp_path / "user").mkdir()
    return tmp_path / "user"


@contextlib.contextmanager
def background(command: str, cwd: Path) -> Iterator[Background]:
    job = Background(command, cwd, cwd.parent / f"{len(list(cwd.parent.iterdir()))}.log")
    try:
        yield job
    finally:
        job.close()


def quick_start_command() -> str:
    """The quick start: the install (done by .ci/run already) and one command."""
    (block,) = [b for b in plan.section("Quick start", "sh")
                if "mecanum-mav" in b.text][:1]
    commands = plan.shell_commands(block.text)
    rest = [c for c in commands if not c.startswith(INSTALL_STEPS)]
    assert len(rest) == 1 and rest[0].startswith("mecanum-mav "), commands
    return rest[0]


def test_readme_quick_start_then_its_mavproxy_session_drives_the_rover(workdir):
    port = free_port()
    sh = [b for b in plan.section("MAVProxy", "sh") if "mavproxy.py" in b.text]
    typed = plan.section("MAVProxy", "text")
    assert sh and typed, "the README's MAVProxy session: a sh block and a text block"
    mavproxy_command = plan.localize(plan.shell_commands(sh[0].text)[0], gcs_port=port)
    steps = [plan.localize(c, gcs_port=port) for c in plan.prompt_commands(typed[0].text)]
    with background(plan.localize(quick_start_command(), gcs_port=port), workdir) as rover:
        session = MavProxySession(mavproxy_command, workdir)
        try:
            mavproxy_steps(session, steps)
        except AssertionError as exc:
            raise AssertionError(f"{exc}\nrover:\n{rover.log()}") from None
        finally:
            session.close()
        assert rover.close() == 0, rover.log()


# --------------------------------------------------------------------------- real hardware

BINARY, WHY_NO_SITL = find_sitl()


def needs_sitl(test: Callable[..., None]) -> Callable[..., None]:
    """A real-firmware test: marked ``sitl`` (conftest: CI fails if it is skipped), skipped
    without the firmware."""
    return pytest.mark.sitl(pytest.mark.skipif(BINARY is None, reason=WHY_NO_SITL)(test))


REACT_S = 20.0  # generous: the suite must hold on a loaded 2-core machine


def run_step(command: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """A README command run to its end, as typed (``cp`` and ``mecanum-mav ...``)."""
    words = shlex.split(command)
    words[0] = executable(words[0]) if words[0] != "cp" else "cp"
    if words[0].endswith(".py"):
        words.insert(0, sys.executable)
    return subprocess.run(words, cwd=cwd, capture_output=True, text=True, timeout=180)


def expect(command: str, done: subprocess.CompletedProcess[str]) -> None:
    """What the README says each finished step does."""
    out = done.stdout + done.stderr
    words = command.split()
    if words[:2] == ["mecanum-mav", "setup-fc"] and "--apply" not in words:
        # a board as it comes (the SITL's plain pass-through): the hazards are listed
        assert done.returncode == 1 and "HAZARD" in out, out
    elif words[:2] == ["mecanum-mav", "setup-fc"]:
        assert "--reboot" in words, f"README: {command!r} without --reboot"
        assert done.returncode == 0 and "set up safely for the companion" in out, out
    else:
        assert done.returncode == 0, f"{command}: {done.returncode}\n{out}"


def hardware_steps(heading: str, fc: Sitl, cwd: Path, port: int) -> str:
    """Run the README's steps under ``heading`` in order up to ``mecanum-mav run``; the run
    command (localized), which is left to the caller."""
    run = None
    for block in plan.section(heading, "sh"):
        for command in plan.shell_commands(block.text):
            if run is not None:
                raise AssertionError(f"README {heading}: a step after 'run': {command!r}")
            local = plan.localize(command, gcs_port=port, fc_url=fc.fc_url)
            if command.startswith("mecanum-mav run"):
                run = local
                continue
            if "--reboot" in command:  # a rebooted board streams only what it is asked for
                done = run_step(local, cwd)
                assert fc.monitor is not None
                fc.monitor.request_servo_output(REACT_S)
            else:
                done = run_step(local, cwd)
            expect(command, done)
    assert run is not None, f"README {heading}: no 'mecanum-mav run' step"
    return run


def forward_pulses(params_file: Path, channels: range) -> tuple[int, ...]:
    """The pulse width on each of ``channels`` for full forward stick, by the rover's file."""
    params = load(params_file)
    _, pulses = manual_output(1.0, 0.0, 0.0, InputConfig.from_params(params),
                              PwmMap.from_params(params))
    by_channel = {int(params[f"MOT_{w}_CH"]): p for w, p in zip(WHEEL_KEYS, pulses,
                                                                strict=True)}
    return tuple(by_channel[ch] for ch in channels)


@contextlib.contextmanager
def rover_on(run: str, cwd: Path, port: int, fc: Sitl) -> Iterator[tuple[Background, Rig]]:
    gcs, gcs_port = udp_ground_station(f"udpin:127.0.0.1:{port}")
    try:
        with background(run, cwd) as job:
            yield job, Rig(fc, gcs, job)  # (a Rig reads only the process's .log())
    finally:
        gcs_port.close()


@needs_sitl
def test_readme_real_hardware_steps_on_real_ardupilot_then_sigterm_and_kill_9(workdir):
    """Steps 2-7 of the README's Real hardware on ArduPilot Rover SITL with no receiver (the
    companion its only RC input): setup-fc finds the hazards, --apply --reboot fixes them, the
    rover's file, setup-fc for the file, run; a ground station arms (pre-arm checks on) and
    drives, every wheel forward; disarm gives trim; SIGTERM exits 0; and a companion killed
    with -9 while driving leaves the wheels at trim within RC_OVERRIDE_TIME + 0.6 s."""
    assert BINARY is not None
    port = free_port()
    with Sitl(BINARY, "udp", receiver=None, boot_timeout_s=REACT_S) as fc:
        run = hardware_steps("Real hardware", fc, workdir, port)
        forward = forward_pulses(workdir / "rover.parm", range(1, 5))
        trim = (1500, 1500, 1500, 1500)
        for ending in ("SIGTERM", "kill -9"):
            with rover_on(run, workdir, port, fc) as (job, rig):
                rig.arm()
                rig.drive(1000, 0, 0, forward)
                if ending == "SIGTERM":
                    ack = rig.gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                          timeout_s=REACT_S)
                    assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED
                    assert rig.monitor.wait_servos(lambda s: s == trim, REACT_S), rig.why()
                    job.signal(signal.SIGTERM)
                    assert job.proc.wait(REACT_S) == 0, job.log()
                else:
                    since = rig.monitor.mark()
                    killed = time.monotonic()
                    job.signal(signal.SIGKILL)
                    stopped = rig.monitor.wait_servos(lambda s: s == trim, REACT_S, since=since)
                    assert stopped is not None, f"the wheels kept turning\n{rig.why()}"
                    print(f"kill -9 while driving: SERVO1..4 at trim after "
                          f"{(stopped.t - killed) * 1000:.0f} ms")
                    assert stopped.t - killed < 0.5 + 0.6, rig.why()


@needs_sitl
def test_readme_rc_receiver_steps_with_the_reboot_drive_outputs_9_to_12_alike(workdir):
    """The README's receiver steps after its real-hardware ones, on a board with a receiver:
    the wheels move to outputs 9-12 and the radio failsafe to channel 9, which takes the
    reboot (setup-fc --reboot: the firmware restarts on its stored parameters); a forward
    stick gives all four outputs the same pulse (a dead zone written but not stored would
    give the front-left another)."""
    assert BINARY is not None
    port = free_port()
    centre = (1500, 1500, 1500, 1500, 1500, 1500, 1000, 1100)
    with Sitl(BINARY, "udp", receiver=centre, first_servo=9, boot_timeout_s=REACT_S) as fc:
        hardware_steps("Real hardware", fc, workdir, port)
        run = hardware_steps("RC receiver", fc, workdir, port)
        forward = forward_pulses(workdir / "rover.parm", range(9, 13))
        with rover_on(run, workdir, port, fc) as (job, rig):
            assert rig.said("FC setup checked: safe"), rig.why()
            rig.arm()
            rig.drive(1000, 0, 0, forward)
            assert len(set(forward)) == 2  # (mirrored motors: two pulse widths, in pairs)
            job.signal(signal.SIGTERM)
            assert job.proc.wait(REACT_S) == 0, job.log()


# --------------------------------------------------------------------------- the rest


def test_readme_fleet_loop_from_an_empty_directory_shows_three_rovers(workdir):
    """The fleet block as a bash script in an empty folder (the instances' ports 14560,
    14570, 14580 are the product's; only the ground station's 14550 is moved)."""
    (block,) = [b for b in plan.section("Fleet", "sh") if "--instance" in b.text]
    port = free_port()
    script = block.text.replace(str(plan.README_GCS_PORT), str(port))
    gcs, gcs_port = udp_ground_station(f"udpin:127.0.0.1:{port}")
    gcs.beating = False
    env = {**os.environ, "PATH": f"{BIN}:{os.environ['PATH']}"}
    log = workdir.parent / "fleet.log"
    with log.open("wb") as out:
        proc = subprocess.Popen(["bash", "-c", script], cwd=workdir, env=env,
                                stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        seen: set[int] = set()

        def listen(wait_s: float) -> None:
            seen.update(msg.get_srcSystem() for msg in gcs.pump(wait_s)
                        if msg.get_type() == "HEARTBEAT"
                        and msg.type == mavlink.MAV_TYPE_GROUND_ROVER)

        wait_until(lambda: seen == {1, 2, 3}, 60.0, pump=listen, pump_s=0.2)
        assert seen == {1, 2, 3}, log.read_text()
        assert all((workdir / f"rover{i}.tlog").exists() for i in range(3))
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(20)
        gcs_port.close()


def test_readme_signing_how_to_with_mavproxy_arms_only_once_it_has_the_key(workdir):
    port = free_port()
    (rover_block,) = [b for b in plan.section("Signing", "sh") if "--signing-key" in b.text]
    typed = plan.prompt_commands(plan.section("Signing", "text")[0].text)
    mavproxy = plan.localize(plan.shell_commands(
        plan.section("MAVProxy", "sh")[0].text)[0], gcs_port=port)
    *prepare, start = plan.shell_commands(rover_block.text)
    subprocess.run(" && ".join(prepare), shell=True, cwd=workdir, check=True)  # the key file
    start = plan.localize(start, gcs_port=port)
    with background(start, workdir) as rover:
        session = MavProxySession(mavproxy, workdir)
        try:
            assert session.heartbeat(lambda m: True, 60.0), session.why()
            session.type("arm throttle")  # without the key: refused, and said why
            assert session.printed("Unsigned packet refused: signing required"), session.why()
            assert not session.heartbeat(lambda m: m.base_mode & ARMED, 3.0)
            for command in typed:
                session.type(command)
            session.type("arm throttle")
            assert session.heartbeat(lambda m: m.base_mode & ARMED), session.why()
        finally:
            session.close()
        assert rover.close() == 0, rover.log()


def test_readme_looking_at_a_drive_summarizes_the_sample_drive(workdir):
    (block,) = [b for b in plan.section("Looking at a drive", "sh") if "log_example" in b.text]
    for command in plan.shell_commands(block.text):
        done = run_step(plan.localize(command, gcs_port=0), workdir)
        assert done.returncode == 0, done.stdout + done.stderr
    assert "distance" in done.stdout and "modes:" in done.stdout, done.stdout
    assert (workdir / "sample.png").stat().st_size > 10_000


# --------------------------------------------------------------------------- the live view

VIEW_PORT = 14551
"""The README's port for MAVProxy's extra output, where ``mecanum-mav view`` listens."""
VIEWER_ADDRESS = re.compile(r"(http://127\.0\.0\.1:\d+/\S*)")


def view_command(command: str, gcs_port: int, view_port: int) -> str:
    """A README command of the live view, localized: the ground station's port and the view's
    to free ones, the web viewer on a free port (``--web-port 0``) and ``view`` told where
    MAVProxy's extra output now goes."""
    local = plan.localize(command, gcs_port=gcs_port).replace(str(VIEW_PORT), str(view_port))
    words = shlex.split(local)
    if words[:2] == ["mecanum-mav", "view"] and "--connect" not in words:
        words += ["--connect", f"udpin:127.0.0.1:{view_port}"]
    if words[0] == "mecanum-mav" and ("view" in words[:2] or "--view" in words):
        words += ["--web-port", "0"]
    return shlex.join(words)


def served_viewer(job: Background) -> str:
    """The web viewer's address ``job`` printed (no display here), once it answers."""
    found = wait_until(lambda: VIEWER_ADDRESS.search(job.log()), REACT_S)
    assert found, f"{job.command}: no viewer address printed\n{job.log()}"
    address = found.group(1)
    with urllib.request.urlopen(address.split("?")[0], timeout=10) as page:
        assert page.status == 200 and b"rerun" in page.read().lower(), address
    return address


def interrupted(job: Background) -> int | None:
    """Ctrl-C to ``job``, as a user ends it; its exit status."""
    job.signal(signal.SIGINT)
    try:
        job.proc.wait(20)
    except subprocess.TimeoutExpired:
        raise AssertionError(f"{job.command}: still running 20 s after Ctrl-C\n{job.log()}"
                             ) from None
    return job.proc.returncode


def test_readme_watch_it_live_serves_the_view_of_the_sim_of_mavproxys_output_and_of_a_log(
        workdir):
    """Watch it live, as written: ``sim --view`` serves its view; MAVProxy's extra output
    feeds ``mecanum-mav view``, which counts what it showed when Ctrl-C ends it; a finished
    drive's ``log ... --view`` serves its view too. Each ends with status 0 on Ctrl-C."""
    (sample,) = [b for b in plan.section("Looking at a drive", "sh") if "log_example" in b.text]
    for command in plan.shell_commands(sample.text)[:1]:  # the sample drive's tlog
        assert run_step(plan.localize(command, gcs_port=0), workdir).returncode == 0
    (block,) = [b for b in plan.section("Watch it live", "sh")]
    sim, mavproxy, view, log = plan.shell_commands(block.text)
    gcs_port, view_port = free_port(), free_port()
    with background(view_command(sim, gcs_port, view_port), workdir) as rover, \
            background(view_command(mavproxy, gcs_port, view_port), workdir), \
            background(view_command(view, gcs_port, view_port), workdir) as live:
        served_viewer(rover)
        served_viewer(live)
        forwarded = workdir / "mav.tlog"  # what MAVProxy relayed, its extra output's too
        assert wait_until(lambda: forwarded.exists() and forwarded.stat().st_size > 20_000,
                          REACT_S), "MAVProxy relayed nothing"
        assert interrupted(live) == 0, live.log()
        shown = re.search(r"(\d+) messages", live.log())
        assert shown and int(shown.group(1)) > 50, live.log()
        assert interrupted(rover) == 0, rover.log()
    with background(view_command(log, gcs_port, view_port), workdir) as finished:
        served_viewer(finished)
        assert interrupted(finished) == 0, finished.log()


# --------------------------------------------------------------------------- the twin


@needs_sitl
def test_readme_twin_command_brings_up_a_companion_a_ground_station_arms_and_drives_north(
        workdir):
    """The quick start's twin, as written (ArduPilot's SITL where this machine has it): it
    says it is ready; a ground station on the port arms the companion with the firmware's
    pre-arm checks on and drives it forward in MANUAL; the twin's own report then shows the
    true pose north of the start; Ctrl-C ends it with status 0."""
    pytest.importorskip("mujoco", reason="the twin needs the physics extra")
    (block,) = [b for b in plan.section("Quick start", "sh") if "twin" in b.text]
    (command,) = plan.shell_commands(block.text)
    port = free_port()
    station, udp = udp_ground_station(f"udpin:127.0.0.1:{port}")
    true_north = re.compile(r"true pose N ([+-][\d.]+) m")
    try:
        with background(plan.localize(command, gcs_port=port, sitl=str(BINARY)),
                        workdir) as twin:
            assert wait_until(lambda: "ready." in twin.log() or twin.proc.poll() is not None,
                              90.0) and "ready." in twin.log(), twin.log()
            station.arm(timeout_s=60.0)

            def driven_north() -> bool:
                station.sticks(x=500)
                station.pump(0.05)
                estimates = station.received("LOCAL_POSITION_NED")
                return bool(estimates) and estimates[-1].x > 0.8

            assert wait_until(driven_north, 20.0), f"did not drive north\n{twin.log()}"
            station.sticks()
            reports = len(true_north.findall(twin.log()))
            assert wait_until(lambda: len(true_north.findall(twin.log())) > reports, 10.0)
            assert float(true_north.findall(twin.log())[-1]) > 0.5, twin.log()
            assert interrupted(twin) == 0, twin.log()
    finally:
        udp.close()
