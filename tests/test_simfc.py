"""The simulated ArduPilot flight controller, over real UDP sockets on 127.0.0.1.

The simulator listens on ``udpin:127.0.0.1:0``; a pymavlink peer sending as the ground station
(system 255, component 190) drives it with RC_CHANNELS_OVERRIDE addressed to system 1,
component 1. Tests wait on conditions with deadlines (``wait_for``, or a selector on the peer
link), never on blind sleeps.
"""

from __future__ import annotations

import math
import random
import re
import select
import selectors
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from typing import Any

import pytest
from support import wait_until

from mecanum_mav.app.cli import serve_simfc as main
from mecanum_mav.config.params import Params
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.io.links import Link, mavlink, open_link
from mecanum_mav.protocol.heartbeat import send_gcs_heartbeat
from mecanum_mav.sim.simfc import RcOverrides, SimFlightController, SimState

WAIT_S = 3.0
LEAVE_LOW = 65535  # channels 1-8: leave alone
LEAVE_HIGH = 0  # channels 9-18: leave alone (65535 too)
RELEASE_HIGH = 65534  # channels 9-18: release


def all_four(pulse: int) -> dict[int, int]:
    return {1: pulse, 2: pulse, 3: pulse, 4: pulse}


class Gcs:
    """A ground-station peer sending to the simulator."""

    def __init__(self, port: int, sysid: int = 255) -> None:
        self.port = port
        self.link: Link = open_link(
            f"udpout:127.0.0.1:{port}", source_system=sysid, source_component=190, name="gcs"
        )

    def override(self, pulses: Mapping[int, int], target: tuple[int, int] = (1, 1)) -> None:
        """Send one override: ``pulses`` by channel, every other channel left alone."""
        self.link.send(self.override_message(pulses, target))

    def override_message(self, pulses: Mapping[int, int], target: tuple[int, int] = (1, 1)) -> Any:
        fields = [pulses.get(ch, LEAVE_LOW if ch <= 8 else LEAVE_HIGH) for ch in range(1, 19)]
        return self.link.mav.rc_channels_override_encode(*target, *fields)

    def hello(self) -> None:
        """A GCS heartbeat, so the simulator knows where to send telemetry."""
        send_gcs_heartbeat(self.link.mav)

    def receive(
        self, kind: str, accept: Callable[[Any], bool] = lambda m: True, timeout_s: float = WAIT_S
    ) -> Any:
        """The first ``kind`` message from now on that ``accept`` takes; fails at the deadline."""
        def match() -> Any:
            return next((m for m in self.link.read() if m.get_type() == kind and accept(m)),
                        None)

        fd = self.link.fileno()
        msg = wait_until(match, timeout_s, pump=lambda s: select.select([fd], [], [], s))
        if msg is None:
            pytest.fail(f"no matching {kind} within {timeout_s} s")
        return msg


MakeSim = Callable[..., tuple[SimFlightController, Gcs]]


@pytest.fixture
def simulator() -> Iterator[MakeSim]:
    """``simulator(NAME=value, ...)`` -> a running simulator with those parameters, and a GCS."""
    made: list[tuple[SimFlightController, Gcs]] = []

    def make(**values: float) -> tuple[SimFlightController, Gcs]:
        params = Params()
        params.update(values)
        sim = SimFlightController("udpin:127.0.0.1:0", params)
        sim.start()
        assert sim.local_port
        made.append((sim, Gcs(sim.local_port)))
        return made[-1]

    yield make
    for sim, gcs in made:
        gcs.link.close()
        sim.stop()


def wait(sim: SimFlightController, predicate: Callable[[SimState], bool]) -> SimState:
    state = sim.wait_for(predicate, WAIT_S)
    assert state is not None, f"condition not reached in {WAIT_S} s; last {sim.snapshot()}"
    return state


def send_and_sync(sim: SimFlightController, gcs: Gcs, pulses: Mapping[int, int]) -> SimState:
    """Send one override and wait until the simulator has obeyed it."""
    before = sim.snapshot().overrides_received
    gcs.override(pulses)
    return wait(sim, lambda s: s.overrides_received > before)


def sim_thread_alive(sim: SimFlightController) -> bool:
    return any(t.name == f"simfc:{sim.local_port}" for t in threading.enumerate())


# --------------------------------------------------------------------------- overrides


def test_forward_pulses_on_channels_1_to_4_drive_the_true_pose_north(simulator):
    sim, gcs = simulator()
    gcs.override(all_four(1750))
    state = wait(sim, lambda s: s.pose.x_m > 0.1)
    assert state.wheel_commands == (0.5, 0.5, 0.5, 0.5)
    assert state.channel_pwm == all_four(1750)
    assert state.pose.y_m == pytest.approx(0.0, abs=1e-9)
    assert state.pose.yaw_rad == pytest.approx(0.0, abs=1e-9)
    assert state.velocity_body[0] > 0.0


def test_an_override_from_a_sender_other_than_the_gcs_id_is_ignored_and_counted(simulator):
    sim, gcs = simulator()
    intruder = Gcs(gcs.port, sysid=1)
    try:
        intruder.override(all_four(1900))
        state = wait(sim, lambda s: s.overrides_ignored == 1)
    finally:
        intruder.link.close()
    assert (state.overrides_received, state.channel_pwm) == (0, {})
    assert state.wheel_commands == (0.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("target", [(2, 1), (1, 5), (0, 5)])
def test_an_override_addressed_to_another_board_is_ignored_and_counted(simulator, target):
    sim, gcs = simulator()
    gcs.override(all_four(1900), target=target)
    state = wait(sim, lambda s: s.overrides_ignored == 1)
    assert (state.overrides_received, state.channel_pwm) == (0, {})


def test_a_broadcast_override_is_obeyed(simulator):
    sim, gcs = simulator()
    gcs.override(all_four(1600), target=(0, 0))
    state = wait(sim, lambda s: s.overrides_received == 1)
    assert state.channel_pwm == all_four(1600)


def test_65535_leaves_a_channel_alone(simulator):
    sim, gcs = simulator()
    send_and_sync(sim, gcs, all_four(1600))
    state = send_and_sync(sim, gcs, {1: LEAVE_LOW, 2: 1400, 3: LEAVE_LOW, 4: LEAVE_LOW})
    assert state.channel_pwm == {1: 1600, 2: 1400, 3: 1600, 4: 1600}
    assert state.wheel_commands == pytest.approx((0.2, -0.2, 0.2, 0.2))


def test_zero_releases_a_channel_1_to_8_and_its_wheel_stops(simulator):
    sim, gcs = simulator()
    send_and_sync(sim, gcs, {**all_four(1600), 7: 1200})
    state = send_and_sync(sim, gcs, {1: 0, 7: 0})
    assert state.channel_pwm == {2: 1600, 3: 1600, 4: 1600}
    assert state.wheel_commands == pytest.approx((0.0, 0.2, 0.2, 0.2))


def test_on_channels_9_to_18_0_and_65535_leave_alone_and_65534_releases(simulator):
    sim, gcs = simulator(MOT_FL_CH=10)
    state = send_and_sync(sim, gcs, {10: 1700, 2: 1500})
    assert state.channel_pwm == {10: 1700, 2: 1500}
    assert state.wheel_commands[0] == pytest.approx(0.4)
    for leave in (0, 65535):
        state = send_and_sync(sim, gcs, {10: leave, 2: 1501})
        assert state.channel_pwm == {10: 1700, 2: 1501}
    state = send_and_sync(sim, gcs, {10: RELEASE_HIGH})
    assert state.channel_pwm == {2: 1501}
    assert state.wheel_commands[0] == 0.0


def test_an_override_lapses_after_the_timeout_and_the_wheels_stop(simulator):
    timeout_s = 0.3
    sim, gcs = simulator(SIM_RC_TMO=timeout_s)
    sent = time.monotonic()
    gcs.override(all_four(1800))
    wait(sim, lambda s: min(s.wheel_speeds_mps) > 0.3)
    lapsed = wait(sim, lambda s: s.channel_pwm == {})
    assert time.monotonic() - sent >= timeout_s
    assert lapsed.wheel_commands == (0.0, 0.0, 0.0, 0.0)
    wait(sim, lambda s: max(abs(v) for v in s.wheel_speeds_mps) < 1e-3)


def test_each_channel_lapses_on_its_own_timestamp():
    overrides = RcOverrides(timeout_s=3.0)
    overrides.apply([1600, 1600, *[65535] * 6, *[0] * 10], now_s=10.0)
    overrides.apply([65535, 1700, *[65535] * 6, *[0] * 10], now_s=12.0)
    assert overrides.active(12.9) == {1: 1600, 2: 1700}
    assert overrides.active(13.0) == {2: 1700}
    assert overrides.active(15.0) == {}


def test_a_pulse_beyond_the_motor_range_is_limited_to_full_speed(simulator):
    sim, gcs = simulator()
    state = send_and_sync(sim, gcs, {1: 2500, 2: 700})
    assert state.channel_pwm == {1: 2500, 2: 700}
    assert state.wheel_commands == (1.0, -1.0, 0.0, 0.0)


def test_a_reversed_motor_parameter_inverts_that_wheel(simulator):
    sim, gcs = simulator(MOT_FR_REV=1)
    state = send_and_sync(sim, gcs, all_four(1750))
    assert state.wheel_commands == (0.5, -0.5, 0.5, 0.5)


def test_the_companions_pulses_from_the_same_parameters_drive_north(simulator):
    values = {"MOT_FR_REV": 1, "MOT_RR_REV": 1, "MOT_FL_CH": 3, "MOT_RL_CH": 1}
    sim, gcs = simulator(**values)
    params = Params()
    params.update(values)
    outputs = PwmMap.from_params(params)
    pulses = outputs.pulses_us([0.5, 0.5, 0.5, 0.5])
    gcs.override(dict(zip(outputs.channels, pulses, strict=True)))
    state = wait(sim, lambda s: s.pose.x_m > 0.1)
    assert state.wheel_commands == (0.5, 0.5, 0.5, 0.5)
    assert (state.pose.y_m, state.pose.yaw_rad) == pytest.approx((0.0, 0.0), abs=1e-9)


# --------------------------------------------------------------------------- telemetry


def test_heartbeat_is_a_disarmed_ardupilot_ground_rover_in_manual(simulator):
    _, gcs = simulator(FC_SYSID=7, FC_COMPID=3)
    gcs.hello()
    beat = gcs.receive("HEARTBEAT")
    assert (beat.get_srcSystem(), beat.get_srcComponent()) == (7, 3)
    assert beat.type == mavlink.MAV_TYPE_GROUND_ROVER
    assert beat.autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    assert beat.base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert not beat.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    # (as the SITL firmware sends it: custom mode + manual input, ACTIVE while disarmed)
    assert beat.base_mode == (mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
                              | mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED)
    assert (beat.custom_mode, beat.system_status) == (0, mavlink.MAV_STATE_ACTIVE)


def test_wheel_distance_reports_four_growing_encoder_distances(simulator):
    _, gcs = simulator()
    gcs.override(all_four(1800))
    first = gcs.receive("WHEEL_DISTANCE", lambda m: m.distance[0] > 0.05)
    later = gcs.receive("WHEEL_DISTANCE", lambda m: m.distance[0] > first.distance[0] + 0.05)
    assert first.count == later.count == 4
    assert later.time_usec > first.time_usec
    assert all(later.distance[i] > first.distance[i] for i in range(4))
    assert list(later.distance[4:]) == [0.0] * 12
    assert later.distance[0] == pytest.approx(later.distance[3])


def test_attitude_yaw_follows_the_true_yaw_after_a_clockwise_spin(simulator):
    sim, gcs = simulator(SIM_RC_TMO=60.0)  # one override holds through the spin
    gcs.override({1: 1700, 2: 1300, 3: 1700, 4: 1300})  # wheels +-0.4 m/s
    steady_rate = 0.4 / (0.15 + 0.15)  # rad/s clockwise, default half extents
    wait(sim, lambda s: s.pose.yaw_rad > 0.5 and s.yaw_rate > steady_rate * 0.9995)
    gcs.link.read()  # drop what was sent before the spin settled
    attitude = gcs.receive("ATTITUDE")
    assert attitude.yawspeed == pytest.approx(steady_rate, rel=1e-3)
    assert (attitude.roll, attitude.pitch) == (0.0, 0.0)
    gcs.override(all_four(0))
    still = wait(sim, lambda s: abs(s.yaw_rate) < 1e-3)
    attitude = gcs.receive("ATTITUDE", lambda m: abs(m.yawspeed) < 1e-3)
    assert still.pose.yaw_rad > 0.5
    assert attitude.yaw == pytest.approx(still.pose.yaw_rad, abs=2e-3)


def test_attitude_yaw_is_wrapped_to_minus_pi_to_pi(simulator):
    sim, gcs = simulator(SIM_RC_TMO=60.0)  # one override holds through the spin
    gcs.override({1: 2000, 2: 1000, 3: 2000, 4: 1000})  # about 3.3 rad/s clockwise
    wait(sim, lambda s: s.pose.yaw_rad < -2.0)  # went past pi: now counted from -pi
    attitude = gcs.receive("ATTITUDE", lambda m: m.yaw < 0.0)
    assert -math.pi <= attitude.yaw < math.pi


def test_servo_output_raw_shows_overrides_wheel_trims_and_zero_on_idle_outputs(simulator):
    _, gcs = simulator(MOT_RR_TRIM=1520)
    gcs.override({1: 1600, 2: 1400, 3: 1700, 6: 1234})
    servo = gcs.receive("SERVO_OUTPUT_RAW", lambda m: m.servo1_raw == 1600)
    raw = [getattr(servo, f"servo{i}_raw") for i in range(1, 17)]
    assert raw == [1600, 1400, 1700, 1520, 0, 1234, *[0] * 10]
    assert servo.port == 0


# --------------------------------------------------------------------------- robustness


def test_random_bytes_and_truncated_packets_do_not_stop_it_obeying(simulator):
    sim, gcs = simulator()
    rng = random.Random(1)
    valid = gcs.override_message(all_four(1650)).pack(gcs.link.mav)
    bad_crc = valid[:-2] + bytes([valid[-2] ^ 0xFF, valid[-1]])
    junk = [rng.randbytes(rng.randint(1, 300)) for _ in range(40)]
    junk += [b"\xfd" + rng.randbytes(20), bad_crc, b"", b"\xfe\xff"]
    junk += [valid[:cut] for cut in (1, 5, 10, len(valid) - 1)]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as raw:
        for chunk in junk:
            raw.sendto(chunk, ("127.0.0.1", gcs.port))

    def obeyed() -> SimState | None:  # (junk may swallow one packet: send it again)
        gcs.override(all_four(1650))
        return sim.wait_for(lambda s: s.channel_pwm == all_four(1650), 0.2)

    state = wait_until(obeyed, WAIT_S)
    assert state is not None and state.wheel_commands == pytest.approx((0.3,) * 4)
    assert sim_thread_alive(sim)


def test_stop_is_idempotent_and_the_thread_ends():
    with SimFlightController("udpin:127.0.0.1:0", Params()) as sim:
        sim.start()
        sim.start()
        assert sim_thread_alive(sim)
        name = f"simfc:{sim.local_port}"
        sim.stop()
        sim.stop()
        assert not any(t.name == name for t in threading.enumerate())
        assert sim.local_port is None
        assert sim.snapshot().overrides_received == 0


def test_stop_also_ends_a_loop_run_in_the_callers_own_thread():
    sim = SimFlightController("udpin:127.0.0.1:0", Params())
    never = threading.Event()
    loop = threading.Thread(target=sim.run, args=(never,), daemon=True)
    loop.start()
    assert sim.wait_for(lambda s: s.time_s > 0.0, WAIT_S) is not None
    sim.stop()
    loop.join(WAIT_S)
    assert not loop.is_alive()


def test_main_serves_until_sigterm_and_says_where_it_listens():
    code = (
        "import sys\nfrom mecanum_mav.params import Params\n"
        "from mecanum_mav.app.cli import serve_simfc as main\n"
        "sys.exit(main('udpin:127.0.0.1:0', Params()))"
    )
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        with selectors.DefaultSelector() as selector:
            selector.register(proc.stdout, selectors.EVENT_READ)
            assert selector.select(10.0), "simfc printed nothing"
        line = proc.stdout.readline()
        port = int(re.search(r"udpin:127\.0\.0\.1:0 \(port (\d+)\)", line).group(1))
        gcs = Gcs(port)
        try:
            gcs.hello()
            assert gcs.receive("HEARTBEAT").type == mavlink.MAV_TYPE_GROUND_ROVER
        finally:
            gcs.link.close()
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0
    finally:
        proc.kill()
        proc.wait()


def test_main_reports_a_link_it_cannot_open(capsys):
    assert main("udpin:no-such-host.invalid:0", Params()) == 1
    assert "simfc:" in capsys.readouterr().err
