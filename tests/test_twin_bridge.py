"""The twin's bridge (mecanum_mav.sim.twinbridge) between a fake firmware on a real UDP socket
and the MuJoCo chassis: lockstep by frame count (a repeated frame is answered again without a
step, a gap is counted, a restart starts the firmware's clock again), malformed packets
ignored, the wheel map and the ESCs, the sensors in NED/FRD, the truth; the bridge in a process
of its own, read through shared memory, gone with the process that started it."""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from support import wait_until

pytest.importorskip("mujoco", reason="the MuJoCo chassis needs the physics extra")

from mecanum_mav.config.params import Params
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.sim.mujocochassis import MujocoChassis
from mecanum_mav.sim.sitljson import encode_servo_packet
from mecanum_mav.sim.twinbridge import (
    BridgeCore,
    BridgeProcess,
    ChassisSensors,
    TruthSample,
    TwinBridge,
    TwinRecord,
    WheelMap,
)

RATE = 1200
NEUTRAL = [1500] * 4
FORWARD = [1750] * 4
G = 9.81


def core(wheel_map=((1, 1.0), (2, 1.0), (3, 1.0), (4, 1.0))) -> BridgeCore:
    params = Params()
    return BridgeCore(MujocoChassis.from_params(params),
                      WheelMap(PwmMap.from_params(params), wheel_map, params["SIM_ESC_DZ"]))


class FakeFirmware:
    """The firmware's side of the JSON backend: a UDP socket that sends servo packets to the
    bridge and reads its answers."""

    def __init__(self, port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(5.0)
        self.bridge = ("127.0.0.1", port)

    def send(self, raw: bytes) -> None:
        self.sock.sendto(raw, self.bridge)

    def frame(self, count: int, pwm=NEUTRAL) -> dict:
        self.send(encode_servo_packet(RATE, count, pwm))
        return json.loads(self.sock.recv(4096))

    def nothing_within(self, timeout_s: float) -> bool:
        self.sock.settimeout(timeout_s)
        try:
            self.sock.recv(4096)
        except TimeoutError:
            return True
        finally:
            self.sock.settimeout(5.0)
        return False


@pytest.fixture
def served() -> Iterator[tuple[TwinBridge, FakeFirmware]]:
    bridge = TwinBridge(core())
    firmware = FakeFirmware(bridge.port)
    try:
        yield bridge, firmware
    finally:
        firmware.sock.close()
        bridge.close()


def test_each_new_frame_steps_the_chassis_one_frame_period_and_answers_its_time(served):
    bridge, firmware = served
    times = [firmware.frame(n)["timestamp"] for n in range(5)]
    assert times == pytest.approx([(n + 1) / RATE for n in range(5)])
    assert bridge.core.stats().frames == 5


def test_a_repeated_frame_count_is_answered_again_without_a_step(served):
    bridge, firmware = served
    first = firmware.frame(0, FORWARD)
    again = firmware.frame(0, FORWARD)
    assert again == first
    stats = bridge.core.stats()
    assert (stats.frames, stats.repeated) == (1, 1)
    assert bridge.core.chassis.time_s == pytest.approx(1 / RATE)


def test_a_gap_in_the_frame_count_is_counted_as_dropped_frames(served):
    bridge, firmware = served
    firmware.frame(0)
    firmware.frame(1)
    answer = firmware.frame(5)
    assert bridge.core.stats().dropped == 3
    assert answer["timestamp"] == pytest.approx(3 / RATE)  # one step per frame answered


def test_a_frame_count_going_back_is_a_restart_that_starts_the_firmwares_clock_again(served):
    bridge, firmware = served
    for n in range(10):
        firmware.frame(n)
    answer = firmware.frame(0)  # a rebooted firmware counts from 0
    stats = bridge.core.stats()
    assert (stats.restarts, stats.dropped) == (1, 0)
    assert answer["timestamp"] == pytest.approx(1 / RATE)
    assert bridge.core.truth_now().time_s == pytest.approx(11 / RATE)  # the physics went on


@pytest.mark.parametrize("raw", [b"", b"garbage", encode_servo_packet(RATE, 0, NEUTRAL)[:-2],
                                 b"\x00\x00" + encode_servo_packet(RATE, 0, NEUTRAL)[2:]],
                         ids=["empty", "text", "short", "magic"])
def test_a_malformed_packet_is_ignored_unanswered_and_the_bridge_goes_on(served, raw):
    bridge, firmware = served
    firmware.frame(0)
    firmware.send(raw)
    assert firmware.nothing_within(0.2)
    assert bridge.core.stats().malformed == 1
    assert firmware.frame(1)["timestamp"] == pytest.approx(2 / RATE)


def test_sticks_forward_drive_the_chassis_north_and_the_truth_records_every_frame():
    bridge = core()
    for n in range(RATE):  # 1 s
        bridge.answer(encode_servo_packet(RATE, n, NEUTRAL if n < 10 else FORWARD))
    truth = bridge.truth()
    assert len(truth) == RATE + 1  # the start and every frame
    assert truth[-1].north_m > 0.2 and abs(truth[-1].east_m) < 0.02
    assert truth[-1].forward_mps > 0.3
    assert [s.time_s for s in truth] == sorted(s.time_s for s in truth)
    assert bridge.truth_now() == truth[-1]


def test_the_sensors_at_rest_read_gravity_as_minus_g_down_the_body_z_axis():
    chassis = MujocoChassis.from_params(Params())
    sensors = ChassisSensors(chassis)
    for _ in range(100):
        chassis.step(1 / RATE, (0.0, 0.0, 0.0, 0.0))
        state = sensors.read()
    assert state.accel_body == pytest.approx((0.0, 0.0, -G), abs=0.05)
    assert state.gyro == pytest.approx((0.0, 0.0, 0.0), abs=1e-3)
    assert state.velocity_ned == pytest.approx((0.0, 0.0, 0.0), abs=1e-3)
    assert state.position_ned == pytest.approx((0.0, 0.0, 0.0), abs=1e-3)


def test_the_sensors_speak_ned_and_frd_forward_acceleration_clockwise_turn_east_velocity():
    chassis = MujocoChassis.from_params(Params())
    sensors = ChassisSensors(chassis)
    accelerating = []
    for _ in range(60):  # 50 ms of full forward: the body accelerates forward
        chassis.step(1 / RATE, (1.0, 1.0, 1.0, 1.0))
        accelerating.append(sensors.read().accel_body[0])
    mean = sum(accelerating) / len(accelerating)
    assert mean > 0.5
    # each frame's own velocity change (the roller contacts make each one noisy): together
    # they add up to the speed gained
    assert mean == pytest.approx(chassis.velocity_body[0] / (60 / RATE), rel=0.1)
    chassis.push(0.0, 0.5, 0.4)  # right at 0.5 m/s, turning clockwise at 0.4 rad/s
    chassis.step(1 / RATE, (0.0, 0.0, 0.0, 0.0))
    state = sensors.read()
    assert state.gyro[2] > 0.3  # FRD z down: clockwise is positive
    assert state.velocity_ned[1] > 0.4  # facing north, moving right is east
    assert state.attitude[2] == pytest.approx(chassis.pose.yaw_rad)


def test_the_wheel_map_takes_each_wheel_from_its_channel_with_its_sign():
    wheels = WheelMap(PwmMap.from_params(Params()), ((5, 1.0), (6, -1.0), (7, 1.0), (8, 1.0)))
    assert wheels.commands([1500] * 16) == (0.0, 0.0, 0.0, 0.0)  # neutral arms the ESCs
    pwm = [1000] * 4 + [2000, 2000, 1250, 1500] + [0] * 8
    assert wheels.commands(pwm) == pytest.approx((1.0, -1.0, -0.5, 0.0))


def test_an_esc_drives_only_after_it_has_seen_neutral_and_no_pulse_is_a_stop():
    wheels = WheelMap(PwmMap.from_params(Params()))
    assert wheels.commands([1000, 2000, 1500, 1500]) == (0.0, 0.0, 0.0, 0.0)  # not armed
    assert wheels.commands([1000, 2000, 1500, 1500]) == (0.0, 0.0, 0.0, 0.0)  # still not
    assert wheels.commands([1500, 1500, 1500, 1500]) == (0.0, 0.0, 0.0, 0.0)
    assert wheels.commands([1000, 2000, 1750, 1500]) == (-1.0, 1.0, 0.5, 0.0)
    assert wheels.commands([0, 2000, 1750, 1500]) == (0.0, 1.0, 0.5, 0.0)  # no signal: stop
    assert wheels.commands([1000, 2000, 1750, 1500])[0] == 0.0  # and not again until neutral


@pytest.mark.parametrize("entry", [((0, 1.0),), ((1, 1.0), (2, 1.0), (3, 1.0), (33, 1.0)),
                                   ((1, 1.0), (2, 0.0), (3, 1.0), (4, 1.0)),
                                   ((1, 1.0), (2, math.nan), (3, 1.0), (4, 1.0))],
                         ids=["three-short", "channel-33", "sign-0", "sign-nan"])
def test_a_bad_wheel_map_is_refused(entry):
    with pytest.raises(ValueError):
        WheelMap(PwmMap.from_params(Params()), entry)


def test_the_real_time_factor_is_physics_seconds_over_wall_seconds_between_frames():
    clock = iter([0.0, 10.0, 10.5, 11.0]).__next__  # start, then three frames
    bridge = BridgeCore(MujocoChassis.from_params(Params()),
                        WheelMap(PwmMap.from_params(Params())), clock=clock)
    for n in range(3):
        bridge.answer(encode_servo_packet(2, n, NEUTRAL))  # 0.5 s frames
    stats = bridge.stats()
    assert stats.physics_s == pytest.approx(1.0)  # from the first frame answered to the last
    assert stats.real_time_factor == pytest.approx(1.0)


def sample(k: float) -> TruthSample:
    return TruthSample(k, k, k, k, k, k, k)


def test_the_record_keeps_the_last_capacity_frames_oldest_first():
    record = TwinRecord(np.zeros(TwinRecord.size(3)))
    for k in range(5):
        record.add(sample(k))
    assert [s.time_s for s in record.truth()] == [2.0, 3.0, 4.0]
    assert record.truth_now() == sample(4)
    assert record.truth_array().shape == (3, 7)


def test_the_bridge_process_answers_the_firmware_and_this_process_reads_its_truth():
    bridge = BridgeProcess(Params().as_dict())
    firmware = FakeFirmware(bridge.port)
    try:
        for n in range(5):
            firmware.frame(n, FORWARD if n else NEUTRAL)
        stats = bridge.record.stats()
        assert (stats.frames, stats.wheel_pulses) == (5, (1750, 1750, 1750, 1750))
        assert bridge.record.truth_now().time_s == pytest.approx(5 / RATE)
        pid = bridge.pid
    finally:
        firmware.sock.close()
        bridge.close()
    assert not bridge.alive() and not process_runs(pid)
    assert len(bridge.record.truth()) == 6  # (still readable after close: the start + 5)


def process_runs(pid: int | None) -> bool:
    """Whether ``pid`` is a live process (not gone, not a zombie)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ", 1)[1][0] != "Z"
    except (OSError, IndexError):
        return False


def test_the_bridge_process_ends_by_itself_when_the_process_that_started_it_is_killed(
        tmp_path):
    script = ("import sys, time\n"
              "from mecanum_mav.config.params import Params\n"
              "from mecanum_mav.sim.twinbridge import BridgeProcess\n"
              "bridge = BridgeProcess(Params().as_dict())\n"
              "print(bridge.pid, flush=True)\n"
              "time.sleep(60)\n")
    holder = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                              start_new_session=True)
    try:
        assert holder.stdout is not None
        pid = int(holder.stdout.readline())
        assert process_runs(pid)
        setup = Path(Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")[3].decode())
        os.killpg(holder.pid, signal.SIGKILL)  # (the bridge is in a session of its own)
        holder.wait(timeout=10)
        assert wait_until(lambda: not process_runs(pid), 5.0), f"bridge {pid} still runs"
        assert wait_until(lambda: not setup.parent.exists(), 5.0), "its files are left"
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(holder.pid, signal.SIGKILL)
        holder.wait(timeout=10)


# ---------------------------------------------------------------------------- the record's edges

def test_a_record_before_any_frame_has_no_truth_and_no_load_figure():
    from mecanum_mav.sim.twinrecord import TwinRecord
    record = TwinRecord.local(capacity=4)
    with pytest.raises(LookupError, match="no truth recorded yet"):
        record.truth_now()
    stats = record.stats()
    assert stats.frames == 0
    assert math.isnan(stats.busy_fraction) and math.isnan(stats.real_time_factor)


def test_a_record_without_room_for_one_frame_is_refused():
    import numpy as np

    from mecanum_mav.sim.twinrecord import TwinRecord
    with pytest.raises(ValueError, match="at least one frame"):
        TwinRecord(np.zeros(TwinRecord.size(0)))
