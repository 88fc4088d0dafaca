"""A slow serial flight-controller link keeps no standing queue (issue 13.2).

At 57600 baud (5760 bytes/s, 8N1) one RC_CHANNELS_OVERRIDE is ~5 ms on the wire, so 1 kHz
stick input is far more than the link carries. The companion (the real process) drives the
slave end of a pty; the test's flight controller reads the master end no faster than a
57600-baud wire would deliver it, and plays the board's HEARTBEAT on it. A pty takes ~20 KB
ahead of such a reader (~4 s at this rate): only the companion's pacing keeps that buffer
from becoming a queue of old commands. Each command's forward stick is unique within ~0.9 s
(the same encoding as ``tools/bench_latency.py``), so each override that arrives maps back to
the command it reflects.
"""

from __future__ import annotations

import array
import bisect
import contextlib
import fcntl
import importlib.util
import os
import select
import sys
import termios
import threading
import time
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
from sitl import CompanionProcess
from support import RawPty, fc_heartbeat, read_for, wait_until

from mecanum_mav.config.params import Params
from mecanum_mav.io import links
from mecanum_mav.io.links import Link, mavlink, open_link
from mecanum_mav.sim.groundstation import udp_ground_station

BAUD = 57600
WIRE_BYTES_PER_S = BAUD / 10  # 8N1: ten bits a byte
READ_PERIOD_S = 0.005  # the far side reads at most 28.8 bytes every 5 ms (on a schedule)
FC_BEAT_PERIOD_S = 0.5
STICK_PERIOD_S = 0.001  # 1 kHz
STICK_PHASE_S = 3.0
GOAL_AGE_P99_S = 0.020
GOAL_HEARTBEAT_GAP_S = 1.2


def _bench() -> ModuleType:
    """tools/bench_latency.py (its stick encoding), imported by path."""
    path = Path(__file__).resolve().parent.parent / "tools" / "bench_latency.py"
    spec = importlib.util.spec_from_file_location("bench_latency", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("bench_latency", module)
    spec.loader.exec_module(module)
    return module


class SlowWireBoard:
    """The flight controller behind a 57600-baud wire, on the master end of a pty (in a
    thread): every 5 ms (an absolute schedule: a late read is followed by the next at once)
    it reads at most what the wire delivers in 5 ms, and a wire left idle banks nothing; it
    sends HEARTBEAT every 0.5 s and records when each override's last byte was read
    (monotonic s) with its channel 1, and how many bytes waited in the pty at each read."""

    def __init__(self) -> None:
        self.pty = RawPty()
        self.master, self.path = self.pty.master, self.pty.path
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self.mav.robust_parsing = True
        self.overrides: list[tuple[float, int]] = []  # (read at, chan1_raw)
        self.waiting: list[tuple[float, int]] = []  # (when, bytes in the pty not yet read)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="slow-wire", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        per_read = READ_PERIOD_S * WIRE_BYTES_PER_S
        waiting = array.array("i", [0])
        allowance = 0.0
        next_read = next_beat = time.monotonic()
        while not self._stop.wait(max(0.0, next_read - time.monotonic())):
            now = time.monotonic()
            if now >= next_beat:
                os.write(self.master, fc_heartbeat(self.mav).pack(self.mav))
                next_beat += FC_BEAT_PERIOD_S
            allowance = min(allowance + per_read, per_read + 1.0)  # (a fraction carries)
            next_read += READ_PERIOD_S
            fcntl.ioctl(self.master, termios.FIONREAD, waiting, True)
            self.waiting.append((now, waiting[0]))
            try:
                data = os.read(self.master, int(allowance))
            except (BlockingIOError, InterruptedError):
                continue  # nothing on the wire: an idle wire's time is gone
            allowance -= len(data)
            self.overrides += [(now, m.chan1_raw) for m in self.mav.parse_buffer(data) or ()
                               if m.get_type() == "RC_CHANNELS_OVERRIDE"]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.pty.close()


def test_at_57600_baud_1khz_sticks_reach_the_board_at_most_20ms_old_and_heartbeats_keep_time(
        tmp_path: Path) -> None:
    bench = _bench()
    channel, pulse = bench.companion_pulse_fn(Params())
    assert channel == 1  # FL on RC channel 1: chan1_raw
    cycle = bench.stick_cycle([pulse], {1500})
    command_of = {pulse(x): x for x in cycle}
    board = SlowWireBoard()
    gcs, port = udp_ground_station()
    sent_s: dict[int, list[float]] = defaultdict(list)  # x -> when sent (monotonic s)
    beats: list[float] = []
    fd = port.link.fileno()
    try:
        with CompanionProcess(port.url, f"{board.path},{BAUD}", tmp_path) as companion:
            assert gcs.wait("STATUSTEXT", lambda m: m.text == "Flight controller link up",
                            15.0, since=0), companion.log()
            gcs.arm()
            start = time.monotonic()
            end, next_s, i = start + STICK_PHASE_S, start, 0
            while (now := time.monotonic()) < end:
                if now >= next_s:
                    x = cycle[i % len(cycle)]
                    i += 1
                    sent_s[x].append(time.monotonic())
                    gcs.mav.manual_control_send(1, x, 0, bench.MANUAL_Z, 0, 0)
                    next_s = max(next_s + STICK_PERIOD_S, now - 0.01)  # no catch-up burst
                    continue
                gcs.on_time(now)  # the ground station's own 1 Hz HEARTBEAT
                if select.select([fd], [], [], next_s - now)[0]:
                    beats += [time.monotonic() for m in port.link.read()
                              if m.get_type() == "HEARTBEAT" and m.get_srcSystem() == 1]
            alive = companion.proc.poll() is None
            log = companion.log()
    finally:
        board.close()
        port.close()
    assert alive, log
    ages = []
    for read_s, chan1 in board.overrides:
        times = sent_s.get(command_of.get(chan1, -9999), [])
        k = bisect.bisect_right(times, read_s)
        if k and start <= read_s <= end:
            ages.append(read_s - times[k - 1])  # the newest send of that stick before it
    gaps = np.diff([start, *beats, end])
    backlog = max(n for t, n in board.waiting if start <= t <= end)
    p50, p99 = np.percentile(ages, [50, 99])
    print(f"57600 baud, {i / STICK_PHASE_S:.0f} Hz sticks for {STICK_PHASE_S:.0f} s: "
          f"{len(ages) / STICK_PHASE_S:.0f} overrides/s reached the board, age p50 "
          f"{p50 * 1e3:.1f} ms p99 {p99 * 1e3:.1f} ms max {max(ages) * 1e3:.1f} ms; "
          f"at most {backlog} bytes waited in the pty; "
          f"ground-station HEARTBEAT gaps max {gaps.max():.3f} s")
    assert i >= 0.9 * STICK_PHASE_S / STICK_PERIOD_S  # the input really was ~1 kHz
    # the wire carries ~190 overrides/s (30 bytes each, and the heartbeat): most is used
    assert len(ages) >= 100 * STICK_PHASE_S
    # No standing queue: the pty never held 20 ms of the wire (so no override can be a
    # stick cycle, ~0.95 s, older than the command it is matched with).
    assert backlog <= GOAL_AGE_P99_S * WIRE_BYTES_PER_S
    assert p99 <= GOAL_AGE_P99_S
    assert gaps.max() < GOAL_HEARTBEAT_GAP_S


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


def hand_over_all(link: Link, timeout_s: float = 2.0) -> None:
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
def serial_link(baud: int = BAUD) -> Iterator[tuple[Link, UnreadPty]]:
    board = UnreadPty()
    link = open_link(f"{board.path},{baud}", source_system=255, source_component=190,
                     name="fc")
    try:
        yield link, board
    finally:
        link.close()
        board.close()


def test_an_override_waiting_for_the_wire_is_replaced_by_a_newer_one_and_others_keep_order():
    with serial_link() as (link, board):
        beat = link.mav.heartbeat_encode(6, 8, 0, 0, 4)
        link.send_rc_override(1, 1, override(1001))  # the wire is free: handed over at once
        link.send(beat)
        link.send_rc_override(1, 1, override(1002))
        link.send(link.mav.param_request_read_encode(1, 1, b"RCMAP_THROTTLE", -1))
        link.send_rc_override(1, 1, override(1003))
        assert summary(board.messages(1)) == [1001]  # the rest waits in the link
        hand_over_all(link)
        # overrides and queued packets take turns; the waiting override was replaced
        assert summary(board.messages(3)) == ["HEARTBEAT", 1003, "PARAM_REQUEST_READ"]
        assert link.superseded == 1


def test_the_last_overrides_at_close_all_reach_a_slow_serial_board_in_order():
    with serial_link() as (link, board):
        link.send_rc_override(1, 1, override(2000))  # on the wire
        link.send_rc_override(1, 1, override(1900))  # waiting: superseded by the last words
        for pulse in (1500, 1500, 0):  # neutral, neutral, release
            link.send_rc_override(1, 1, override(pulse), replace=False)
        link.close(linger_s=0.3)
        assert summary(board.messages(4)) == [2000, 1500, 1500, 0]
        assert link.superseded == 1


def test_a_board_that_stops_reading_never_blocks_the_sender_and_excess_is_dropped_and_counted():
    with serial_link(baud=9600) as (link, board):
        start = time.monotonic()
        for i in range(1000):  # ~37 KB of messages, ~40 s of a 9600-baud wire
            link.send(link.mav.param_request_read_encode(1, 1, b"RCMAP_THROTTLE", i))
            link.send_rc_override(1, 1, override(1000 + i))
        took_s = time.monotonic() - start
        handed = board.messages(1)
    print(f"1000 overrides and 1000 other packets offered in {took_s * 1e3:.0f} ms; "
          f"{len(handed)} handed to the kernel; {link.send_errors} dropped")
    assert summary(handed) == ["PARAM_REQUEST_READ"]  # the first, at once; the rest waits
    assert link.superseded == 999  # all overrides but the newest
    fits = links.QUEUE_MIN_BYTES // len(handed[0].get_msgbuf())  # the queue's bound (4 KB)
    assert link.send_errors == 1000 - 1 - fits
    assert took_s < 1.0
