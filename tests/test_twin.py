"""The twin (mecanum_mav.sim.twin): real ArduPilot Rover firmware (SITL) driving the MuJoCo
chassis through its JSON backend, with the companion unchanged in the loop, set up by the
user's path (``setup-fc --apply --reboot``, then ``run``), driven by a ground station on the
companion. Skipped, with the reason, without the firmware or mujoco (in CI a skip fails).

``pytest -rP tests/test_twin.py`` shows the figures: the real-time factor, the bridge's load,
and how far and how long the chassis ran on after the companion was killed at 1 m/s."""

from __future__ import annotations

import importlib.util
import io
import math
import socket
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

import numpy as np
import pytest
from pymavlink import mavutil
from sitl import find_sitl
from support import wait_until

from mecanum_mav.app.cli import main
from mecanum_mav.config.params import Params
from mecanum_mav.io.tlog import parse_tlog
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.mecanum.geometry import body_to_ned
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.fcsetup import SAFE_OVERRIDE_TIME_S
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.groundstation import ScriptedGroundStation, UdpPort, udp_ground_station
from mecanum_mav.sim.physics import WheelContact
from mecanum_mav.sim.process import CliProcess, free_port
from mecanum_mav.sim.truthsender import CONTACT_NAMES, TRUTH_SOURCE, TruthPublisher
from mecanum_mav.sim.twin import SETUP_OK, TruthSample, Twin, describe
from mecanum_mav.sim.twinrecord import TwinRecord

BINARY, WHY_NOT = find_sitl()
HAS_MUJOCO = importlib.util.find_spec("mujoco") is not None
REAL_FIRMWARE = (pytest.mark.sitl, pytest.mark.skipif(BINARY is None, reason=WHY_NOT),
                 pytest.mark.skipif(not HAS_MUJOCO, reason="the twin's chassis needs the "
                                    "physics extra (mujoco)"))


def real_firmware(test: T) -> T:
    """Marks a test that runs the real firmware on the MuJoCo chassis (skipped without)."""
    for mark in REAL_FIRMWARE:
        test = mark(test)
    return test


T = TypeVar("T")
READY_S = 60.0
FULL = 1000
"""Full stick: WHL_MAX_SPD (1 m/s by default) straight ahead."""


def truth_if(twin: Twin, predicate: Callable[[TruthSample], bool]) -> TruthSample | None:
    """The twin's latest truth if it satisfies ``predicate``, else None."""
    sample = twin.truth_now()
    return sample if predicate(sample) else None


class Rig:
    """A twin and a scripted ground station on its companion; the twin sends its truth to
    ``udpout:127.0.0.1:truth_port`` (a test listens there when it needs it)."""

    def __init__(self, twin: Twin, gcs: ScriptedGroundStation, truth_port: int) -> None:
        self.twin = twin
        self.gcs = gcs
        self.truth_port = truth_port

    def drive(self, x: int, until: Callable[[TruthSample], bool],
              timeout_s: float) -> TruthSample | None:
        """In MANUAL, stream MANUAL_CONTROL x forward at 20 Hz until ``until(truth)``; that
        truth. (The module's tests share the rig and nothing sends the ground station's
        HEARTBEAT between them: a test that ran longer than FS_GCS_TMO leaves the companion
        in the failsafe's HOLD, as a silent ground station should. The pilot takes MANUAL
        back first.)"""
        assert self.gcs.set_mode(Mode.MANUAL, timeout_s=3.0) == mavlink.MAV_RESULT_ACCEPTED, \
            self.why()

        def pump(wait_s: float) -> None:
            self.gcs.sticks(x, 0, 0)
            self.gcs.pump(wait_s)
        return wait_until(lambda: truth_if(self.twin, until), timeout_s, pump=pump)

    def why(self) -> str:
        return f"{describe(self.twin.stats())}\n{self.twin.why()}"


def _rig() -> Iterator[Rig]:
    assert BINARY is not None
    gcs, port = udp_ground_station()
    truth_port = free_port(socket.SOCK_DGRAM)
    try:
        with Twin(BINARY, gcs_port=_port_number(port),
                  truth=f"udpout:127.0.0.1:{truth_port}") as twin:
            rig = Rig(twin, gcs, truth_port)
            try:
                gcs.arm(timeout_s=READY_S)
            except RuntimeError:
                raise AssertionError(f"the companion never armed\n{rig.why()}") from None
            yield rig
    finally:
        port.close()


def _port_number(port: UdpPort) -> int:
    return int(port.url.rsplit(":", 1)[1])


@pytest.fixture(scope="module")
def rig() -> Iterator[Rig]:
    yield from _rig()


@pytest.fixture
def own_rig() -> Iterator[Rig]:
    """A twin of the test's own (for a test that kills the companion)."""
    yield from _rig()


def firmware_param(twin: Twin, name: str, timeout_s: float = 10.0) -> float | None:
    """``name`` read from the firmware itself, on its own port (SERIAL1)."""
    conn = mavutil.mavlink_connection(twin.firmware_url, source_system=250, source_component=190)
    try:
        deadline = time.monotonic() + timeout_s
        asked = 0.0
        while (now := time.monotonic()) < deadline:
            if now - asked > 1.0:
                conn.mav.param_request_read_send(1, 1, name.encode(), -1)
                asked = now
            msg = conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.5)
            if msg is not None and msg.param_id.rstrip("\x00") == name:
                return float(msg.param_value)
        return None
    finally:
        conn.close()


@real_firmware
def test_the_twin_is_set_up_by_setup_fc_and_steps_in_lockstep_with_the_firmware(rig):
    twin = rig.twin
    assert SETUP_OK in twin.setup_output, twin.setup_output
    stats = twin.stats()
    assert stats.restarts >= 1, rig.why()  # setup-fc --reboot rebooted the firmware
    assert stats.frames > 1000 and stats.dropped == 0 and stats.malformed == 0, rig.why()
    assert stats.real_time_factor == pytest.approx(1.0, abs=0.1), rig.why()
    print(f"\ntwin: {describe(stats)}")


@real_firmware
def test_the_companion_arms_while_the_firmwares_own_prearm_checks_stay_on(rig):
    # (the fixture armed the companion with a ground station's COMMAND_LONG, as a user does)
    assert rig.gcs.wait("HEARTBEAT", lambda m: m.base_mode & 128, 5.0) is not None, rig.why()
    assert firmware_param(rig.twin, "ARMING_CHECK") == 1.0, rig.why()


@real_firmware
def test_the_twins_truth_at_rest_has_each_wheels_contact_at_10_hz_carrying_its_weight(rig):
    # (the chassis stands still here: armed, no stick yet)
    listener = TruthListener(rig.truth_port)
    try:
        vectors = by_type(listener.take(2.0), "DEBUG_VECT")
    finally:
        listener.close()
    names = [m.name for m in vectors]
    assert all(18 <= names.count(n) <= 22 for n in CONTACT_NAMES), names
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in vectors} == {TRUTH_SOURCE}
    weight = Params()["SIM_MASS"] * 9.81
    last = vectors[-4:]
    assert [m.name for m in last] == list(CONTACT_NAMES)
    print(f"\nat rest: normal forces {[round(m.x, 2) for m in last]} N, sum "
          f"{sum(m.x for m in last):.2f} N, m*g {weight:.2f} N")
    assert sum(m.x for m in last) == pytest.approx(weight, rel=0.03), rig.why()
    # (each wheel on the floor, none slipping; four wheels on a rigid chassis share the
    # weight unevenly: the twin measured 3.5, 16.2, 16.1, 3.6 N)
    assert all(m.x > 0.0 and m.z == 0.0 for m in last)


@real_firmware
def test_the_view_of_the_twins_truth_records_its_true_path_and_contact_forces(
        rig, tmp_path, monkeypatch):
    """``view --connect udpin:...`` on the port the twin sends its truth to (as the twin
    prints it): the recording (read back with Rerun's reader) has the true path and each
    wheel's normal force, summing to the weight at rest."""
    pytest.importorskip("rerun", reason="the view extra (rerun-sdk) is not installed")
    from test_view import read_rrd

    from mecanum_mav.app.view import run_view

    monkeypatch.setenv("DISPLAY", "")
    monkeypatch.setenv("WAYLAND_DISPLAY", "")
    saved = tmp_path / "truth.rrd"
    deadline = time.monotonic() + 30.0
    status = run_view(f"udpin:127.0.0.1:{rig.truth_port}", Params(), save=saved, web_port=0,
                      out=io.StringIO(), stop_when=lambda mapping: mapping.messages >= 180
                      or time.monotonic() > deadline)
    assert status == 0
    temporal, _ = read_rrd(saved)
    assert len(temporal["map/truth"]) >= 20, rig.why()  # 3 s at 20 Hz
    truth = rig.twin.truth_now()
    east, minus_north = temporal["map/truth"][-1][1]["LineStrips2D:strips"][0][-1]
    assert (-minus_north, east) == (pytest.approx(truth.north_m, abs=0.02),
                                    pytest.approx(truth.east_m, abs=0.02))
    forces = [temporal[f"contacts/normal/{w}"][-1][1]["Scalars:scalars"][0]
              for w in ("FL", "FR", "RL", "RR")]
    assert sum(forces) == pytest.approx(Params()["SIM_MASS"] * 9.81, rel=0.03)


@real_firmware
def test_manual_sticks_forward_drive_the_mujoco_chassis_north(rig):
    start = rig.twin.truth_now()
    moved = rig.drive(FULL // 2, lambda s: s.north_m - start.north_m > 0.5, 15.0)
    assert moved is not None, f"not 0.5 m north: {rig.twin.truth_now()}\n{rig.why()}"
    assert abs(moved.east_m - start.east_m) < 0.1 * (moved.north_m - start.north_m)
    assert moved.forward_mps > 0.3
    stopped = rig.drive(0, lambda s: abs(s.forward_mps) < 0.01, 5.0)
    assert stopped is not None, rig.why()


@real_firmware
def test_the_twins_truth_comes_at_20_hz_as_sim_state_matching_the_bridges_record(rig):
    """While the chassis drives north, the twin's SIM_STATEs (about 0, 0: ORIGIN_LAT/LON
    unset) come at 20 Hz, each one the pose and velocity of a frame in the bridge's record,
    and the last one a frame of the last 0.1 s."""
    listener = TruthListener(rig.truth_port)
    started = rig.twin.truth_now()
    try:
        messages = listener.take(3.0, pump=lambda: (rig.gcs.sticks(FULL // 2, 0, 0),
                                                     rig.gcs.pump(0.0)))
        now = rig.twin.truth_now()
    finally:
        listener.close()
        rig.drive(0, lambda s: abs(s.forward_mps) < 0.01, 5.0)
    states = by_type(messages, "SIM_STATE")
    rows = rig.twin.truth_array()
    rows = rows[rows[:, 1] >= started.time_s - 0.2]
    cos, sin = np.cos(rows[:, 4]), np.sin(rows[:, 4])
    v_north = cos * rows[:, 5] - sin * rows[:, 6]  # body FRD -> NED
    v_east = sin * rows[:, 5] + cos * rows[:, 6]
    print(f"\ntruth: {len(states)} SIM_STATE in 3 s; {describe(rig.twin.stats())}")
    assert len(states) >= 3.0 * 18, len(states)
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in states} == {TRUTH_SOURCE}
    matched = []
    for msg in states:
        north, east = GlobalOrigin(0, 0).to_local(msg.lat_int, msg.lon_int)
        same = ((np.abs(rows[:, 2] - north) < 0.012) & (np.abs(rows[:, 3] - east) < 0.012)
                & (np.abs(rows[:, 4] - msg.yaw) < 1e-6) & (np.abs(v_north - msg.vn) < 1e-5)
                & (np.abs(v_east - msg.ve) < 1e-5))
        assert same.any(), f"no frame of the record is {msg}"
        matched.append(float(rows[np.flatnonzero(same)[-1], 1]))
    assert matched == sorted(matched) and matched[-1] - matched[0] > 2.5
    assert now.time_s - matched[-1] < 0.1


def stop_after(rig: Rig, end: Callable[[], object]) -> tuple[TruthSample, TruthSample, float]:
    """Drive at full stick until 0.95 m/s, then ``end()`` the companion: the truth then, the
    truth once the chassis stood still, and when ``end`` was called (monotonic s)."""
    fast = rig.drive(FULL, lambda s: s.forward_mps > 0.95, 15.0)
    assert fast is not None, f"never 0.95 m/s: {rig.twin.truth_now()}\n{rig.why()}"
    ended_s = time.monotonic()
    at_end = rig.twin.truth_now()
    end()
    stopped = wait_until(lambda: truth_if(rig.twin, lambda s: math.hypot(
        s.forward_mps, s.right_mps) < 0.01), 5.0)
    assert stopped is not None, f"still moving 5 s later: {rig.twin.truth_now()}\n{rig.why()}"
    return at_end, stopped, ended_s


def travel_m(a: TruthSample, b: TruthSample) -> float:
    return math.hypot(b.north_m - a.north_m, b.east_m - a.east_m)


@real_firmware
def test_a_sigterm_of_the_companion_at_1_m_s_stops_the_chassis_at_once_with_its_neutral(rig):
    # (the last test on the module's twin: its companion ends here)
    assert rig.twin.companion is not None
    at_term, stopped, _ = stop_after(rig, rig.twin.companion.terminate)
    took_s = stopped.time_s - at_term.time_s
    print(f"\nSIGTERM at {at_term.forward_mps:.2f} m/s: the chassis stopped "
          f"{travel_m(at_term, stopped) * 100:.0f} cm and {took_s:.2f} s later")
    # the neutral reached the wheels, not the radio failsafe: that releases the channels only
    # RC_OVERRIDE_TIME (setup-fc's 0.5 s) after the last override, and the chassis then still
    # has to slow down, so no stop by the failsafe comes this early (0.42 s was measured with
    # the suite's four workers on two cores; the kill -9 test below measures the failsafe's).
    assert took_s < SAFE_OVERRIDE_TIME_S, rig.why()
    assert rig.twin.stats().wheel_pulses == (1500, 1500, 1500, 1500), rig.why()


@real_firmware
def test_a_kill_9_of_the_companion_at_1_m_s_stops_the_chassis_by_the_firmwares_failsafe(own_rig):
    rig = own_rig
    at_kill, stopped, killed_s = stop_after(rig, rig.twin.kill_companion)
    distance_m = travel_m(at_kill, stopped)
    wait_until(lambda: rig.twin.truth_now().time_s > stopped.time_s + 0.5, 5.0)
    settled = rig.twin.truth_now()
    print(f"\nkill -9 at {at_kill.forward_mps:.2f} m/s: the chassis stopped "
          f"{distance_m * 100:.0f} cm and {stopped.time_s - at_kill.time_s:.2f} s (physics; "
          f"{stopped.wall_s - killed_s:.2f} s wall) later; {describe(rig.twin.stats())}")
    assert distance_m < 1.5
    # the wheels ran on the dead companion's last override until the firmware's radio
    # failsafe took them to trim (0.5 s without RC): not the companion's shutdown path
    assert stopped.time_s - at_kill.time_s > 0.4
    assert travel_m(stopped, settled) < 0.01  # and stays stopped
    assert rig.twin.stats().wheel_pulses == (1500, 1500, 1500, 1500), rig.why()  # its trim


# --------------------------------------------------------------------------- the command


def test_the_twin_command_without_sitl_or_mecanum_sitl_says_so_and_exits_2(monkeypatch, capsys):
    monkeypatch.delenv("MECANUM_SITL", raising=False)
    assert main(["twin"]) == 2
    assert "--sitl PATH" in capsys.readouterr().err


def test_the_twin_command_with_an_empty_mecanum_sitl_says_so_as_when_unset(monkeypatch, capsys):
    monkeypatch.setenv("MECANUM_SITL", "")
    assert main(["twin"]) == 2
    assert "--sitl PATH" in capsys.readouterr().err


def test_the_twin_commands_firmware_is_mecanum_sitl_unless_sitl_is_given(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # docs/twin.md: "`--sitl` defaults to `$MECANUM_SITL`" (the path as given: whether a
    # program is there is the twin's to find out)
    import mecanum_mav.app.twin as twin_app

    started: list[Path] = []
    monkeypatch.setattr(twin_app, "run_twin", lambda params, sitl, **options: started.append(
        sitl) or 0)
    monkeypatch.setenv("MECANUM_SITL", str(tmp_path / "build" / "ardurover"))
    assert main(["twin", "--gcs", "udpout:127.0.0.1:9"]) == 0
    given = tmp_path / "other" / "ardurover"
    assert main(["twin", "--sitl", str(given), "--gcs", "udpout:127.0.0.1:9"]) == 0
    assert started == [tmp_path / "build" / "ardurover", given]


def test_the_twin_command_with_a_sitl_that_is_not_a_program_exits_2(tmp_path, capsys):
    assert main(["twin", "--sitl", str(tmp_path / "ardurover")]) == 2
    assert "is not an executable file" in capsys.readouterr().err


def test_the_twin_command_without_mujoco_gives_the_install_hint_and_exits_2(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "mujoco", None)  # (import mujoco raises ImportError)
    monkeypatch.delitem(sys.modules, "mecanum_mav.sim.mujocochassis", raising=False)
    started = time.monotonic()
    assert main(["twin", "--sitl", sys.executable, "--gcs", "udpout:127.0.0.1:9"]) == 2
    assert time.monotonic() - started < 5.0  # nothing was started
    assert "pip install 'mecanum-mav[physics]'" in capsys.readouterr().err


def twin_command(tmp_path: Path, *extra: str) -> CliProcess:
    """``mecanum-mav twin --sitl BINARY --gcs udpout:127.0.0.1:9 *extra`` as its own process
    (its group killed on the way out), no display (a view serves its web viewer)."""
    assert BINARY is not None
    return CliProcess(["twin", "--sitl", str(BINARY), "--gcs", "udpout:127.0.0.1:9", *extra],
                      tmp_path, log_name="twin.log")


def ready(twin: CliProcess) -> str:
    """The command's output once it says it is ready (or has ended)."""
    wait_until(lambda: "ready." in twin.log(100_000) or not twin.alive(), READY_S)
    text = twin.log(100_000)
    assert "ready." in text, text
    return text


@real_firmware
def test_the_twin_command_starts_everything_says_where_to_connect_and_ends_it_on_sigterm(
        tmp_path):
    with twin_command(tmp_path) as twin:
        text = ready(twin)
        firmware_pid = int(text.split("firmware pid ", 1)[1].split(",", 1)[0])
        companion_pid = int(text.split("companion pid ", 1)[1].split(")", 1)[0])
        assert "firmware directly: udpin:127.0.0.1:" in text
        twin.terminate()
        assert twin.wait(20) == 0, twin.log()
        assert "stopped; real-time factor" in twin.log()
        for pid in (firmware_pid, companion_pid):
            assert not Path(f"/proc/{pid}").exists(), f"{pid} still runs"


@real_firmware
def test_the_twin_command_with_view_serves_the_view_of_the_companions_links_and_ends_it(
        tmp_path, monkeypatch):
    """``twin --view``: a view follows the companion's tlog (its overrides and the firmware's
    SIMSTATE) and the twin's truth on the port it prints, serves the web viewer here (no
    display) and, at SIGTERM, ends after saying how many messages it showed; the tlog holds
    the firmware's truth (SIMSTATE)."""
    monkeypatch.setenv("DISPLAY", "")
    monkeypatch.setenv("WAYLAND_DISPLAY", "")
    with twin_command(tmp_path, "--view", "--web-port", "0") as twin:
        ready(twin)
        said = "the truth (SIM_STATE, wheel contacts) goes to udpout:127.0.0.1:"
        assert wait_until(lambda: said in twin.log(100_000), 5.0), twin.log()
        text = twin.log(100_000)
        assert "mecanum-mav view: " in text, text
        sources = text.split("mecanum-mav view: ", 1)[1].split(" -> ", 1)[0].split(", ")
        followed = Path(sources[0])
        assert sources[1:] == [text.split("mecanum-mav view --connect ", 1)[1].split()[0]]
        assert " -> http://127.0.0.1:" in text, text

        def truth_recorded() -> bool:
            entries = parse_tlog(followed.read_bytes(), followed.name).entries
            return any(e.msg.get_type() == "SIMSTATE" for e in entries)

        assert wait_until(truth_recorded, 10.0), "no SIMSTATE in the companion's tlog"
        twin.terminate()
        assert twin.wait(30) == 0, twin.log()
        shown = twin.log(100_000).split("mecanum-mav view: ")[-1]
        assert shown.split(" ", 1)[0].isdigit() and int(shown.split(" ", 1)[0]) > 0, \
            twin.log()


# --------------------------------------------------------------------------- the truth, fast


class TruthListener:
    """A view's end of the truth: ``udpin`` on a port from the OS (:attr:`url` is where a
    publisher sends)."""

    def __init__(self, port: int = 0) -> None:
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}")
        self.port = self.conn.port.getsockname()[1]
        self.url = f"udpout:127.0.0.1:{self.port}"

    def take(self, seconds: float, pump: Callable[[], object] | None = None) -> list:
        """Every message that comes in the next ``seconds`` (``pump()`` between reads)."""
        got: list = []
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0.0:
            if pump is not None:
                pump()
            msg = self.conn.recv_match(blocking=True, timeout=min(left, 0.05))
            while msg is not None:
                got.append(msg)
                msg = self.conn.recv_match(blocking=False)
        return got

    def close(self) -> None:
        self.conn.close()


def by_type(messages: list, kind: str) -> list:
    return [m for m in messages if m.get_type() == kind]


def moving_record(frames: int, yaw_rate: float = 0.2) -> TwinRecord:
    """A record of ``frames`` frames at 1200 Hz: driving forward-right at 0.4/0.1 m/s from
    1.5 m N, 2 m W, heading 0.3 rad and turning clockwise at ``yaw_rate``."""
    record = TwinRecord.local(capacity=1000)
    for k in range(frames):
        t = k / 1200
        record.add(TruthSample(100.0 + t, t, 1.5 + 0.4 * t, -2.0 + 0.1 * t,
                               0.3 + yaw_rate * t, 0.4, 0.1))
    return record


@pytest.fixture
def listener() -> Iterator[TruthListener]:
    end = TruthListener()
    yield end
    end.close()


def test_the_truth_publisher_sends_the_records_latest_pose_as_sim_state_from_its_own_sender(
        listener):
    # Kills: north and east swapped, the body velocity not rotated to NED, the yaw rate left
    # 0, the simulator's ids instead of the truth's own, an older row than the latest.
    record = moving_record(600)
    publisher = TruthPublisher(record, listener.url, GlobalOrigin(0, 0))
    try:
        states = by_type(listener.take(0.3), "SIM_STATE")
    finally:
        publisher.close()
    assert len(states) == 1  # the physics did not move on: the pose is not sent again
    msg = states[0]
    assert (msg.get_srcSystem(), msg.get_srcComponent()) == TRUTH_SOURCE != (1, 1)
    last = record.truth_now()
    north, east = GlobalOrigin(0, 0).to_local(msg.lat_int, msg.lon_int)
    assert (north, east) == (pytest.approx(last.north_m, abs=0.012),
                             pytest.approx(last.east_m, abs=0.012))
    assert msg.yaw == pytest.approx(last.yaw_rad, abs=1e-6)
    assert msg.zgyro == pytest.approx(0.2, rel=1e-3)
    v_north, v_east = body_to_ned(0.4, 0.1, last.yaw_rad)
    assert (msg.vn, msg.ve) == (pytest.approx(v_north, abs=1e-6), pytest.approx(v_east, abs=1e-6))
    assert (msg.q1, msg.q4) == (pytest.approx(math.cos(last.yaw_rad / 2)),
                                pytest.approx(math.sin(last.yaw_rad / 2)))


def test_the_truth_publisher_sends_each_new_pose_at_20_hz_while_the_physics_moves_on(listener):
    # Kills: the pose sent once only, or sent at a wrong rate.
    record = moving_record(1)
    publisher = TruthPublisher(record, listener.url, GlobalOrigin(0, 0))
    frames = [1]

    def step() -> None:  # the bridge's frames, as the wall clock goes
        while frames[0] < 1200 * (time.monotonic() - started):
            t = frames[0] / 1200
            record.add(TruthSample(t, t, 1.5 + t, 0.0, 0.0, 1.0, 0.0))
            frames[0] += 1

    started = time.monotonic()
    try:
        states = by_type(listener.take(1.0, pump=step), "SIM_STATE")
    finally:
        publisher.close()
    assert 15 <= len(states) <= 22, len(states)
    norths = [GlobalOrigin(0, 0).to_local(m.lat_int, m.lon_int)[0] for m in states]
    assert norths == sorted(norths) and norths[-1] - norths[0] > 0.5


def test_the_truth_publisher_sends_each_contact_reading_once_as_the_boards_debug_vects(listener):
    # Kills: a reading sent again (every tick) or never, the force, slip and flag in other
    # fields, wheels out of order.
    record = moving_record(10)
    contacts = (WheelContact(10.0, 0.01, False), WheelContact(11.0, 0.02, False),
                WheelContact(12.0, 0.5, True), WheelContact(13.0, 0.03, False))
    record.set_contacts(1.25, contacts)
    publisher = TruthPublisher(record, listener.url, GlobalOrigin(0, 0))
    try:
        vectors = by_type(listener.take(0.3), "DEBUG_VECT")
        record.set_contacts(1.35, contacts)
        vectors += by_type(listener.take(0.3), "DEBUG_VECT")
    finally:
        publisher.close()
    assert [m.name for m in vectors] == [*CONTACT_NAMES, *CONTACT_NAMES]
    assert [m.time_usec for m in vectors] == [1_250_000] * 4 + [1_350_000] * 4
    assert [(m.x, round(m.y, 3), m.z) for m in vectors[:4]] == [
        (10.0, 0.01, 0.0), (11.0, 0.02, 0.0), (12.0, 0.5, 1.0), (13.0, 0.03, 0.0)]
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in vectors} == {TRUTH_SOURCE}


def test_the_twin_command_with_a_truth_url_that_is_not_udpout_exits_2(capsys):
    assert main(["twin", "--sitl", sys.executable, "--truth", "tcp:127.0.0.1:5760"]) == 2
    assert "udpout:HOST:PORT" in capsys.readouterr().err


@pytest.mark.skipif(not HAS_MUJOCO, reason="the twin's chassis needs the physics extra (mujoco)")
def test_the_bridge_records_the_wheel_contacts_every_tenth_of_a_second_carrying_the_weight():
    # Kills: the contacts never recorded, or recorded every frame (the lockstep's cost).
    from mecanum_mav.config.params import Params
    from mecanum_mav.control.pwm import PwmMap
    from mecanum_mav.sim.mujocochassis import MujocoChassis
    from mecanum_mav.sim.sitljson import encode_servo_packet
    from mecanum_mav.sim.twinbridge import BridgeCore, WheelMap

    params = Params()
    core = BridgeCore(MujocoChassis.from_params(params),
                      WheelMap(PwmMap.from_params(params), esc_dead_band=params["SIM_ESC_DZ"]))
    assert core.record.contacts() is None
    times = set()
    for count in range(1, 1201):  # one second at 1200 Hz, wheels at neutral
        core.answer(encode_servo_packet(1200, count, [1500] * 4))
        read = core.record.contacts()
        assert read is not None
        times.add(read[0])
    assert len(times) == 10  # 0.0, 0.1, ... 0.9 s of physics
    _, wheels = core.record.contacts() or (0.0, ())
    weight = params["SIM_MASS"] * 9.81
    assert sum(w.normal_n for w in wheels) == pytest.approx(weight, rel=0.03)
    assert not any(w.slipping for w in wheels)
