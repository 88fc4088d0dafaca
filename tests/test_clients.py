"""The real client programs users run, driving the companion with the built-in simulator."""

from __future__ import annotations

import asyncio
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


def free_tcp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


async def _first(stream, timeout_s: float = 10.0):
    async def first():
        async for item in stream:
            return item
        return None

    return await asyncio.wait_for(first(), timeout_s)


async def _until(condition: Callable[[], object], timeout_s: float) -> object:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        result = condition()
        if result:
            return result
        await asyncio.sleep(0.05)
    return None


async def _mavsdk_scenario(port: int, grpc_port: int, sim: SimFlightController,
                           params: Params) -> None:
    from mavsdk import System
    from mavsdk.offboard import PositionNedYaw, VelocityBodyYawspeed, VelocityNedYaw

    drone = System(port=grpc_port)
    await drone.connect(system_address=f"udpin://127.0.0.1:{port}")
    state = await _first(drone.core.connection_state())
    while not state.is_connected:
        state = await _first(drone.core.connection_state())
    # Parameters (ArduPilot's float encoding).
    assert await drone.param.get_param_float("INP_EXPO") == 0.0
    await drone.param.set_param_float("INP_EXPO", 0.25)
    assert params["INP_EXPO"] == 0.25
    assert await drone.param.get_param_int("MIX_ALGO") == 0
    # Arm, then drive by manual control input in MANUAL.
    await drone.action.arm()
    start = sim.snapshot().pose.x_m
    async def forward() -> bool:
        for _ in range(40):
            await drone.manual_control.set_manual_control_input(0.6, 0.0, 0.5, 0.0)
            await asyncio.sleep(0.05)
            if sim.snapshot().pose.x_m > start + 0.3:
                return True
        return False
    assert await forward()
    # Offboard (GUIDED): body velocity right, then NED velocity north, then a position.
    await drone.offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.5, 0.0, 0.0))
    await drone.offboard.start()
    y0 = sim.snapshot().pose.y_m
    assert await _until(lambda: sim.snapshot().pose.y_m > y0 + 0.3, 5.0)
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.5, 0.0, 0.0, 0.0))
    x0 = sim.snapshot().pose.x_m
    assert await _until(lambda: sim.snapshot().pose.x_m > x0 + 0.3, 5.0)
    goal = (sim.snapshot().pose.x_m + 0.5, sim.snapshot().pose.y_m - 0.5)
    await drone.offboard.set_position_ned(PositionNedYaw(goal[0], goal[1], 0.0, 30.0))
    reached = await _until(
        lambda: abs(sim.snapshot().pose.x_m - goal[0]) < 0.05
        and abs(sim.snapshot().pose.y_m - goal[1]) < 0.05
        and abs(sim.snapshot().pose.yaw_rad - 0.5236) < 0.035, 8.0)
    assert reached, sim.snapshot().pose
    # Telemetry: odometry and local position agree with the true pose.
    truth = sim.snapshot().pose
    odometry = await _first(drone.telemetry.odometry())
    assert abs(odometry.position_body.x_m - truth.x_m) < 0.05
    assert abs(odometry.position_body.y_m - truth.y_m) < 0.05
    pv = await _first(drone.telemetry.position_velocity_ned())
    assert abs(pv.position.north_m - truth.x_m) < 0.05
    assert abs(pv.position.east_m - truth.y_m) < 0.05
    await drone.offboard.stop()
    await drone.action.disarm()


def test_mavsdk_connects_sets_params_arms_and_drives_manual_and_offboard():
    pytest.importorskip("mavsdk")
    port, grpc_port = free_udp_port(), free_tcp_port()
    with rover_for_client(port) as (sim, _, params):
        asyncio.run(asyncio.wait_for(_mavsdk_scenario(port, grpc_port, sim, params), 90.0))
