"""A killed parent leaves no child running: the companion and the firmware the twin, the
tools and the tests start get a signal when the thread that started them ends (Linux's
parent-death signal), so ``kill -9`` of ``mecanum-mav twin`` leaves no ``ardurover`` or
companion behind."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from sitl import find_sitl
from support import wait_until

BINARY, WHY_NOT = find_sitl()


def _gone(pid: int) -> bool:
    """Whether ``pid`` has ended (a zombie waiting for init counts as ended)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return True
    return state in ("Z", "X")


def _start_parent(code: str, tmp_path: Path) -> tuple[subprocess.Popen[str], int]:
    """A Python parent running ``code`` (which prints its child's pid and then sleeps)."""
    parent = subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], cwd=tmp_path,
                              stdout=subprocess.PIPE, text=True)
    assert parent.stdout is not None
    line = parent.stdout.readline()
    assert line.strip().isdigit(), line
    return parent, int(line)


def _kill_9_and_expect_the_child_gone(parent: subprocess.Popen[str], child: int) -> None:
    try:
        assert not _gone(child)
        parent.send_signal(signal.SIGKILL)
        parent.wait(5)
        assert wait_until(lambda: _gone(child), 10.0), f"child {child} outlived its parent"
    finally:
        if not _gone(child):
            os.kill(child, signal.SIGKILL)


def test_a_companion_process_ends_when_its_parent_is_killed(tmp_path: Path):
    parent, child = _start_parent(f"""
        import sys, time
        from pathlib import Path
        from mecanum_mav.sim.process import CompanionProcess
        p = CompanionProcess("udpout:127.0.0.1:9", "udpout:127.0.0.1:9", Path({str(tmp_path)!r}))
        print(p.pid, flush=True)
        time.sleep(60)
        """, tmp_path)
    _kill_9_and_expect_the_child_gone(parent, child)


@pytest.mark.sitl
@pytest.mark.skipif(BINARY is None, reason=WHY_NOT)
def test_the_firmware_ends_when_its_parent_is_killed(tmp_path: Path):
    sitl = BINARY
    parent, child = _start_parent(f"""
        import time
        from pathlib import Path
        from mecanum_mav.sim.firmware import Firmware
        f = Firmware(Path({str(sitl)!r}), 9003)
        f.start()
        print(f.proc.pid, flush=True)
        time.sleep(60)
        """, tmp_path)
    _kill_9_and_expect_the_child_gone(parent, child)
