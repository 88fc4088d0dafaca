#!/usr/bin/env python3
"""Fuzz the real companion process on both links (issue 11.1): bad input from either link never
crashes the process and never moves a wheel.

Method
    The companion runs as its own process (``python -m mecanum_mav run --gcs
    udpin:127.0.0.1:P --fc udpout:127.0.0.1:Q --params FILE``, default parameters, in a
    temporary directory). This script plays both its peers on UDP loopback: a ground station
    (system 255, HEARTBEAT every 0.5 s) and a flight controller (system 1, HEARTBEAT at 1 Hz as
    ArduPilot). The hostile datagrams come from :class:`mecanum_mav.sim.fuzz.DatagramFuzzer`
    (the categories are listed there), sent from the peers' own sockets:

    1. baseline: valid, centred MANUAL_CONTROLs on the ground-station link, disarmed (a
       fiftieth of ``--gcs-count``, at least 1,000): what a datagram costs the companion when
       it is good input;
    2. gcs: ``--gcs-count`` fuzzed datagrams on the ground-station link, disarmed;
    3. the genuine ground station arms (COMMAND_LONG) in HOLD, its streams reset to default;
    4. fc: ``--fc-count`` fuzzed datagrams on the flight-controller link, armed and holding;
    5. lane: the genuine ground station sets ``SYSID_MYGCS`` to itself (PARAM_SET), disarms,
       sets MANUAL and arms; then ``--lane-count`` datagrams shaped like its stick that must
       move nothing (:meth:`~mecanum_mav.sim.fuzz.DatagramFuzzer.lane_datagram`: strangers'
       sticks, its own for another vehicle, out of range, corrupted or truncated, random
       bytes), one at a time so that the stick lane decides each, with its own centred stick
       every tenth: driving in MANUAL, the wheels must stay neutral;
    6. afterwards: drive with MANUAL_CONTROL x=500: the wheels must move; then SIGTERM: exit
       status 0, the last overrides neutral then released.

    Throughout, every RC_CHANNELS_OVERRIDE the flight controller receives must be neutral
    (each wheel's trim) or the release, the rover's HEARTBEAT must reach the ground station
    with no gap of 1.5 s or more, and every ODOMETRY and LOCAL_POSITION_NED must be finite
    (:class:`mecanum_mav.sim.fuzz.SafetyWatch`).

    Pacing: UDP drops what a receiver cannot take, so the datagrams go out in batches and the
    sender waits while the companion's socket holds more than half its receive buffer (its
    queue and drop counts are read from /proc/net/udp). The rate is datagrams sent per second
    over a phase, until the companion's queue is empty again; the kernel's drop count for the
    companion's socket is reported beside it (0 when the companion kept up), and so is the
    companion's own status line (messages received, malformed packets, refusals by kind;
    SIGUSR1 after each phase). CPU: the companion's (the kernel's clock of its process), as %
    of one core over the phase and as microseconds per datagram, and as a ratio to the
    baseline's per datagram.

The exit status is 0 when every check passed, 1 otherwise.

    .venv/bin/python tools/fuzz.py [--seed N] [--gcs-count N] [--fc-count N] [--lane-count N]
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import os
import selectors
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, TypeVar

from mecanum_mav.config.params import Params
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.io.links import Link, open_link
from mecanum_mav.io.paramfile import save
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.heartbeat import send_gcs_heartbeat
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.rcoverride import release_fields
from mecanum_mav.sim.fuzz import DatagramFuzzer, SafetyWatch
from mecanum_mav.sim.process import CompanionProcess, free_port

GCS_ID = (255, mavlink.MAV_COMP_ID_MISSIONPLANNER)
FC_ID = (1, 1)
GCS_BEAT_S = 0.5
FC_BEAT_S = 1.0
BATCH = 32
"""Datagrams sent between two looks at the companion's receive queue."""
ROVER = (1, 1)
STATUS_PREFIX = "mecanum-mav: received "
T = TypeVar("T")


# ---------------------------------------------------------------------------- the process


def udp_socket_state(port: int) -> tuple[int, int]:
    """(bytes queued, datagrams dropped) of the UDP socket bound to 127.0.0.1:``port``, from
    /proc/net/udp; (0, 0) if there is none."""
    wanted = f"0100007F:{port:04X}"
    with Path("/proc/net/udp").open() as table:
        for line in table:
            fields = line.split()
            if len(fields) > 12 and fields[1] == wanted:
                return int(fields[4].split(":")[1], 16), int(fields[12])
    return 0, 0


def receive_buffer_bytes() -> int:
    """A new UDP socket's receive buffer (bytes): what the companion's sockets get."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        return int(s.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF))


class FuzzedCompanion(CompanionProcess):
    """The companion process the fuzzer fires at (``--gcs`` listening on ``gcs_port``,
    ``--fc`` sending to ``fc_port``, a parameter file of defaults in ``workdir``), with its
    status line on request."""

    def __init__(self, workdir: Path, gcs_port: int, fc_port: int) -> None:
        params_path = workdir / "rover.parm"
        save(Params(), params_path)
        super().__init__(f"udpin:127.0.0.1:{gcs_port}", f"udpout:127.0.0.1:{fc_port}", workdir,
                         "--params", str(params_path))

    def status_lines(self) -> list[str]:
        return [line for line in self.log(10**7).splitlines() if line.startswith(STATUS_PREFIX)]

    def status(self, wait: Callable[[Callable[[], bool], float], bool]) -> str:
        """The status line it prints on SIGUSR1 (``wait`` pumps the peers meanwhile)."""
        before = len(self.status_lines())
        with contextlib.suppress(ProcessLookupError):
            self.proc.send_signal(signal.SIGUSR1)
        wait(lambda: len(self.status_lines()) > before, 5.0)
        lines = self.status_lines()
        return lines[-1][len("mecanum-mav: "):] if len(lines) > before else "(no status line)"


# ---------------------------------------------------------------------------- the peers


class Peers:
    """The ground station and the flight controller around the companion (see the module
    docstring); what they receive goes to :attr:`watch`."""

    def __init__(self, gcs_port: int, params: Params) -> None:
        self.params = params
        self.gcs: Link = open_link(f"udpout:127.0.0.1:{gcs_port}", source_system=GCS_ID[0],
                                   source_component=GCS_ID[1], name="fuzz-gcs")
        self.fc: Link = open_link("udpin:127.0.0.1:0", source_system=FC_ID[0],
                                  source_component=FC_ID[1], name="fuzz-fc")
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.gcs.fileno(), selectors.EVENT_READ, self.gcs)
        self.selector.register(self.fc.fileno(), selectors.EVENT_READ, self.fc)
        self.watch = SafetyWatch(params, time.monotonic())
        self.gcs_messages: list[Any] = []
        self.last_override: list[int] | None = None
        self.overrides_total = 0
        self._gcs_beat_s = self._fc_beat_s = -1.0
        self.heartbeat: Any = None

    @property
    def fc_port(self) -> int:
        port = self.fc.local_port
        assert port is not None
        return port

    def companion_fc_address(self) -> tuple[str, int] | None:
        """Where the companion's flight-controller link sends from (once it has)."""
        # pymavlink's udpin remembers the peers it heard from
        clients: set[tuple[str, int]] = getattr(self.fc.conn, "clients", set())
        if not clients:
            return None
        address = next(iter(clients))
        return str(address[0]), int(address[1])

    def beat(self, now: float) -> None:
        if now - self._gcs_beat_s >= GCS_BEAT_S:
            self._gcs_beat_s = now
            send_gcs_heartbeat(self.gcs.mav)
        if self.companion_fc_address() is not None and now - self._fc_beat_s >= FC_BEAT_S:
            self._fc_beat_s = now
            self.fc.mav.heartbeat_send(mavlink.MAV_TYPE_GROUND_ROVER,
                                       mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0,
                                       mavlink.MAV_STATE_ACTIVE)

    def pump(self, timeout_s: float) -> None:
        """Beat, and read what arrives within ``timeout_s``."""
        self.beat(time.monotonic())
        for key, _ in self.selector.select(timeout_s):
            link: Link = key.data
            messages = link.read()
            now = time.monotonic()
            if link is self.gcs:
                for msg in messages:
                    self.watch.on_gcs_message(msg, now)
                    if msg.get_type() == "HEARTBEAT" and msg.get_srcSystem() == ROVER[0]:
                        self.heartbeat = msg
                    elif msg.get_type() in ("COMMAND_ACK", "STATUSTEXT", "PARAM_VALUE"):
                        self.gcs_messages.append(msg)
            else:
                for msg in messages:
                    if msg.get_type() == "RC_CHANNELS_OVERRIDE":
                        channels = [getattr(msg, f"chan{i}_raw") for i in range(1, 19)]
                        self.watch.on_override(channels)
                        self.last_override = channels
                        self.overrides_total += 1

    def wait(self, done: Callable[[], bool], timeout_s: float) -> bool:
        """Pump until ``done()`` or ``timeout_s`` has passed; whether it is done."""
        deadline = time.monotonic() + timeout_s
        while not done():
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            self.pump(min(0.05, left))
        return True

    def seen_heartbeat(self) -> bool:
        """Whether the rover's HEARTBEAT arrived since the watch began."""
        return self.watch.heartbeats > 0

    def new_watch(self) -> SafetyWatch:
        """Start a new watch (a phase); returns the one that ends."""
        old = self.watch
        now = time.monotonic()
        old.finish(now)
        self.watch = SafetyWatch(self.params, now)
        return old

    def command(self, command: int, *params: float, timeout_s: float = 3.0) -> int | None:
        """COMMAND_LONG from the genuine ground station, retried; the ACK's result or None."""
        values = [*params, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0][:7]
        return self._request(lambda: self.gcs.mav.command_long_send(*ROVER, command, 0, *values),
                             partial(self._ack, command), timeout_s)

    def set_param(self, name: str, value: float, timeout_s: float = 3.0) -> float | None:
        """PARAM_SET from the genuine ground station, retried; the value its PARAM_VALUE
        reports, or None."""
        return self._request(lambda: self.gcs.mav.param_set_send(
            *ROVER, name.encode(), value, mavlink.MAV_PARAM_TYPE_REAL32),
            partial(self._param_value, name), timeout_s)

    def _request(self, send: Callable[[], None], answer: Callable[[int], T | None],
                 timeout_s: float) -> T | None:
        """``send()`` every half second until ``answer(since)`` finds the reply among the
        messages from index ``since`` on, or ``timeout_s`` has passed (None)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            mark = len(self.gcs_messages)
            send()
            if self.wait(lambda since=mark: answer(since) is not None,
                         min(0.5, max(0.0, deadline - time.monotonic()))):
                return answer(mark)
        return None

    def _ack(self, command: int, since: int) -> int | None:
        """The result of the first COMMAND_ACK for ``command`` from index ``since`` on."""
        return next((int(m.result) for m in self.gcs_messages[since:]
                     if m.get_type() == "COMMAND_ACK" and m.command == command), None)

    def _param_value(self, name: str, since: int) -> float | None:
        """The value of the first PARAM_VALUE for ``name`` from index ``since`` on."""
        return next((float(m.param_value) for m in self.gcs_messages[since:]
                     if m.get_type() == "PARAM_VALUE" and m.param_id == name), None)

    def manual(self, x: int = 0) -> None:
        self.gcs.mav.manual_control_send(ROVER[0], x, 0, 500, 0, 0)

    def close(self) -> None:
        self.selector.close()
        self.gcs.close()
        self.fc.close()


# ---------------------------------------------------------------------------- the phases


@dataclass
class Phase:
    name: str
    sent: int = 0
    seconds: float = 0.0
    cpu_s: float = 0.0
    dropped: int = 0
    paused: int = 0
    status: str = ""
    watch: SafetyWatch | None = None
    counts: dict[str, int] = field(default_factory=dict)

    @property
    def rate(self) -> float:
        return self.sent / self.seconds if self.seconds > 0 else 0.0

    @property
    def cpu_pct(self) -> float:
        return 100.0 * self.cpu_s / self.seconds if self.seconds > 0 else 0.0

    @property
    def us_per_datagram(self) -> float:
        return 1e6 * self.cpu_s / self.sent if self.sent else 0.0


def send_paced(peers: Peers, companion: FuzzedCompanion, phase: Phase,
               sock: socket.socket, dest: tuple[str, int], port: int, count: int,
               make: Callable[[], bytes], batch: int = BATCH) -> None:
    """Send ``count`` datagrams from ``make`` to ``dest`` (the companion's socket bound to
    ``port``) ``batch`` at a time, pacing on its receive queue; fills in the phase's figures.
    With ``batch`` 1 each waits until the companion has read the one before."""
    limit = receive_buffer_bytes() // 2
    _, dropped_before = udp_socket_state(port)
    cpu_before = companion.cpu_s()
    start = time.monotonic()
    sent, next_report = 0, start + 10.0
    while sent < count and companion.alive():
        for _ in range(min(batch, count - sent)):
            with contextlib.suppress(BlockingIOError):
                sock.sendto(make(), dest)
            sent += 1
        peers.pump(0.0)
        while udp_socket_state(port)[0] > (limit if batch > 1 else 0) and companion.alive():
            phase.paused += 1
            peers.pump(0.0005)
        if time.monotonic() >= next_report:
            next_report += 10.0
            elapsed = time.monotonic() - start
            print(f"  {phase.name}: {sent:,} sent, {sent / elapsed:,.0f}/s", flush=True)
    peers.wait(lambda: udp_socket_state(port)[0] == 0 or not companion.alive(), 10.0)
    phase.seconds = time.monotonic() - start
    phase.cpu_s = companion.cpu_s() - cpu_before
    phase.sent = sent
    phase.dropped = udp_socket_state(port)[1] - dropped_before


Checks = list[tuple[bool, str]]


def run(seed: int, gcs_count: int, fc_count: int, lane_count: int, workdir: Path
        ) -> tuple[list[Phase], Checks]:
    """All phases; (the phases, the checks as (passed, text))."""
    params = Params()
    pwm = PwmMap.from_params(params)
    released = release_fields(pwm.channels)
    gcs_port = free_port()
    peers = Peers(gcs_port, params)
    companion = FuzzedCompanion(workdir, gcs_port, peers.fc_port)
    checks: list[tuple[bool, str]] = []
    phases: list[Phase] = []

    def check(ok: bool, text: str) -> bool:
        checks.append((ok, text))
        return ok

    try:
        up = peers.wait(lambda: peers.heartbeat is not None
                        and peers.companion_fc_address() is not None, 20.0)
        # ... and the companion has decided on the flight controller's setup (its fake board
        # answers no parameter: "not checked"), as a pilot waits for before arming
        up = up and peers.wait(lambda: any(
            m.get_type() == "STATUSTEXT" and m.text.startswith("FC setup")
            for m in peers.gcs_messages), 20.0)
        if not check(up, "the companion starts and both links come up"):
            return phases, checks
        fuzzer = DatagramFuzzer(seed, rover_sysid=ROVER[0], gcs_sysid=GCS_ID[0],
                                fc_sysid=FC_ID[0], fc_compid=FC_ID[1])
        gcs_sock = peers.gcs.conn.port
        gcs_dest = ("127.0.0.1", gcs_port)
        centred = peers.gcs.mav.manual_control_encode(ROVER[0], 0, 0, 500, 0, 0).pack(
            peers.gcs.mav)

        # 1. baseline and 2. gcs, disarmed
        for name, count, make in (("baseline", max(1000, gcs_count // 50), lambda: centred),
                                  ("gcs", gcs_count, fuzzer.gcs_datagram)):
            peers.new_watch()
            phase = Phase(name)
            send_paced(peers, companion, phase, gcs_sock, gcs_dest, gcs_port, count, make)
            peers.wait(peers.seen_heartbeat, 1.5)  # a short phase: one heartbeat at least
            phase.status = companion.status(peers.wait)
            phase.watch = peers.new_watch()
            phases.append(phase)
            phase_checks(check, phase, companion)
            if not companion.alive():
                return phases, checks
        phases[-1].counts = dict(fuzzer.counts)
        fuzzer.counts.clear()

        # 3. arm in HOLD
        for stream in (mavlink.MAVLINK_MSG_ID_ODOMETRY, mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED):
            peers.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, stream, 0)
        peers.manual(0)
        hold = peers.command(mavlink.MAV_CMD_DO_SET_MODE,
                             mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, Mode.HOLD)
        armed = peers.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        accepted = mavlink.MAV_RESULT_ACCEPTED
        if not check(hold == accepted and armed == accepted,
                     f"the genuine ground station sets HOLD and arms (ACK results {hold}, "
                     f"{armed})"):
            return phases, checks

        # 4. fc, armed and holding
        peers.new_watch()
        phase = Phase("fc")
        dest = peers.companion_fc_address()
        assert dest is not None
        send_paced(peers, companion, phase, peers.fc.conn.port, dest, dest[1], fc_count,
                   fuzzer.fc_datagram)
        if not end_armed_phase(peers, companion, phase, fuzzer, Mode.HOLD,
                               "the flight-controller fuzz", phases, check):
            return phases, checks

        # 5. lane: the pilot drives in MANUAL, centred, among its stick's look-alikes
        pilot = peers.set_param("SYSID_MYGCS", GCS_ID[0])
        disarmed = peers.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0)
        manual = peers.command(mavlink.MAV_CMD_DO_SET_MODE,
                               mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, Mode.MANUAL)
        peers.manual(0)
        armed = peers.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        if not check(pilot == GCS_ID[0] and (disarmed, manual, armed) == (accepted,) * 3,
                     f"lane: SYSID_MYGCS set to {pilot}; disarm, MANUAL, arm accepted (ACK "
                     f"results {disarmed}, {manual}, {armed})"):
            return phases, checks
        peers.new_watch()
        phase = Phase("lane")
        fuzzer.counts.clear()
        turn = itertools.count()

        def lane_datagram() -> bytes:  # the pilot's own centred stick every tenth
            return centred if next(turn) % 10 == 0 else fuzzer.lane_datagram()

        send_paced(peers, companion, phase, gcs_sock, gcs_dest, gcs_port, lane_count,
                   lane_datagram, batch=1)
        if not end_armed_phase(peers, companion, phase, fuzzer, Mode.MANUAL,
                               "the stick lane's fuzz", phases, check):
            return phases, checks

        # 6. a normal drive
        fl = pwm.channels[0] - 1
        trim = pwm.neutral()[0]

        def drove() -> bool:
            peers.manual(500)
            last = peers.last_override
            return last is not None and last[fl] != trim

        moved = peers.wait(drove, 3.0)
        last = peers.last_override
        check(moved, f"afterwards: MANUAL_CONTROL x=500 drives (FL "
                     f"{last[fl] if last else None} us, trim {trim} us)")
        peers.manual(0)
        peers.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0)
        peers.new_watch()
        start_total = peers.overrides_total
        companion.proc.send_signal(signal.SIGTERM)
        try:
            code: int | None = companion.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            code = None
        peers.wait(lambda: peers.last_override == released, 1.0)
        check(code == 0 and peers.last_override == released
              and peers.overrides_total > start_total,
              f"SIGTERM: exit status {code}, last override "
              f"{'released' if peers.last_override == released else peers.last_override}")
        at_exit = companion.status_lines()[-1:]
        if at_exit:
            print(f"companion status at exit: {at_exit[0][len('mecanum-mav: '):]}")
        return phases, checks
    finally:
        if not all(ok for ok, _ in checks):
            print("companion log (tail):\n" + companion.log())
        companion.kill()
        peers.close()


def end_armed_phase(peers: Peers, companion: FuzzedCompanion, phase: Phase,
                    fuzzer: DatagramFuzzer, mode: Mode, what: str, phases: list[Phase],
                    check: Callable[[bool, str], bool]) -> bool:
    """After an armed phase's datagrams: a heartbeat at least, the companion's status, the
    watch's checks and that it is still armed in ``mode``; whether the process lives."""
    peers.wait(peers.seen_heartbeat, 1.5)
    phase.status = companion.status(peers.wait)
    phase.counts = dict(fuzzer.counts)
    beat = peers.heartbeat
    still = (beat is not None and bool(beat.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
             and beat.custom_mode == mode)
    phase.watch = peers.new_watch()
    phases.append(phase)
    phase_checks(check, phase, companion)
    check(still, f"still armed in {mode.name} after {what}")
    return companion.alive()


def phase_checks(check: Callable[[bool, str], bool], phase: Phase,
                 companion: FuzzedCompanion) -> None:
    w = phase.watch
    assert w is not None
    name = phase.name
    check(companion.alive(), f"{name}: the companion process is alive")
    check(w.bad_overrides == 0 and w.overrides > 0,
          f"{name}: {w.overrides:,} overrides, {w.bad_overrides} neither neutral nor released")
    check(w.worst_gap_s < 1.5 and w.heartbeats > 0,
          f"{name}: {w.heartbeats} HEARTBEATs, worst gap {w.worst_gap_s:.3f} s (< 1.5 s)")
    check(w.non_finite == 0 and w.telemetry > 0,
          f"{name}: {w.telemetry:,} ODOMETRY/LOCAL_POSITION_NED, {w.non_finite} not finite")
    tracebacks = companion.log(10**7).count("Traceback")
    check(w.faults == 0 and tracebacks == 0,
          f"{name}: {w.faults} exceptions caught by the core, {tracebacks} tracebacks logged")
    for example in w.examples:
        print(f"  {name}: {example}")


def report(phases: list[Phase], checks: list[tuple[bool, str]]) -> None:
    print(f"{'phase':<9} {'datagrams':>10} {'seconds':>8} {'rate/s':>8} {'paused':>7} "
          f"{'drops':>6} {'CPU %':>6} {'us/dgram':>9} {'x base':>7}")
    base = next((p.us_per_datagram for p in phases if p.name == "baseline"), 0.0)
    for p in phases:
        ratio = p.us_per_datagram / base if base else float("nan")
        print(f"{p.name:<9} {p.sent:>10,} {p.seconds:>8.1f} {p.rate:>8,.0f} {p.paused:>7,} "
              f"{p.dropped:>6,} {p.cpu_pct:>6.1f} {p.us_per_datagram:>9.1f} {ratio:>7.2f}")
    for p in phases:
        if p.counts:
            print(f"{p.name} categories: " + ", ".join(f"{k} {v:,}" for k, v in
                                                       sorted(p.counts.items())))
        print(f"{p.name} companion status: {p.status}")
    for ok, text in checks:
        print(f"{'PASS' if ok else 'FAIL'}  {text}")
    print("PASS" if checks and all(ok for ok, _ in checks) else "FAIL")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seed", type=int, default=1, help="the generator's seed (default 1)")
    parser.add_argument("--gcs-count", type=int, default=1_000_000,
                        help="fuzzed datagrams on the ground-station link (default 1,000,000)")
    parser.add_argument("--fc-count", type=int, default=200_000,
                        help="fuzzed datagrams on the flight-controller link (default 200,000)")
    parser.add_argument("--lane-count", type=int, default=50_000,
                        help="datagrams at the stick lane while the pilot drives, one in ten "
                             "the pilot's own (default 50,000)")
    args = parser.parse_args(argv)
    print(f"tools/fuzz.py: seed {args.seed}, {args.gcs_count:,} datagrams on the ground-station "
          f"link (disarmed), {args.fc_count:,} on the flight-controller link (armed, HOLD), "
          f"{args.lane_count:,} at the stick lane (armed, MANUAL); {os.cpu_count()} CPUs, "
          f"Python {sys.version.split()[0]}", flush=True)
    with tempfile.TemporaryDirectory(prefix="mecanum-fuzz-") as tmp:
        phases, checks = run(args.seed, args.gcs_count, args.fc_count, args.lane_count,
                             Path(tmp))
    report(phases, checks)
    return 0 if checks and all(ok for ok, _ in checks) else 1


if __name__ == "__main__":
    sys.exit(main())
