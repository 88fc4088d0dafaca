"""Real ArduPilot Rover firmware (SITL) as the flight controller of integration tests.

:class:`Sitl` starts ``ardurover`` (../shared/ardupilot-sitl/ardurover from the repository
root, or ``$MECANUM_SITL``) in its own temporary directory and process group, with the
pass-through parameters of ``sitl_passthrough.parm`` (RC channels 1-4 straight to SERVO1-4),
its flight-controller port on UDP, TCP or a serial pty, a simulated RC receiver fed with a
distinctive pulse, and a :class:`Monitor` on its second serial port that timestamps every
SERVO_OUTPUT_RAW. :class:`CompanionProcess` runs ``python -m mecanum_mav run`` against it.
Both kill their whole process group on every way out. Ports come from the OS (bind port 0).
See ../shared/ardupilot-sitl/README.md for what the firmware does and needs.
"""

from __future__ import annotations

import contextlib
import os
import select
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from pymavlink import mavutil
from support import RawPty, at_most_every, wait_until

from mecanum_mav.sim.firmware import Started, kill_group
from mecanum_mav.sim.groundstation import udp_ground_station
from mecanum_mav.sim.process import CompanionProcess, free_port  # (tests import them here)

if TYPE_CHECKING:
    from mecanum_mav.sim.groundstation import ScriptedGroundStation

__all__ = ["CompanionProcess", "Monitor", "PtyCable", "Rig", "Sample", "Sitl", "find_sitl",
           "free_port"]

R = TypeVar("R", bound="Rig")
T = TypeVar("T")

REPO_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_BINARY = REPO_ROOT.parent / "shared" / "ardupilot-sitl" / "ardurover"
PASSTHROUGH_PARM = Path(__file__).with_name("sitl_passthrough.parm")
TRANSPORTS = ("udp", "tcp", "serial")

SERVO_OUTPUT_RAW = 36
SET_MESSAGE_INTERVAL = 511  # MAV_CMD_SET_MESSAGE_INTERVAL
SERVO_INTERVAL_US = 25_000
"""The fastest SERVO_OUTPUT_RAW this firmware grants (20 ms is DENIED, 25 ms accepted)."""
RECEIVER_PERIOD_S = 0.05
MONITOR_SYSID = 254  # not the ground station's 255: the monitor only reads


def find_sitl() -> tuple[Path | None, str]:
    """The ``ardurover`` binary to use, or None and why not (a pytest skip reason)."""
    env = os.environ.get("MECANUM_SITL")
    if env:
        path = Path(env)
        if path.is_file() and os.access(path, os.X_OK):
            return path, ""
        return None, f"$MECANUM_SITL={env!r} is not an executable file"
    if DEFAULT_BINARY.is_file() and os.access(DEFAULT_BINARY, os.X_OK):
        return DEFAULT_BINARY, ""
    return None, ("ArduPilot SITL not found: neither ../shared/ardupilot-sitl/ardurover "
                  "(from the repository root) nor $MECANUM_SITL")


# --------------------------------------------------------------------------- the monitor


@dataclass(frozen=True)
class Sample:
    """One SERVO_OUTPUT_RAW: when it arrived (monotonic s) and SERVO1..4 (us)."""

    t: float
    servos: tuple[int, int, int, int]


class Monitor:
    """A pymavlink connection on SITL's second serial port (``udpin:127.0.0.1:PORT``).

    A thread reads it and timestamps every SERVO_OUTPUT_RAW on arrival, so that times are
    right even while the test is busy elsewhere (waiting for a COMMAND_ACK, for instance).
    """

    def __init__(self, port: int, first_servo: int = 1) -> None:
        self.first_servo = first_servo
        """:attr:`Sample.servos` are SERVO{first_servo}.. the next three (1: SERVO1..4)."""
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}",
                                               source_system=MONITOR_SYSID, source_component=191)
        self.samples: list[Sample] = []
        self.heartbeats = 0
        self.signed_heartbeats = 0
        """The firmware's HEARTBEATs that came signed (it has a signing key)."""
        self._acks: list[Any] = []
        self._cond = threading.Condition()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sitl-monitor", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        fd = self.conn.port.fileno()
        while not self._stop.is_set():
            try:
                ready = select.select([fd], [], [], 0.1)[0]
            except (OSError, ValueError):
                return
            if not ready:
                continue
            now = time.monotonic()
            got = []
            while (msg := self.conn.recv_msg()) is not None:
                got.append(msg)
            with self._cond:
                for msg in got:
                    kind = msg.get_type()
                    if kind == "SERVO_OUTPUT_RAW":
                        a, b, c, d = (getattr(msg, f"servo{self.first_servo + i}_raw")
                                      for i in range(4))
                        self.samples.append(Sample(now, (a, b, c, d)))
                    elif kind == "HEARTBEAT" and msg.get_srcSystem() == 1:
                        self.heartbeats += 1
                        self.signed_heartbeats += msg.get_msgbuf()[2] & 1  # signed flag
                    elif kind == "COMMAND_ACK":
                        self._acks.append(msg)
                self._cond.notify_all()

    def _wait_for(self, ready: Callable[[], T], timeout_s: float,
                  tick: Callable[[], object] | None = None, period_s: float = 0.05) -> T | None:
        """``ready()`` (called under the lock) once it is truthy, or None at the deadline;
        ``tick()`` runs every ``period_s`` meanwhile (outside the lock)."""
        due = at_most_every(period_s, tick or (lambda: None))

        def ready_now() -> T:
            due()
            with self._cond:
                return ready()

        def sleep(wait_s: float) -> None:  # until a message arrives (notify_all) at the most
            with self._cond:
                self._cond.wait(wait_s)

        return wait_until(ready_now, timeout_s, pump=sleep, pump_s=min(period_s, 0.05))

    def wait_heartbeat(self, timeout_s: float) -> bool:
        """Whether the firmware's HEARTBEAT came within ``timeout_s``."""
        return bool(self._wait_for(lambda: self.heartbeats > 0, timeout_s))

    def setup_signing(self, key: bytes, initial_timestamp: int, timeout_s: float) -> None:
        """SETUP_SIGNING with ``key`` (32 bytes) and ``initial_timestamp`` (10 us ticks since
        2015), sent unsigned (only SERIAL0 takes unsigned packets once a key is set), and
        resent until the firmware's HEARTBEATs come signed. ArduPilot does not acknowledge it.

        Raises:
            TimeoutError: not within ``timeout_s``.
        """
        with self._cond:
            signed_before = self.signed_heartbeats

        def send() -> None:
            self.conn.mav.setup_signing_send(1, 1, list(key), initial_timestamp)

        if not self._wait_for(lambda: self.signed_heartbeats > signed_before, timeout_s,
                              tick=send, period_s=1.0):
            raise TimeoutError("the firmware's HEARTBEATs never came signed after SETUP_SIGNING")

    def request_servo_output(self, timeout_s: float, interval_us: int = SERVO_INTERVAL_US) -> None:
        """MAV_CMD_SET_MESSAGE_INTERVAL for SERVO_OUTPUT_RAW, retried until accepted and the
        first sample is in.

        Raises:
            TimeoutError: not within ``timeout_s``.
        """
        accepted = False

        def ask() -> None:
            if not accepted:
                self.conn.mav.command_long_send(1, 1, SET_MESSAGE_INTERVAL, 0, SERVO_OUTPUT_RAW,
                                                interval_us, 0, 0, 0, 0, 0)

        def done() -> bool:
            nonlocal accepted
            accepted = accepted or any(a.command == SET_MESSAGE_INTERVAL and a.result == 0
                                       for a in self._acks)
            return accepted and len(self.samples) > 0

        if not self._wait_for(done, timeout_s, tick=ask, period_s=0.3):
            raise TimeoutError(f"SERVO_OUTPUT_RAW never streamed (accepted={accepted}, "
                               f"acks={[a.result for a in self._acks]})")

    def mark(self) -> int:
        """An index into :attr:`samples`: wait only for what arrives after this point."""
        with self._cond:
            return len(self.samples)

    def wait_servos(self, predicate: Callable[[tuple[int, int, int, int]], bool],
                    timeout_s: float, *, since: int | None = None,
                    tick: Callable[[], object] | None = None,
                    period_s: float = 0.05) -> Sample | None:
        """The first sample from index ``since`` (default: from now on) whose SERVO1..4
        satisfy ``predicate``, or None after ``timeout_s``; ``tick()`` runs every
        ``period_s`` while waiting (stream the sticks there)."""
        index = self.mark() if since is None else since

        def ready() -> Sample | None:
            nonlocal index
            while index < len(self.samples):
                sample = self.samples[index]
                index += 1
                if predicate(sample.servos):
                    return sample
            return None

        return self._wait_for(ready, timeout_s, tick, period_s)

    def last(self, n: int = 5) -> list[tuple[int, int, int, int]]:
        """SERVO1..4 of the last ``n`` samples (for assertion messages)."""
        with self._cond:
            return [s.servos for s in self.samples[-n:]]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        self.conn.close()


# --------------------------------------------------------------------------- a serial cable


class PtyCable:
    """Two pseudo-terminals joined by a relay thread: a null-modem cable with a device path
    at each end (:attr:`fc_path` for SITL, :attr:`companion_path` for pyserial).

    The slave ends stay open here too, so that a peer closing its end never makes the
    master read fail; what cannot be delivered (nobody reading) is dropped, like a wire.
    """

    def __init__(self) -> None:
        self._ptys: list[RawPty] = []
        self._fds: list[int] = []
        try:
            self._ptys += [RawPty(), RawPty()]
            self._a, self._b = (end.master for end in self._ptys)
            self.fc_path, self.companion_path = (end.path for end in self._ptys)
            self._stop_r, self._stop_w = os.pipe()
            self._fds += [self._stop_r, self._stop_w]
        except BaseException:
            self.close()
            raise
        self._thread = threading.Thread(target=self._run, name="pty-cable", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        peer = {self._a: self._b, self._b: self._a}
        while True:
            try:
                ready = select.select([self._a, self._b, self._stop_r], [], [])[0]
            except (OSError, ValueError):
                return
            if self._stop_r in ready:
                return
            for src in ready:
                try:
                    data = os.read(src, 65536)
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError:
                    return
                self._write(peer[src], data)

    def _write(self, fd: int, data: bytes) -> None:
        """Write ``data`` to ``fd`` as it takes it, for 0.1 s at the most."""

        def written() -> bool:
            nonlocal data
            try:
                data = data[os.write(fd, data):]
            except (BlockingIOError, InterruptedError):
                return False
            except OSError:
                return True  # the end is gone: drop it, like a wire
            return not data

        wait_until(written, 0.1, pump=lambda wait_s: select.select([], [fd], [], wait_s),
                   pump_s=0.01)

    def close(self) -> None:
        if hasattr(self, "_thread"):
            os.write(self._stop_w, b"x")
            self._thread.join(timeout=2)
        for end in self._ptys:
            end.close()
        for fd in self._fds:
            with contextlib.suppress(OSError):
                os.close(fd)
        self._fds = []


# --------------------------------------------------------------------------- the firmware


class Sitl(Started):
    """``ardurover`` with pass-through parameters, a monitor and an RC receiver.

    Use as a context manager; the process group is killed on every way out (also when the
    start fails). ``transport`` is the flight-controller port (SERIAL0, or SERIAL1 with
    ``fc_serial=1``; the monitor is on the other one): ``udp`` (``udpclient:``, the companion
    uses ``udpin:``), ``tcp`` (SITL listens) or ``serial`` (a pty :class:`PtyCable`).
    :attr:`fc_url` is the companion's ``--fc``. Once a signing key is set, ArduPilot takes
    unsigned packets on SERIAL0 only: ``fc_serial=1`` puts the companion where signing is
    required and leaves the monitor able to send SETUP_SIGNING unsigned.

    The simulated receiver (``--rc-in-port``) is fed ``receiver`` on channels 1-8 (1500 on
    those it does not give) every 50 ms, so that "released to the radio" reads differently
    from neutral; assign :attr:`receiver` to move the sticks and switches; ``receiver=None``
    is a board with no receiver at all (``SIM_RC_FAIL 1``), a companion its only RC input.
    ``first_servo`` chooses the four outputs the monitor samples (9: SERVO9..12).
    """

    def __init__(self, binary: Path, transport: str = "udp", *,
                 receiver: Sequence[int] | None = (1600, 1600, 1600, 1600),
                 extra_params: Sequence[str] = (), boot_timeout_s: float = 20.0,
                 fc_serial: int = 0, first_servo: int = 1) -> None:
        if transport not in TRANSPORTS:
            raise ValueError(f"transport {transport!r}: one of {TRANSPORTS}")
        if fc_serial not in (0, 1):
            raise ValueError(f"fc_serial {fc_serial}: 0 or 1")
        self.fc_serial = fc_serial
        self.first_servo = first_servo
        self.binary = binary
        self.transport = transport
        self.receiver = None if receiver is None else tuple(receiver)
        self.extra_params = tuple(extra_params) + (("SIM_RC_FAIL 1",) if receiver is None else ())
        self.boot_timeout_s = boot_timeout_s
        self.workdir: Path | None = None
        self.proc: subprocess.Popen[bytes] | None = None
        self.monitor: Monitor | None = None
        self.cable: PtyCable | None = None
        self.fc_url = ""
        self.command: list[str] = []
        self.boot_s = float("nan")
        self._stop = threading.Event()
        self._receiver_thread: threading.Thread | None = None

    @property
    def log_path(self) -> Path:
        assert self.workdir is not None
        return self.workdir / "ardurover.log"

    def log(self) -> str:
        """The firmware's output so far (for assertion messages)."""
        try:
            return self.log_path.read_text(errors="replace")[-3000:]
        except (OSError, AssertionError):
            return ""

    def _fc_port(self) -> str:
        if self.transport == "udp":
            port = free_port(socket.SOCK_DGRAM)
            self.fc_url = f"udpin:127.0.0.1:{port}"
            return f"udpclient:127.0.0.1:{port}"
        if self.transport == "tcp":
            port = free_port(socket.SOCK_STREAM, "")  # SITL listens on all interfaces
            self.fc_url = f"tcp:127.0.0.1:{port}"
            return f"tcp:{port}"
        self.cable = PtyCable()
        self.fc_url = f"{self.cable.companion_path},115200"
        return f"uart:{self.cable.fc_path}:115200"

    def start(self) -> None:
        self.workdir = Path(tempfile.mkdtemp(prefix="mecanum-sitl-"))
        defaults = [str(self.binary.with_name("rover.parm"))] * (
            self.binary.with_name("rover.parm").is_file())
        extra = self.workdir / "extra.parm"
        extra.write_text(PASSTHROUGH_PARM.read_text() + "".join(
            f"{line}\n" for line in self.extra_params))
        defaults.append(str(extra))
        mon_port = free_port(socket.SOCK_DGRAM)
        self.rc_port = free_port(socket.SOCK_DGRAM, "")  # SITL binds it on all interfaces
        ports = [self._fc_port(), f"udpclient:127.0.0.1:{mon_port}"]
        serial0, serial1 = ports if self.fc_serial == 0 else ports[::-1]
        self.command = [str(self.binary), "-w", "--model", "rover", "--speedup", "1",
                        "--defaults", ",".join(defaults), "--serial0", serial0,
                        "--serial1", serial1, "--serial2", "none",
                        *(["--rc-in-port", str(self.rc_port)] if self.receiver else [])]
        self.monitor = Monitor(mon_port, self.first_servo)
        started = time.monotonic()
        with self.log_path.open("wb") as log:
            self.proc = subprocess.Popen(self.command, cwd=self.workdir, stdin=subprocess.DEVNULL,
                                         stdout=log, stderr=subprocess.STDOUT,
                                         start_new_session=True)
        if self.receiver is not None:
            self._receiver_thread = threading.Thread(target=self._feed_receiver,
                                                     name="sitl-receiver", daemon=True)
            self._receiver_thread.start()
        if not self.monitor.wait_heartbeat(self.boot_timeout_s):
            raise TimeoutError(f"no HEARTBEAT from SITL within {self.boot_timeout_s} s "
                               f"(exit code {self.proc.poll()}):\n{self.log()}")
        self.boot_s = time.monotonic() - started
        self.monitor.request_servo_output(self.boot_timeout_s)

    def _feed_receiver(self) -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            while not self._stop.is_set():
                receiver = self.receiver or ()
                pulses = struct.pack("<8H", *receiver[:8], *[1500] * (8 - len(receiver[:8])))
                with contextlib.suppress(OSError):
                    s.sendto(pulses, ("127.0.0.1", self.rc_port))
                self._stop.wait(RECEIVER_PERIOD_S)

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def setup_fc(self, *args: str, timeout_s: float = 120.0) -> subprocess.CompletedProcess[str]:
        """``mecanum-mav setup-fc --fc URL ARGS`` on this board, as a user runs it (its own
        process, the companion not running); its exit status and output."""
        return subprocess.run([sys.executable, "-m", "mecanum_mav", "setup-fc", "--fc",
                               self.fc_url, *args], capture_output=True, text=True,
                              timeout=timeout_s)

    def set_up(self, *args: str) -> str:
        """``setup-fc ARGS`` (by default ``--apply``), which must leave the board safe (exit
        status 0): what a user does before the first drive; its output.

        Raises:
            AssertionError: setup-fc did not end with a safe board.
        """
        done = self.setup_fc(*(args or ("--apply",)))
        assert done.returncode == 0, f"setup-fc {args}: {done.returncode}\n{done.stdout}" \
            f"{done.stderr}\n{self.log()}"
        assert "the flight controller is set up safely" in done.stdout, done.stdout
        if "--reboot" in args:  # a rebooted board streams only what it is asked for again
            assert self.monitor is not None
            self.monitor.request_servo_output(self.boot_timeout_s)
        return done.stdout

    def close(self) -> None:
        """Kill the process group, stop the threads, remove the directory; idempotent."""
        self._stop.set()
        if self.proc is not None:
            kill_group(self.proc)
        if self._receiver_thread is not None:
            self._receiver_thread.join(timeout=2)
        if self.monitor is not None:
            self.monitor.close()
        if self.cable is not None:
            self.cable.close()
        if self.workdir is not None:
            shutil.rmtree(self.workdir, ignore_errors=True)


# --------------------------------------------------------------------------- the companion




# --------------------------------------------------------------------------- the three


class Rig:
    """The firmware, a companion process on it, and a ground station on the companion.

    Deadlines are generous (:attr:`boot_s`, :attr:`react_s`): the suite must hold on a loaded
    2-core machine.
    """

    boot_s = 20.0
    react_s = 10.0

    def __init__(self, fc: Sitl, gcs: ScriptedGroundStation, companion: CompanionProcess):
        self.fc = fc
        self.gcs = gcs
        self.companion = companion
        assert fc.monitor is not None
        self.monitor = fc.monitor

    @classmethod
    @contextlib.contextmanager
    def on(cls: type[R], fc: Sitl, workdir: Path, *options: str,
           fc_url: str | None = None) -> Iterator[R]:
        """A companion process on ``fc`` (``mecanum-mav run --fc fc.fc_url *options``, its
        files in ``workdir``; ``fc_url`` instead of the board's own, e.g. a relay in the
        link) and a scripted ground station on UDP: the three, as ``cls``."""
        gcs, port = udp_ground_station()
        try:
            with CompanionProcess(port.url, fc_url or fc.fc_url, workdir, *options) as process:
                yield cls(fc, gcs, process)
        finally:
            port.close()

    def why(self) -> str:
        return (f"last SERVO1..4: {self.monitor.last()}\ncompanion: {self.companion.log()}"
                f"\nsitl ({' '.join(self.fc.command)}):\n{self.fc.log()}")

    def arm(self) -> None:
        try:
            self.gcs.arm(timeout_s=self.boot_s)
        except RuntimeError:
            raise AssertionError(f"the companion never armed\n{self.why()}") from None

    def drive(self, x: int, y: int, r: int, expected: tuple[int, ...]) -> float:
        """Stream the sticks until SERVO1..4 read ``expected``; when they did (monotonic s)."""
        sample = self.monitor.wait_servos(lambda s: s == expected, self.react_s,
                                          tick=lambda: self.gcs.sticks(x, y, r))
        assert sample is not None, f"sticks {(x, y, r)} never gave {expected}\n{self.why()}"
        return sample.t

    def said(self, start: str) -> bool:
        """Whether the companion told the ground station a STATUSTEXT starting with ``start``
        (waiting for it; a STATUSTEXT holds 50 characters, longer texts come in pieces)."""
        return self.gcs.wait("STATUSTEXT", lambda m: m.text.startswith(start), self.react_s,
                             0) is not None
