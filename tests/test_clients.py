"""The real client programs users run (MAVProxy, MAVSDK), driving the rover as a user runs it:
its own process with the built-in simulator (``python -m mecanum_mav sim``). What
these tests assert comes from outside: the lines MAVProxy prints, what MAVSDK's API returns,
a pymavlink observer behind MAVProxy, and the simulator's truth in the rover's tlog."""

from __future__ import annotations

import asyncio
import contextlib
import inspect
import math
import re
import socket
import subprocess
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from clients import (
    MavProxy,
    Observer,
    key_file,
    mavproxy_on_rover,
    now_unix_s,
    rover,
    true_pose_at,
    true_track,
)
from conftest import wait_until

from mecanum_mav.io.links import mavlink
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.sim.process import free_port

PASSPHRASE = "rover-on-a-shared-radio"
SAFETY_ARMED = mavlink.MAV_MODE_FLAG_SAFETY_ARMED


def test_a_mavproxy_line_is_seen_only_as_a_whole_line_so_armed_is_not_disarmed():
    """What the client tests read from MAVProxy's console: "ARMED" is not seen in "DISARMED",
    nor "Mode HOLD" in "Mode HOLD not available"; a pattern is a regular expression over the
    whole line, from ``since`` on."""
    console = MavProxy.__new__(MavProxy)  # its console lines only, no process
    console.lines = ["DISARMED", "Mode HOLD not available", "AP: ARMED here", "ARMED"]
    assert console.find("ARMED") == 3 and console.find("ARMED", 4) is None
    assert console.find("DISARMED") == 0 and console.find("DISARMED", 1) is None
    assert console.find("Mode HOLD") is None
    assert console.find(r"Mode HOLD .*") == 1
    assert console.saw("ARMED", 0, 0.1) and not console.saw("Mode HOLD", 0, 0.1)


@pytest.mark.slow
def test_mavproxy_with_the_passphrase_arms_and_drives_the_signed_rover_and_without_it_cannot(
        tmp_path):
    """``signing key PASSPHRASE`` in MAVProxy and the same passphrase in --signing-key's file
    give the same key. Before MAVProxy has it, its arm request is refused and said so, and the
    rover's HEARTBEAT stays disarmed."""
    port = free_port()
    key = key_file(tmp_path, PASSPHRASE)
    with rover(tmp_path, port, "--signing-key", str(key)) as process, Observer() as seen:
        mavproxy = MavProxy(port, tmp_path, f"--out={seen.url}")
        try:
            assert mavproxy.saw(r"Detected vehicle 1:\d+ on link 0", timeout_s=30.0), (
                mavproxy.lines, process.log())
            since = mavproxy.mark()
            mavproxy.send("arm throttle")
            assert mavproxy.saw("AP: Unsigned packet refused: signing required", since), (
                mavproxy.lines)
            beat = seen.next_heartbeat()  # one sent after the refusal
            assert beat is not None and not beat.base_mode & SAFETY_ARMED
            assert mavproxy.find("ARMED", since) is None
            mavproxy.send(f"signing key {PASSPHRASE}")
            assert mavproxy.arm(since), "\n".join(mavproxy.lines)
            assert wait_until(seen.armed, 15.0)
            north = seen.north_east()[0]
            mavproxy.send("rc 3 1800")  # throttle channel: forward (north)
            assert wait_until(lambda: seen.north_east()[0] > north + 0.3, 10.0), (
                seen.north_east())
            mavproxy.send("rc 3 1500")
        finally:
            mavproxy.close()


@pytest.mark.slow
def test_mavproxy_without_the_key_sees_a_listening_signed_rover_and_why_then_with_it_arms(
        tmp_path):
    """The rover listens (``--gcs udpin:``) with a key and MAVProxy connects to it
    (``--master=udpout:``) without one: the rover answers it only with its HEARTBEAT, signed
    (MAVProxy does not verify without a key), and the reason, so MAVProxy shows the vehicle and
    why; no parameters, and its arm is refused. With the key it is the rover's ground station."""
    port = free_port()
    key = key_file(tmp_path, PASSPHRASE)
    with rover(tmp_path, port, "--signing-key", str(key), listen=True) as process, \
            Observer() as seen:
        mavproxy = MavProxy(port, tmp_path, f"--out={seen.url}", master="udpout")
        try:
            assert mavproxy.saw(r"Detected vehicle 1:\d+ on link 0", timeout_s=30.0), (
                mavproxy.lines, process.log())
            assert mavproxy.saw("AP: Unsigned packet refused: signing required"), mavproxy.lines
            since = mavproxy.mark()
            mavproxy.send("arm throttle")
            assert mavproxy.saw("AP: Unsigned packet refused: signing required", since)
            beat = seen.next_heartbeat()  # one sent after the refusal
            assert beat is not None and not beat.base_mode & SAFETY_ARMED
            assert mavproxy.find(r"Received \d+ parameters") is None  # none for a stranger
            mavproxy.send(f"signing key {PASSPHRASE}")
            assert mavproxy.arm(since), "\n".join(mavproxy.lines)
            assert wait_until(seen.armed, 15.0)
        finally:
            mavproxy.close()


FACE_EAST = ("message SET_POSITION_TARGET_LOCAL_NED 0 1 1 8 3064 0 0 0 0 0 0 0 0 0 "
             f"{math.pi / 2:.6f} 0")
"""A MAVProxy user's way to a heading (``module load message`` first): a GUIDED target in
BODY_NED 0 m ahead (stay here) with yaw 90 deg (east); type_mask 3064 keeps position and yaw."""


@pytest.mark.slow
def test_mavproxy_fetches_params_sets_one_arms_and_drives_by_rc_velocity_and_position(
        tmp_path):
    """Turned to face east (heading 90) through MAVProxy first: its ``velocity`` and
    ``position`` are in the body frame (BODY_NED), so "ahead" is east, and ``position 1 0 0``
    is the point 1 m ahead. Positions: the rover's LOCAL_POSITION_NED, as MAVProxy gets it."""
    port = free_port()
    with mavproxy_on_rover(tmp_path, port) as (_process, seen, mavproxy):
        since = mavproxy.mark()
        assert mavproxy.set_param("INP_EXPO", 0.2, seen), mavproxy.lines[since:]
        assert mavproxy.arm(since), mavproxy.lines[since:]
        assert wait_until(seen.armed, 15.0)

        mavproxy.send("module load message")
        mavproxy.send("mode GUIDED")
        assert mavproxy.saw("Mode GUIDED", since), mavproxy.lines[since:]
        mavproxy.send(FACE_EAST)
        assert seen.wait(lambda s: abs(s.yaw() - math.pi / 2) < 0.005
                         and abs(s.latest("ATTITUDE").yawspeed) < 0.01, 15.0), seen.yaw()
        since = mavproxy.mark()
        mavproxy.send("mode MANUAL")
        assert mavproxy.saw("Mode MANUAL", since), mavproxy.lines[since:]

        east = seen.north_east()[1]
        mavproxy.send("rc 3 1800")  # throttle channel: forward, here east
        assert wait_until(lambda: seen.north_east()[1] > east + 0.3, 10.0), seen.north_east()
        mavproxy.send("rc 3 1500")
        assert wait_until(lambda: seen.speed() < 0.01, 10.0), seen.speed()

        since = mavproxy.mark()
        mavproxy.send("mode GUIDED")
        assert mavproxy.saw("Mode GUIDED", since), mavproxy.lines[since:]
        north, east = seen.north_east()
        mavproxy.send("velocity 0 0.5 0")  # body frame: 0.5 m/s to the right, here south
        assert wait_until(lambda: seen.north_east()[0] < north - 0.3, 10.0), (
            seen.north_east())
        assert abs(seen.north_east()[1] - east) < 0.05, (east, seen.north_east())
        assert abs(seen.yaw() - math.pi / 2) < 0.02  # it did not turn
        mavproxy.send("velocity 0 0 0")
        assert wait_until(lambda: seen.speed() < 0.01, 10.0), seen.speed()

        north, east = seen.north_east()
        mavproxy.send("position 1 0 0")  # 1 m ahead of the rover: here 1 m east
        assert wait_until(lambda: abs(seen.north_east()[1] - east - 1.0) < 0.03
                          and seen.speed() < 0.01, 15.0), ((north, east), seen.north_east())
        assert abs(seen.north_east()[0] - north) < 0.03, ((north, east), seen.north_east())
        assert mavproxy.find(r".*fence breach.*") is None


# --------------------------------------------------------------------------- MAVSDK


async def _first(stream: AsyncIterator[Any], timeout_s: float = 10.0,
                 condition: Callable[[Any], object] = lambda item: True) -> Any:
    """The first item of ``stream`` for which ``condition`` holds (None if it ends first)."""
    async def first() -> Any:
        async for item in stream:
            if condition(item):
                return item
        return None

    return await asyncio.wait_for(first(), timeout_s)


async def _until(condition: Callable[[], object], timeout_s: float) -> object:
    """Poll ``condition`` (a function, or a coroutine function such as MAVSDK's
    ``is_mission_finished``) every 50 ms until it returns something true; that, or None at
    the deadline."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        result = condition()
        if inspect.isawaitable(result):
            result = await result
        if result:
            return result
        await asyncio.sleep(0.05)
    return None


class Watch:
    """The latest item of MAVSDK telemetry streams, each kept by a task of its own: ``pv``
    (LOCAL_POSITION_NED), ``odometry`` (ODOMETRY), ``attitude`` (ATTITUDE, degrees)."""

    def __init__(self, drone: Any) -> None:
        telemetry = drone.telemetry
        self.latest: dict[str, Any] = {}
        self._tasks = [asyncio.ensure_future(self._keep(name, stream)) for name, stream in (
            ("pv", telemetry.position_velocity_ned()), ("odometry", telemetry.odometry()),
            ("attitude", telemetry.attitude_euler()))]

    async def _keep(self, name: str, stream: AsyncIterator[Any]) -> None:
        async for item in stream:
            self.latest[name] = item

    def ready(self) -> bool:
        return len(self.latest) == len(self._tasks)

    def north_east(self) -> tuple[float, float]:
        """The rover's position (metres north, east of where it started)."""
        position = self.latest["pv"].position
        return position.north_m, position.east_m

    def yaw_deg(self) -> float:
        return float(self.latest["attitude"].yaw_deg)

    def close(self) -> None:
        for task in self._tasks:
            task.cancel()


@contextlib.asynccontextmanager
async def _mavsdk_connected(port: int, grpc_port: int) -> AsyncIterator[Any]:
    """A MAVSDK ``System`` (its own mavsdk_server on ``grpc_port``) connected to the rover whose
    ground-station link sends to ``port``; its server is killed and reaped afterwards."""
    from mavsdk import System

    drone = System(port=grpc_port)
    try:
        await drone.connect(system_address=f"udpin://127.0.0.1:{port}")
        await _first(drone.core.connection_state(), 30.0, lambda state: state.is_connected)
        yield drone
    finally:
        server = drone._server_process
        drone._stop_mavsdk_server()  # (kills it, does not wait for it)
        if isinstance(server, subprocess.Popen):
            server.wait(timeout=5.0)


@contextlib.asynccontextmanager
async def _watching(drone: Any) -> AsyncIterator[Watch]:
    watch = Watch(drone)
    try:
        assert await _until(watch.ready, 15.0), watch.latest
        yield watch
    finally:
        watch.close()


async def _arm(drone: Any, timeout_s: float = 30.0) -> None:
    """``action.arm()`` as a pilot does it: again every second while the rover denies it (it
    refuses while it still checks its flight controller's setup)."""
    from mavsdk.action import ActionError, ActionResult

    deadline = time.monotonic() + timeout_s
    while True:
        try:
            await drone.action.arm()
            return
        except ActionError as exc:
            if (exc._result.result != ActionResult.Result.COMMAND_DENIED
                    or time.monotonic() > deadline):
                raise
        await asyncio.sleep(1.0)


async def _armed(drone: Any, timeout_s: float = 10.0) -> bool:
    """The rover's HEARTBEAT (MAVSDK's ``telemetry.armed``) says armed within ``timeout_s``."""
    with contextlib.suppress(asyncio.TimeoutError):
        return bool(await _first(drone.telemetry.armed(), timeout_s, bool))
    return False


GOAL_YAW_DEG = 30.0


@dataclass(frozen=True)
class OffboardSeen:
    """What MAVSDK reported when the rover held its offboard position goal, at ``time_s``
    (Unix seconds): the goal (north, east m), ODOMETRY and LOCAL_POSITION_NED (north, east m)."""

    time_s: float
    goal: tuple[float, float]
    odometry: tuple[float, float]
    local_position: tuple[float, float]


async def _mavsdk_scenario(port: int, grpc_port: int) -> OffboardSeen:
    from mavsdk.offboard import PositionNedYaw, VelocityBodyYawspeed, VelocityNedYaw

    async with _mavsdk_connected(port, grpc_port) as drone, _watching(drone) as watch:
        # Parameters (ArduPilot's float encoding), read back from the rover.
        assert await drone.param.get_param_float("INP_EXPO") == 0.0
        await drone.param.set_param_float("INP_EXPO", 0.25)
        assert await drone.param.get_param_float("INP_EXPO") == 0.25
        assert await drone.param.get_param_int("MIX_ALGO") == 0
        # Arm, then drive by manual control input in MANUAL.
        await _arm(drone)
        assert await _armed(drone)
        start = watch.north_east()[0]

        async def forward(timeout_s: float = 30.0) -> bool:
            deadline = time.monotonic() + timeout_s  # (streaming the stick at 20 Hz)
            while time.monotonic() < deadline:
                await drone.manual_control.set_manual_control_input(0.6, 0.0, 0.5, 0.0)
                await asyncio.sleep(0.05)
                if watch.north_east()[0] > start + 0.3:
                    return True
            return False
        assert await forward(), watch.north_east()
        # Offboard (GUIDED): body velocity right, then NED velocity north, then a position.
        await drone.offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.5, 0.0, 0.0))
        await drone.offboard.start()
        east = watch.north_east()[1]
        assert await _until(lambda: watch.north_east()[1] > east + 0.3, 10.0)
        await drone.offboard.set_velocity_ned(VelocityNedYaw(0.5, 0.0, 0.0, 0.0))
        north = watch.north_east()[0]
        assert await _until(lambda: watch.north_east()[0] > north + 0.3, 10.0)
        here = watch.north_east()
        goal = (here[0] + 0.5, here[1] - 0.5)
        await drone.offboard.set_position_ned(
            PositionNedYaw(goal[0], goal[1], 0.0, GOAL_YAW_DEG))
        reached = await _until(
            lambda: math.dist(watch.north_east(), goal) < 0.05
            and abs(watch.yaw_deg() - GOAL_YAW_DEG) < 2.0
            and math.hypot(watch.latest["pv"].velocity.north_m_s,
                           watch.latest["pv"].velocity.east_m_s) < 0.01, 15.0)
        assert reached, (watch.north_east(), watch.yaw_deg())
        odometry = watch.latest["odometry"].position_body
        seen = OffboardSeen(now_unix_s(), goal, (odometry.x_m, odometry.y_m), watch.north_east())
        await drone.offboard.stop()
        await drone.action.disarm()
        return seen


async def _mavsdk_arm(port: int, grpc_port: int) -> bool:
    async with _mavsdk_connected(port, grpc_port) as drone:
        await _arm(drone)
        return await _armed(drone)


@pytest.mark.slow
def test_mavsdk_behind_mavproxy_with_the_key_arms_the_signed_rover(tmp_path):
    """MAVSDK cannot sign; MAVProxy signs what it forwards (its mavfwd_signing setting). It
    re-packs what it signs with its own system and component ids, so it is given MAVSDK's
    (245, 190): the rover's answers are addressed to those, and MAVSDK takes only its own."""
    pytest.importorskip("mavsdk")
    port, out_port, grpc_port = free_port(), free_port(), free_port(socket.SOCK_STREAM)
    key = key_file(tmp_path, PASSPHRASE)
    with rover(tmp_path, port, "--signing-key", str(key)) as process:
        mavproxy = MavProxy(port, tmp_path, f"--out=udp:127.0.0.1:{out_port}",
                            "--source-system=245", "--source-component=190")
        try:
            assert mavproxy.saw(r"Detected vehicle 1:\d+ on link 0", timeout_s=30.0), (
                mavproxy.lines, process.log())
            since = mavproxy.mark()
            mavproxy.send(f"signing key {PASSPHRASE}")
            assert asyncio.run(asyncio.wait_for(_mavsdk_arm(out_port, grpc_port), 60.0))
            assert mavproxy.saw("ARMED", since), mavproxy.lines[since:]
        finally:
            mavproxy.close()


@pytest.mark.slow
def test_mavsdk_connects_sets_params_arms_and_drives_manual_and_offboard(tmp_path):
    """Offboard velocity (body, then NED) and a position with a heading; the odometry and local
    position MAVSDK reports there agree with the simulator's truth (SIM_STATE, --tlog)."""
    pytest.importorskip("mavsdk")
    port, grpc_port = free_port(), free_port(socket.SOCK_STREAM)
    with rover(tmp_path, port):
        seen = asyncio.run(asyncio.wait_for(_mavsdk_scenario(port, grpc_port), 120.0))
    truth = true_pose_at(true_track(tmp_path), seen.time_s)
    assert math.dist((truth.north_m, truth.east_m), seen.goal) < 0.05, (truth, seen)
    assert abs(math.degrees(truth.yaw_rad) - GOAL_YAW_DEG) < 2.0, truth
    for north, east in (seen.odometry, seen.local_position):
        assert abs(north - truth.north_m) < 0.05, (truth, seen)
        assert abs(east - truth.east_m) < 0.05, (truth, seen)


# --------------------------------------------------------------------------- missions

# Exact in float32 (ORIGIN_LAT/LON travel and are stored as float32).
ORIGIN_LAT_DEG, ORIGIN_LON_DEG = 47.375, 8.5
ORIGIN = GlobalOrigin.from_degrees(ORIGIN_LAT_DEG, ORIGIN_LON_DEG)
"""The origin the tests give the rover through the client (its ORIGIN_LAT/LON)."""


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


async def _mavsdk_mission_scenario(port: int, grpc_port: int) -> None:
    from mavsdk.mission import MissionPlan
    from mavsdk.telemetry import FlightMode

    points = [ORIGIN.to_global(n, e) for n, e in MAVSDK_LEGS_NE]
    # MAVSDK 3.x's mission plugin does not insert ArduPilot's home item 0 (it sends the plan's
    # items from seq 0, and downloads item 0 back as the first item), so a MAVSDK user talking
    # to an ArduPilot vehicle puts a placeholder for home first; without it the first
    # waypoint would be taken as home and never driven to.
    home = _mavsdk_waypoint(ORIGIN.lat_e7 / 1e7, ORIGIN.lon_e7 / 1e7, speed_m_s=math.nan,
                            fly_through=True, radius_m=math.nan)
    plan = MissionPlan([home, *(_mavsdk_waypoint(lat / 1e7, lon / 1e7, speed_m_s=0.5,
                                                 fly_through=False, radius_m=0.05)
                                for lat, lon in points)])
    async with _mavsdk_connected(port, grpc_port) as drone:
        await drone.param.set_param_float("ORIGIN_LAT", ORIGIN_LAT_DEG)
        await drone.param.set_param_float("ORIGIN_LON", ORIGIN_LON_DEG)
        await drone.mission.upload_mission(plan)
        # What the rover stored, item by item (MAVSDK's raw mission download): seq 0 home,
        # then each waypoint followed by its DO_CHANGE_SPEED.
        stored = await drone.mission_raw.download_mission()
        assert len(stored) == 1 + 2 * len(points), stored
        assert [(it.x, it.y) for it in stored[1::2]] == points, stored
        assert {it.command for it in stored[1::2]} == {mavlink.MAV_CMD_NAV_WAYPOINT}, stored
        assert {it.command for it in stored[2::2]} == {mavlink.MAV_CMD_DO_CHANGE_SPEED}, stored

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
        await _arm(drone)
        assert await _armed(drone)
        await drone.mission.start_mission()
        finished = await _until(drone.mission.is_mission_finished, 60.0)
        assert finished, progress
        total = len(plan.mission_items)
        assert await _until(lambda: progress and progress[-1] == (total, total), 10.0), progress
        watcher.cancel()
        mode = await _first(drone.telemetry.flight_mode(), 10.0,
                            lambda mode: mode == FlightMode.HOLD)
        assert mode == FlightMode.HOLD
        await drone.action.disarm()


@pytest.mark.slow
def test_mavsdk_uploads_a_mission_downloads_it_and_runs_it_to_the_end(tmp_path):
    """The origin is given through MAVSDK (ORIGIN_LAT/LON); the simulator's truth (--tlog)
    passes within 10 cm of every waypoint, the first one too, and ends at the last."""
    pytest.importorskip("mavsdk")
    port, grpc_port = free_port(), free_port(socket.SOCK_STREAM)
    with rover(tmp_path, port):
        asyncio.run(asyncio.wait_for(_mavsdk_mission_scenario(port, grpc_port), 120.0))
    track = true_track(tmp_path)
    closest = [min(math.dist((p.north_m, p.east_m), goal) for p in track)
               for goal in MAVSDK_LEGS_NE]
    assert max(closest) < 0.10, closest  # every waypoint visited, the first one too
    end = track[-1]
    assert math.dist((end.north_m, end.east_m), MAVSDK_LEGS_NE[-1]) < 0.10, end


WP_LINE = re.compile(r"(\d+) (\d+) (-?\d+\.\d+) (-?\d+\.\d+) .*")  # MAVProxy's "wp list" rows


def _waypoint_file(path: Path, legs: list[tuple[float, float]]) -> list[tuple[int, int]]:
    """QGC WPL 110 of NAV_WAYPOINTs at ``legs`` (north, east m of :data:`ORIGIN`; the first
    is home) in MAV_FRAME_GLOBAL_RELATIVE_ALT; their (lat_e7, lon_e7)."""
    points = [ORIGIN.to_global(n, e) for n, e in legs]
    rows = ["QGC WPL 110"]
    for seq, (lat, lon) in enumerate(points):
        fields = (seq, int(seq == 0), mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                  mavlink.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, 0, f"{lat / 1e7:.7f}",
                  f"{lon / 1e7:.7f}", 0, 1)
        rows.append("\t".join(str(f) for f in fields))
    path.write_text("\n".join(rows) + "\n")
    return points


@pytest.mark.slow
def test_mavproxy_loads_a_waypoint_file_lists_it_and_clears_it(tmp_path):
    """QGC WPL 110 in a global frame (MAVProxy scales every location command's x/y by 1e7,
    which is right only for global frames), the origin given by ``param set``. Between list
    and clear it also runs the mission; the simulator's truth (--tlog) ends at the last
    waypoint."""
    legs = [(0.0, 0.0), (0.8, 0.0), (0.8, 0.5)]  # home, then two waypoints (north, east)
    points = _waypoint_file(tmp_path / "square.waypoints", legs)
    port = free_port()
    with mavproxy_on_rover(tmp_path, port) as (_process, seen, mavproxy):
        since = mavproxy.mark()
        assert mavproxy.set_param("ORIGIN_LAT", ORIGIN_LAT_DEG, seen), mavproxy.lines[since:]
        assert mavproxy.set_param("ORIGIN_LON", ORIGIN_LON_DEG, seen), mavproxy.lines[since:]

        since = mavproxy.mark()
        mavproxy.send("wp load square.waypoints")
        assert mavproxy.saw("Sent all 3 waypoints", since), mavproxy.lines[since:]
        assert mavproxy.saw("Got MISSION_ACK: TYPE_MISSION: ACCEPTED", since), (
            mavproxy.lines[since:])

        since, items_before = mavproxy.mark(), len(seen.received)
        mavproxy.send("wp list")
        assert mavproxy.saw(r"Requesting 3 waypoints .*", since), mavproxy.lines[since:]

        def rows_listed() -> list[re.Match[str]]:
            found = [m for line in mavproxy.lines[since:] if (m := WP_LINE.fullmatch(line))]
            return found if len(found) >= 3 else []

        listed = wait_until(rows_listed, 15.0)
        assert listed, mavproxy.lines[since:]
        for match, (lat, lon) in zip(listed, points, strict=True):
            assert int(match[1]) == mavlink.MAV_CMD_NAV_WAYPOINT
            assert int(match[2]) == mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT
            assert abs(float(match[3]) - lat / 1e7) < 2e-7, match[0]
            assert abs(float(match[4]) - lon / 1e7) < 2e-7, match[0]
        # The rover's own answers to that listing, as MAVProxy received them.
        answers = [m for m in seen.received[items_before:]
                   if m.get_type() in ("MISSION_ITEM_INT", "MISSION_ITEM")]
        assert [m.seq for m in answers] == [0, 1, 2], answers
        for item, (lat, lon) in zip(answers, points, strict=True):
            assert item.frame == mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT
            assert item.command == mavlink.MAV_CMD_NAV_WAYPOINT
            assert abs(item.x - lat) <= 1 and abs(item.y - lon) <= 1  # MAVProxy truncates

        since = mavproxy.mark()
        assert mavproxy.arm(since), mavproxy.lines[since:]
        assert wait_until(seen.armed, 15.0)
        mavproxy.send("mode AUTO")
        assert mavproxy.saw("AP: Mission started at item 1", since), mavproxy.lines[since:]
        assert mavproxy.saw("AP: Mission complete", since, 30.0), (
            mavproxy.lines[since:], seen.north_east())
        assert mavproxy.saw("Mode HOLD", since), mavproxy.lines[since:]

        since = mavproxy.mark()
        mavproxy.send("wp clear")
        assert mavproxy.saw("Got MISSION_ACK: TYPE_MISSION: ACCEPTED", since), (
            mavproxy.lines[since:])
        since = mavproxy.mark()
        mavproxy.send("wp list")
        assert mavproxy.saw(r"Requesting 0 waypoints .*", since), mavproxy.lines[since:]
    end = true_track(tmp_path)[-1]
    assert math.dist((end.north_m, end.east_m), legs[-1]) < 0.10, end
