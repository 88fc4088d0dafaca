"""The stick lane over a stream flight-controller link (issue 24.5): a serial (or TCP) link
takes the lane's packet at once only while nothing waits in it and the wire is free; else
the stick takes the general way and the newest override wins, as before. A link with a
signing key never takes the lane's unsigned packets."""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from support import PtyFlightController, lane_answers, tcp_link_to_a_board, wait_until
from support import override_channels as channels
from test_link_timing import START_S, Pty, exactly, override, serial
from test_links import FakeClock

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.io import links
from mecanum_mav.io.links import Link, mavlink, open_link, serialport
from mecanum_mav.sim.groundstation import ScriptedGroundStation, udp_ground_station

KEY = bytes(range(32))
ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM


def lane_packet(link: Link, pulse: int) -> bytes:
    """An override packed elsewhere with the link's next sequence number, as the lane packs
    it."""
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    mav.seq = link.mav.seq
    return bytes(mav.rc_channels_override_encode(1, 1, *override(pulse)).pack(mav))


# --------------------------------------------------------------------------- the link alone


def test_a_serial_link_takes_the_lanes_packet_only_while_the_wire_is_free(tmp_path: Path):
    clock = FakeClock()
    with serial(tmp_path, 57600, clock) as (link, pty):
        assert link.unchecked and link.takes_packet()
        packet = lane_packet(link, 1100)
        link.send_packet(packet)
        assert pty.take() == packet  # handed to the kernel at once
        assert link.sent == 1 and not link.pending
        due = START_S + len(packet) * 10 / 57600 - links.PACING_LEAD_S
        clock.now = due - 2.0 ** -20  # the wire still busy with it
        assert not link.takes_packet()
        clock.now = due
        assert link.takes_packet()


def test_a_serial_link_never_lets_the_lane_pass_an_override_waiting_in_it_and_newest_wins(
        tmp_path: Path):
    clock = FakeClock()
    with serial(tmp_path, 57600, clock) as (link, pty):
        link.send_rc_override(1, 1, override(1100))  # on the wire
        link.send_rc_override(1, 1, override(1200))  # waiting for it
        assert link.pending and [m.chan1_raw for m in pty.messages()] == [1100]
        clock.now = START_S + 1.0  # the wire long free, the override still waiting
        assert not link.takes_packet()
        link.send_packet(lane_packet(link, 1300))  # sent anyway: it supersedes the older
        assert [m.chan1_raw for m in pty.messages()] == [1300]
        assert link.superseded == 1 and not link.pending


def test_a_lane_packet_keeps_the_pacing_of_what_follows_it(tmp_path: Path):
    clock = FakeClock()
    with serial(tmp_path, 57600, clock) as (link, _):
        packet = lane_packet(link, 1100)
        link.send_packet(packet)
        link.send_rc_override(1, 1, override(1200))  # the tick's refresh, right behind it
        assert link.pending and link.next_send_s == exactly(
            START_S + len(packet) * 10 / 57600 - links.PACING_LEAD_S)


def test_a_serial_link_with_a_signing_key_never_takes_the_lane(tmp_path: Path):
    pty = Pty(tmp_path / "ttyFC")
    signed = open_link(f"{pty.path},57600", source_system=255, source_component=190,
                       name="fc", signing_key=KEY)
    try:
        assert not signed.unchecked
    finally:
        signed.close()
        pty.unplug()


def test_a_tcp_server_link_without_a_client_never_takes_the_lanes_packet():
    link = open_link("tcpin:127.0.0.1:0", source_system=255, source_component=190, name="fc")
    try:
        assert link.up and not link.takes_packet()
        link.send_packet(lane_packet(link, 1100))  # never raises: nobody to send it to
        assert link.sent == 0 and link.unsent == 1
    finally:
        link.close()


def test_a_tcp_link_takes_the_lanes_packet_at_once():
    with tcp_link_to_a_board() as (link, board):
        assert link.takes_packet()
        packet = lane_packet(link, 1100)
        link.send_packet(packet)
        board.settimeout(2.0)
        assert board.recv(4096) == packet


def test_after_the_lanes_writes_a_serial_link_asks_the_kernel_once_every_kernel_look_s(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """KERNEL_LOOK_S: after the lane's write the link asks what the kernel holds at most
    that often (the system call costs about what the write does), and asks again as soon as
    that long has passed (a slow device runs ahead by at most that much)."""
    asked: list[float] = []
    clock = FakeClock()

    def queued_bytes(fd: int, request: int) -> int:
        asked.append(clock.now)
        return 0

    monkeypatch.setattr(serialport, "queued_bytes", queued_bytes)
    with serial(tmp_path, 230400, clock) as (link, pty):  # (an override: 2.3 ms of wire)
        half = serialport.KERNEL_LOOK_S / 2
        for k in range(4):  # a lane's packet every half KERNEL_LOOK_S
            clock.now = START_S + k * half
            assert link.takes_packet()
            link.send_packet(lane_packet(link, 1100 + k))
        assert [m.chan1_raw for m in pty.messages()] == [1100, 1101, 1102, 1103]
        assert asked == [START_S, START_S + serialport.KERNEL_LOOK_S]


# --------------------------------------------------------------------------- the companion


@contextlib.contextmanager
def armed_over_serial(baud: int, params: Params | None = None) -> Iterator[
        tuple[Companion, PtyFlightController, ScriptedGroundStation, list[bytes]]]:
    """A companion between a UDP ground station and a flight controller on a pty at
    ``baud``, armed; the list gathers every datagram its loop answered in the lane."""
    fc = PtyFlightController()
    gcs, port = udp_ground_station()
    companion = Companion(params or Params(), port.url, f"{fc.path},{baud}")
    answered = lane_answers(companion.gcs)
    companion.start()
    try:
        def armed() -> bool:
            fc.pump(0.05)
            ack = gcs.command(ARM, 1, timeout_s=0.2)
            return ack is not None and ack.result == 0

        assert wait_until(armed, 5.0), "no arming over the serial link"
        yield companion, fc, gcs, answered
    finally:
        companion.close()
        port.close()
        fc.close()


def test_the_companions_loop_answers_a_pilots_sticks_in_the_lane_over_a_serial_board():
    with armed_over_serial(921600) as (_, fc, gcs, answered):

        def pushed() -> bool:
            gcs.sticks(1000)
            fc.pump(0.02)
            return len(answered) >= 10

        assert wait_until(pushed, 5.0), len(answered)
        forward = [m for m in fc.messages if m.get_type() == "RC_CHANNELS_OVERRIDE"
                   and channels(m)[:4] == [2000] * 4]
        assert forward


def test_after_the_pilots_last_stick_in_its_lane_the_refresh_and_the_input_timeout_still_come():
    """Sticks one per wake make the loop's passes a stick alone, each waiting for the next
    (issue 24); that wait must still end when a timer is due. After the last stick, with
    the ground station and the board silent (nothing else to wake the loop), the override
    is refreshed at OUT_RATE and goes neutral at FS_INPUT_TMO."""
    params = Params()
    params.set("FS_INPUT_TMO", 0.3)
    with armed_over_serial(921600, params) as (_, fc, gcs, answered):
        for _ in range(50):  # a stick at a time, each in a pass of its own
            before = len(answered)
            gcs.sticks(1000)
            # (the lane answers it unless the refresh has the wire just then: then it takes
            # the general way, and the wait ends at its deadline)
            wait_until(lambda before=before: len(answered) > before, 0.2, pump=fc.pump,
                       pump_s=0.001)
        assert len(answered) >= 40, len(answered)  # (the passes were sticks alone)
        fc.beat_period_s = math.inf  # the board falls silent too
        last = time.monotonic()  # the last stick: the input timeout runs from here on
        gcs.sticks(1000)
        forward, neutral = [2000] * 4, [1500] * 4
        seen: list[tuple[float, list[int]]] = []

        def went_neutral() -> bool:
            before = len(fc.messages)
            fc.pump(0.01)
            seen.extend((time.monotonic() - last, channels(m)[:4]) for m in fc.messages[before:]
                        if m.get_type() == "RC_CHANNELS_OVERRIDE")
            return any(wheels == neutral for _, wheels in seen)

        assert wait_until(went_neutral, 2.0), seen[-3:]
        first_neutral = next(t for t, wheels in seen if wheels == neutral)
        assert 0.3 <= first_neutral < 0.55, first_neutral  # (a loaded machine: +0.25 s)
        refreshed = [t for t, wheels in seen if wheels == forward and t > 0.05]
        assert len(refreshed) >= 3  # OUT_RATE 20 Hz until the timeout


def test_sticks_faster_than_a_slow_serial_wire_take_the_general_way_and_the_newest_wins():
    """At 9600 baud an override is ~50 ms on the wire: sticks at 100 Hz find it busy, go the
    general way, and the override waiting in the link is replaced by each newer one; the
    board gets the last stick's override."""
    with armed_over_serial(9600) as (companion, fc, gcs, answered):
        for i in range(100):
            gcs.mav.manual_control_send(1, 0, -1000 + 20 * i, 500, 0, 0)
            fc.pump(0.01)
        last = [2000, 1000, 1000, 2000]  # the last stick: y 980, strafe right (MAN_* 1.0)

        def reached() -> bool:
            fc.pump(0.05)
            return any(m.get_type() == "RC_CHANNELS_OVERRIDE" and
                       abs(channels(m)[0] - last[0]) <= 20 for m in fc.messages[-5:])

        assert wait_until(reached, 5.0)
        # the wire carries one override in ~50 ms: at most one stick in five found it free
        assert len(answered) <= 25
        assert companion.fc.superseded >= 50


def test_after_the_lanes_write_a_serial_link_follows_a_device_slower_than_its_baud_rate(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """The lane asks without asking the kernel (the baud rate alone); after its write the
    link reads what the kernel still holds (TIOCOUTQ), so a device slower than its baud rate
    holds the next packet back until its queue is out. (A pty's TIOCOUTQ is always 0: here
    the kernel says what a slow UART would.)"""
    held = [0]
    monkeypatch.setattr(serialport, "queued_bytes", lambda fd, request: held[0])
    clock = FakeClock()
    with serial(tmp_path, 57600, clock) as (link, pty):
        link.send_packet(lane_packet(link, 1100))
        clock.now = START_S + 1.0  # by the baud rate, long on the wire; the device is slow:
        held[0] = 500  # the kernel still holds it and more
        assert link.takes_packet()
        link.send_packet(lane_packet(link, 1200))
        clock.now = START_S + 1.0 + 499 * 10 / 57600 - links.PACING_LEAD_S
        assert not link.takes_packet()
        clock.now = START_S + 1.0 + 500 * 10 / 57600 - links.PACING_LEAD_S
        assert link.takes_packet()
        assert [m.chan1_raw for m in pty.messages()] == [1100, 1200]
