"""The companion as its own process, for tests and tools that meet it from outside.

:class:`CompanionProcess` runs ``python -m mecanum_mav run --gcs GCS --fc FC ...`` (and
:class:`CliProcess` any sub-command) in a process group of its own (so that killing it takes
everything it started), with its output in ``workdir/companion.log``, and reads what it
costs (CPU from the kernel's clock of the process, resident memory from ``/proc``).
The tests, ``tools/fuzz.py``, ``tools/soak.py`` and ``tools/bench_ab.py`` all start the
companion this one way.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import random
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from types import TracebackType
from typing import TypeVar

__all__ = ["CliProcess", "CompanionProcess", "dies_with_this_thread", "free_port",
           "process_cpu_s"]

def free_port(kind: int = socket.SOCK_DGRAM, host: str = "127.0.0.1") -> int:
    """A port free now, for programs that cannot bind port 0 themselves and say which one
    they got (SITL, MAVProxy, MAVSDK).

    Drawn at random from :data:`FREE_PORTS`, below Linux's ephemeral range (32768-60999), and
    checked by binding it: a port the OS handed out for port 0 could be handed out again to
    any socket that binds port 0 before the program meant to use it binds it (seen: a rover's
    simulated flight controller got the port a test had set aside for MAVProxy)."""
    for _ in range(200):
        port = _random.randrange(*FREE_PORTS)
        with socket.socket(socket.AF_INET, kind) as s:
            try:
                s.bind((host, port))
            except OSError:
                continue
            return port
    raise OSError(f"no free port in {FREE_PORTS}")


FREE_PORTS = (20000, 32768)
"""Where :func:`free_port` draws from: above the fixed MAVLink ports (5760, 14550, 14560 +
10 N), below the ephemeral range, so no port-0 bind can take it meanwhile."""
_random = random.SystemRandom()


_PR_SET_PDEATHSIG = 1
"""Linux's ``prctl`` option: the signal a process gets when its parent ends."""


def dies_with_this_thread(sig: int) -> Callable[[], None]:
    """A ``preexec_fn`` for :class:`subprocess.Popen`: the child gets ``sig`` when the thread
    that started it ends (Linux's parent-death signal; for the main thread, when the process
    ends, ``kill -9`` included), so a killed twin, tool or test run leaves no firmware or
    companion behind. It also holds across SITL's reboot (the firmware re-executes itself).
    Where ``prctl`` is missing it does nothing. Start such children from a thread that lives
    as long as they should."""
    parent = os.getpid()
    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):  # not Linux
        prctl = None

    def arm() -> None:
        if prctl is None:
            return
        prctl(_PR_SET_PDEATHSIG, sig)
        if os.getppid() != parent:  # it ended between the fork and the prctl
            os.kill(os.getpid(), sig)

    return arm


_PACKAGE_ROOT = Path(__file__).resolve().parents[2]
"""Where the package being run lives: the child imports the same code (a checkout too)."""


_CPUCLOCK_SCHED = 2
"""Linux: the CPU clock id of process ``pid`` is ``(~pid << 3) | CPUCLOCK_SCHED``."""


def process_cpu_s(pid: int) -> float:
    """User + system CPU time (s) process ``pid`` has used so far, all threads: the kernel's
    CPU clock of the process, to the nanosecond (``/proc/PID/stat`` counts 10 ms ticks).

    Raises:
        OSError: the process is gone.
    """
    return time.clock_gettime((~pid << 3) | _CPUCLOCK_SCHED)


def process_run_queue_s(pid: int) -> float:
    """Seconds process ``pid``'s main thread has waited, ready to run, for a CPU so far (the
    kernel's ``run_delay``, the second field of ``/proc/PID/schedstat``): how much a busy
    machine held it back; NaN where the kernel does not keep it, or once it is gone."""
    try:
        return int(Path(f"/proc/{pid}/schedstat").read_text().split()[1]) / 1e9
    except (OSError, IndexError, ValueError):
        return float("nan")


_Process = TypeVar("_Process", bound="CliProcess")


class CliProcess:
    """``python -m mecanum_mav *argv`` in its own process group, the package imported from
    ``package_root`` (default: the one this module belongs to; another checkout's tree to run
    another version), its output (stdout and stderr) in ``workdir/log_name``.

    A context manager: on the way out the group is killed if it is still running. It gets
    SIGTERM (the companion's orderly stop: neutral, then the channels released) when the
    thread that started it ends (:func:`dies_with_this_thread`): a killed parent leaves none
    running.
    """

    def __init__(self, argv: Sequence[str], workdir: Path, *,
                 package_root: Path = _PACKAGE_ROOT, log_name: str = "companion.log") -> None:
        self.command = [sys.executable, "-m", "mecanum_mav", *argv]
        workdir.mkdir(parents=True, exist_ok=True)
        self.log_path = workdir / log_name
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(package_root),
                                                          env.get("PYTHONPATH")]))
        with self.log_path.open("wb") as log:
            self.proc = subprocess.Popen(self.command, cwd=workdir, env=env,
                                         stdin=subprocess.DEVNULL, stdout=log,
                                         stderr=subprocess.STDOUT, start_new_session=True,
                                         preexec_fn=dies_with_this_thread(signal.SIGTERM))
        self.pid = self.proc.pid

    def alive(self) -> bool:
        return self.proc.poll() is None

    def log(self, tail: int = 3000) -> str:
        """The last ``tail`` characters of its output ("" if there is none)."""
        try:
            return self.log_path.read_text(errors="replace")[-tail:]
        except OSError:
            return ""

    def cpu_s(self) -> float:
        """CPU seconds it has used so far (:func:`process_cpu_s`); NaN once it is gone."""
        try:
            return process_cpu_s(self.pid)
        except OSError:
            return float("nan")

    def run_queue_s(self) -> float:
        """:func:`process_run_queue_s` of it."""
        return process_run_queue_s(self.pid)

    def rss_kb(self) -> int:
        """Its resident set size (kB, ``VmRSS`` of ``/proc/PID/status``).

        Raises:
            OSError: the process is gone.
        """
        for line in Path(f"/proc/{self.pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
        raise OSError(f"no VmRSS for process {self.pid}")

    def terminate(self) -> float:
        """SIGTERM; returns when it was sent (monotonic s)."""
        sent = time.monotonic()
        self.proc.send_signal(signal.SIGTERM)
        return sent

    def wait(self, timeout_s: float) -> int | None:
        """The exit code, or None if still running after ``timeout_s``."""
        try:
            return self.proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            return None

    def stop(self, timeout_s: float = 5.0) -> int | None:
        """SIGTERM, and SIGKILL to the group if it has not ended within ``timeout_s``; its
        exit code (None: it had to be killed)."""
        if not self.alive():
            return self.proc.returncode
        self.terminate()
        code = self.wait(timeout_s)
        if code is None:
            self.kill()
        return code

    def kill(self) -> None:
        """SIGKILL the process group (if the companion still runs) and reap it."""
        if self.proc.poll() is None:  # still ours: the group id cannot have been reused
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(self.proc.pid, signal.SIGKILL)
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.proc.wait(timeout=10)

    def __enter__(self: _Process) -> _Process:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.kill()


class CompanionProcess(CliProcess):
    """``python -m mecanum_mav run --gcs GCS --fc FC *extra`` (see :class:`CliProcess`)."""

    def __init__(self, gcs_url: str, fc_url: str, workdir: Path, *extra: str,
                 package_root: Path = _PACKAGE_ROOT) -> None:
        super().__init__(["run", "--gcs", gcs_url, "--fc", fc_url, *extra], workdir,
                         package_root=package_root)

    @staticmethod
    def sim(gcs_url: str, workdir: Path, *extra: str,
            package_root: Path = _PACKAGE_ROOT) -> CliProcess:
        """``python -m mecanum_mav sim --gcs GCS *extra``: the rover with the built-in
        simulated flight controller, as a user starts it first."""
        return CliProcess(["sim", "--gcs", gcs_url, *extra], workdir, package_root=package_root)
