"""Ctrl-C and SIGTERM on real processes: the companion always ends at neutral, then releases
the channels, however many signals come and however fast; no sub-command prints a traceback
when interrupted."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from sitl import CompanionProcess
from support import FakeFlightController, Override, wait_until

from mecanum_mav.sim.groundstation import udp_ground_station

NEUTRAL = (1500, 1500, 1500, 1500)
RELEASE = (0, 0, 0, 0)
FORWARD_STICK = 500


def driving(override: Override) -> bool:
    return override.wheels not in (NEUTRAL, RELEASE)


@pytest.mark.parametrize("link", ["udp", "tcp"])
def test_two_ctrl_c_10_ms_apart_still_send_neutral_then_the_release(link: str,
                                                                    tmp_path: Path) -> None:
    gcs, port = udp_ground_station()
    try:
        with FakeFlightController(link) as fc, CompanionProcess(port.url, fc.url,
                                                            tmp_path) as companion:
            assert gcs.wait("HEARTBEAT", timeout_s=15.0), companion.log()
            gcs.arm(timeout_s=10.0)

            def moving() -> bool:
                gcs.sticks(FORWARD_STICK)
                gcs.pump(0.02)
                return any(driving(o) for o in fc.received())

            assert wait_until(moving, 10.0), companion.log()
            for _ in range(3):
                gcs.sticks(FORWARD_STICK)
            companion.proc.send_signal(signal.SIGINT)
            time.sleep(0.01)  # the second Ctrl-C, 10 ms after the first
            companion.proc.send_signal(signal.SIGINT)
            code = companion.wait(10.0)
            log = companion.log()
            assert wait_until(lambda: fc.received()[-1].wheels == RELEASE, 2.0), log
            after = fc.received()
            last_drive = max(i for i, o in enumerate(after) if driving(o))
            tail = [o.wheels for o in after[last_drive + 1:]]
            assert NEUTRAL in tail and tail[-1] == RELEASE, (tail, log)
            assert tail.index(NEUTRAL) < len(tail) - 1
            assert "Traceback" not in log, log
            assert code == 0, log
    finally:
        port.close()


def blocked_opening_a_fifo(pid: int) -> bool:
    """Whether process ``pid`` waits in the kernel for a FIFO's other end."""
    try:
        return Path(f"/proc/{pid}/wchan").read_text() in ("wait_for_partner", "fifo_open")
    except OSError:
        return False


def test_ctrl_c_while_run_starts_up_exits_130_with_one_line_and_no_traceback(
        tmp_path: Path) -> None:
    """Start-up stuck opening --tlog (a FIFO nobody reads) until Ctrl-C."""
    fifo = tmp_path / "drive.tlog"
    os.mkfifo(fifo)
    with FakeFlightController() as fc, CompanionProcess("udpout:127.0.0.1:9", fc.url, tmp_path,
                                                        "--tlog", str(fifo)) as companion:
        assert wait_until(lambda: blocked_opening_a_fifo(companion.pid), 20.0), companion.log()
        companion.proc.send_signal(signal.SIGINT)
        code = companion.wait(10.0)
        log = companion.log()
        assert "Traceback" not in log, log
        assert log.strip().splitlines()[-1] == "mecanum-mav: interrupted", log
        assert code == 130, log
        assert fc.received() == []  # nothing was sent: the loop never ran


def test_ctrl_c_while_setup_fc_waits_for_the_board_exits_130_without_a_traceback(
        tmp_path: Path) -> None:
    board = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # silent: never answers
    board.bind(("127.0.0.1", 0))
    board.settimeout(20.0)
    try:
        proc = subprocess.Popen(
            [sys.executable, "-m", "mecanum_mav", "setup-fc", "--fc",
             f"udpout:127.0.0.1:{board.getsockname()[1]}"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
        try:
            board.recvfrom(4096)  # its heartbeat: it is waiting for the board's
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=10.0)
        finally:
            proc.kill()
            proc.wait()
        assert "Traceback" not in err, err
        assert err.strip().splitlines() == ["mecanum-mav: interrupted"], err
        assert proc.returncode == 130
    finally:
        board.close()
