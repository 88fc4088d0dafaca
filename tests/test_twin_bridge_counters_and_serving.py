"""The twin bridge's lockstep counters and its serving (mecanum_mav/sim/twinbridge.py,
docs/twin.md "The bridge"): every malformed, repeated, dropped and restarted frame counted,
the last frame's wheel commands and pulses, the record it is given, the wheel contacts every
0.1 s of physics (CONTACTS_PERIOD_S), the time spent answering; a UDP socket with a port of
its own from the OS, an answer that could not be sent lost without the bridge, and a
TwinBridge's thread, which does not hold the program open and goes with close()."""

from __future__ import annotations

import errno
import json
import socket
import threading
import time
from typing import Any

import pytest

pytest.importorskip("mujoco", reason="the MuJoCo chassis needs the physics extra")

from mecanum_mav.config.params import Params
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.sim.mujocochassis import MujocoChassis
from mecanum_mav.sim.sitljson import encode_servo_packet
from mecanum_mav.sim.twinbridge import (
    BridgeCore,
    TwinBridge,
    TwinRecord,
    WheelMap,
    bridge_socket,
    serve,
)
from mecanum_mav.sim.twinrecord import CONTACTS_PERIOD_S

RATE = 1200
NEUTRAL = [1500] * 4


def core(record: TwinRecord | None = None) -> BridgeCore:
    params = Params()
    return BridgeCore(MujocoChassis.from_params(params),
                      WheelMap(PwmMap.from_params(params), esc_dead_band=params["SIM_ESC_DZ"]),
                      record=record)


def frame(count: int, pwm: list[int] = NEUTRAL, rate: int = RATE) -> bytes:
    return encode_servo_packet(rate, count, pwm)


def test_every_malformed_repeated_dropped_and_restarted_frame_is_counted() -> None:
    bridge = core()
    first = bridge.answer(frame(0))
    assert bridge.answer(b"garbage") is None and bridge.answer(b"") is None
    assert bridge.answer(frame(0)) == first and bridge.answer(frame(0)) == first
    assert bridge.answer(frame(2)) != first  # one frame skipped
    bridge.answer(frame(5))  # two more
    bridge.answer(frame(1))  # the firmware restarted
    bridge.answer(frame(0))  # and again
    stats = bridge.stats()
    assert (stats.frames, stats.malformed, stats.repeated) == (5, 2, 2)
    assert (stats.dropped, stats.restarts) == (3, 2)


def test_the_stats_carry_the_last_frames_wheel_commands_and_pulses() -> None:
    bridge = core()
    bridge.answer(frame(0))  # (neutral arms the ESCs)
    bridge.answer(frame(1, [1750, 1250, 2000, 1500]))
    stats = bridge.stats()
    assert stats.commands == pytest.approx((0.5, -0.5, 1.0, 0.0))
    assert stats.wheel_pulses == (1750, 1250, 2000, 1500)


def test_a_bridge_core_counts_and_records_into_the_record_it_is_given() -> None:
    record = TwinRecord.local(capacity=8)
    bridge = core(record)
    for n in range(3):
        bridge.answer(frame(n))
    assert bridge.record is record
    assert record.stats().frames == 3
    assert record.truth_now().time_s == pytest.approx(3 / RATE)


def test_frames_one_contacts_period_long_each_read_the_wheel_contacts() -> None:
    """At 10 frames a second each frame is CONTACTS_PERIOD_S (0.1 s) of physics: each one's
    contacts are read, at that frame's physics time."""
    rate = round(1 / CONTACTS_PERIOD_S)
    bridge = core()
    for n in range(3):
        bridge.answer(frame(n, rate=rate))
        contacts = bridge.record.contacts()
        assert contacts is not None
        assert contacts[0] == bridge.truth_now().time_s
    assert bridge.truth_now().time_s == pytest.approx(3 * CONTACTS_PERIOD_S)


def test_busy_seconds_are_the_time_spent_answering_every_frame() -> None:
    bridge = core()
    spent = 0.0
    for n in range(40):
        started = time.perf_counter()
        bridge.answer(frame(n))
        spent += time.perf_counter() - started
    busy = bridge.stats().busy_s
    assert 0.2 * spent <= busy <= spent  # (most of it: only the calls themselves are not)


def test_two_bridge_sockets_each_get_a_port_of_their_own_from_the_os() -> None:
    with bridge_socket() as one, bridge_socket() as two:
        ports = {one.getsockname()[1], two.getsockname()[1]}
        assert len(ports) == 2 and 0 not in ports
        assert not one.getblocking()


class LossySocket(socket.socket):
    """A UDP socket whose first send fails as a full buffer's does."""

    failures = 1

    def sendto(self, *args: Any) -> int:  # type: ignore[override]
        if self.failures:
            self.failures -= 1
            raise OSError(errno.ENOBUFS, "No buffer space available")
        return super().sendto(*args)


def test_an_answer_that_could_not_be_sent_is_lost_and_the_bridge_answers_the_resend() -> None:
    """The firmware sends the frame again when no answer came: that one is answered."""
    bridge = core()
    sock = LossySocket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.setblocking(False)
    stop_r, stop_w = socket.socketpair()
    thread = threading.Thread(target=serve, args=(sock, bridge, stop_r.fileno()), daemon=True)
    thread.start()
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as firmware:
            firmware.bind(("127.0.0.1", 0))
            firmware.settimeout(0.3)
            firmware.sendto(frame(0), sock.getsockname())
            with pytest.raises(TimeoutError):
                firmware.recv(4096)
            firmware.settimeout(5.0)
            firmware.sendto(frame(0), sock.getsockname())
            answer = json.loads(firmware.recv(4096))
        assert answer["timestamp"] == pytest.approx(1 / RATE)
        assert (bridge.stats().frames, bridge.stats().repeated) == (1, 1)
    finally:
        stop_w.send(b"x")
        thread.join(timeout=5)
        for s in (sock, stop_r, stop_w):
            s.close()
    assert not thread.is_alive()


def test_a_bridge_thread_left_open_does_not_keep_the_program_from_exiting() -> None:
    before = set(threading.enumerate())
    bridge = TwinBridge(core())
    try:
        started = set(threading.enumerate()) - before
        assert len(started) == 1
        assert all(thread.daemon for thread in started)
    finally:
        bridge.close()


def test_closing_a_bridge_thread_ends_its_thread_and_frees_its_port() -> None:
    before = set(threading.enumerate())
    bridge = TwinBridge(core())
    started = set(threading.enumerate()) - before
    bridge.close()
    assert not any(thread.is_alive() for thread in started)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as again:
        again.bind(("127.0.0.1", bridge.port))  # (the port is free again)
