"""The companion as a process from outside (mecanum_mav/sim/process.py): ``stop()`` kills the
group of one that ignores SIGTERM, a process that has ended reports its exit code, no resident
memory and no CPU clock, ``free_port`` never hands out a taken port, and a child armed with
``dies_with_this_thread`` ends with its parent, whether it armed before the parent ended or
after.

``CliProcess`` runs ``python -m mecanum_mav`` from the package root it is given: here a
stand-in package of the test's own (a few lines, started in a fraction of the companion's
time), which exits or ignores SIGTERM as told."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from support import wait_until

from mecanum_mav.sim import process
from mecanum_mav.sim.process import CliProcess, free_port

STAND_IN = """\
import os, signal, sys, time
if sys.argv[1] == "exit":
    print("exiting", flush=True)
    sys.exit(int(sys.argv[2]))
if sys.argv[1] == "work":  # hold MB megabytes, spin a CPU for S seconds, then wait
    held = bytearray(int(sys.argv[2]) << 20)
    held[::4096] = b"x" * len(held[::4096])  # (touched: resident)
    end = time.process_time() + float(sys.argv[3])
    while time.process_time() < end:
        pass
    print("worked", flush=True)
    time.sleep(30)
signal.signal(signal.SIGTERM, signal.SIG_IGN)
print("ignoring SIGTERM", flush=True)
time.sleep(10)
"""


@pytest.fixture
def stand_in(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A package root whose ``mecanum_mav`` is the stand-in (not measured by coverage: it is
    not the package)."""
    package = tmp_path / "root" / "mecanum_mav"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "__main__.py").write_text(STAND_IN)
    for name in ("COVERAGE_PROCESS_START", "COVERAGE_PROCESS_CONFIG"):
        monkeypatch.delenv(name, raising=False)
    return package.parent


def state(pid: int) -> str:
    """The process's state letter in ``/proc`` ("" once it is reaped)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return ""


def test_stop_kills_the_group_of_a_process_that_ignores_sigterm_after_the_timeout(
        tmp_path: Path, stand_in: Path):
    with CliProcess(["ignore"], tmp_path / "work", package_root=stand_in) as proc:
        assert wait_until(lambda: "ignoring SIGTERM" in proc.log(), 10.0), proc.log()
        assert proc.wait(0.05) is None  # still running
        assert proc.stop(timeout_s=0.2) is None  # it had to be killed
        assert not proc.alive()
        assert proc.proc.returncode == -signal.SIGKILL


def test_a_process_that_has_ended_reports_its_exit_code_no_memory_and_no_cpu_clock(
        tmp_path: Path, stand_in: Path):
    with CliProcess(["exit", "3"], tmp_path / "work", package_root=stand_in) as proc:
        assert wait_until(lambda: state(proc.pid) in ("Z", ""), 10.0)  # ended, not reaped
        with pytest.raises(OSError, match=f"no VmRSS for process {proc.pid}"):
            proc.rss_kb()  # (a zombie has no resident set)
        assert proc.wait(5.0) == 3
        assert proc.cpu_s() != proc.cpu_s()  # NaN: the process is gone
        assert proc.run_queue_s() != proc.run_queue_s()  # NaN too
        assert proc.stop() == 3  # nothing to stop: its exit code
        assert "exiting" in proc.log()
        proc.log_path.unlink()
        assert proc.log() == ""


def ticks_s(pid: int) -> float:
    """User + system CPU time of ``pid`` from ``/proc/PID/stat`` (clock ticks), s."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def test_a_running_process_reports_its_own_cpu_time_and_resident_memory(
        tmp_path: Path, stand_in: Path):
    with CliProcess(["work", "64", "0.3"], tmp_path / "work", package_root=stand_in) as proc:
        assert wait_until(lambda: "worked" in proc.log(), 20.0), proc.log()
        cpu_s, ticks = proc.cpu_s(), ticks_s(proc.pid)
        assert 0.3 <= cpu_s < 5.0
        assert abs(cpu_s - ticks) <= 0.05  # the same time, finer than /proc's ticks
        assert abs(process.process_cpu_s(os.getpid()) - time.process_time()) < 0.05
        assert 64 * 1024 <= proc.rss_kb() < 1024 * 1024  # kB: the 64 MB it holds, and more
        assert 0.0 <= proc.run_queue_s() < 5.0  # (a number: not NaN)


def test_two_processes_sharing_one_cpu_each_report_waiting_for_it(tmp_path: Path):
    """The run queue wait (the kernel's run_delay) of a process that shares one core with
    another busy one for most of a second: a good part of that time, never more than all of
    it."""
    spin = "import time\nend = time.monotonic() + 1.0\nwhile time.monotonic() < end: pass"
    started = time.monotonic()
    spinners = [subprocess.Popen([sys.executable, "-c", spin],
                                 preexec_fn=lambda: os.sched_setaffinity(0, {0}))
                for _ in range(2)]
    try:
        assert wait_until(lambda: time.monotonic() - started > 0.8, 5.0)  # (both spinning)
        waited = [process.process_run_queue_s(p.pid) for p in spinners]
        elapsed = time.monotonic() - started
    finally:
        for p in spinners:
            p.wait(10)
    assert all(0.1 <= w <= elapsed for w in waited), (waited, elapsed)


def test_a_running_process_reports_the_time_it_waited_for_a_cpu_and_it_never_goes_back():
    first = process.process_run_queue_s(os.getpid())
    sum(range(200_000))  # (some work, so the scheduler has looked at it again)
    assert 0.0 <= first <= process.process_run_queue_s(os.getpid())


def test_free_port_never_hands_out_a_port_that_is_taken(monkeypatch: pytest.MonkeyPatch):
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        monkeypatch.setattr(process, "FREE_PORTS", (port, port + 1))  # only that one to draw
        with pytest.raises(OSError, match="no free port"):
            free_port(socket.SOCK_DGRAM)


PARENT = """\
import os, signal, sys, time
from mecanum_mav.sim.process import dies_with_this_thread

arm = dies_with_this_thread(signal.SIGTERM)
parent = os.getpid()
ready_r, ready_w = os.pipe()
child = os.fork()
if child == 0:
    quiet = os.open(os.devnull, os.O_WRONLY)  # (the parent's output ends with the parent)
    os.dup2(quiet, 1)
    os.dup2(quiet, 2)
    if sys.argv[1] == "after":
        while os.getppid() == parent:  # (the parent ends right after the fork)
            time.sleep(0.005)
    arm()
    os.write(ready_w, b"x")
    time.sleep(30)
    sys.exit(0)
print(child, flush=True)
if sys.argv[1] == "before":
    os.read(ready_r, 1)  # armed while the parent lives
"""


@pytest.mark.parametrize("armed", ["before", "after"])
def test_a_child_armed_by_dies_with_this_thread_ends_when_its_parent_has_ended(
        tmp_path: Path, armed: str):
    parent = subprocess.run([sys.executable, "-c", PARENT, armed],
                            cwd=tmp_path, capture_output=True, text=True, timeout=30)
    assert parent.returncode == 0, parent.stderr
    child = int(parent.stdout)
    try:
        assert wait_until(lambda: state(child) in ("Z", "X", ""), 10.0), (
            "the child outlived its parent")
    finally:
        if state(child) not in ("Z", "X", ""):
            os.kill(child, signal.SIGKILL)


def test_where_prctl_is_missing_arming_does_nothing(monkeypatch: pytest.MonkeyPatch):
    def no_prctl(*args: object, **kwargs: object) -> object:
        raise AttributeError("prctl")  # (what ctypes says on a system without it)

    monkeypatch.setattr(process.ctypes, "CDLL", no_prctl)
    arm = process.dies_with_this_thread(signal.SIGUSR1)
    got: list[int] = []
    previous = signal.signal(signal.SIGUSR1, lambda signum, frame: got.append(signum))
    try:
        arm()  # called here, not in a child: it would signal this process if it went on
    finally:
        signal.signal(signal.SIGUSR1, previous)
    assert got == []
