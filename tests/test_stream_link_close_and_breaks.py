"""A stream link's close and its breaks (``mecanum_mav.io.links.stream``), on a real pty:

- ``close(linger_s=...)`` hands over what waits, paced, for at most the linger, but the last
  words at shutdown whatever the wire needs for them (at most ``LAST_WORDS_MAX_S``), and never
  raises, even on a device that is gone;
- a read that fails puts the link down and says so once at INFO: ``NAME: REASON: read: ...``;
- what a break drops adds to ``unsent`` (it is never reset), and after the link is back its
  queue holds exactly ``queue_limit`` bytes again, and its new descriptor is watched for
  writing only once the kernel refuses more;
- a send the full queue cannot take is counted in ``send_errors`` and logged at WARNING with
  the reason.
"""

from __future__ import annotations

import logging
import math
import signal
import threading
import time
from collections.abc import Iterator

import pytest
from support import RawPty
from test_stream_link_counts_and_sequence import BAUD, NEUTRAL, Clock, board_reads, serial_link
from test_stream_link_queue_reads_and_signing import busy

from mecanum_mav.io.links import open_link, serialport
from mecanum_mav.io.links.serialport import SerialLink
from mecanum_mav.io.links.stream import LAST_WORDS_MAX_S
from mecanum_mav.protocol.dialect import mavlink


@pytest.fixture
def pty() -> Iterator[RawPty]:
    end = RawPty()
    yield end
    end.close()


def slow_link(pty: RawPty, baud: int = 2400) -> SerialLink:
    """A link on the real clock at ``baud`` (2400: 240 bytes/s, an override 0.2 s)."""
    link = open_link(f"{pty.path},{baud}", source_system=1, source_component=191, name="fc")
    assert isinstance(link, SerialLink)
    return link


def test_closing_with_a_linger_gives_up_on_ordinary_packets_when_the_linger_is_over(pty):
    link = slow_link(pty)
    for k in range(20):  # 20 STATUSTEXT of 60 bytes: 5 s of the wire
        link.conn.mav.statustext_send(6, f"queued {k}".encode())
    began = time.monotonic()
    link.close(linger_s=0.2)
    took = time.monotonic() - began
    assert 0.15 < took < 1.0  # the linger, not LAST_WORDS_MAX_S, not the 5 s of the queue
    got = board_reads(pty)
    assert 0 < len(got) < 20


def test_closing_a_serial_link_without_a_linger_ends_it_at_once_with_the_wire_still_busy(pty):
    """No linger is the default (``close()``: immediate): not the queue's 5 s of wire, nor
    the wait for what the kernel holds to drain to a board that reads nothing."""
    link = slow_link(pty)
    for k in range(20):  # 20 STATUSTEXT of 60 bytes: 5 s of the wire
        link.conn.mav.statustext_send(6, f"queued {k}".encode())
    link.flush()  # (the first handed to the kernel: on the wire for 0.25 s)
    began = time.monotonic()
    link.close()
    assert time.monotonic() - began < 0.2


def test_closing_waits_for_the_wire_to_carry_every_last_word_however_short_the_linger(pty):
    link = slow_link(pty)
    link.send_rc_override(1, 1, NEUTRAL, replace=False)
    link.send_rc_override(1, 1, NEUTRAL, replace=False)
    link.send_rc_override(1, 1, [0] * 18, replace=False)  # 3 x 0.2 s on the wire
    began = time.monotonic()
    link.close(linger_s=0.05)
    assert time.monotonic() - began < LAST_WORDS_MAX_S + 0.5
    got = board_reads(pty)
    assert [m.get_type() for m in got] == ["RC_CHANNELS_OVERRIDE"] * 3
    assert [m.chan1_raw for m in got] == [1500, 1500, 0]


def test_closing_a_link_whose_device_is_gone_does_not_raise(pty):
    link = slow_link(pty)
    link.conn.mav.statustext_send(6, b"waiting")
    link.conn.mav.statustext_send(6, b"waiting too")
    pty.close()
    link.close(linger_s=0.3)  # (the writes fail: down; nothing raised)


def test_a_ctrl_c_during_the_linger_comes_out_of_close_as_it_is(pty):
    """``mecanum-mav`` ends a Ctrl-C anywhere with one line and status 130, never a traceback
    (app/cli.py ``main``), ``setup-fc`` closing its link with a linger included: what close
    does not handle itself (a failed write, a device gone) passes through unchanged."""
    link = slow_link(pty)
    for _ in range(3):
        link.send_rc_override(1, 1, NEUTRAL, replace=False)  # 0.6 s of the wire
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # Python's Ctrl-C
    ctrl_c = threading.Timer(0.1, signal.pthread_kill, (threading.get_ident(), signal.SIGINT))
    try:
        ctrl_c.start()
        with pytest.raises(KeyboardInterrupt):
            link.close(linger_s=0.05)
    finally:
        ctrl_c.cancel()
        ctrl_c.join()
        signal.signal(signal.SIGINT, previous)
        link.close()


def test_closing_with_a_linger_a_link_whose_device_went_unnoticed_closes_it_without_raising(
        pty):
    """Nothing waited, so no write found the device gone: the wait for the output to drain
    (``tcdrain``) fails instead, with an error that is no ``OSError``."""
    link = slow_link(pty)
    pty.close()
    link.close(linger_s=0.3)
    assert not link.conn.port.is_open


def test_a_read_that_fails_puts_the_link_down_and_says_so_once_at_info(
        pty, caplog: pytest.LogCaptureFixture):
    link = serial_link(pty, Clock())
    pty.close()
    with caplog.at_level(logging.DEBUG, logger="mecanum_mav.io.links"):
        assert link.read() == []
        assert link.read() == []
    said = [r for r in caplog.records if r.levelno >= logging.INFO]
    assert len(said) == 1
    assert said[0].getMessage().startswith("fc: device gone: read: ")
    assert said[0].getMessage() != "fc: device gone: read: "  # the system's reason follows
    link.close()


def test_unsent_adds_up_over_breaks_and_the_queue_is_whole_again_after_reopening(tmp_path):
    device = RawPty(tmp_path / "ttyFC")
    clock = Clock()
    link = serial_link(device, clock)
    busy(link)
    link.conn.mav.system_time_send(1, 0)
    device.close()
    clock.now_s += 1.0
    link.flush()  # the write fails: down, one dropped
    assert link.down_reason is not None and link.unsent == 1
    assert not link.pending and link.next_send_s == math.inf  # nothing waits, nothing due
    link.send_rc_override(1, 1, NEUTRAL)  # while down: dropped too
    assert link.unsent == 2
    replugged = RawPty(tmp_path / "ttyFC")
    try:
        clock.now_s = link.next_reopen_s
        assert link.reopen(clock.now_s)
        busy(link)
        link.write(b"x" * link.queue_limit)  # exactly full again
        replugged.close()
        clock.now_s += 1.0
        link.flush()
        assert link.unsent == 3  # (the one packet waiting)
    finally:
        link.close()
        replugged.close()


def test_a_send_the_full_queue_cannot_take_is_counted_and_logged_with_the_reason(
        pty, caplog: pytest.LogCaptureFixture):
    link = serial_link(pty, Clock())
    busy(link)
    link.write(b"x" * link.queue_limit)
    packet = mavlink.MAVLink(None).heartbeat_encode(6, 8, 0, 0, 4).pack(mavlink.MAVLink(None))
    with caplog.at_level(logging.WARNING, logger="mecanum_mav.io.links"):
        link.send_packet(packet)  # the lane's packet: queued behind, but there is no room
    assert link.send_errors == 1
    assert any("outgoing queue full" in m and m.startswith("fc: send failed (1 so far): ")
               for m in caplog.messages), caplog.messages
    link.close()


def test_a_link_keeps_its_url_and_reading_it_idle_finds_nothing_and_counts_nothing_bad(pty):
    link = serial_link(pty, Clock())
    assert link.url == f"{pty.path},115200"
    assert link.read() == [] and link.bad == 0 and link.received == 0
    link.close()


def test_closing_on_a_clock_that_stands_still_ends_by_the_real_clock(pty):
    """(The lockstep harness's links run on virtual time: the linger is over when either
    clock says so.)"""
    link = serial_link(pty, Clock())
    busy(link)
    link.conn.mav.system_time_send(1, 0)  # waits for a wire that never frees on this clock
    began = time.monotonic()
    link.close(linger_s=0.2)
    assert time.monotonic() - began < 1.0


def test_closing_while_the_device_takes_nothing_gives_up_on_the_packet_begun_in_time(pty):
    """A packet the kernel took part of is the last words' kind of wait (the wire needs
    it), but at most LAST_WORDS_MAX_S: a device that takes nothing more is given up."""
    clock = Clock()
    link = serial_link(pty, clock)
    while not link.wants_write:
        clock.now_s += 10.0
        link.conn.mav.statustext_send(6, b"filling the device's buffer".ljust(50, b"."))
    began = time.monotonic()
    link.close(linger_s=0.1)
    took = time.monotonic() - began
    assert 0.5 * LAST_WORDS_MAX_S < took < LAST_WORDS_MAX_S + 1.0


def test_a_break_found_by_a_read_leaves_nothing_due_for_the_loop_to_wait_on(pty):
    """(The loop waits on ``next_send_s``: a link that broke while packets waited must say
    "nothing due", not keep a time or lose it.)"""
    clock = Clock()
    link = serial_link(pty, clock)
    busy(link)
    link.conn.mav.system_time_send(1, 0)  # waits
    assert link.next_send_s < math.inf
    pty.close()
    assert link.read() == []  # the read fails first: down
    assert link.down_reason is not None and link.unsent == 1
    assert not link.pending and link.next_send_s == math.inf
    link.close()


def test_a_link_back_up_watches_its_new_descriptor_for_writing_only_once_the_kernel_refuses(
        tmp_path, monkeypatch: pytest.MonkeyPatch):
    """``wants_write``: the kernel refused more and something waits. The old descriptor was
    full when the device went; after reopening, a packet that waits only for pacing (a UART
    whose tty still holds a second of the wire, which a pty never reports) waits on the
    pacing timer, not on a descriptor writable all along (the loop would wake at once, over
    and over, until the timer is due)."""
    device = RawPty(tmp_path / "ttyFC")
    clock = Clock()
    link = serial_link(device, clock)
    for _ in range(10_000):  # the board reads nothing: its buffer fills
        clock.now_s += 10.0
        link.conn.mav.statustext_send(6, b"telemetry for a board that does not read")
        if link.wants_write:
            break
    assert link.wants_write, "the pty never filled"
    device.close()
    assert link.read() == [] and link.down_reason is not None  # the read fails: down
    replugged = RawPty(tmp_path / "ttyFC")
    try:
        clock.now_s = link.next_reopen_s
        assert link.reopen(clock.now_s)
        monkeypatch.setattr(serialport, "queued_bytes", lambda fd, request: BAUD // 10)
        link.conn.mav.system_time_send(1, 0)
        assert link.pending and link.next_send_s < math.inf  # paced: due in about a second
        assert not link.wants_write
    finally:
        link.close()
        replugged.close()
