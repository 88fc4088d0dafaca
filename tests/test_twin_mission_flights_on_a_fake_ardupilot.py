"""The twin's flights and probes (mecanum_mav/sim/twinmission.py) against a fake ArduPilot
Rover: what the ground station does when the firmware (or the companion) arms, refuses,
completes or stays silent, and how the flight is graded against the truth.

The fake (:class:`FakeArduPilot`) answers as ArduPilot Rover does on its SERIAL1: HEARTBEAT
with its mode, COMMAND_ACK, PreArm STATUSTEXT, HOME_POSITION where it was armed, the mission
protocol, AUTO driving to each waypoint (MISSION_ITEM_REACHED, then "Mission Complete", staying
in AUTO), MANUAL driving from MANUAL_CONTROL, ATTITUDE, EKF_STATUS_REPORT and its EKF's
LOCAL_POSITION_NED (about an origin of its own). Its chassis is its truth (the bridge's
record on the twin). It runs on a real UDP socket in a thread (:class:`FirmwareOnUdp`:
wall-clock time, where the module waits on ``time.monotonic()``), or behind a virtual port in
virtual time (:class:`VirtualPort`) where the module's waits are seconds long (no heartbeat
for 10 s, HOLD refused for 2 s), the module's own clock made the port's where its deadlines and
holds matter (:func:`all_in_virtual_time`)."""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import math
import re
import select
import socket
import threading
import time
from collections.abc import Iterator
from types import SimpleNamespace
from typing import Any

import pytest

from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim import twinmission as tm
from mecanum_mav.sim.groundstation import ScriptedGroundStation
from mecanum_mav.sim.missionrun import MISSION_COMPLETE, MissionRun
from mecanum_mav.sim.process import free_port
from mecanum_mav.sim.twin import Twin
from mecanum_mav.sim.twinbridge import TruthSample

REF = GlobalOrigin.from_degrees(-35.363262, 149.165237)
"""Where the fake's chassis frame (north 0, east 0) is on the earth (SITL's home)."""
POINTS = [(0.6, 0.0), (0.6, 0.6)]
"""A short mission: 0.6 m north, then 0.6 m east (a corner where ArduPilot stops)."""
YAWS: list[float | None] = [None, None]
PREARM = "PreArm: GPS 1: Bad fix"
EKF_ORIGIN = (-5.0, 4.0)
"""Where the fake's EKF has its origin, in the chassis frame (where GPS first came)."""
ALWAYS = 1_000_000
"""Refusals left: all of them."""


# ---------------------------------------------------------------------------- the fake

class FakeArduPilot:
    """ArduPilot Rover as its ground station sees it (module docstring): :meth:`handle` what
    the ground station sent, :meth:`tick` as time passes; both return the packets to send.
    The attributes after the pose are its behaviour; change them before the flight."""

    def __init__(self, now_s: float, north: float = 0.0, east: float = 0.0,
                 yaw_deg: float = 0.0) -> None:
        self.lock = threading.Lock()
        self._mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self._other = mavlink.MAVLink(None, srcSystem=2, srcComponent=1)
        self._t0 = now_s
        self.north, self.east, self.yaw = north, east, math.radians(yaw_deg)
        self.samples = [TruthSample(now_s, 0.0, north, east, self.yaw, 0.0, 0.0)]
        self.received: list[Any] = []
        """Everything the ground station sent."""
        self.received_s: list[float] = []
        """When each of :attr:`received` arrived."""
        self.mode = Mode.HOLD
        self.armed = False
        self.silent = False
        self.prearm_failure: str | None = None
        self.refusals: dict[int, int] = {}
        """Mode -> how many more DO_SET_MODE to it are refused."""
        self.has_home = True
        self.home = _origin_at(north, east)
        self.mission_result = mavlink.MAV_MISSION_ACCEPTED
        self.set_home_result: int | None = mavlink.MAV_RESULT_ACCEPTED
        self.speed_mps = 2.0
        self.pause_s = 0.1
        """At each waypoint it stops this long (a pivot) before the next."""
        self.positioned_at = -math.inf
        """From then on its EKF has an absolute position (uses GPS)."""
        self.heading_error_deg = (12.0, 1.5)
        """Its heading minus the truth: before, and once positioned."""
        self.other_attitude = False
        """Also ATTITUDE from another system (2), its yaw all over the place."""
        self.unpositioned_flags = (mavlink.EKF_ATTITUDE | mavlink.EKF_POS_HORIZ_ABS
                                   | mavlink.EKF_CONST_POS_MODE)
        """EKF_STATUS_REPORT's flags before it is positioned (ArduPilot's EKF3 without GPS:
        constant-position mode); once positioned: attitude and absolute position."""
        self.periods = {"beat": 0.1, "attitude": 0.05, "ekf": 0.1, "position": 0.1}
        """How often (s) it sends HEARTBEAT, ATTITUDE, EKF_STATUS_REPORT, LOCAL_POSITION_NED."""
        self.due = dict.fromkeys(self.periods, now_s)
        """When each of :attr:`periods` is sent next: later to start it late, math.inf never."""
        self.mode_delays: dict[int, float] = {}
        """Mode -> how long (s) after it accepts it that mode takes effect (and shows in its
        HEARTBEAT); at once otherwise."""
        self._pending_mode: tuple[Mode, float] | None = None
        self.items: list[Any] = []
        self._upload: list[Any] = []
        self._target = 0
        self._pause_until = -math.inf
        self.sticks = (0, 0, 0, 0)
        self._last_s = now_s

    # -------------------------------------------------------------- what the GCS sent

    def handle(self, msg: Any, now_s: float) -> list[bytes]:
        self.received.append(msg)
        self.received_s.append(now_s)
        if self.silent:
            return []
        kind = msg.get_type()
        if kind == "COMMAND_LONG":
            return self._command(msg, now_s)
        if kind == "MISSION_COUNT":
            if self.mission_result != mavlink.MAV_MISSION_ACCEPTED:
                return [self._pack(self._mav.mission_ack_encode(255, 190, self.mission_result))]
            self._upload = [None] * msg.count
            return [self._pack(self._mav.mission_request_int_encode(255, 190, 0))]
        if kind == "MISSION_ITEM_INT" and msg.seq < len(self._upload):
            self._upload[msg.seq] = msg
            missing = [k for k, item in enumerate(self._upload) if item is None]
            if missing:
                return [self._pack(self._mav.mission_request_int_encode(255, 190, missing[0]))]
            self.items = list(self._upload)
            return [self._pack(self._mav.mission_ack_encode(
                255, 190, mavlink.MAV_MISSION_ACCEPTED))]
        if kind == "MANUAL_CONTROL":
            self.sticks = (msg.x, msg.y, msg.z, msg.r)
        return []

    def _command(self, msg: Any, now_s: float) -> list[bytes]:
        out: list[bytes] = []
        cmd, result = msg.command, mavlink.MAV_RESULT_ACCEPTED
        if cmd == mavlink.MAV_CMD_COMPONENT_ARM_DISARM and msg.param1 == 1:
            if self.prearm_failure is not None:
                out.append(self._pack(self._mav.statustext_encode(
                    mavlink.MAV_SEVERITY_CRITICAL, self.prearm_failure.encode())))
                result = mavlink.MAV_RESULT_FAILED
            else:
                self.armed = True
                self.home = _origin_at(self.north, self.east)  # home where it is armed
        elif cmd == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            self.armed = False
        elif cmd == mavlink.MAV_CMD_DO_SET_MODE:
            mode = int(msg.param2)
            if self.refusals.get(mode, 0) > 0:
                self.refusals[mode] -= 1
                result = mavlink.MAV_RESULT_FAILED
            else:
                self._pending_mode = (Mode(mode), now_s + self.mode_delays.get(mode, 0.0))
                self._take_mode(now_s)
        elif cmd == mavlink.MAV_CMD_REQUEST_MESSAGE:
            if int(msg.param1) == mavlink.MAVLINK_MSG_ID_HOME_POSITION and self.has_home:
                h = self.home
                out.append(self._pack(self._mav.home_position_encode(
                    h.lat_e7, h.lon_e7, h.alt_mm, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0)))
        elif cmd == mavlink.MAV_CMD_DO_SET_HOME:
            if self.set_home_result is None:  # (never answered)
                return []
            result = self.set_home_result
        return [self._pack(self._mav.command_ack_encode(cmd, result)), *out]

    # -------------------------------------------------------------- as time passes

    def _take_mode(self, now_s: float) -> None:
        if self._pending_mode is not None and now_s >= self._pending_mode[1]:
            self.mode, self._pending_mode = self._pending_mode[0], None
            self._target = 0

    def tick(self, now_s: float) -> list[bytes]:
        dt, self._last_s = now_s - self._last_s, now_s
        self._take_mode(now_s)
        out: list[bytes] = []
        if self.armed and self.mode == Mode.AUTO:
            out += self._drive_auto(now_s, dt)
        elif self.armed and self.mode == Mode.MANUAL:
            x, y, _, r = self.sticks
            forward, right = x / 1000, y / 1000
            self.north += (forward * math.cos(self.yaw) - right * math.sin(self.yaw)) * dt
            self.east += (forward * math.sin(self.yaw) + right * math.cos(self.yaw)) * dt
            self.yaw = _wrap(self.yaw + r / 1000 * dt)
        self.samples.append(TruthSample(now_s, now_s - self._t0, self.north, self.east,
                                        self.yaw, 0.0, 0.0))
        if self.silent:
            return []
        return out + self._streams(now_s)

    def _drive_auto(self, now_s: float, dt: float) -> list[bytes]:
        waypoints = [item for item in self.items[1:]
                     if item.command == mavlink.MAV_CMD_NAV_WAYPOINT]
        if self._target >= len(waypoints) or now_s < self._pause_until:
            return []
        item = waypoints[self._target]
        goal = self._local(item)
        dn, de = goal[0] - self.north, goal[1] - self.east
        left = math.hypot(dn, de)
        step = self.speed_mps * dt
        if left > step:
            self.north += dn / left * step
            self.east += de / left * step
            self.yaw = math.atan2(de, dn)
            return []
        self.north, self.east = goal
        self._target += 1
        self._pause_until = now_s + self.pause_s
        out = [self._pack(self._mav.mission_item_reached_encode(item.seq))]
        if self._target == len(waypoints):
            out += self._mission_complete()
        return out

    def _local(self, item: Any) -> tuple[float, float]:
        """Where a waypoint is in the chassis frame (ArduPilot's: global, about REF)."""
        return REF.to_local(item.x, item.y)

    def _mission_complete(self) -> list[bytes]:
        """What it does after the last waypoint (ArduPilot's: says so, stays in AUTO)."""
        return [self._pack(self._mav.statustext_encode(
            mavlink.MAV_SEVERITY_INFO, tm.ARDUPILOT_MISSION_COMPLETE.encode()))]

    def _streams(self, now_s: float) -> list[bytes]:
        out: list[bytes] = []
        boot_ms = int((now_s - self._t0) * 1000)
        positioned = now_s >= self.positioned_at
        if self._is_due("beat", now_s):
            base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (
                mavlink.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
            out.append(self._pack(self._mav.heartbeat_encode(
                mavlink.MAV_TYPE_GROUND_ROVER, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, base,
                int(self.mode), mavlink.MAV_STATE_ACTIVE)))
        if self._is_due("attitude", now_s):
            error = math.radians(self.heading_error_deg[1 if positioned else 0])
            out.append(self._pack(self._mav.attitude_encode(
                boot_ms, 0, 0, _wrap(self.yaw + error), 0, 0, 0)))
            if self.other_attitude:
                wild = 1.0 if boot_ms % 100 < 50 else -2.0
                out.append(self._other.attitude_encode(boot_ms, 0, 0, wild, 0, 0, 0)
                           .pack(self._other))
        if self._is_due("ekf", now_s):
            flags = (mavlink.EKF_ATTITUDE | mavlink.EKF_POS_HORIZ_ABS if positioned
                     else self.unpositioned_flags)
            out.append(self._pack(self._mav.ekf_status_report_encode(flags, 0, 0, 0, 0, 0)))
        if positioned and self._is_due("position", now_s):
            out.append(self._pack(self._mav.local_position_ned_encode(
                boot_ms, self.north - EKF_ORIGIN[0], self.east - EKF_ORIGIN[1], 0, 0, 0, 0)))
        return out

    def _is_due(self, what: str, now_s: float) -> bool:
        if now_s < self.due[what]:
            return False
        self.due[what] = now_s + self.periods[what]
        return True

    def _pack(self, msg: Any) -> bytes:
        return bytes(msg.pack(self._mav))

    # -------------------------------------------------------------- for the tests

    def modes_asked(self) -> list[int]:
        return [int(m.param2) for m in self.received if m.get_type() == "COMMAND_LONG"
                and m.command == mavlink.MAV_CMD_DO_SET_MODE]

    def uploads(self) -> int:
        return sum(m.get_type() == "MISSION_COUNT" for m in self.received)


class FakeCompanion(FakeArduPilot):
    """The companion as its ground station sees it, where it differs from ArduPilot: it says
    "Flight controller link up" once it hears its flight controller, takes missions in its
    local frame (MAV_FRAME_LOCAL_NED, x and y in 1e-4 m) and holds after the last waypoint,
    saying "Mission complete"."""

    def __init__(self, now_s: float) -> None:
        super().__init__(now_s)
        self._linked = False

    def _local(self, item: Any) -> tuple[float, float]:
        return (item.x / 1e4, item.y / 1e4)

    def _mission_complete(self) -> list[bytes]:
        self.mode = Mode.HOLD
        return [self._pack(self._mav.statustext_encode(mavlink.MAV_SEVERITY_INFO,
                                                       MISSION_COMPLETE.encode()))]

    def tick(self, now_s: float) -> list[bytes]:
        out = super().tick(now_s)
        if out and not self._linked:
            self._linked = True
            out.append(self._pack(self._mav.statustext_encode(
                mavlink.MAV_SEVERITY_INFO, b"Flight controller link up")))
        return out

    def commands(self, until: str) -> list[tuple[int, float]]:
        """(command, param1) of each COMMAND_LONG received before the first ``until``."""
        out = []
        for m in self.received:
            if m.get_type() == until:
                break
            if m.get_type() == "COMMAND_LONG":
                out.append((m.command, m.param1))
        return out


def _origin_at(north: float, east: float) -> GlobalOrigin:
    lat, lon = REF.to_global(north, east)
    return GlobalOrigin(lat, lon)


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


class FakeTwin:
    """What the module asks of a twin: its URLs and the truth (the fake's chassis)."""

    def __init__(self, fake: FakeArduPilot, firmware_url: str = "") -> None:
        self.fake = fake
        self.firmware_url = firmware_url
        self.gcs_url = ""

    def truth(self) -> list[TruthSample]:
        with self.fake.lock:
            return list(self.fake.samples)

    def truth_now(self) -> TruthSample:
        with self.fake.lock:
            return self.fake.samples[-1]


class FirmwareOnUdp:
    """The fake on a real UDP socket, served by a thread: it sends to the port the ground
    station listens on (``url``, as the firmware's SERIAL1 is a UDP client)."""

    def __init__(self, fake: FakeArduPilot) -> None:
        self.fake = fake
        self.gcs_port = free_port(socket.SOCK_DGRAM)
        self.url = f"udpin:127.0.0.1:{self.gcs_port}"
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self._parser = mavlink.MAVLink(None)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while not self._stop.is_set():
            readable = select.select([self.sock], [], [], 0.005)[0]
            now = time.monotonic()
            out: list[bytes] = []
            with self.fake.lock:
                if readable:
                    for msg in self._parser.parse_buffer(self.sock.recv(65536)) or []:
                        out += self.fake.handle(msg, now)
                out += self.fake.tick(now)
            for packet in out:
                with contextlib.suppress(OSError):
                    self.sock.sendto(packet, ("127.0.0.1", self.gcs_port))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self.sock.close()


class VirtualPort:
    """The fake behind a ground station's port in virtual time (10 ms a tick)."""

    TICK_S = 0.01

    def __init__(self, fake: FakeArduPilot, start_s: float) -> None:
        self.fake = fake
        self.t = start_s
        self.mav = mavlink.MAVLink(self, srcSystem=255, srcComponent=190)
        self._to_fake = bytearray()
        self._fake_reads = mavlink.MAVLink(None)
        self._gcs_reads = mavlink.MAVLink(None)
        self.closed = False

    def write(self, data: bytes) -> None:  # (the ground station's MAVLink sends here)
        self._to_fake += data

    def now(self) -> float:
        return self.t

    def pump(self, timeout_s: float) -> list[Any]:
        out = self._exchange()
        end = self.t + max(timeout_s, 0.0)
        while not out and self.t < end:
            self.t = min(end, self.t + self.TICK_S)
            out = self.fake.tick(self.t) + self._exchange()
        return [m for packet in out for m in self._gcs_reads.parse_buffer(packet) or []]

    def _exchange(self) -> list[bytes]:
        data, self._to_fake = bytes(self._to_fake), bytearray()
        msgs = (self._fake_reads.parse_buffer(data) or []) if data else []
        return [packet for msg in msgs for packet in self.fake.handle(msg, self.t)]

    def close(self) -> None:
        self.closed = True


@pytest.fixture
def firmware() -> Iterator[FirmwareOnUdp]:
    """The fake ArduPilot on UDP, standing at (2, 3) facing north."""
    served = FirmwareOnUdp(FakeArduPilot(time.monotonic(), 2.0, 3.0))
    try:
        yield served
    finally:
        served.close()


def on_udp(served: FirmwareOnUdp) -> FakeTwin:
    return FakeTwin(served.fake, served.url)


class GridPort(VirtualPort):
    """A virtual port whose every time is a binary fraction, exact in floating point: ticks
    of 1/64 s from a fake started at :data:`GRID_START_S` with its streams every 1/32 s
    (:func:`on_the_grid`), so that every look at the link ends on a tick and sums of times
    land exactly on a deadline (the boundaries of the module's waits)."""

    TICK_S = 1 / 64


GRID_START_S = 1024.0


def on_the_grid(north: float = 0.0, east: float = 0.0) -> FakeArduPilot:
    """A fake for :class:`GridPort`."""
    fake = FakeArduPilot(GRID_START_S, north, east)
    fake.periods = dict.fromkeys(fake.periods, 1 / 32)
    return fake


def virtual(fake: FakeArduPilot, port_type: type[VirtualPort] = VirtualPort
            ) -> tuple[ScriptedGroundStation, VirtualPort]:
    """A ground station on the fake in virtual time."""
    port = port_type(fake, fake.samples[0].wall_s)
    return ScriptedGroundStation(port), port


def firmware_in_virtual_time(monkeypatch: pytest.MonkeyPatch, fake: FakeArduPilot,
                             port_type: type[VirtualPort] = VirtualPort) -> VirtualPort:
    """The module's ground station on the firmware (``udp_ground_station``) is one on the
    fake in virtual time; its port."""
    gcs, port = virtual(fake, port_type)
    monkeypatch.setattr(tm, "udp_ground_station", lambda url: (gcs, port))
    return port


VIRTUAL_START_S = 2000.0
"""Where virtual time starts for a fake that runs all in virtual time: the same on every
machine, and so are the roundings of its sums (started at the machine's ``time.monotonic()``,
four looks of 0.1 s summed to 0.4 s on one machine and to just less on another)."""


def all_in_virtual_time(monkeypatch: pytest.MonkeyPatch, fake: FakeArduPilot,
                        port_type: type[VirtualPort] = VirtualPort) -> VirtualPort:
    """:func:`firmware_in_virtual_time`, and the module's clock (``time.monotonic()``) is the
    port's: its deadlines and hold times pass in virtual time too."""
    port = firmware_in_virtual_time(monkeypatch, fake, port_type)
    monkeypatch.setattr(tm, "time", SimpleNamespace(monotonic=port.now))
    return port


def arrivals_m(run: MissionRun) -> list[float]:
    return [leg.arrival_error_m for leg in run.legs]


# ---------------------------------------------------------------------------- ArduPilot's AUTO

def test_ardupilots_flight_is_graded_from_where_it_stood_at_auto_its_estimate_from_there_too(
        firmware):
    run, failure = tm.fly_firmware(on_udp(firmware), POINTS, YAWS, 0.0, 10.0)
    assert failure is None
    # the waypoints, uploaded about the home where it was armed, are where it stopped
    assert arrivals_m(run) == [pytest.approx(0.0, abs=0.02)] * 2
    assert run.true_path[-1][:2] == pytest.approx((0.6, 0.6), abs=0.02)
    # its EKF's origin is 7 m south and 1 m west of the start: the estimate is shifted
    assert run.final_estimate == pytest.approx(run.final_truth, abs=0.02)


def test_auto_refused_while_the_ekf_has_no_position_is_asked_again_and_the_flight_ends_disarmed(
        firmware):
    fake = firmware.fake
    with fake.lock:
        fake.refusals[Mode.AUTO] = 2
    _, failure = tm.fly_firmware(on_udp(firmware), POINTS, YAWS, 0.0, 10.0)
    assert failure is None
    assert fake.modes_asked() == [Mode.AUTO] * 3 + [Mode.HOLD]  # HOLD at "Mission Complete"
    assert fake.mode == Mode.HOLD and not fake.armed


def test_arming_refused_fails_the_flight_with_the_last_prearm_message_and_uploads_nothing(
        firmware, monkeypatch):
    monkeypatch.setattr(tm, "ARM_TIMEOUT_S", 0.5)
    fake = firmware.fake
    with fake.lock:
        fake.prearm_failure = PREARM
        fake.positioned_at = math.inf  # (no GPS: no estimate either)
    run, failure = tm.fly_firmware(on_udp(firmware), POINTS, YAWS, 0.0, 10.0)
    assert failure == f"arming refused: {PREARM}"
    assert fake.uploads() == 0 and run.legs == [] and run.final_estimate is None


def test_a_refused_upload_fails_the_flight_and_leaves_the_firmware_in_hold_disarmed(firmware):
    fake = firmware.fake
    with fake.lock:
        fake.mission_result = mavlink.MAV_MISSION_NO_SPACE
        fake.mode = Mode.AUTO  # (still in AUTO from before)
    _, failure = tm.fly_firmware(on_udp(firmware), POINTS, YAWS, 0.0, 10.0)
    assert failure == f"mission upload refused (MISSION_ACK {mavlink.MAV_MISSION_NO_SPACE})"
    assert fake.mode == Mode.HOLD and not fake.armed


def test_auto_refused_for_the_whole_wait_fails_the_flight_naming_the_ekf(firmware, monkeypatch):
    monkeypatch.setattr(tm, "ARM_TIMEOUT_S", 0.3)
    with firmware.fake.lock:
        firmware.fake.refusals[Mode.AUTO] = ALWAYS
    _, failure = tm.fly_firmware(on_udp(firmware), POINTS, YAWS, 0.0, 10.0)
    assert failure == "AUTO refused for 0.3 s (no EKF position?)"
    assert not firmware.fake.armed


def test_a_mission_not_complete_in_time_fails_and_stops_the_firmware_in_hold(firmware):
    fake = firmware.fake
    with fake.lock:
        fake.speed_mps = 0.5  # 1.2 m: 2.4 s, more than it has
    run, failure = tm.fly_firmware(on_udp(firmware), POINTS, YAWS, 0.0, 0.4)
    assert failure == "the mission did not finish in time"
    assert run.legs == []
    assert fake.modes_asked()[-1] == Mode.HOLD and fake.mode == Mode.HOLD and not fake.armed


def test_a_firmware_without_a_home_fails_the_flight_for_want_of_a_gps_fix(firmware, monkeypatch):
    monkeypatch.setattr(tm, "HOME_TIMEOUT_S", 0.2)
    with firmware.fake.lock:
        firmware.fake.has_home = False
    with pytest.raises(RuntimeError, match=r"the firmware has no home \(no GPS fix\?\)"):
        tm.fly_firmware(on_udp(firmware), POINTS, YAWS, 0.0, 10.0)
    assert firmware.fake.uploads() == 0


def test_hold_refused_at_the_missions_end_is_the_flights_failure_its_legs_graded(monkeypatch):
    fake = FakeArduPilot(time.monotonic())
    fake.refusals[Mode.HOLD] = ALWAYS
    firmware_in_virtual_time(monkeypatch, fake)
    run, failure = tm.fly_firmware(FakeTwin(fake), POINTS, YAWS, 0.0, 10.0)
    assert failure == "HOLD refused at the mission's end"
    assert arrivals_m(run) == [pytest.approx(0.0, abs=0.01)] * 2  # (1e-7 degrees: 1 cm)


def test_a_firmware_never_heard_fails_at_once_and_its_ground_station_is_closed(monkeypatch):
    fake = FakeArduPilot(time.monotonic())
    fake.silent = True
    port = firmware_in_virtual_time(monkeypatch, fake)
    with pytest.raises(RuntimeError, match="no heartbeat from the firmware"):
        tm.fly_firmware(FakeTwin(fake), POINTS, YAWS, 0.0, 10.0)
    assert port.closed and fake.received == []


def test_a_hold_shown_late_within_the_flights_time_ends_the_flight_in_hold(monkeypatch):
    fake = FakeArduPilot(VIRTUAL_START_S)
    fake.mode_delays[Mode.HOLD] = 4.0  # (more than the 2 s it gets when the time is up)
    all_in_virtual_time(monkeypatch, fake)
    _, failure = tm.fly_firmware(FakeTwin(fake), POINTS, YAWS, 0.0, 10.0)
    assert failure is None
    assert fake.modes_asked() == [Mode.AUTO, Mode.HOLD] and fake.mode == Mode.HOLD


@pytest.mark.parametrize(("shown_after_s", "failure"),
                         [(1.7, None), (2.1, "HOLD refused at the mission's end")])
def test_with_the_flights_time_up_the_firmware_still_gets_2_s_to_show_hold(
        monkeypatch, shown_after_s, failure):
    """_until_hold: HOLD's HEARTBEAT is waited for what is left of the time, at least 2 s."""
    fake = FakeArduPilot(VIRTUAL_START_S)
    fake.mode_delays[Mode.HOLD] = shown_after_s
    all_in_virtual_time(monkeypatch, fake)
    # 1.2 m at 2 m/s and a pause: "Mission Complete" some 0.7 s after AUTO, of 1 s
    assert tm.fly_firmware(FakeTwin(fake), POINTS, YAWS, 0.0, 1.0)[1] == failure


def test_auto_refused_by_a_quiet_firmware_is_asked_every_half_second_until_the_wait_is_over(
        monkeypatch):
    """The failure's "AUTO refused for N s" is true to within one retry."""
    monkeypatch.setattr(tm, "ARM_TIMEOUT_S", 0.8)
    fake = FakeArduPilot(VIRTUAL_START_S)
    fake.refusals[Mode.AUTO] = ALWAYS
    fake.periods = dict.fromkeys(fake.periods, math.inf)  # one of each, then only answers
    all_in_virtual_time(monkeypatch, fake)
    _, failure = tm.fly_firmware(FakeTwin(fake), POINTS, YAWS, 0.0, 10.0)
    assert failure == "AUTO refused for 0.8 s (no EKF position?)"
    asked_s = [t for m, t in zip(fake.received, fake.received_s, strict=True)
               if m.get_type() == "COMMAND_LONG" and m.command == mavlink.MAV_CMD_DO_SET_MODE
               and m.param2 == Mode.AUTO]
    assert len(asked_s) >= 3
    assert all(b - a <= 0.5 + 1e-6 for a, b in itertools.pairwise(asked_s))
    assert 0.8 < asked_s[-1] - asked_s[0] <= 0.8 + 0.5 + 1e-6


def test_an_estimate_shifted_without_any_estimate_stays_without_one():
    run = MissionRun([], [(0.0, 0.0)])
    tm.shift_estimate(run, (5.0, -4.0))
    assert run.final_estimate is None and run.odometry_path == []


# ---------------------------------------------------------------------------- the companion

HEADINGS: list[float | None] = [None, 90.0]
"""The second waypoint with a heading of its own (east)."""


def test_a_companion_flight_sets_home_here_and_item_1_current_then_flies_the_mission_asked():
    fake = FakeCompanion(time.monotonic())
    gcs, port = virtual(fake)
    run, failure = tm.fly_companion(FakeTwin(fake), POINTS, HEADINGS, 45.0, 10.0, gcs=gcs)
    assert failure is None
    assert arrivals_m(run) == [pytest.approx(0.0, abs=0.02)] * 2
    # before the upload: MAV_CMD_DO_SET_HOME with param1 1 ("use current location"), then
    # MAV_CMD_DO_SET_MISSION_CURRENT to item 1
    assert fake.commands(until="MISSION_COUNT") == [(mavlink.MAV_CMD_DO_SET_HOME, 1.0),
                                                    (mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, 1.0)]
    # the mission asked for (waypoint_mission): home, CONDITION_YAW to the heading, then the
    # waypoints, each with its own heading or none (NaN)
    _, turn, first, second = fake.items
    assert [item.command for item in fake.items] == [
        mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_CONDITION_YAW,
        mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_WAYPOINT]
    assert turn.param1 == 45.0
    assert math.isnan(first.param4) and second.param4 == 90.0
    assert not port.closed


def test_a_ground_station_that_has_heard_the_companion_already_sets_home_at_once():
    fake = FakeCompanion(time.monotonic())
    gcs, port = virtual(fake)
    # one ground station for every mission of a twin: it heard the companion's heartbeat
    # (its first message) before this mission
    assert gcs.wait("HEARTBEAT", timeout_s=1.0) is not None
    called_s = port.now()
    tm.fly_companion(FakeTwin(fake), POINTS, YAWS, 0.0, 10.0, gcs=gcs)
    k = next(k for k, m in enumerate(fake.received) if m.get_type() == "COMMAND_LONG")
    assert fake.received[k].command == mavlink.MAV_CMD_DO_SET_HOME
    assert fake.received_s[k] == called_s


def test_a_companion_flight_without_a_ground_station_opens_one_on_the_twins_url_and_closes_it(
        monkeypatch):
    fake = FakeCompanion(time.monotonic())
    gcs, port = virtual(fake)
    asked: list[str] = []

    def udp_ground_station(url: str) -> tuple[ScriptedGroundStation, VirtualPort]:
        asked.append(url)
        return gcs, port

    monkeypatch.setattr(tm, "udp_ground_station", udp_ground_station)
    twin = FakeTwin(fake)
    twin.gcs_url = "udpin:127.0.0.1:14552"
    run, failure = tm.fly_companion(twin, POINTS, YAWS, 0.0, 10.0)
    assert failure is None and len(run.legs) == 2
    assert asked == [twin.gcs_url] and port.closed


def test_a_companion_flight_without_its_heartbeat_fails_and_keeps_the_ground_station_given():
    fake = FakeArduPilot(time.monotonic())
    fake.silent = True
    gcs, port = virtual(fake)
    called_s = port.now()
    run, failure = tm.fly_companion(FakeTwin(fake), POINTS, YAWS, 0.0, 10.0, gcs=gcs)
    assert failure == "no heartbeat from the vehicle"
    assert port.now() - called_s == pytest.approx(10.0, abs=0.02)  # (_fresh_start: 10 s)
    assert run.legs == [] and not port.closed


def test_a_companion_that_never_answers_set_home_fails_the_flight_saying_so():
    fake = FakeCompanion(time.monotonic())
    fake.set_home_result = None
    gcs, _ = virtual(fake)
    run, failure = tm.fly_companion(FakeTwin(fake), POINTS, YAWS, 0.0, 10.0, gcs=gcs)
    assert failure == "set home refused (None)"
    assert fake.uploads() == 0 and run.legs == []


def test_a_companion_refusing_set_home_fails_the_flight_before_any_upload():
    fake = FakeArduPilot(time.monotonic())
    fake.set_home_result = mavlink.MAV_RESULT_DENIED
    gcs, port = virtual(fake)
    run, failure = tm.fly_companion(FakeTwin(fake), POINTS, YAWS, 0.0, 10.0, gcs=gcs)
    assert failure == f"set home refused ({mavlink.MAV_RESULT_DENIED})"
    assert fake.uploads() == 0 and run.legs == [] and not port.closed


# ---------------------------------------------------------------------------- the heading

def test_the_heading_settles_only_once_the_ekf_uses_gps_and_only_the_firmwares_attitude_counts(
        firmware, monkeypatch):
    monkeypatch.setattr(tm, "SETTLED_FOR_S", 0.5)
    fake = firmware.fake
    with fake.lock:
        fake.positioned_at = time.monotonic() + 0.4
        fake.heading_error_deg = (1.4, 1.5)  # steady before too: that must not count
        fake.other_attitude = True  # another system's wild ATTITUDE: that must not either
    took_s, error_deg = tm.wait_heading_settled(on_udp(firmware), timeout_s=5.0)
    assert error_deg == pytest.approx(1.5, abs=0.01)
    # positioned 0.4 s after the call, then SETTLED_FOR_S less 0.2 s of the band (less the
    # ground station's start, which hears the firmware within 0.1 s)
    assert took_s > 0.5


def test_a_settled_twins_setup_fc_step_ends_only_once_the_firmwares_heading_has_settled(
        firmware, monkeypatch, tmp_path):
    monkeypatch.setattr(tm, "SETTLED_FOR_S", 0.5)
    setup_fc: list[tuple[float, int]] = []  # (its timeout, what the firmware had heard then)

    def run_setup_fc(self: Twin, timeout_s: float) -> None:  # (setup-fc's subprocess)
        setup_fc.append((timeout_s, len(firmware.fake.received)))

    monkeypatch.setattr(Twin, "_setup_fc", run_setup_fc)
    twin = tm.SettledTwin(tmp_path / "ardurover", workdir=tmp_path)
    twin.firmware_url = firmware.url
    monkeypatch.setattr(twin, "truth_now", on_udp(firmware).truth_now)
    twin._setup_fc(42.0)
    assert setup_fc == [(42.0, 0)]  # setup-fc first, with the step's time
    assert twin.heading_error_deg == pytest.approx(1.5, abs=0.01)
    assert 0.2 < twin.settle_s < 2.0


def test_a_heading_never_settled_says_the_last_difference_and_that_the_ekf_has_no_position(
        firmware):
    with firmware.fake.lock:
        firmware.fake.positioned_at = math.inf
    with pytest.raises(RuntimeError, match=r"did not settle within 0\.4 s \(last \+12\.0 deg "
                                           r"from the truth; EKF position none\)"):
        tm.wait_heading_settled(on_udp(firmware), timeout_s=0.4)


def intervals_asked(fake: FakeArduPilot) -> dict[int, int]:
    """Message id -> the interval (us) the ground station asked for with
    MAV_CMD_SET_MESSAGE_INTERVAL."""
    return {int(m.param1): int(m.param2) for m in fake.received
            if m.get_type() == "COMMAND_LONG"
            and m.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL}


def test_the_heading_settles_a_band_time_after_gps_its_difference_the_attitude_less_the_truth(
        monkeypatch):
    """Facing east (the truth's yaw not 0), ATTITUDE at 10 Hz as asked, each with a HEARTBEAT
    and an EKF_STATUS_REPORT in the same datagram; the EKF takes GPS 1 s after the call."""
    start_s = VIRTUAL_START_S
    fake = FakeArduPilot(start_s, 2.0, 3.0, yaw_deg=90.0)
    fake.positioned_at = start_s + 1.0
    fake.periods["attitude"] = 0.1
    all_in_virtual_time(monkeypatch, fake)
    took_s, error_deg = tm.wait_heading_settled(FakeTwin(fake), timeout_s=10.0)
    assert error_deg == pytest.approx(1.5, abs=0.01)  # not the 12 degrees before GPS
    # the band held for SETTLED_FOR_S less the 0.2 s allowance, from when it took GPS
    assert took_s == pytest.approx(1.0 + tm.SETTLED_FOR_S - 0.2, abs=0.15)
    # MAV_CMD_SET_MESSAGE_INTERVAL: ATTITUDE at 10 Hz, EKF_STATUS_REPORT at 2 Hz
    asked = intervals_asked(fake)
    assert asked[mavlink.MAVLINK_MSG_ID_ATTITUDE] == 100_000
    assert asked[mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT] == 500_000


def test_a_firmware_positioned_before_its_first_attitude_settles_from_that_attitude(
        monkeypatch):
    start_s = VIRTUAL_START_S
    fake = FakeArduPilot(start_s)
    fake.due["attitude"] = start_s + 0.5  # (its EKF reports positioned well before)
    all_in_virtual_time(monkeypatch, fake)
    took_s, error_deg = tm.wait_heading_settled(FakeTwin(fake), timeout_s=10.0)
    assert error_deg == pytest.approx(1.5, abs=0.01)
    assert took_s == pytest.approx(0.5 + tm.SETTLED_FOR_S - 0.2, abs=0.1)


@pytest.mark.parametrize("ekf", ["no EKF_STATUS_REPORT", "no absolute position"])
def test_a_steady_heading_without_the_ekfs_absolute_position_never_counts_as_settled(
        monkeypatch, ekf):
    """EKF_POS_HORIZ_ABS is what says it uses GPS; a relative position (optical flow, wheel
    odometry) is not, and a firmware that never says anything is not positioned either."""
    fake = FakeArduPilot(VIRTUAL_START_S)
    fake.positioned_at = math.inf
    fake.heading_error_deg = (1.5, 1.5)
    if ekf == "no EKF_STATUS_REPORT":
        fake.due["ekf"] = math.inf
    else:
        fake.unpositioned_flags = mavlink.EKF_ATTITUDE | mavlink.EKF_POS_HORIZ_REL
    all_in_virtual_time(monkeypatch, fake)
    with pytest.raises(RuntimeError, match=r"within 4 s \(last \+1\.5 deg from the truth; "
                                           r"EKF position none\)$"):
        tm.wait_heading_settled(FakeTwin(fake), timeout_s=4.0)


def test_a_firmware_fallen_silent_fails_the_wait_on_time_without_any_difference(monkeypatch):
    fake = FakeArduPilot(VIRTUAL_START_S)
    fake.periods = dict.fromkeys(fake.periods, math.inf)  # one of each, then only answers
    port = all_in_virtual_time(monkeypatch, fake)
    called_s = port.now()
    with pytest.raises(RuntimeError, match=r"within 0\.4 s \(last \+nan deg from the truth; "
                                           r"EKF position none\)$"):
        tm.wait_heading_settled(FakeTwin(fake), timeout_s=0.4)
    # the 0.4 s run from the first answer (a tick after the call) and end within a look of
    # 0.1 s; one that ends on the dot may take one more (the sum of the looks' floats)
    assert port.now() - called_s <= VirtualPort.TICK_S + 0.4 + 0.1 + 1e-6
    assert port.closed


class WanderingTruth(FakeTwin):
    """A truth whose yaw swings by a degree from one look to the next."""

    looks = 0

    def truth_now(self) -> TruthSample:
        self.looks += 1
        sample = super().truth_now()
        swing = math.radians(0.5 if self.looks % 2 else -0.5)
        return dataclasses.replace(sample, yaw_rad=sample.yaw_rad + swing)


def test_a_heading_out_of_the_band_after_gps_never_settles_and_says_the_ekf_is_positioned(
        monkeypatch):
    fake = FakeArduPilot(VIRTUAL_START_S)
    all_in_virtual_time(monkeypatch, fake)
    with pytest.raises(RuntimeError, match=r"within 4 s \(last [+-]\d\.\d deg from the truth; "
                                           r"EKF position absolute\)$"):
        tm.wait_heading_settled(WanderingTruth(fake), timeout_s=4.0)


def ekf_asked_s(fake: FakeArduPilot) -> float:
    """When the ground station asked for EKF_STATUS_REPORT (the wait's start)."""
    return next(t for m, t in zip(fake.received, fake.received_s, strict=True)
                if m.get_type() == "COMMAND_LONG"
                and m.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL
                and m.param1 == mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT)


def test_the_heading_counts_as_settled_at_the_first_attitude_the_band_has_held_long_enough(
        monkeypatch):
    """On the grid: the EKF takes GPS at an ATTITUDE's instant; the band (from that ATTITUDE)
    has held SETTLED_FOR_S less the 0.2 s allowance exactly one second later."""
    monkeypatch.setattr(tm, "SETTLED_FOR_S", 1.2)
    fake = on_the_grid()
    fake.positioned_at = GRID_START_S + 1 / 64 + 16 / 32  # (ATTITUDEs: 1/64 s on, every 1/32)
    all_in_virtual_time(monkeypatch, fake, GridPort)
    took_s, _ = tm.wait_heading_settled(FakeTwin(fake), timeout_s=10.0)
    assert took_s == fake.positioned_at + 1.0 - ekf_asked_s(fake)


class OneSwerve(FakeTwin):
    """A truth whose yaw swerves by 2 degrees at one look (the 10th) only; when that was."""

    looks = 0
    swerved_s = math.nan

    def truth_now(self) -> TruthSample:
        self.looks += 1
        sample = super().truth_now()
        if self.looks != 10:
            return sample
        self.swerved_s = sample.wall_s
        return dataclasses.replace(sample, yaw_rad=sample.yaw_rad + math.radians(2.0))


def test_a_difference_out_of_the_band_exactly_settled_for_s_ago_still_spoils_the_band(
        monkeypatch):
    """On the grid, SETTLED_FOR_S 1.25 s: the band counts the last SETTLED_FOR_S, both ends
    included; settled at the first ATTITUDE after the swerve has left it."""
    monkeypatch.setattr(tm, "SETTLED_FOR_S", 1.25)
    fake = on_the_grid()
    all_in_virtual_time(monkeypatch, fake, GridPort)
    twin = OneSwerve(fake)
    took_s, _ = tm.wait_heading_settled(twin, timeout_s=10.0)
    assert took_s == twin.swerved_s + 1.25 + 1 / 32 - ekf_asked_s(fake)


def test_a_heading_wait_gives_up_the_moment_its_time_has_passed(monkeypatch):
    fake = on_the_grid()
    port = all_in_virtual_time(monkeypatch, fake, GridPort)
    with pytest.raises(RuntimeError, match=r"did not settle within 0\.5 s"):
        tm.wait_heading_settled(WanderingTruth(fake), timeout_s=0.5)
    assert port.now() - ekf_asked_s(fake) == 0.5


# ---------------------------------------------------------------------------- MANUAL

def test_the_manual_probe_reports_each_steps_motion_in_the_body_frame_at_its_start():
    served = FirmwareOnUdp(FakeArduPilot(time.monotonic(), yaw_deg=90.0))  # facing east
    try:
        forward, rotate = tm.manual_probe(
            on_udp(served), [("forward", 500, 0, 0, 0), ("rotate", 0, 0, 0, 500)], hold_s=0.25)
    finally:
        served.close()
    # 0.5 m/s for about 0.25 s (the threads' scheduling aside), east: forward in the body
    # frame, not right
    assert 0.06 < forward.forward_m < 0.2 and abs(forward.right_m) < 0.005
    assert abs(forward.turn_deg) < 0.1
    # 0.5 rad/s clockwise for about 0.25 s, on the spot
    assert 3.5 < rotate.turn_deg < 12.0
    assert abs(rotate.forward_m) < 0.005 and abs(rotate.right_m) < 0.005
    assert served.fake.mode == Mode.MANUAL and not served.fake.armed  # disarmed after


def stick_runs(fake: FakeArduPilot) -> list[tuple[tuple[int, int, int, int], float]]:
    """The MANUAL_CONTROLs the firmware received, runs of the same (x, y, z, r): each with how
    long from its first to the next run's first."""
    sticks = [((m.x, m.y, m.z, m.r), t) for m, t in zip(fake.received, fake.received_s,
                                                        strict=True)
              if m.get_type() == "MANUAL_CONTROL"]
    starts = [(axes, t) for k, (axes, t) in enumerate(sticks)
              if k == 0 or sticks[k - 1][0] != axes]
    ends = [t for _, t in starts[1:]] + [sticks[-1][1]]
    return [(axes, end - t) for (axes, t), end in zip(starts, ends, strict=True)]


def test_the_manual_probe_holds_each_steps_sticks_then_centres_them_for_as_long(monkeypatch):
    """From (2, 3) facing east, in virtual time; z 0 is Rover's centred throttle."""
    fake = FakeArduPilot(VIRTUAL_START_S, 2.0, 3.0, yaw_deg=90.0)
    all_in_virtual_time(monkeypatch, fake)
    steps = [("forward", 400, 0, 500, 0), ("strafe", 0, 500, 0, 0), ("rotate", 0, 0, 0, 600)]
    forward, strafe, rotate = tm.manual_probe(FakeTwin(fake), steps, hold_s=0.5)
    assert [(s.name, s.x, s.y, s.z, s.r) for s in (forward, strafe, rotate)] == steps
    centre = (0, 0, 0, 0)
    runs = stick_runs(fake)
    assert [axes for axes, _ in runs] == [(400, 0, 500, 0), centre, (0, 500, 0, 0), centre,
                                          (0, 0, 0, 600), centre]
    assert [held_s for _, held_s in runs[:-1]] == [pytest.approx(0.5, abs=0.06)] * 5
    # the fake drives x/1000 m/s forward, y/1000 m/s right, r/1000 rad/s clockwise
    assert (forward.forward_m, forward.right_m) == pytest.approx((0.2, 0.0), abs=0.03)
    assert (strafe.forward_m, strafe.right_m) == pytest.approx((0.0, 0.25), abs=0.03)
    assert rotate.turn_deg == pytest.approx(math.degrees(0.3), abs=2.0)
    assert fake.mode == Mode.MANUAL and not fake.armed


def test_a_manual_steps_sticks_go_out_for_hold_s_and_at_hold_s_they_are_centred(monkeypatch):
    fake = on_the_grid()
    all_in_virtual_time(monkeypatch, fake, GridPort)
    tm.manual_probe(FakeTwin(fake), [("forward", 400, 0, 500, 0)], hold_s=0.5)
    sent = [((m.x, m.y, m.z, m.r), t) for m, t in zip(fake.received, fake.received_s,
                                                      strict=True)
            if m.get_type() == "MANUAL_CONTROL"]
    step_s = [t for axes, t in sent if axes == (400, 0, 500, 0)]
    first_centred_s = next(t for axes, t in sent if axes == (0, 0, 0, 0))
    assert max(step_s) < step_s[0] + 0.5 == first_centred_s


@pytest.mark.parametrize(("refuse", "reason"), [("mode", "MANUAL refused"),
                                                ("arming", f"arming refused: {PREARM}")])
def test_the_manual_probe_stops_at_a_refused_mode_or_arming_with_the_reason(
        firmware, monkeypatch, refuse, reason):
    monkeypatch.setattr(tm, "ARM_TIMEOUT_S", 0.3)
    fake = firmware.fake
    with fake.lock:
        if refuse == "mode":
            fake.refusals[Mode.MANUAL] = ALWAYS
        else:
            fake.prearm_failure = PREARM
    with pytest.raises(RuntimeError, match=f"^{re.escape(reason)}$"):
        tm.manual_probe(on_udp(firmware), [("forward", 500, 0, 0, 0)], hold_s=0.1)
    assert not any(m.get_type() == "MANUAL_CONTROL" for m in fake.received)


def test_a_manual_step_is_described_in_centimetres_and_degrees():
    step = tm.ManualStep("strafe", 0, 500, 0, 0, 0.012, 0.456, -3.26)
    assert step.describe() == ("strafe   x     0 y   500 z     0 r     0: forward     1.2 cm, "
                               "right    45.6 cm, turned    -3.3 deg")
    step = tm.ManualStep("forward", 500, 0, 500, 0, 1.234, -0.05, 0.4)
    assert step.describe() == ("forward  x   500 y     0 z   500 r     0: forward   123.4 cm, "
                               "right    -5.0 cm, turned     0.4 deg")
