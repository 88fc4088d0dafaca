"""A slow serial flight-controller link keeps no standing queue (issue 13.2).

At 57600 baud (5760 bytes/s, 8N1) one RC_CHANNELS_OVERRIDE is ~5 ms on the wire, so 1 kHz
stick input is far more than the link carries. The real process's run is
``tools/bench_serial.py`` (imported): the companion drives the slave end of a pty whose far
side reads no faster than a 57600-baud wire. What this test asserts is causal: the overrides
reach the board, the rover's heartbeats keep reaching the ground station, and no standing
queue builds in the pty (never 2 KB; without pacing the companion fills it within a
second). How old the overrides are, in wall-clock time, is
the tool's figure (p99 goal 20 ms, with the ratio to a paced writer of the same run); the
pacing itself is asserted exactly on a fake clock in test_link_timing.py, and the link's
queueing rules below.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))

import bench_serial
from support import RawPty, read_for, wait_until

from mecanum_mav.io import links
from mecanum_mav.io.links import Link, mavlink, open_link

BAUD = bench_serial.BAUD
STANDING_QUEUE_BYTES = 2048
"""More than the pty ever holds for a paced link (~100 bytes), half of what it shows for an
unpaced one (4095, its read buffer; ~0.35 s of the wire)."""
DEADLINE_S = 30.0


@pytest.mark.slow
def test_at_57600_baud_1khz_sticks_reach_the_board_heartbeats_keep_coming_and_no_queue_builds(
        tmp_path: Path) -> None:
    result = bench_serial.run_serial(3.0, tmp_path)
    report = "\n".join(bench_serial.report(result)) if not result.error else result.log
    print(report)
    assert not result.error, report
    assert result.sent > 0 and result.companion.ages_s, report
    assert result.beats, report  # the rover's 1 Hz HEARTBEAT kept reaching the ground station
    assert result.companion.backlog_bytes < STANDING_QUEUE_BYTES, report


# --------------------------------------------------------------------------- the link alone


class UnreadPty:
    """A pty whose far side reads only when asked: what the link handed to the kernel."""

    def __init__(self) -> None:
        self.pty = RawPty()
        self.master, self.path = self.pty.master, self.pty.path
        self.mav = mavlink.MAVLink(None)
        self.mav.robust_parsing = True

    def messages(self, count: int, timeout_s: float = 1.0) -> list[Any]:
        """Read until ``count`` messages came (a pty passes bytes on a moment after they
        were written) or ``timeout_s`` passed, and 50 ms more for any extra."""
        return read_for(self.master, lambda: [
            m for m in self.mav.parse_buffer(os.read(self.master, 65536)) or ()
            if m.get_type() != "BAD_DATA"], timeout_s, enough=count, settle_s=0.05)

    def close(self) -> None:
        self.pty.close()


def hand_over_all(link: Link, timeout_s: float = DEADLINE_S) -> None:
    """Flush ``link`` on its pacing timer until nothing waits in it."""

    def flush_when_due(wait_s: float) -> None:
        threading.Event().wait(max(0.0, min(link.next_send_s - time.monotonic(), wait_s)))
        link.flush()

    wait_until(lambda: not link.pending, timeout_s, pump=flush_when_due)
    assert not link.pending


def override(pulse: int) -> list[int]:
    return [pulse] * 4 + [65535] * 4 + [0] * 10


def summary(messages: list[Any]) -> list[Any]:
    return [m.chan1_raw if m.get_type() == "RC_CHANNELS_OVERRIDE" else m.get_type()
            for m in messages]


@contextlib.contextmanager
def serial_link(baud: int = BAUD, clock: Callable[[], float] = time.monotonic,
                ) -> Iterator[tuple[Link, UnreadPty]]:
    board = UnreadPty()
    link = open_link(f"{board.path},{baud}", source_system=255, source_component=190,
                     name="fc", clock=clock)
    try:
        yield link, board
    finally:
        link.close()
        board.close()


class HeldClock:
    """A link's clock that stands still while the test offers packets (however slowly this
    machine runs the statements, the wire stays busy with the first packet), then, released,
    follows the real clock (the pacing's timing is test_link_timing.py's)."""

    def __init__(self) -> None:
        self.held_at: float | None = time.monotonic()

    def __call__(self) -> float:
        return self.held_at if self.held_at is not None else time.monotonic()

    def release(self) -> None:
        self.held_at = None


def test_an_override_waiting_for_the_wire_is_replaced_by_a_newer_one_and_others_keep_order():
    clock = HeldClock()
    with serial_link(clock=clock) as (link, board):
        beat = link.mav.heartbeat_encode(6, 8, 0, 0, 4)
        link.send_rc_override(1, 1, override(1001))  # the wire is free: handed over at once
        link.send(beat)
        link.send_rc_override(1, 1, override(1002))
        link.send(link.mav.param_request_read_encode(1, 1, b"RCMAP_THROTTLE", -1))
        link.send_rc_override(1, 1, override(1003))
        assert summary(board.messages(1)) == [1001]  # the rest waits in the link
        clock.release()
        hand_over_all(link)
        # overrides and queued packets take turns; the waiting override was replaced
        assert summary(board.messages(3)) == ["HEARTBEAT", 1003, "PARAM_REQUEST_READ"]
        assert link.superseded == 1


def test_the_last_overrides_at_close_all_reach_a_slow_serial_board_in_order():
    clock = HeldClock()
    with serial_link(clock=clock) as (link, board):
        link.send_rc_override(1, 1, override(2000))  # on the wire
        link.send_rc_override(1, 1, override(1900))  # waiting: superseded by the last words
        for pulse in (1500, 1500, 0):  # neutral, neutral, release
            link.send_rc_override(1, 1, override(pulse), replace=False)
        clock.release()
        link.close(linger_s=0.3)
        assert summary(board.messages(4)) == [2000, 1500, 1500, 0]
        assert link.superseded == 1


def test_a_board_that_stops_reading_never_blocks_the_sender_and_excess_is_dropped_and_counted():
    # the link's clock stands still: however slowly this machine offers the 2000 packets, the
    # wire never frees for a second one (the pacing's timing is test_link_timing.py's)
    with serial_link(baud=9600, clock=lambda: 0.0) as (link, board):

        def offer() -> None:
            for i in range(1000):  # ~37 KB of messages, ~40 s of a 9600-baud wire
                link.send(link.mav.param_request_read_encode(1, 1, b"RCMAP_THROTTLE", i))
                link.send_rc_override(1, 1, override(1000 + i))

        sender = threading.Thread(target=offer, daemon=True)
        start = time.monotonic()
        sender.start()
        sender.join(DEADLINE_S)  # a blocking write would wait for the board forever
        took_s = time.monotonic() - start
        assert not sender.is_alive(), "a send blocked on the full device"
        handed = board.messages(1)
    print(f"1000 overrides and 1000 other packets offered in {took_s * 1e3:.0f} ms; "
          f"{len(handed)} handed to the kernel; {link.send_errors} dropped")
    assert summary(handed) == ["PARAM_REQUEST_READ"]  # the first, at once; the rest waits
    assert link.superseded == 999  # all overrides but the newest
    fits = links.QUEUE_MIN_BYTES // len(handed[0].get_msgbuf())  # the queue's bound (4 KB)
    assert link.send_errors == 1000 - 1 - fits
