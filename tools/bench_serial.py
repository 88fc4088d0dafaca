#!/usr/bin/env python3
"""Benchmark a slow serial flight-controller link: 1 kHz sticks over a 57600-baud wire.

Method
    At 57600 baud (5760 bytes/s, 8N1) one RC_CHANNELS_OVERRIDE is ~5 ms on the wire, so 1 kHz
    stick input is far more than the link carries (issue 13.2). The companion (the real
    process, ``python -m mecanum_mav run``) drives the slave end of a pty; a flight controller
    played by this script (:class:`SlowWireBoard`, a thread) reads the master end no faster
    than a 57600-baud wire would deliver it (every 5 ms on an absolute schedule, at most what
    the wire carries in 5 ms; an idle wire banks nothing) and sends the board's HEARTBEAT on
    it. A pty takes ~20 KB ahead of such a reader (~4 s at this rate): only the companion's
    pacing keeps that buffer from becoming a queue of old commands. The ground station sends
    MANUAL_CONTROL at 1 kHz for ``--seconds`` after arming; each command's forward stick is
    unique within ~0.9 s (:func:`bench_latency.stick_cycle`), so each override the board reads
    maps back to the command it reflects. Age = when the board read the override's last byte
    minus when the newest send of that stick before it left the ground station.

    Baseline, in the same run and on the same machine: a second slow-wire board fed by this
    script itself (the *floor*): at each stick it makes that stick's override the newest, and
    writes the newest whenever the previous one is off the wire (the same 2 ms lead as the
    companion's pacing). Its ages are the least this wire, this reader and this machine's
    scheduling allow; the companion's are reported as ratios to it.

Goals (issue 13.2)
    - p99 age at most 20 ms;
    - no standing queue: the pty never holds 20 ms of the wire;
    - the ground station's HEARTBEAT from the rover keeps coming: no gap of 1.2 s or more.
    Ratios to the floor (p50, p99 age) are printed without a goal.

The exit status is 0 when all goals are met, 1 when one is not, 2 when the companion died or
could not be started or armed.

    python tools/bench_serial.py [--seconds 3]
"""

from __future__ import annotations

import argparse
import array
import bisect
import fcntl
import os
import select
import sys
import tempfile
import termios
import threading
import time
import tty
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from bench_latency import MANUAL_Z, companion_pulse_fn, stick_cycle

from mecanum_mav.config.params import Params
from mecanum_mav.io.links import PACING_LEAD_S, mavlink
from mecanum_mav.sim.groundstation import ScriptedGroundStation, UdpPort, udp_ground_station
from mecanum_mav.sim.process import CompanionProcess

BAUD = 57600
WIRE_BYTES_PER_S = BAUD / 10  # 8N1: ten bits a byte
READ_PERIOD_S = 0.005  # the far side reads at most 28.8 bytes every 5 ms (on a schedule)
FC_BEAT_PERIOD_S = 0.5
STICK_PERIOD_S = 0.001  # 1 kHz
GOAL_AGE_P99_S = 0.020
GOAL_BACKLOG_BYTES = GOAL_AGE_P99_S * WIRE_BYTES_PER_S
GOAL_HEARTBEAT_GAP_S = 1.2


class SlowWireBoard:
    """The flight controller behind a 57600-baud wire, on the master end of a pty (in a
    thread): every 5 ms (an absolute schedule: a late read is followed by the next at once)
    it reads at most what the wire delivers in 5 ms, and a wire left idle banks nothing; it
    sends HEARTBEAT every 0.5 s (``beat``) and records when each override's last byte was
    read (monotonic s) with its channel 1, and how many bytes waited in the pty at each read."""

    def __init__(self, *, beat: bool = True) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # no echo, no CR/LF translation
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self.mav.robust_parsing = True
        self.beat = beat
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
            if self.beat and now >= next_beat:
                os.write(self.master, self.mav.heartbeat_encode(
                    mavlink.MAV_TYPE_GROUND_ROVER, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0,
                    mavlink.MAV_STATE_STANDBY).pack(self.mav))
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
        os.close(self.master)
        os.close(self.slave)


class FloorWriter:
    """The baseline: this script's own paced writer to a :class:`SlowWireBoard` (newest
    override wins, written when the previous one is off the wire, less the pacing lead)."""

    def __init__(self, board: SlowWireBoard) -> None:
        self.board = board
        self.mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        self.pending: bytes | None = None
        self.wire_free_s = 0.0

    def command(self, pulse: int) -> None:
        self.pending = self.mav.rc_channels_override_encode(
            1, 1, *([pulse] * 4), *([65535] * 4)).pack(self.mav)

    def pump(self, now: float) -> float:
        """Write the newest override if the wire is free; when to look again (monotonic s)."""
        if self.pending is not None and now >= self.wire_free_s - PACING_LEAD_S:
            os.write(self.board.slave, self.pending)
            self.wire_free_s = max(self.wire_free_s, now) + len(self.pending) / WIRE_BYTES_PER_S
            self.pending = None
        return self.wire_free_s - PACING_LEAD_S if self.pending is not None else float("inf")


@dataclass
class Ages:
    """What one board received in the stick phase."""

    ages_s: list[float] = field(default_factory=list)
    backlog_bytes: int = 0

    def pct(self, q: float) -> float:
        return float(np.percentile(self.ages_s, q)) if self.ages_s else float("nan")


@dataclass
class SerialResult:
    """One run: the companion's ages and the floor's, the sticks sent, the rover's HEARTBEAT
    arrivals at the ground station (monotonic s), and why it failed (empty if it did not)."""

    seconds: float
    sent: int = 0
    companion: Ages = field(default_factory=Ages)
    floor: Ages = field(default_factory=Ages)
    beats: list[float] = field(default_factory=list)
    start_s: float = 0.0
    end_s: float = 0.0
    error: str = ""
    log: str = ""

    def heartbeat_gap_s(self) -> float:
        return float(np.diff([self.start_s, *self.beats, self.end_s]).max())

    def goals(self) -> list[tuple[str, str, bool]]:
        """(goal, value, met) for each goal of the module's description."""
        p99, backlog, gap = self.companion.pct(99), self.companion.backlog_bytes, (
            self.heartbeat_gap_s())
        return [
            ("p99 age <= 20 ms", f"{p99 * 1e3:.1f} ms", p99 <= GOAL_AGE_P99_S),
            ("pty backlog < 20 ms of the wire", f"{backlog} bytes",
             backlog <= GOAL_BACKLOG_BYTES),
            ("rover HEARTBEAT gaps < 1.2 s", f"{gap:.3f} s", gap < GOAL_HEARTBEAT_GAP_S),
        ]


def _ages(board: SlowWireBoard, sent_s: dict[int, list[float]], command_of: dict[int, int],
          start: float, end: float) -> Ages:
    out = Ages()
    for read_s, chan1 in board.overrides:
        times = sent_s.get(command_of.get(chan1, -9999), [])
        k = bisect.bisect_right(times, read_s)
        if k and start <= read_s <= end:
            out.ages_s.append(read_s - times[k - 1])  # the newest send of that stick before it
    out.backlog_bytes = max((n for t, n in board.waiting if start <= t <= end), default=0)
    return out


def run_serial(seconds: float, workdir: Path) -> SerialResult:
    """One run (see the module's description)."""
    channel, pulse = companion_pulse_fn(Params())
    assert channel == 1  # FL on RC channel 1: chan1_raw
    cycle = stick_cycle([pulse], {1500})
    command_of = {pulse(x): x for x in cycle}
    board, floor_board = SlowWireBoard(), SlowWireBoard(beat=False)
    floor = FloorWriter(floor_board)
    gcs, port = udp_ground_station()
    result = SerialResult(seconds)
    sent_s: dict[int, list[float]] = defaultdict(list)  # x -> when sent (monotonic s)
    try:
        with CompanionProcess(port.url, f"{board.path},{BAUD}", workdir) as companion:
            if gcs.wait("STATUSTEXT", lambda m: m.text == "Flight controller link up",
                        15.0, since=0) is None:
                result.error = "the companion never heard the flight controller"
            else:
                try:
                    gcs.arm()
                except RuntimeError as exc:
                    result.error = f"the companion could not be armed: {exc}"
                else:
                    _sticks(result, gcs, port, floor, cycle, pulse, sent_s)
                if companion.proc.poll() is not None:
                    result.error = "the companion died"
            result.log = companion.log()
    finally:
        board.close()
        floor_board.close()
        port.close()
    result.companion = _ages(board, sent_s, command_of, result.start_s, result.end_s)
    result.floor = _ages(floor_board, sent_s, command_of, result.start_s, result.end_s)
    return result


def _sticks(result: SerialResult, gcs: ScriptedGroundStation, port: UdpPort,
            floor: FloorWriter, cycle: list[int], pulse: Callable[[int], int],
            sent_s: dict[int, list[float]]) -> None:
    """The stick phase: 1 kHz on an absolute schedule, the floor fed alongside."""
    fd = port.link.fileno()
    result.start_s = start = time.monotonic()
    end, next_s, i, floor_s = start + result.seconds, start, 0, float("inf")
    while (now := time.monotonic()) < end:
        if now >= next_s:
            x = cycle[i % len(cycle)]
            i += 1
            sent_s[x].append(time.monotonic())
            gcs.mav.manual_control_send(1, x, 0, MANUAL_Z, 0, 0)
            floor.command(pulse(x))
            floor_s = floor.pump(time.monotonic())
            next_s = max(next_s + STICK_PERIOD_S, now - 0.01)  # no catch-up burst
            continue
        if now >= floor_s:
            floor_s = floor.pump(now)
            continue
        gcs.on_time(now)  # the ground station's own 1 Hz HEARTBEAT
        if select.select([fd], [], [], max(0.0, min(next_s, floor_s) - now))[0]:
            result.beats += [time.monotonic() for m in port.link.read()
                             if m.get_type() == "HEARTBEAT" and m.get_srcSystem() == 1]
    result.end_s, result.sent = end, i


def report(result: SerialResult) -> list[str]:
    """The figures and the goals, one line each."""
    c, f = result.companion, result.floor
    lines = [f"{BAUD} baud, {result.sent / result.seconds:.0f} Hz sticks for "
             f"{result.seconds:.0f} s; python {sys.version.split()[0]}"]
    for name, ages in (("companion", c), ("floor", f)):
        lines.append(f"{name:9s}: {len(ages.ages_s) / result.seconds:.0f} overrides/s reached "
                     f"the board, age p50 {ages.pct(50) * 1e3:.1f} ms p99 "
                     f"{ages.pct(99) * 1e3:.1f} ms max "
                     f"{max(ages.ages_s, default=float('nan')) * 1e3:.1f} ms; at most "
                     f"{ages.backlog_bytes} bytes waited in the pty")
    lines.append(f"ratio companion/floor: age p50 {c.pct(50) / f.pct(50):.2f}, "
                 f"p99 {c.pct(99) / f.pct(99):.2f}")
    lines += [f"{goal}: {value}: {'met' if met else 'NOT MET'}"
              for goal, value, met in result.goals()]
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    parser.add_argument("--seconds", type=float, default=3.0,
                        help="length of the 1 kHz stick phase (default 3)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        result = run_serial(args.seconds, Path(tmp))
    if result.error:
        print(f"{result.error}\n{result.log}")
        return 2
    print("\n".join(report(result)))
    return 0 if all(met for _, _, met in result.goals()) else 1


if __name__ == "__main__":
    sys.exit(main())
