"""What ``run`` and ``sim`` tell the person who started them (:mod:`mecanum_mav.app.progress`):
waiting for the flight controller, found, and on a terminal a status line every 5 s
(``--quiet``: none); ``--log-level`` on every sub-command."""

from __future__ import annotations

import contextlib
import io
import logging
import math
import os
import pty
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from conftest import lockstep
from sitl import CompanionProcess
from support import FakeFlightController, wait_until

from mecanum_mav.app.cli import build_parser, main
from mecanum_mav.app.progress import (
    FC_HINT_S,
    STATUS_PERIOD_S,
    Progress,
    fc_check_state,
    status_line,
)
from mecanum_mav.config.params import Params
from mecanum_mav.control.core import RoverCore
from mecanum_mav.control.fccheck import FcCheckState, FcSetupCheck
from mecanum_mav.protocol.fcsetup import Finding

STATUS_MARK = " m/s"
"""How a status line ends."""


# ------------------------------------------------------------------ the status line


def test_the_setup_check_reads_checking_safe_unsafe_unconfirmed_or_not_checked() -> None:
    check = FcSetupCheck()
    assert fc_check_state(check) == "not checked"  # no board yet
    check.start(Params(), 0.0)
    assert fc_check_state(check) == "checking"
    check.state = FcCheckState.SAFE
    assert fc_check_state(check) == "safe"
    check.state = FcCheckState.UNSAFE
    check.hazards = [Finding("RC_OVERRIDE_TIME", 0.0, "> 0", "why", True),
                     Finding("SYSID_MYGCS", 1.0, "255", "why", True)]
    assert fc_check_state(check) == "UNSAFE: RC_OVERRIDE_TIME, SYSID_MYGCS"
    check.state, check.missing = FcCheckState.UNCONFIRMED, ["RC4_DZ"]
    assert fc_check_state(check) == "NOT CONFIRMED: RC4_DZ"
    check.state = FcCheckState.NOT_CHECKED
    assert fc_check_state(check) == "not checked"


def test_the_status_line_shows_mode_arming_links_check_position_and_speed() -> None:
    h = lockstep()
    assert status_line(h.core, h.now_s) == (
        "MANUAL disarmed | fc up gcs up | FC setup safe | N 0.00 E 0.00 m | 0.00 m/s")
    h.gcs.arm()
    h.every(0.05, lambda now: h.gcs.sticks(1000))
    h.run_for(4.0)
    line = status_line(h.core, h.now_s)
    pose, speed = h.core.estimator.pose, math.hypot(*h.core.estimator.velocity_body)
    assert line == (f"MANUAL armed | fc up gcs up | FC setup safe | "
                    f"N {pose.x_m:.2f} E {pose.y_m:.2f} m | {speed:.2f} m/s")
    assert pose.x_m > 1.0 and speed > 0.5  # it drove north


def test_progress_says_found_and_lost_once_and_the_status_line_only_when_periodic() -> None:
    h = lockstep()
    for periodic in (True, False):
        out = io.StringIO()
        progress = Progress(h.core, "udpout:FC", out, periodic=periodic)
        progress.started()
        t = h.now_s
        for _ in range(12):  # 12 s, a look each second
            t = progress.tick(t)
        lines = out.getvalue().splitlines()
        assert lines[:2] == [
            "mecanum-mav: waiting for the flight controller's HEARTBEAT (system 1) on udpout:FC",
            "mecanum-mav: flight controller found (system 1) on udpout:FC"]
        status = [line for line in lines if line.endswith(STATUS_MARK)]
        assert len(status) == (2 if periodic else 0)  # at 5 and 10 s
    h.core.vehicle.fc_lost = True
    progress.tick(t)
    assert out.getvalue().splitlines()[-1] == (
        "mecanum-mav: flight controller lost on udpout:FC: waiting for its HEARTBEAT")


def test_a_flight_controller_not_found_in_10_s_gets_one_hint_of_what_to_check() -> None:
    core = RoverCore(Params(), now_s=0.0)  # no board: its link never comes up
    out = io.StringIO()
    progress = Progress(core, "/dev/ttyACM0,115200", out, periodic=False)
    t = 0.0
    while t < FC_HINT_S - 0.5:
        t = progress.tick(t)
    assert "no HEARTBEAT" not in out.getvalue()
    for _ in range(20):
        t = progress.tick(t)
    assert out.getvalue().splitlines() == [
        "mecanum-mav: no HEARTBEAT from the flight controller (system 1) on "
        "/dev/ttyACM0,115200 after 10 s: is it powered and connected (device, baud rate, "
        "port), and is its system id FC_SYSID (1)?"]


# ------------------------------------------------------------------ real processes


def ran_past(fc: FakeFlightController, seconds: float) -> bool:
    """Whether the companion has driven ``fc`` for more than ``seconds``, by the board's
    clock (its overrides come at 20 Hz from the start)."""
    got = fc.received()
    return bool(got) and got[-1].time_s - got[0].time_s > seconds


@pytest.mark.slow
def test_run_says_it_waits_for_the_flight_controller_and_when_it_is_found(
        tmp_path: Path) -> None:
    """Not a terminal: no status line; --log-level WARNING hides the INFO log."""
    with FakeFlightController() as fc:
        fc_port = fc.url.rsplit(":", 1)[1]
        silent = f"udpout:127.0.0.1:{fc_port}"
        fc.sock.close()  # nobody answers at first
        with CompanionProcess("udpout:127.0.0.1:9", silent, tmp_path,
                              "--log-level", "WARNING") as companion:
            waiting = (f"mecanum-mav: waiting for the flight controller's HEARTBEAT (system 1) "
                       f"on {silent}")
            assert wait_until(lambda: waiting in companion.log(), 20.0), companion.log()
            assert "found" not in companion.log()
    with FakeFlightController() as fc, CompanionProcess(
            "udpout:127.0.0.1:9", fc.url, tmp_path / "2", "--log-level", "WARNING") as companion:
        found = f"mecanum-mav: flight controller found (system 1) on {fc.url}"
        assert wait_until(lambda: found in companion.log(), 20.0), companion.log()
        assert wait_until(lambda: ran_past(fc, STATUS_PERIOD_S + 0.5), 20.0)
        assert companion.stop(10.0) == 0
        log = companion.log()
        assert log.index("waiting for the flight controller") < log.index(found)
        assert "Flight controller link up" not in log  # an INFO line
        assert STATUS_MARK not in log


class PtyReader:
    """A process's stdout and stderr on a pseudo-terminal (it sees isatty), read into
    :attr:`text` by a thread."""

    def __init__(self, argv: list[str], cwd: Path) -> None:
        master, slave = pty.openpty()
        self.proc = subprocess.Popen([sys.executable, "-m", "mecanum_mav", *argv], cwd=cwd,
                                     stdin=subprocess.DEVNULL, stdout=slave,
                                     stderr=subprocess.STDOUT, start_new_session=True)
        os.close(slave)
        self.text = ""
        self._master = master
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while True:
            try:
                data = os.read(self._master, 4096)
            except OSError:  # the process ended (EIO)
                return
            if not data:
                return
            self.text += data.decode(errors="replace")

    def close(self) -> int:
        self.proc.terminate()
        try:
            code = self.proc.wait(10.0)
        finally:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, 9)
            self.proc.wait()
            self._thread.join(5.0)
            os.close(self._master)
        return code


@pytest.mark.slow
@pytest.mark.parametrize("quiet", [False, True])
def test_on_a_terminal_run_prints_a_status_line_every_5_s_unless_quiet(
        quiet: bool, tmp_path: Path) -> None:
    with FakeFlightController() as fc:
        reader = PtyReader(["run", "--gcs", "udpout:127.0.0.1:9", "--fc", fc.url,
                            *(["--quiet"] if quiet else [])], tmp_path)
        try:
            assert wait_until(lambda: "flight controller found" in reader.text, 20.0), \
                reader.text
            assert wait_until(lambda: ran_past(fc, 2 * STATUS_PERIOD_S + 0.5), 20.0)
        finally:
            code = reader.close()
        status = [line for line in reader.text.splitlines() if line.endswith(STATUS_MARK)]
        assert code == 0, reader.text
        if quiet:
            assert status == [], reader.text
        else:
            assert len(status) >= 2, reader.text
            assert status[-1].startswith("mecanum-mav: MANUAL disarmed | fc up gcs not heard")


# ------------------------------------------------------------------ --log-level


SUBCOMMANDS = {"sim": [], "demo": [], "run": ["--fc", "sim"], "setup-fc": ["--fc", "sim"],
               "simfc": [], "log": ["x.tlog"], "mix": [], "plot": [], "params": []}


@pytest.mark.parametrize("command", sorted(SUBCOMMANDS))
def test_every_subcommand_takes_log_level(command: str) -> None:
    args = build_parser().parse_args([command, *SUBCOMMANDS[command], "--log-level", "debug"])
    assert args.log_level == "DEBUG"


def test_log_level_sets_the_root_logger_and_defaults_to_warning_outside_run_and_sim(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    root = logging.getLogger()
    monkeypatch.setattr(root, "level", root.level)  # restored after the test
    assert main(["mix", "-x", "1", "--log-level", "ERROR"]) == 0
    assert root.level == logging.ERROR
    assert main(["mix", "-x", "1"]) == 0
    assert root.level == logging.WARNING
