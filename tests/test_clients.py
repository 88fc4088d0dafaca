"""The real client programs users run, driving the companion with the built-in simulator."""

from __future__ import annotations

import shutil
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from mecanum_mav.companion import Companion
from mecanum_mav.params import SCHEMA, Params
from mecanum_mav.simfc import SimFlightController


def free_udp_port() -> int:
    """A port the OS just handed out (clients that cannot bind port 0 themselves)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@contextmanager
def rover_for_client(port: int) -> Iterator[tuple[SimFlightController, Companion, Params]]:
    """Simulator + companion whose ground-station link goes to a client on ``port``."""
    params = Params()
    sim = SimFlightController("udpin:127.0.0.1:0", params)
    sim.start()
    companion = Companion(params, f"udpout:127.0.0.1:{port}",
                          f"udpout:127.0.0.1:{sim.local_port}")
    companion.start()
    try:
        yield sim, companion, params
    finally:
        companion.close()
        sim.stop()


def wait_until(condition: Callable[[], object], timeout_s: float) -> object:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        result = condition()
        if result:
            return result
        time.sleep(0.05)  # polling a condition another thread updates, with a deadline
    return None


class MavProxy:
    """MAVProxy headless, driven through a pipe, its output collected line by line."""

    def __init__(self, port: int, workdir: Path) -> None:
        exe = shutil.which("mavproxy.py", path=str(Path(sys.executable).parent))
        if exe is None:
            pytest.skip("MAVProxy is not installed (pip install '.[test]')")
        self.proc = subprocess.Popen(
            [sys.executable, exe, f"--master=udpin:127.0.0.1:{port}", "--nowait"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            bufsize=1, cwd=workdir)
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line)

    def saw(self, text: str, timeout_s: float = 15.0) -> bool:
        return bool(wait_until(lambda: any(text in line for line in self.lines), timeout_s))

    def send(self, command: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()

    def close(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()


def test_mavproxy_fetches_params_sets_one_arms_and_drives_by_rc_and_velocity(tmp_path):
    port = free_udp_port()
    with rover_for_client(port) as (sim, _, params):
        mavproxy = MavProxy(port, tmp_path)
        try:
            assert mavproxy.saw(f"Received {len(SCHEMA)} parameters", 30.0), mavproxy.lines
            mavproxy.send("param set INP_EXPO 0.2")
            assert wait_until(lambda: params["INP_EXPO"] == 0.2, 5.0)
            mavproxy.send("arm throttle")
            assert mavproxy.saw("ARMED")
            mavproxy.send("rc 3 1800")  # throttle channel: forward
            assert wait_until(lambda: sim.snapshot().pose.x_m > 0.3, 5.0)
            mavproxy.send("rc 3 1500")
            mavproxy.send("mode GUIDED")
            assert mavproxy.saw("Mode GUIDED")
            mavproxy.send("velocity 0 0.5 0")  # north 0, east 0.5 m/s
            assert wait_until(lambda: sim.snapshot().pose.y_m > 0.3, 5.0)
            assert abs(sim.snapshot().pose.yaw_rad) < 0.02  # holonomic: it did not turn
        finally:
            mavproxy.close()
