"""Meeting the rover from outside, as a user of a real client does: the rover is its own
process (``python -m mecanum_mav sim``), MAVProxy is driven through its console, and
what a test asserts is what a client prints or receives, never the rover's objects.

- :func:`rover`: ``mecanum-mav sim`` as a process (the companion with its simulator), its
  ground-station link sending to a client's port, recording both links to a tlog (``--tlog``).
- :class:`MavProxy`: MAVProxy headless; :meth:`MavProxy.saw` waits for a whole console line.
- :class:`Observer`: a pymavlink listener behind MAVProxy's ``--out``: it receives what
  MAVProxy receives from the rover (HEARTBEAT, LOCAL_POSITION_NED, ATTITUDE, ...).
- :func:`true_track`: the simulator's ground truth (SIM_STATE) from the rover's tlog, read
  after the rover stopped (the ground-station link does not carry SIM_STATE).
"""

from __future__ import annotations

import contextlib
import math
import re
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from support import ClosedOnExit, at_most_every, wait_until, write_key_file

from mecanum_mav.config.params import SCHEMA
from mecanum_mav.io.tlog import read_tlog
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.dialect import mavlink, mavutil
from mecanum_mav.sim.process import CliProcess, CompanionProcess

VEHICLE_SYSID = 1
"""The rover's system id (SYSID_THISMAV's default)."""


@contextmanager
def rover(workdir: Path, port: int, *options: str,
          listen: bool = False) -> Iterator[CliProcess]:
    """``python -m mecanum_mav sim --gcs udpout:127.0.0.1:PORT --tlog rover.tlog *options``
    (``listen``: ``--gcs udpin:...``, the rover waits for its ground station), its output in
    ``workdir/rover/companion.log``, stopped (SIGTERM) and reaped on the way out, so that its
    tlog is complete."""
    gcs = f"{'udpin' if listen else 'udpout'}:127.0.0.1:{port}"
    with CompanionProcess.sim(gcs, workdir / "rover", "--tlog", str(tlog_path(workdir)),
                              *options) as process:
        try:
            yield process
        finally:
            process.stop(10.0)


@contextmanager
def mavproxy_on_rover(workdir: Path, port: int, *options: str
                      ) -> Iterator[tuple[CliProcess, Observer, MavProxy]]:
    """A :func:`rover` (with ``options``), an :class:`Observer` and MAVProxy connected to the
    rover with an ``--out`` to the observer, once MAVProxy has read the rover's parameters (as
    a user waits for "Received N parameters" before typing)."""
    with rover(workdir, port, *options) as process, Observer() as seen:
        mavproxy = MavProxy(port, workdir, f"--out={seen.url}")
        try:
            assert mavproxy.saw(f"Received {len(SCHEMA)} parameters", timeout_s=30.0), (
                mavproxy.lines, process.log())
            yield process, seen, mavproxy
        finally:
            mavproxy.close()


def tlog_path(workdir: Path) -> Path:
    """Where :func:`rover` records the rover's two links."""
    return workdir / "rover" / "rover.tlog"


def key_file(workdir: Path, passphrase: str) -> Path:
    """A private file holding ``passphrase``, for ``--signing-key``."""
    return write_key_file(workdir / "signing.key", passphrase + "\n")


_PROMPT = re.compile(r"^(?:\S+> )+")
"""MAVProxy's prompt ("MANUAL> "), which may stand before a line it prints, even twice."""


class MavProxy:
    """MAVProxy headless, driven through a pipe, its output collected line by line; it listens
    on ``port`` (``udpin:``), or with ``master="udpout"`` sends there first (a rover that
    listens)."""

    def __init__(self, port: int, workdir: Path, *options: str, master: str = "udpin") -> None:
        exe = shutil.which("mavproxy.py", path=str(Path(sys.executable).parent))
        if exe is None:
            pytest.skip("MAVProxy is not installed (pip install '.[test]')")
        self.proc = subprocess.Popen(
            [sys.executable, exe, f"--master={master}:127.0.0.1:{port}", "--nowait", *options],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            bufsize=1, cwd=workdir)
        self.lines: list[str] = []
        """What it printed, one line each, without its prompt and the line end."""
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(_PROMPT.sub("", line.rstrip("\r\n")))

    def mark(self) -> int:
        """Where the output stands now: :meth:`saw` from here on sees only what follows."""
        return len(self.lines)

    def find(self, pattern: str, since: int = 0) -> int | None:
        """Index of the first line from ``since`` on that is exactly ``pattern`` (a regular
        expression matched against the whole line), or None."""
        regex = re.compile(pattern)
        for index in range(since, len(self.lines)):
            if regex.fullmatch(self.lines[index]):
                return index
        return None

    def saw(self, pattern: str, since: int = 0, timeout_s: float = 20.0) -> bool:
        """Wait for a line from ``since`` on that is exactly ``pattern`` (see :meth:`find`)."""
        return bool(wait_until(lambda: self.find(pattern, since) is not None, timeout_s))

    def arm(self, since: int, timeout_s: float = 30.0) -> bool:
        """``arm throttle`` as a pilot does it: again every 3 s until MAVProxy prints a line
        that is exactly "ARMED" (the rover refuses while it still checks its flight
        controller's setup)."""
        again = at_most_every(3.0, lambda: self.send("arm throttle"))

        def armed() -> bool:
            again()
            return self.find("ARMED", since) is not None

        return bool(wait_until(armed, timeout_s))

    def set_param(self, name: str, value: float, observer: Observer,
                  timeout_s: float = 20.0) -> bool:
        """``param set NAME VALUE`` until the rover's answer (PARAM_VALUE) says ``value``, then
        ``param fetch NAME``: True if MAVProxy then prints the value the rover stored."""
        since = self.mark()
        self.send(f"param set {name} {value}")
        if not wait_until(lambda: observer.param(name) == pytest.approx(value), timeout_s):
            return False
        self.send(f"param fetch {name}")
        return self.saw(rf"{name} = {re.escape(f'{value:.7f}')}", since, timeout_s)

    def send(self, command: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()

    def close(self) -> None:
        """End of input first: MAVProxy's main thread sits in its stdin read and only sees
        SIGTERM after the next line; then SIGTERM, SIGKILL after 10 s."""
        assert self.proc.stdin is not None
        with contextlib.suppress(OSError):
            self.proc.stdin.close()
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(10)


class Observer(ClosedOnExit):
    """A pymavlink listener on a port of its own (``udpin:127.0.0.1:0``) that keeps the
    rover's messages (system :data:`VEHICLE_SYSID`): give MAVProxy ``--out=`` :attr:`url`.
    It sends nothing. Positions are the rover's own (LOCAL_POSITION_NED, metres north and
    east of where it started), yaw radians clockwise from north (ATTITUDE)."""

    def __init__(self) -> None:
        self._conn = mavutil.mavlink_connection("udpin:127.0.0.1:0")
        self.port = int(self._conn.port.getsockname()[1])
        self.url = f"udp:127.0.0.1:{self.port}"
        self._latest: dict[str, Any] = {}
        self._counts: dict[str, int] = {}
        self._params: dict[str, float] = {}
        self.received: list[Any] = []
        """Every message from the rover, in order."""
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            msg = self._conn.recv_match(blocking=True, timeout=0.1)
            if msg is None or msg.get_srcSystem() != VEHICLE_SYSID:
                continue
            kind = msg.get_type()
            with self._lock:
                self._latest[kind] = msg
                self._counts[kind] = self._counts.get(kind, 0) + 1
                self.received.append(msg)
                if kind == "PARAM_VALUE":
                    self._params[msg.param_id] = float(msg.param_value)

    def latest(self, kind: str) -> Any:
        """The last ``kind`` message the rover sent (None before the first)."""
        with self._lock:
            return self._latest.get(kind)

    def count(self, kind: str) -> int:
        with self._lock:
            return self._counts.get(kind, 0)

    def param(self, name: str) -> float | None:
        """The value of parameter ``name`` in the rover's last PARAM_VALUE of it (None before
        the first)."""
        with self._lock:
            return self._params.get(name)

    def armed(self) -> bool:
        """The rover's last HEARTBEAT says SAFETY_ARMED."""
        beat = self.latest("HEARTBEAT")
        return beat is not None and bool(beat.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)

    def next_heartbeat(self, timeout_s: float = 5.0) -> Any:
        """Wait for a HEARTBEAT sent after this call; None if none comes."""
        before = self.count("HEARTBEAT")
        return wait_until(lambda: self.count("HEARTBEAT") > before
                          and self.latest("HEARTBEAT"), timeout_s)

    def north_east(self) -> tuple[float, float]:
        """The rover's position (LOCAL_POSITION_NED), NaN before the first."""
        pos = self.latest("LOCAL_POSITION_NED")
        return (math.nan, math.nan) if pos is None else (pos.x, pos.y)

    def speed(self) -> float:
        """The rover's ground speed (LOCAL_POSITION_NED), m/s; NaN before the first."""
        pos = self.latest("LOCAL_POSITION_NED")
        return math.nan if pos is None else math.hypot(pos.vx, pos.vy)

    def yaw(self) -> float:
        """The rover's heading (ATTITUDE), radians clockwise from north; NaN before it."""
        att = self.latest("ATTITUDE")
        return math.nan if att is None else float(att.yaw)

    def wait(self, condition: Callable[[Observer], object], timeout_s: float) -> object:
        return wait_until(lambda: condition(self), timeout_s)

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        self._conn.close()


@dataclass(frozen=True)
class TruePose:
    """The simulated chassis at one moment: ``time_s`` Unix seconds, metres north and east
    of where it started, yaw radians clockwise from north."""

    time_s: float
    north_m: float
    east_m: float
    yaw_rad: float


SIM_ORIGIN = GlobalOrigin(0, 0)
"""The simulator places its truth about ORIGIN_LAT/LON as they were when it started; the
rovers here start without one (an origin is given later, through the client), so about 0, 0."""


def true_track(workdir: Path) -> list[TruePose]:
    """The simulator's SIM_STATE messages in the tlog of :func:`rover` (read once the rover
    has stopped), in time order."""
    track = []
    for entry in read_tlog(tlog_path(workdir)).entries:
        msg = entry.msg
        if msg.get_type() == "SIM_STATE":
            north, east = SIM_ORIGIN.to_local(msg.lat_int, msg.lon_int)
            track.append(TruePose(entry.time_s, north, east, float(msg.yaw)))
    return track


def true_pose_at(track: list[TruePose], unix_s: float) -> TruePose:
    """The sample of ``track`` nearest to ``unix_s`` (SIM_STATE comes at 5 Hz)."""
    assert track, "the tlog holds no SIM_STATE"
    return min(track, key=lambda pose: abs(pose.time_s - unix_s))


def now_unix_s() -> float:
    """Wall-clock time, as the tlog stamps it."""
    return time.time()
