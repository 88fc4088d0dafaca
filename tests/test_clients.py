"""The real client programs users run, driving the companion with the built-in simulator."""

from __future__ import annotations

import asyncio
import contextlib
import math
import re
import shutil
import socket
import subprocess
import sys
import threading
import time
from collections.abc import AsyncIterator, Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from conftest import wait_until

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import SCHEMA, Params
from mecanum_mav.io.links import mavlink
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.mecanum.geometry import Pose2d
from mecanum_mav.protocol.signing import key_from_text
from mecanum_mav.sim.board import ORIGIN
from mecanum_mav.sim.process import free_port
from mecanum_mav.sim.simfc import SimFlightController


@contextmanager
def rover_for_client(port: int, pose: Pose2d = ORIGIN, signing_key: bytes | None = None,
                     *, listen: bool = False
                     ) -> Iterator[tuple[SimFlightController, Companion, Params]]:
    """Simulator (its chassis starting at ``pose``) + companion whose ground-station link goes
    to a client on ``port`` (or, ``listen``, listens there: ``udpin:``), signed with
    ``signing_key``, if given."""
    params = Params()
    sim = SimFlightController("udpin:127.0.0.1:0", params, pose)
    sim.start()
    companion = Companion(params, f"{'udpin' if listen else 'udpout'}:127.0.0.1:{port}",
                          f"udpout:127.0.0.1:{sim.local_port}", gcs_signing_key=signing_key)
    companion.start()
    try:
        yield sim, companion, params
    finally:
        companion.close()
        sim.stop()


class MavProxy:
    """MAVProxy headless, driven through a pipe, its output collected line by line; it listens
    on ``port`` (``udpin:``), or with ``master="udpout"`` sends there first."""

    def __init__(self, port: int, workdir: Path, *options: str, master: str = "udpin") -> None:
        exe = shutil.which("mavproxy.py", path=str(Path(sys.executable).parent))
        if exe is None:
            pytest.skip("MAVProxy is not installed (pip install '.[test]')")
        self.proc = subprocess.Popen(
            [sys.executable, exe, f"--master={master}:127.0.0.1:{port}", "--nowait", *options],
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


def test_mavproxy_with_the_passphrase_arms_and_drives_the_signed_rover_and_without_it_cannot(
        tmp_path):
    """``signing key PASSPHRASE`` in MAVProxy and the same passphrase in --signing-key's file
    give the same key. Before MAVProxy has it, its arm request is refused and said so."""
    port = free_port()
    passphrase = "rover-on-a-shared-radio"
    with rover_for_client(port, signing_key=key_from_text(passphrase)) as (sim, companion, _):
        mavproxy = MavProxy(port, tmp_path)
        try:
            assert mavproxy.saw("Detected vehicle", 30.0), mavproxy.lines
            mavproxy.send("arm throttle")
            assert mavproxy.saw("Unsigned packet refused: signing required"), mavproxy.lines
            assert not companion.core.vehicle.armed
            mavproxy.send(f"signing key {passphrase}")
            mavproxy.send("arm throttle")
            assert mavproxy.saw("ARMED"), mavproxy.lines
            mavproxy.send("rc 3 1800")  # throttle channel: forward
            assert wait_until(lambda: sim.snapshot().pose.x_m > 0.3, 5.0)
            mavproxy.send("rc 3 1500")
        finally:
            mavproxy.close()


def test_mavproxy_without_the_key_sees_a_listening_signed_rover_and_why_then_with_it_arms(
        tmp_path):
    """The rover listens (``--gcs udpin:``) with a key and MAVProxy connects to it
    (``--master=udpout:``) without one: the rover answers it only with its HEARTBEAT, signed
    (MAVProxy does not verify without a key), and the reason, so MAVProxy shows the vehicle and
    why; no parameters, and its arm is refused. With the key it is the rover's ground station."""
    port = free_port()
    passphrase = "rover-on-a-shared-radio"
    with rover_for_client(port, signing_key=key_from_text(passphrase), listen=True) as (
            _sim, companion, _):
        mavproxy = MavProxy(port, tmp_path, master="udpout")
        try:
            assert mavproxy.saw("Detected vehicle", 30.0), mavproxy.lines
            assert mavproxy.saw("Unsigned packet refused: signing required"), mavproxy.lines
            mavproxy.send("arm throttle")
            since = len(mavproxy.lines)
            assert saw_since(mavproxy, "Unsigned packet refused", since), mavproxy.lines
            assert not companion.core.vehicle.armed
            assert not [line for line in mavproxy.lines if "parameters" in line]
            mavproxy.send(f"signing key {passphrase}")
            mavproxy.send("arm throttle")
            assert mavproxy.saw("ARMED"), mavproxy.lines
            assert wait_until(lambda: companion.core.vehicle.armed, 5.0)
        finally:
            mavproxy.close()


def test_mavproxy_fetches_params_sets_one_arms_and_drives_by_rc_velocity_and_position(
        tmp_path):
    """The rover faces east (heading 90): MAVProxy's ``velocity`` and ``position`` are in the
    body frame (BODY_NED), so "ahead" is east, and ``position 1 0 0`` is the point 1 m ahead."""
    port = free_port()
    with rover_for_client(port, Pose2d(0.0, 0.0, math.pi / 2)) as (sim, _, params):
        mavproxy = MavProxy(port, tmp_path)
        try:
            assert mavproxy.saw(f"Received {len(SCHEMA)} parameters", 30.0), mavproxy.lines
            mavproxy.send("param set INP_EXPO 0.2")
            assert wait_until(lambda: params["INP_EXPO"] == 0.2, 5.0)
            mavproxy.send("arm throttle")
            assert mavproxy.saw("ARMED")
            mavproxy.send("rc 3 1800")  # throttle channel: forward, here east
            assert wait_until(lambda: sim.snapshot().pose.y_m > 0.3, 5.0)
            mavproxy.send("rc 3 1500")
            mavproxy.send("mode GUIDED")
            assert mavproxy.saw("Mode GUIDED")
            start = sim.snapshot().pose
            mavproxy.send("velocity 0 0.5 0")  # body frame: 0.5 m/s to the right, here south
            assert wait_until(lambda: sim.snapshot().pose.x_m < start.x_m - 0.3, 5.0)
            assert abs(sim.snapshot().pose.y_m - start.y_m) < 0.05
            assert abs(sim.snapshot().pose.yaw_rad - math.pi / 2) < 0.02  # it did not turn
            mavproxy.send("velocity 0 0 0")
            assert wait_until(lambda: math.hypot(*sim.snapshot().velocity_body) < 0.01, 5.0)
            start = sim.snapshot().pose
            mavproxy.send("position 1 0 0")  # 1 m ahead of the rover: here 1 m east
            assert wait_until(lambda: abs(sim.snapshot().pose.y_m - start.y_m - 1.0) < 0.03
                              and math.hypot(*sim.snapshot().velocity_body) < 0.01, 10.0), (
                start, sim.snapshot().pose)
            assert abs(sim.snapshot().pose.x_m - start.x_m) < 0.03
            assert not [line for line in mavproxy.lines if "fence breach" in line]
        finally:
            mavproxy.close()


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


@contextlib.asynccontextmanager
async def _mavsdk_connected(port: int, grpc_port: int) -> AsyncIterator[Any]:
    """A MAVSDK ``System`` (its own mavsdk_server on ``grpc_port``) connected to the rover whose
    ground-station link sends to ``port``; its server is killed and reaped afterwards."""
    from mavsdk import System

    drone = System(port=grpc_port)
    try:
        await drone.connect(system_address=f"udpin://127.0.0.1:{port}")
        state = await _first(drone.core.connection_state())
        while not state.is_connected:
            state = await _first(drone.core.connection_state())
        yield drone
    finally:
        server = drone._server_process
        drone._stop_mavsdk_server()  # (kills it, does not wait for it)
        if isinstance(server, subprocess.Popen):
            server.wait(timeout=5.0)


async def _mavsdk_scenario(port: int, grpc_port: int, sim: SimFlightController,
                           params: Params) -> None:
    from mavsdk.offboard import PositionNedYaw, VelocityBodyYawspeed, VelocityNedYaw

    async with _mavsdk_connected(port, grpc_port) as drone:
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


async def _mavsdk_arm(port: int, grpc_port: int) -> None:
    async with _mavsdk_connected(port, grpc_port) as drone:
        await drone.action.arm()


def test_mavsdk_behind_mavproxy_with_the_key_arms_the_signed_rover(tmp_path):
    """MAVSDK cannot sign; MAVProxy signs what it forwards (its mavfwd_signing setting). It
    re-packs what it signs with its own system and component ids, so it is given MAVSDK's
    (245, 190): the rover's answers are addressed to those, and MAVSDK takes only its own."""
    pytest.importorskip("mavsdk")
    port, out_port, grpc_port = free_port(), free_port(), free_port(socket.SOCK_STREAM)
    passphrase = "rover-on-a-shared-radio"
    with rover_for_client(port, signing_key=key_from_text(passphrase)) as (_, companion, _):
        mavproxy = MavProxy(port, tmp_path, f"--out=udp:127.0.0.1:{out_port}",
                            "--source-system=245", "--source-component=190")
        try:
            assert mavproxy.saw("Detected vehicle", 30.0), mavproxy.lines
            mavproxy.send(f"signing key {passphrase}")
            asyncio.run(asyncio.wait_for(_mavsdk_arm(out_port, grpc_port), 60.0))
            assert wait_until(lambda: companion.core.vehicle.armed, 5.0)
        finally:
            mavproxy.close()


def test_mavsdk_connects_sets_params_arms_and_drives_manual_and_offboard():
    pytest.importorskip("mavsdk")
    port, grpc_port = free_port(), free_port(socket.SOCK_STREAM)
    with rover_for_client(port) as (sim, _, params):
        asyncio.run(asyncio.wait_for(_mavsdk_scenario(port, grpc_port, sim, params), 90.0))


# --------------------------------------------------------------------------- missions

# Exact in float32 (ORIGIN_LAT/LON travel and are stored as float32).
ORIGIN_LAT_DEG, ORIGIN_LON_DEG = 47.375, 8.5


def set_origin(companion) -> GlobalOrigin:
    """ORIGIN_LAT/LON on the running rover (as a PARAM_SET would: store, then reconfigure);
    the origin the companion converts with."""
    params = companion.core.params
    params.update({"ORIGIN_LAT": ORIGIN_LAT_DEG, "ORIGIN_LON": ORIGIN_LON_DEG})
    companion.core.reconfigure()
    return GlobalOrigin.from_degrees(float(params["ORIGIN_LAT"]), float(params["ORIGIN_LON"]))


def _mavsdk_waypoint(lat_deg: float, lon_deg: float, *, speed_m_s: float,
                     fly_through: bool, radius_m: float):
    from mavsdk.mission import MissionItem

    nan = math.nan
    return MissionItem(
        latitude_deg=lat_deg, longitude_deg=lon_deg, relative_altitude_m=0.0,
        speed_m_s=speed_m_s, is_fly_through=fly_through, gimbal_pitch_deg=nan,
        gimbal_yaw_deg=nan, camera_action=MissionItem.CameraAction.NONE, loiter_time_s=nan,
        camera_photo_interval_s=nan, acceptance_radius_m=radius_m, yaw_deg=nan,
        camera_photo_distance_m=nan, vehicle_action=MissionItem.VehicleAction.NONE)


MAVSDK_LEGS_NE = [(0.8, 0.0), (0.8, 0.6), (0.2, 0.6)]  # metres north, east of the origin


async def _mavsdk_mission_scenario(port: int, grpc_port: int, sim: SimFlightController,
                                   companion: Companion, origin: GlobalOrigin) -> None:
    from mavsdk.mission import MissionPlan
    from mavsdk.telemetry import FlightMode

    points = [origin.to_global(n, e) for n, e in MAVSDK_LEGS_NE]
    # MAVSDK 3.x's mission plugin does not insert ArduPilot's home item 0 (it sends the plan's
    # items from seq 0, and downloads item 0 back as the first item), so a MAVSDK user talking
    # to an ArduPilot vehicle puts a placeholder for home first; without it the first
    # waypoint would be taken as home and never driven to.
    home = _mavsdk_waypoint(origin.lat_e7 / 1e7, origin.lon_e7 / 1e7, speed_m_s=math.nan,
                            fly_through=True, radius_m=math.nan)
    plan = MissionPlan([home, *(_mavsdk_waypoint(lat / 1e7, lon / 1e7, speed_m_s=0.5,
                                                 fly_through=False, radius_m=0.05)
                                for lat, lon in points)])
    async with _mavsdk_connected(port, grpc_port) as drone:
        await drone.mission.upload_mission(plan)
        stored = companion.core.mission.items
        # seq 0 home, then each waypoint followed by its DO_CHANGE_SPEED.
        assert len(stored) == 1 + 2 * len(points), stored
        assert [(it.x, it.y) for it in stored[1::2]] == points, stored

        downloaded = (await drone.mission.download_mission()).mission_items
        assert len(downloaded) == len(plan.mission_items)
        for got, want in zip(downloaded, plan.mission_items, strict=True):
            assert abs(got.latitude_deg - want.latitude_deg) < 1e-6, (got, want)
            assert abs(got.longitude_deg - want.longitude_deg) < 1e-6, (got, want)
        for got in downloaded[1:]:
            assert got.speed_m_s == pytest.approx(0.5)
            assert got.acceptance_radius_m == pytest.approx(0.05)
            assert not got.is_fly_through

        progress: list[tuple[int, int]] = []

        async def watch_progress() -> None:
            async for p in drone.mission.mission_progress():
                progress.append((p.current, p.total))

        watcher = asyncio.ensure_future(watch_progress())
        await drone.action.arm()
        await drone.mission.start_mission()
        closest = [math.inf] * len(MAVSDK_LEGS_NE)
        deadline = time.monotonic() + 30.0
        finished = False
        while time.monotonic() < deadline and not finished:
            pose = sim.snapshot().pose
            for k, goal in enumerate(MAVSDK_LEGS_NE):
                closest[k] = min(closest[k], math.dist((pose.x_m, pose.y_m), goal))
            finished = await drone.mission.is_mission_finished()
            await asyncio.sleep(0.05)
        assert finished, (progress, sim.snapshot().pose)
        total = len(plan.mission_items)
        assert await _until(lambda: progress and progress[-1] == (total, total), 5.0), progress
        watcher.cancel()
        assert max(closest) < 0.10, closest  # every waypoint visited, the first one too
        mode = await _first(drone.telemetry.flight_mode())
        deadline = time.monotonic() + 5.0
        while mode != FlightMode.HOLD and time.monotonic() < deadline:
            mode = await _first(drone.telemetry.flight_mode())
        assert mode == FlightMode.HOLD
        truth = sim.snapshot().pose
        assert math.dist((truth.x_m, truth.y_m), MAVSDK_LEGS_NE[-1]) < 0.10, truth
        await drone.action.disarm()


def test_mavsdk_uploads_a_mission_downloads_it_and_runs_it_to_the_end():
    pytest.importorskip("mavsdk")
    port, grpc_port = free_port(), free_port(socket.SOCK_STREAM)
    with rover_for_client(port) as (sim, companion, _params):
        origin = set_origin(companion)
        asyncio.run(asyncio.wait_for(
            _mavsdk_mission_scenario(port, grpc_port, sim, companion, origin), 90.0))


def saw_since(mavproxy: MavProxy, text: str, since: int, timeout_s: float = 15.0) -> int | None:
    """Index of the first line from ``since`` on that contains ``text``, waiting for it."""
    def find() -> int | None:
        for index in range(since, len(mavproxy.lines)):
            if text in mavproxy.lines[index]:
                return index + 1  # truthy even for line 0
        return None

    found = wait_until(find, timeout_s)
    return None if found is None else int(found) - 1


def stop_mavproxy(mavproxy: MavProxy) -> None:
    """End of input first: MAVProxy's main thread sits in its stdin read and only sees SIGTERM
    after the next line, so ``close`` alone waits out its 10 s timeout."""
    assert mavproxy.proc.stdin is not None
    with contextlib.suppress(OSError):
        mavproxy.proc.stdin.close()
    mavproxy.close()


WP_LINE = re.compile(r"^(\d+) (\d+) (-?\d+\.\d+) (-?\d+\.\d+) ")  # MAVProxy's "wp list" rows


def test_mavproxy_loads_a_waypoint_file_lists_it_and_clears_it(tmp_path):
    """QGC WPL 110 in a global frame (MAVProxy scales every location command's x/y by 1e7,
    which is right only for global frames). Between list and clear it also runs the mission."""
    port = free_port()
    with rover_for_client(port) as (sim, companion, _params):
        origin = set_origin(companion)
        legs = [(0.0, 0.0), (0.8, 0.0), (0.8, 0.5)]  # home, then two waypoints (north, east)
        points = [origin.to_global(n, e) for n, e in legs]
        rows = ["QGC WPL 110"]
        for seq, (lat, lon) in enumerate(points):
            fields = (seq, int(seq == 0), mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                      mavlink.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, 0, f"{lat / 1e7:.7f}",
                      f"{lon / 1e7:.7f}", 0, 1)
            rows.append("\t".join(str(f) for f in fields))
        (tmp_path / "square.waypoints").write_text("\n".join(rows) + "\n")
        mavproxy = MavProxy(port, tmp_path)
        try:
            assert mavproxy.saw(f"Received {len(SCHEMA)} parameters", 30.0), mavproxy.lines
            since = len(mavproxy.lines)
            mavproxy.send("wp load square.waypoints")
            assert saw_since(mavproxy, "Sent all 3 waypoints", since) is not None, mavproxy.lines
            assert saw_since(mavproxy, "MISSION_ACK: TYPE_MISSION: ACCEPTED", since) is not None
            stored = companion.core.mission.items
            assert len(stored) == 3
            for item, (lat, lon) in zip(stored, points, strict=True):
                assert item.frame == mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT
                assert item.command == mavlink.MAV_CMD_NAV_WAYPOINT
                assert abs(item.x - lat) <= 1 and abs(item.y - lon) <= 1  # MAVProxy truncates

            since = len(mavproxy.lines)
            mavproxy.send("wp list")
            at = saw_since(mavproxy, "Requesting 3 waypoints", since)
            assert at is not None, mavproxy.lines[since:]

            def rows_listed() -> list[re.Match[str]]:
                found = [m for line in mavproxy.lines[at + 1:] if (m := WP_LINE.match(line))]
                return found if len(found) >= 3 else []

            listed = wait_until(rows_listed, 10.0)
            assert listed, mavproxy.lines[at:]
            for match, (lat, lon) in zip(listed, points, strict=True):
                assert int(match[1]) == mavlink.MAV_CMD_NAV_WAYPOINT
                assert int(match[2]) == mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT
                assert abs(float(match[3]) - lat / 1e7) < 2e-7, match[0]
                assert abs(float(match[4]) - lon / 1e7) < 2e-7, match[0]

            mavproxy.send("arm throttle")
            assert mavproxy.saw("ARMED")
            since = len(mavproxy.lines)
            mavproxy.send("mode AUTO")
            assert saw_since(mavproxy, "Mission started at item 1", since) is not None
            assert saw_since(mavproxy, "Mission complete", since, 20.0) is not None, (
                mavproxy.lines[since:], sim.snapshot().pose)
            assert saw_since(mavproxy, "Mode HOLD", since) is not None
            truth = sim.snapshot().pose
            assert math.dist((truth.x_m, truth.y_m), legs[-1]) < 0.10, truth

            since = len(mavproxy.lines)
            mavproxy.send("wp clear")
            assert saw_since(mavproxy, "MISSION_ACK: TYPE_MISSION: ACCEPTED", since) is not None
            assert wait_until(lambda: companion.core.mission.items == (), 5.0)
            since = len(mavproxy.lines)
            mavproxy.send("wp list")
            assert saw_since(mavproxy, "Requesting 0 waypoints", since) is not None
        finally:
            stop_mavproxy(mavproxy)
