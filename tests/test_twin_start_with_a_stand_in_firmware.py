"""How the twin (mecanum_mav/sim/twin.py) starts, refuses and stops when a part does not come
up: the firmware exits, stays silent, or its physics process dies; setup-fc fails or does not
end; the companion dies. The firmware is a stand-in script (``ardurover`` in a temporary
folder) that does what the test needs of the real one (HEARTBEAT on its SERIAL1, nothing
else); the bridge is the real MuJoCo process. What the real firmware does is test_twin.py's."""

from __future__ import annotations

import importlib.util
import io
import os
import signal
import sys
import threading
from pathlib import Path

import pytest
from support import not_installed, wait_until

from mecanum_mav.app.twin import run_twin
from mecanum_mav.config.params import Params
from mecanum_mav.sim.twin import Twin, TwinError

pytestmark = pytest.mark.skipif(importlib.util.find_spec("mujoco") is None,
                                reason="the twin's chassis needs the physics extra (mujoco)")

STAND_IN = """#!{python}
import os, socket, sys, time
from pymavlink.dialects.v20 import ardupilotmega as mavlink

args = sys.argv[1:]


def port(flag):
    return int(args[args.index(flag) + 1].rsplit(":", 1)[1])


BEHAVIOUR = "{behaviour}"
if BEHAVIOUR == "exit":
    print("stand-in: no JSON physics", flush=True)
    sys.exit(3)
if BEHAVIOUR == "silent":
    time.sleep(60)
    sys.exit(0)
if BEHAVIOUR == "hog":  # the companion's port (SERIAL0's peer) is taken
    hog = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    hog.bind(("127.0.0.1", port("--serial0")))
sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
told = sys.argv[0] + ".crash"  # (crash: once the test creates this file)
while not (BEHAVIOUR == "crash" and os.path.exists(told)):
    beat = mav.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,
                                mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3)
    sock.sendto(beat.pack(mav), ("127.0.0.1", port("--serial1")))
    time.sleep(0.1)
print("stand-in: crashed", flush=True)
sys.exit(5)
"""


def stand_in(folder: Path, behaviour: str) -> Path:
    """An ``ardurover`` that ``exit``s at once (status 3), stays ``silent``, ``beat``s
    (HEARTBEAT on SERIAL1 at 10 Hz), beats and ``hog``s the companion's port, or beats until
    told to ``crash`` (a file ``ardurover.crash`` beside it; status 5)."""
    folder.mkdir(parents=True, exist_ok=True)
    binary = folder / "ardurover"
    binary.write_text(STAND_IN.format(python=sys.executable, behaviour=behaviour))
    binary.chmod(0o755)
    return binary


def start(twin: Twin, timeout_s: float) -> None:
    """Start ``twin`` as the context manager does (closed on every way out), with a timeout."""
    try:
        twin.start(timeout_s)
    finally:
        twin.close()


class NoSetupTwin(Twin):
    """A twin whose setup-fc step is skipped (a stand-in cannot be set up): the companion
    starts right after the firmware is heard."""

    def _setup_fc(self, timeout_s: float) -> None:
        pass


# ---------------------------------------------------------------------------- no process

def test_a_twin_of_an_unknown_frame_is_refused(tmp_path):
    with pytest.raises(ValueError, match="unknown frame 'quad': one of companion, "
                                         "ardupilot-omni"):
        Twin(tmp_path / "ardurover", frame="quad")


def test_a_twins_truth_is_refused_before_it_started(tmp_path):
    twin = Twin(tmp_path / "ardurover")
    try:
        for read in (twin.truth, twin.truth_now, twin.stats):
            with pytest.raises(RuntimeError, match="the twin has not started"):
                read()
        assert twin.bridge_summary() == "not started"
    finally:
        twin.close()


def test_closing_a_twin_removes_its_own_folder_and_leaves_one_it_was_given(tmp_path):
    given = tmp_path / "work"
    given.mkdir()
    mine, theirs = Twin(tmp_path / "ardurover"), Twin(tmp_path / "ardurover", workdir=given)
    mine.close()
    theirs.close()
    assert not mine.workdir.exists()
    assert given.is_dir()


# ---------------------------------------------------------------------------- starting

def test_an_ardupilot_omni_twin_is_ready_once_the_firmware_is_heard_and_has_no_companion(
        tmp_path):
    with Twin(stand_in(tmp_path, "beat"), frame="ardupilot-omni") as twin:
        assert twin.companion is None and twin.companion_pid is None
        twin.kill_companion()  # (nothing to kill: the rest runs on)
        assert twin.dead() == ""
        assert twin.firmware_pid is not None


def test_a_firmware_that_exits_while_starting_stops_the_twin_with_its_status_and_output(
        tmp_path):
    twin = Twin(stand_in(tmp_path, "exit"), frame="ardupilot-omni")
    with pytest.raises(TwinError, match=r"the firmware exited \(3\)") as raised:
        start(twin, 10.0)
    assert "firmware: stand-in: no JSON physics" in str(raised.value)
    assert twin.bridge is not None and not twin.bridge.alive()


def test_a_firmware_never_heard_stops_the_twin_at_the_start_timeout(tmp_path):
    twin = Twin(stand_in(tmp_path, "silent"), frame="ardupilot-omni")
    with pytest.raises(TwinError, match=r"no HEARTBEAT from the firmware within 0\.5 s"):
        start(twin, 0.5)
    assert twin.firmware is not None and not twin.firmware.alive()


def test_a_physics_process_that_dies_while_starting_stops_the_twin(tmp_path):
    twin = Twin(stand_in(tmp_path, "silent"), frame="ardupilot-omni")

    def kill_the_bridge() -> None:
        if wait_until(lambda: twin.bridge is not None and twin.bridge.pid, 10.0):
            assert twin.bridge is not None and twin.bridge.pid is not None
            os.kill(twin.bridge.pid, signal.SIGKILL)

    killer = threading.Thread(target=kill_the_bridge)
    killer.start()
    try:
        with pytest.raises(TwinError, match=r"the bridge \(physics\) process exited") as raised:
            start(twin, 10.0)
        assert "\nbridge: exited; 0 frames" in str(raised.value)
    finally:
        killer.join()


def test_a_failed_setup_fc_stops_the_twin_with_its_status_and_output(tmp_path):
    twin = Twin(stand_in(tmp_path, "hog"))
    with pytest.raises(TwinError, match=r"setup-fc --apply --reboot failed \(2\)") as raised:
        start(twin, 20.0)
    assert "Address already in use" in str(raised.value)
    assert twin.companion is None


def test_a_setup_fc_that_does_not_end_is_given_up_at_the_start_timeout(tmp_path):
    twin = Twin(stand_in(tmp_path, "beat"))
    with pytest.raises(TwinError, match=r"setup-fc did not end within 1\.5 s") as raised:
        start(twin, 1.5)
    assert twin.companion is None
    # (what the bridge answered: here nothing, the stand-in sends no servo packets)
    assert "\nbridge: running; 0 frames (0 restarts, 0 malformed)" in str(raised.value)


def test_a_companion_that_dies_while_starting_stops_the_twin_with_its_log(tmp_path):
    twin = NoSetupTwin(stand_in(tmp_path, "beat"), gcs="nonsense:1")
    with pytest.raises(TwinError, match=r"the companion exited \(2\)") as raised:
        start(twin, 20.0)
    said = str(raised.value)
    assert "\ncompanion: " in said and "nonsense:1" in said.split("\ncompanion: ", 1)[1]


# ---------------------------------------------------------------------------- mecanum-mav twin


def test_twin_command_reports_a_firmware_that_dies_while_the_twin_runs_and_exits_1(
        tmp_path, capsys, monkeypatch):
    """``mecanum-mav twin``'s watch: the periodic figures, then the part that died with the
    parts' output, exit status 1. (setup-fc is skipped: a stand-in cannot be set up.)"""
    monkeypatch.setattr(Twin, "_setup_fc", NoSetupTwin._setup_fc)
    firmware = stand_in(tmp_path, "crash")
    out = io.StringIO()
    finished = threading.Event()  # (run_twin returned: no more watching)

    def crash_once_running() -> None:  # (run_twin keeps the main thread: its signals)
        if wait_until(lambda: "true pose N" in out.getvalue() or finished.is_set(), 60.0):
            Path(f"{firmware}.crash").touch()  # the firmware dies now, the twin running

    crasher = threading.Thread(target=crash_once_running)
    crasher.start()
    try:
        status = run_twin(Params(), firmware, friction=0.8, gcs="udpout:127.0.0.1:9",
                          report_period_s=0.2, out=out)
    finally:
        finished.set()
        crasher.join()
    err = capsys.readouterr().err
    assert status == 1, (out.getvalue(), err)
    assert "mecanum-mav twin: ready." in out.getvalue()
    assert "mecanum-mav twin: the firmware exited (5)" in err
    assert "stand-in: crashed" in err and "\nbridge: " in err


def test_twin_command_without_the_physics_extra_says_how_to_install_it_and_exits_2(
        tmp_path, capsys, monkeypatch):
    not_installed(monkeypatch, "mujoco", "mecanum_mav.sim.mujocochassis")
    status = run_twin(Params(), stand_in(tmp_path, "beat"), friction=0.8,
                      gcs="udpout:127.0.0.1:9")
    assert status == 2
    assert "pip install 'mecanum-mav[physics]'" in capsys.readouterr().err
