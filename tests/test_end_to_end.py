"""The whole product: ground station -> companion -> simulated flight controller.

Behaviour runs in the lockstep harness (core + simulated board + scripted ground station in
virtual time: exact and fast). What only real I/O can show stays on real sockets: the
``mecanum-mav sim`` and ``mecanum-mav simfc`` processes and the serial flight-controller
link. There, ground truth comes from the simulated flight controller's own telemetry, in the
companion's tlog or relayed by its odometry.
"""

from __future__ import annotations

import signal
import struct
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import pytest
from support import PtyFlightController, at_most_every, wait_until
from support import override_channels as channels

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.io.links import mavlink, mavutil
from mecanum_mav.protocol.rcoverride import override_fields, release_fields
from mecanum_mav.sim.groundstation import ScriptedGroundStation, udp_ground_station
from mecanum_mav.sim.lockstep import Lockstep

ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
STICK_PERIOD_S = 0.02
"""A ground station sends MANUAL_CONTROL at 50 Hz."""
WHEELS = (1, 2, 3, 4)
"""RC channels of FL, FR, RL, RR (the default MOT_*_CH)."""
NEUTRAL = override_fields(WHEELS, [1500] * 4)
RELEASE = release_fields(WHEELS)
T = TypeVar("T")


def fc_link_up(gcs: ScriptedGroundStation, timeout_s: float = 5.0) -> bool:
    """Whether the companion said its flight-controller link is up (from its first message
    on): it accepts arming only then."""
    return gcs.wait("STATUSTEXT", lambda m: m.text == "Flight controller link up", timeout_s,
                    since=0) is not None


# --------------------------------------------------------------------------- virtual time


def stream_sticks(h: Lockstep, until: Callable[[], T], x: int = 0, y: int = 0, r: int = 0,
                  timeout_s: float = 5.0) -> T | None:
    """MANUAL_CONTROL at 50 Hz of virtual time until ``until()`` returns something truthy
    (returned), or None after ``timeout_s``; the stream stops either way."""
    stop = h.every(STICK_PERIOD_S, lambda now_s: h.gcs.mav.manual_control_send(1, x, y, 500, r,
                                                                               0))
    try:
        return h.run_until(until, timeout_s)
    finally:
        stop()


def sticks_for(h: Lockstep, seconds: float, x: int = 0, y: int = 0, r: int = 0) -> float:
    """MANUAL_CONTROL at 50 Hz for ``seconds`` of virtual time; the time of the last one."""
    sent = [h.now_s]

    def send(now_s: float) -> None:
        h.gcs.mav.manual_control_send(1, x, y, 500, r, 0)
        sent.append(now_s)

    stop = h.every(STICK_PERIOD_S, send)
    h.run_for(seconds)
    stop()
    return sent[-1]


@pytest.mark.parametrize(
    ("x", "y", "r", "moved", "pulses"),
    [(1000, 0, 0, lambda s: s.pose.x_m > 0.3 and abs(s.pose.y_m) < 1e-3
      and abs(s.pose.yaw_rad) < 1e-3, [2000, 2000, 2000, 2000]),
     (0, 1000, 0, lambda s: s.pose.y_m > 0.3 and abs(s.pose.x_m) < 1e-3
      and abs(s.pose.yaw_rad) < 1e-3, [2000, 1000, 1000, 2000]),
     (0, 0, 1000, lambda s: s.pose.yaw_rad > 0.5 and abs(s.pose.x_m) < 1e-3
      and abs(s.pose.y_m) < 1e-3, [2000, 1000, 2000, 1000])],
    ids=["forward-goes-north", "strafe-right-goes-east", "clockwise-turns-clockwise"],
)
def test_sticks_move_the_simulated_chassis_the_commanded_way(harness, x, y, r, moved, pulses):
    h = harness
    h.gcs.arm()
    start_s = h.now_s
    state = stream_sticks(h, lambda: moved(h.truth()) and h.truth(), x, y, r, timeout_s=2.0)
    assert state is not None, h.truth().pose
    assert state.overrides_ignored == 0
    driving = [o.channels for o in h.overrides_since(start_s)]
    # FL = x + y + r, FR = x - y - r, RL = x - y + r, RR = x + y - r, full stick = 500 us
    assert driving[-1] == override_fields(WHEELS, pulses)
    assert all(o.source_system == 255 for o in h.overrides)


def test_stopping_the_sticks_stops_the_simulated_chassis(harness):
    h = harness
    h.gcs.arm()
    assert stream_sticks(h, lambda: h.truth().velocity_body[0] > 0.5, 1000)
    last_stick_s = h.now_s  # the stream stopped here
    stopped = h.run_until(lambda: abs(h.truth().velocity_body[0]) < 0.01 and h.truth(), 3.0)
    assert stopped is not None
    # FS_INPUT_TMO (0.5 s) without input -> neutral -> the motors spin down
    first_neutral = next(o for o in h.overrides_since(last_stick_s) if o.channels == NEUTRAL)
    # at the first output refresh (OUT_RATE, 20 Hz) after the timeout
    assert 0.5 - 1e-9 <= first_neutral.time_s - last_stick_s <= 0.5 + 0.05 + h.dt_s
    assert all(o.channels == NEUTRAL for o in h.overrides_since(first_neutral.time_s))
    assert stopped.time_s - first_neutral.time_s < 1.0


# --------------------------------------------------------------------------- real sockets


def stream_real(gcs: ScriptedGroundStation, until: Callable[[], T], x: int = 0, y: int = 0,
                r: int = 0, timeout_s: float = 5.0) -> T | None:
    """MANUAL_CONTROL at 50 Hz of wall-clock time on a real link until ``until()`` returns
    something truthy (returned), or None after ``timeout_s``."""
    stick = at_most_every(STICK_PERIOD_S, lambda: gcs.mav.manual_control_send(1, x, y, 500, r, 0))

    def pump(wait_s: float) -> None:
        stick()
        gcs.pump(wait_s)

    return wait_until(until, timeout_s, pump=pump, pump_s=STICK_PERIOD_S)


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


def test_mecanum_mav_sim_drives_forward_and_sigterm_ends_with_neutral_then_release(tmp_path):
    gcs, port = udp_ground_station()
    tlog = tmp_path / "sim.tlog"
    proc = start_cli("sim", "--gcs", port.url, "--tlog", str(tlog))
    try:
        assert gcs.wait("HEARTBEAT", timeout_s=10.0), proc.stderr
        assert fc_link_up(gcs)
        gcs.arm()
        forward = time.monotonic() + 1.5
        assert stream_real(gcs, lambda: time.monotonic() > forward, 1000, timeout_s=3.0)
        # SIGTERM while driving, and the pilot keeps pushing the stick until the process is
        # gone: the shutdown sequence must still be the last word.
        proc.send_signal(signal.SIGTERM)
        stream_real(gcs, lambda: proc.poll() is not None, 1000, timeout_s=10.0)
        out, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        port.close()
    assert proc.returncode == 0, err
    assert "point a ground station at UDP" in out
    messages = read_tlog(tlog)
    distances = [m.distance[:4] for m in messages if m.get_type() == "WHEEL_DISTANCE"]
    assert distances and min(distances[-1]) > 0.3, distances[-1:]  # every wheel rolled forward
    overrides = [channels(m) for m in messages if m.get_type() == "RC_CHANNELS_OVERRIDE"]
    assert overrides[-4] == override_fields(WHEELS, [2000] * 4)  # driving when it was stopped
    sticks = [m for m in messages if m.get_type() == "MANUAL_CONTROL"]
    assert len(sticks) > 50 and sticks[-1].x == 1000  # the pilot's sticks (the lane's too)
    # then exactly: neutral, neutral, release, and nothing at all after them
    assert [channels(m) if m.get_type() == "RC_CHANNELS_OVERRIDE" else m.get_type()
            for m in messages[-3:]] == [NEUTRAL, NEUTRAL, RELEASE]


def test_simfc_runs_as_its_own_process_behind_a_real_udp_link():
    proc = start_cli("simfc", "--listen", "udpin:127.0.0.1:0")
    gcs, port = udp_ground_station()
    companion = None
    params = Params()
    params.update({"ODOM_SRC": 1})  # odometry from the flight controller's WHEEL_DISTANCE only
    try:
        line = proc.stdout.readline()
        fc_port = int(line.rsplit("port ", 1)[1].rstrip(")\n"))
        companion = Companion(params, port.url, f"udpout:127.0.0.1:{fc_port}")
        companion.start()
        assert fc_link_up(gcs)
        gcs.arm()
        since = gcs.mark()

        def rolled():  # the simulated board's encoders, relayed by the companion's odometry
            return next((m for m in gcs.received("WHEEL_DISTANCE", since)
                         if min(m.distance[:4]) > 0.3), None)

        wheels = stream_real(gcs, rolled, 1000, timeout_s=5.0)
        assert wheels is not None, gcs.received("WHEEL_DISTANCE", since)[-1:]
        assert max(wheels.distance[:4]) - min(wheels.distance[:4]) < 0.01  # all alike: straight
        local = gcs.wait("LOCAL_POSITION_NED", lambda m: m.x > 0.3, 1.0, since)
        assert local is not None and abs(local.y) < 0.01
    finally:
        if companion is not None:
            companion.close()
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=10)
        port.close()
    assert proc.returncode == 0


def test_flight_controller_link_works_over_a_serial_device():
    fc = PtyFlightController()  # a flight controller on the master side of a pty (the cable)
    gcs, port = udp_ground_station()
    companion = Companion(Params(), port.url, f"{fc.path},115200")
    companion.start()
    try:
        assert gcs.wait("HEARTBEAT", timeout_s=3.0)

        def armed() -> bool:
            fc.pump(0.05)
            ack = gcs.command(ARM, 1, timeout_s=0.2)
            return ack is not None and ack.result == 0

        assert wait_until(armed, 5.0), "no arming: the companion never heard the serial heartbeat"

        def strafing() -> Any:
            gcs.mav.manual_control_send(1, 0, 1000, 500, 0, 0)
            fc.pump(0.05)
            return next((m for m in fc.messages if m.get_type() == "RC_CHANNELS_OVERRIDE"
                         and channels(m)[:4] == [2000, 1000, 1000, 2000]), None)

        seen = wait_until(strafing, 5.0)
        assert seen is not None and seen.get_srcSystem() == 255
        assert struct.unpack("<B", seen.get_msgbuf()[:1])[0] == 0xFD
    finally:
        companion.close()
        port.close()
        fc.close()
