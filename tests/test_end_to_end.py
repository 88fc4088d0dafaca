"""The whole product on loopback: ground station -> companion -> simulated flight controller.

Ground truth comes from the simulator (its true pose) or, across processes, from the
simulated flight controller's own telemetry recorded in the companion's tlog.
"""

from __future__ import annotations

import os
import select
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import simulated_rover
from mavpeers import channels, ground_station

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.io.links import mavlink, mavutil

ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM


def arm(gcs, timeout_s: float = 5.0) -> None:
    """Arm once the companion accepts it (it waits for the flight controller's heartbeat)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        since = gcs.mark()
        gcs.mav.command_long_send(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
        ack = gcs.wait("COMMAND_ACK", lambda m: m.command == ARM, 0.5, since)
        if ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED:
            return
        gcs.pump(0.2)
    raise AssertionError("the companion never accepted arming")


def stream_sticks(gcs, until, x: int = 0, y: int = 0, r: int = 0, timeout_s: float = 5.0):
    """Send MANUAL_CONTROL at 50 Hz until ``until()`` returns something truthy."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        gcs.mav.manual_control_send(1, x, y, 500, r, 0)
        gcs.pump(0.02)
        result = until()
        if result:
            return result
    return None


@pytest.fixture
def in_process():
    """Companion and simulator in this process, on a real UDP link between them."""
    with simulated_rover() as rover:
        yield rover


@pytest.mark.parametrize(
    ("x", "y", "r", "moved"),
    [(1000, 0, 0, lambda s: s.pose.x_m > 0.3 and abs(s.pose.y_m) < 0.01),
     (0, 1000, 0, lambda s: s.pose.y_m > 0.3 and abs(s.pose.x_m) < 0.01),
     (0, 0, 1000, lambda s: s.pose.yaw_rad > 0.5 and abs(s.pose.x_m) < 0.01)],
    ids=["forward-goes-north", "strafe-right-goes-east", "clockwise-turns-clockwise"],
)
def test_sticks_move_the_simulated_chassis_the_commanded_way(in_process, x, y, r, moved):
    sim, gcs, _ = in_process
    arm(gcs)
    state = stream_sticks(gcs, lambda: moved(sim.snapshot()) and sim.snapshot(), x, y, r)
    assert state is not None, sim.snapshot().pose
    assert state.overrides_ignored == 0


def test_stopping_the_sticks_stops_the_simulated_chassis(in_process):
    sim, gcs, _ = in_process
    arm(gcs)
    assert stream_sticks(gcs, lambda: sim.snapshot().velocity_body[0] > 0.5, 1000)
    stopped = sim.wait_for(lambda s: abs(s.velocity_body[0]) < 0.01, timeout_s=3.0)
    assert stopped is not None  # input timeout (0.5 s) -> neutral -> motors spin down


def read_tlog(path: Path) -> list:
    """Every message of a tlog, read the way MAVProxy and Mission Planner read it."""
    log = mavutil.mavlink_connection(str(path))
    out = []
    while (msg := log.recv_match()) is not None:
        out.append(msg)
    log.close()
    return out


def start_cli(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "mecanum_mav.app.cli", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_mecanum_mav_sim_drives_the_simulated_chassis_forward(tmp_path):
    gcs = ground_station()
    tlog = tmp_path / "sim.tlog"
    proc = start_cli("sim", "--gcs", gcs.url, "--tlog", str(tlog))
    try:
        assert gcs.wait("HEARTBEAT", timeout_s=10.0), proc.stderr
        arm(gcs)
        assert stream_sticks(gcs, lambda: False, 1000, timeout_s=1.5) is None  # 1.5 s forward
    finally:
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=10)
        gcs.close()
    assert proc.returncode == 0, err
    assert "point a ground station at UDP" in out
    messages = read_tlog(tlog)
    distances = [m.distance[:4] for m in messages if m.get_type() == "WHEEL_DISTANCE"]
    assert distances and min(distances[-1]) > 0.3, distances[-1:]  # every wheel rolled forward
    overrides = [channels(m)[:4] for m in messages if m.get_type() == "RC_CHANNELS_OVERRIDE"]
    assert [2000] * 4 in overrides
    assert overrides[-1] == [0, 0, 0, 0] and overrides[-2] == [1500] * 4  # neutral, release


def test_simfc_runs_as_its_own_process_behind_a_real_udp_link():
    proc = start_cli("simfc", "--listen", "udpin:127.0.0.1:0")
    gcs = ground_station()
    companion = None
    try:
        line = proc.stdout.readline()
        port = int(line.rsplit("port ", 1)[1].rstrip(")\n"))
        companion = Companion(Params(), gcs.url, f"udpout:127.0.0.1:{port}")
        companion.start()
        arm(gcs)
        moved = stream_sticks(gcs, lambda: companion.fc.received > 50, 1000)
        assert moved
    finally:
        if companion is not None:
            companion.close()
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=10)
        gcs.close()
    assert proc.returncode == 0


class SerialFlightController:
    """A flight controller on the master side of a pseudo-terminal (the USB cable)."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        self.path = os.ttyname(self.slave)
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self.mav.robust_parsing = True
        self.messages: list = []

    def heartbeat(self) -> None:
        msg = self.mav.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,
                                        mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3)
        os.write(self.master, msg.pack(self.mav))

    def pump(self, timeout_s: float) -> None:
        if select.select([self.master], [], [], timeout_s)[0]:
            data = os.read(self.master, 4096)
            self.messages += [m for m in self.mav.parse_buffer(data) or []
                              if m.get_type() != "BAD_DATA"]

    def close(self) -> None:
        os.close(self.master)
        os.close(self.slave)


def test_flight_controller_link_works_over_a_serial_device():
    fc = SerialFlightController()
    gcs = ground_station()
    companion = Companion(Params(), gcs.url, f"{fc.path},115200")
    companion.start()
    try:
        assert gcs.wait("HEARTBEAT", timeout_s=3.0)
        deadline = time.monotonic() + 5.0
        armed = False
        while not armed and time.monotonic() < deadline:
            fc.heartbeat()
            fc.pump(0.05)
            gcs.mav.command_long_send(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
            ack = gcs.wait("COMMAND_ACK", lambda m: m.command == ARM, 0.2, gcs.mark())
            armed = ack is not None and ack.result == 0
        assert armed, "no arming: the companion never heard the serial heartbeat"
        seen = None
        while seen is None and time.monotonic() < deadline:
            gcs.mav.manual_control_send(1, 0, 1000, 500, 0, 0)
            fc.heartbeat()
            fc.pump(0.05)
            seen = next((m for m in fc.messages if m.get_type() == "RC_CHANNELS_OVERRIDE"
                         and channels(m)[:4] == [2000, 1000, 1000, 2000]), None)
        assert seen is not None and seen.get_srcSystem() == 255
        assert struct.unpack("<B", seen.get_msgbuf()[:1])[0] == 0xFD
    finally:
        companion.close()
        gcs.close()
        fc.close()
