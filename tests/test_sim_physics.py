"""The built-in board on the MuJoCo chassis (``physics="mujoco"``, ``sim --physics mujoco``):
driven through the companion in the lockstep harness and as a real process; and what happens
without MuJoCo installed."""

from __future__ import annotations

import math
import sys
import time

import pytest
from conftest import lockstep
from support import at_most_every, wait_until

from mecanum_mav.app.cli import main
from mecanum_mav.config.params import Params
from mecanum_mav.io.links import mavutil
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.sim import physics
from mecanum_mav.sim.groundstation import udp_ground_station
from mecanum_mav.sim.process import CompanionProcess

mujoco_chassis = pytest.importorskip("mecanum_mav.sim.mujocochassis")


def test_manual_sticks_drive_the_mujoco_chassis_and_the_board_reports_it():
    h = lockstep(physics="mujoco")
    chassis = h.board.chassis
    assert isinstance(chassis, mujoco_chassis.MujocoChassis)
    sent = []
    board_on_time = h.board.on_time

    def spy(now_s, outbox):  # what the board sends the companion
        board_on_time(now_s, outbox)
        messages = outbox.take()
        sent.extend(messages)
        for msg in messages:
            outbox.send(msg)

    h.board.on_time = spy
    h.gcs.arm()
    stop = h.every(0.05, lambda now_s: h.gcs.sticks(1000, 0, 0))  # full forward, 2 s
    h.run_for(2.0)
    stop()
    truth = h.truth().pose
    # WHL_MAX_SPD 1 m/s for 2 s, less the motor lag (0.08 s) and the start
    assert 1.7 < truth.x_m < 2.0
    assert abs(truth.y_m) < 0.01 and abs(truth.yaw_rad) < 0.01
    assert truth == chassis.pose
    last = {msg.get_type(): msg for msg in sent}
    # WHEEL_DISTANCE: the chassis's encoders (at most one 0.1 s period old)
    assert list(last["WHEEL_DISTANCE"].distance[:4]) == pytest.approx(
        chassis.wheel_distances_m, abs=0.11)
    # ATTITUDE: the body's yaw, roll and pitch
    roll, pitch = chassis.roll_pitch
    assert (last["ATTITUDE"].roll, last["ATTITUDE"].pitch) == pytest.approx((roll, pitch),
                                                                            abs=1e-3)
    assert last["ATTITUDE"].yaw == pytest.approx(truth.yaw_rad, abs=1e-3)
    # SIM_STATE: the chassis's true pose (5 Hz: at most 0.2 s old)
    origin = GlobalOrigin.from_degrees(0.0, 0.0)
    north, east = origin.to_local(last["SIM_STATE"].lat_int, last["SIM_STATE"].lon_int)
    assert north == pytest.approx(truth.x_m, abs=0.21) and abs(east) < 0.01


def test_sim_physics_mujoco_prints_its_real_time_factor_and_simulates_the_chassis(tmp_path):
    gcs, port = udp_ground_station()  # (bound to port 0 first: the OS picks the port)
    tlog = tmp_path / "sim.tlog"
    sim = CompanionProcess.sim(port.url, tmp_path, "--physics", "mujoco", "--tlog", str(tlog))
    try:
        assert gcs.wait("HEARTBEAT", timeout_s=15.0), "no heartbeat"
        assert gcs.wait("STATUSTEXT", lambda m: m.text == "Flight controller link up", 5.0,
                        since=0)
        gcs.arm()
        stick = at_most_every(0.02, lambda: gcs.mav.manual_control_send(1, 1000, 0, 500, 0, 0))

        def pump(wait_s: float) -> None:
            stick()
            gcs.pump(wait_s)

        rolled = wait_until(lambda: next((m for m in gcs.received("WHEEL_DISTANCE")
                                          if min(m.distance[:4]) > 0.5), None),
                            10.0, pump=pump, pump_s=0.02)
        assert rolled is not None, gcs.received("WHEEL_DISTANCE")[-1:]
        code = sim.stop(timeout_s=15.0)
    finally:
        sim.kill()
        port.close()
    out = sim.log(tail=1_000_000)
    assert code == 0, out
    factor = float(out.split("MuJoCo chassis: ", 1)[1].split("x real time", 1)[0])
    print(f"sim --physics mujoco: {factor:.1f}x real time")
    assert factor >= physics.MIN_REAL_TIME_FACTOR
    log = mavutil.mavlink_connection(str(tlog))
    truth = []
    while (msg := log.recv_match(type="SIM_STATE")) is not None:
        truth.append(GlobalOrigin.from_degrees(0.0, 0.0).to_local(msg.lat_int, msg.lon_int))
    log.close()
    assert truth and truth[-1][0] > 0.4 and abs(truth[-1][1]) < 0.02  # true track: north


def test_without_mujoco_the_chassis_and_sim_refuse_with_the_install_hint(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "mujoco", None)  # (import mujoco raises ImportError)
    monkeypatch.delitem(sys.modules, "mecanum_mav.sim.mujocochassis")
    with pytest.raises(physics.PhysicsUnavailableError, match=r"pip install 'mecanum-mav\["):
        physics.make_chassis(Params(), physics="mujoco")
    started = time.monotonic()
    assert main(["sim", "--physics", "mujoco", "--gcs", "udpout:127.0.0.1:9"]) == 2
    assert time.monotonic() - started < 5.0
    err = capsys.readouterr().err
    assert "mujoco" in err and "pip install 'mecanum-mav[physics]'" in err
    assert math.isfinite(physics.make_chassis(Params()).pose.x_m)  # the kinematic one stays
