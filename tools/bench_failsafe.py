#!/usr/bin/env python3
"""Benchmark how late the link failsafes fire in wall-clock time (issue 11).

Method
    The system under test (SUT) runs as its own process between two UDP peers played by this
    script (:class:`Peers`): a ground station and a flight controller, each sending HEARTBEAT
    every 0.1 s. In each trial both stop, the flight controller 0.25 s after the ground
    station; the delay from the last HEARTBEAT sent to the STATUSTEXT that reports the
    failsafe ("GCS link lost", "Flight controller link lost"), as the ground station receives
    it, is recorded; then both beat again until the SUT reports both links back. Timeouts:
    0.5 s (FS_GCS_TMO, FS_FC_TMO, the shortest the schema allows). Two SUTs, in the same run:

    - companion: ``python -m mecanum_mav run`` with those timeouts;
    - floor (the baseline): :func:`run_floor`, the least a Python process does for the same
      answer: two ``udpout`` links in a ``select`` loop that wakes at the earliest deadline,
      says the same texts, and nothing else.

    Lateness = delay - timeout. The companion's is reported beside the floor's, as a ratio.

Goals (issue 11)
    - every failsafe fires after its timeout and within the timeout + 0.3 s.
    The ratio of the companion's worst lateness to the floor's is printed without a goal.

Exit status 0 when the goal is met, 1 when not, 2 when a SUT could not be started.

    python tools/bench_failsafe.py [--trials 30]

The exact deadlines are asserted in virtual time by tests/test_failsafe_deadlines.py; the
real-process test (tests/test_failsafe_timing.py) runs a few trials of this tool's
:func:`run_trials` and asserts only that the failsafes fire (never early) and the links return.
"""

from __future__ import annotations

import argparse
import selectors
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from mecanum_mav.io.links import Link, open_link
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.heartbeat import send_gcs_heartbeat
from mecanum_mav.sim.process import CompanionProcess

TIMEOUT_S = 0.5
GOAL_MARGIN_S = 0.3
DEADLINE_S = 10.0
"""How long a trial's failsafe (or a link's return) may take before the run gives up."""
BEAT_PERIOD_S = 0.1
FC_LAG_S = 0.25
"""The flight controller falls silent this long after the ground station."""
GCS_LOST, FC_LOST = "GCS link lost", "Flight controller link lost"
GCS_BACK, FC_BACK = "GCS link regained", "Flight controller link up"


class Peers:
    """The ground station and the flight controller around the SUT, on UDP loopback.

    :meth:`run_until` sends each peer's HEARTBEAT every ``BEAT_PERIOD_S`` while it is beating
    (``gcs_beating``, ``fc_beating``), remembers when each was last sent, and records every
    STATUSTEXT the ground station receives with its arrival time (monotonic s).
    """

    def __init__(self) -> None:
        self.gcs: Link = open_link("udpin:127.0.0.1:0", source_system=255,
                                   source_component=mavlink.MAV_COMP_ID_MISSIONPLANNER,
                                   name="test-gcs")
        self.fc: Link = open_link("udpin:127.0.0.1:0", source_system=1, source_component=1,
                                  name="test-fc")
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.gcs.fileno(), selectors.EVENT_READ, self.gcs)
        self.selector.register(self.fc.fileno(), selectors.EVENT_READ, self.fc)
        self.gcs_beating = self.fc_beating = True
        self.gcs_beat_s = self.fc_beat_s = -1.0
        self.texts: list[tuple[float, str]] = []
        self._heard: set[str] = set()

    def url(self, link: Link) -> str:
        return f"udpout:127.0.0.1:{link.local_port}"

    def _beat(self, now: float) -> None:
        # udpin answers the address it last heard: nothing to send to before that
        if self.gcs_beating and "gcs" in self._heard and now - self.gcs_beat_s >= BEAT_PERIOD_S:
            self.gcs_beat_s = time.monotonic()
            send_gcs_heartbeat(self.gcs.mav)
        if self.fc_beating and "fc" in self._heard and now - self.fc_beat_s >= BEAT_PERIOD_S:
            self.fc_beat_s = time.monotonic()
            self.fc.mav.heartbeat_send(mavlink.MAV_TYPE_GROUND_ROVER,
                                       mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0,
                                       mavlink.MAV_STATE_STANDBY)

    def run_until(self, done: Callable[[], bool], timeout_s: float) -> bool:
        """Pump both links (and beat) until ``done()`` or the deadline; whether it is done."""
        deadline = time.monotonic() + timeout_s
        while not done():
            now = time.monotonic()
            if now > deadline:
                return False
            self._beat(now)
            wait = min(BEAT_PERIOD_S / 4, deadline - now)
            for key, _ in self.selector.select(max(0.0, wait)):
                link: Link = key.data
                messages = link.read()
                arrived = time.monotonic()
                self._heard.add("gcs" if link is self.gcs else "fc")
                for msg in messages if link is self.gcs else ():
                    if msg.get_type() == "STATUSTEXT":
                        self.texts.append((arrived, msg.text))
        return True

    def said_since(self, text: str, since_s: float) -> float | None:
        """When ``text`` first arrived at or after ``since_s``, or None."""
        return next((t for t, said in self.texts if t >= since_s and text in said), None)

    def close(self) -> None:
        self.selector.close()
        self.gcs.close()
        self.fc.close()


@dataclass
class Trials:
    """The failsafe delays of a run (s from the last HEARTBEAT sent), and why it stopped
    early (empty if it did not)."""

    gcs: list[float] = field(default_factory=list)
    fc: list[float] = field(default_factory=list)
    error: str = ""

    def lateness_s(self) -> list[float]:
        return [d - TIMEOUT_S for d in self.gcs + self.fc]


def run_trials(peers: Peers, trials: int) -> Trials:
    """``trials`` trials against the SUT the peers are connected to (module description)."""
    out = Trials()
    start = time.monotonic()
    if not peers.run_until(lambda: peers.said_since(FC_BACK, start) is not None, 15.0):
        out.error = "the flight controller link never came up"
        return out
    for _ in range(trials):
        trial = time.monotonic()
        peers.gcs_beating = peers.fc_beating = True
        peers.run_until(lambda t=trial: time.monotonic() - t > 0.3, DEADLINE_S)
        peers.gcs_beating = False
        gcs_last = peers.gcs_beat_s
        peers.run_until(lambda g=gcs_last: time.monotonic() - g > FC_LAG_S, DEADLINE_S)
        peers.fc_beating = False
        fc_last = peers.fc_beat_s
        if not peers.run_until(
                lambda g=gcs_last, f=fc_last: (peers.said_since(GCS_LOST, g) is not None
                                               and peers.said_since(FC_LOST, f) is not None),
                DEADLINE_S):
            out.error = "a failsafe never fired"
            return out
        out.gcs.append((peers.said_since(GCS_LOST, gcs_last) or 0.0) - gcs_last)
        out.fc.append((peers.said_since(FC_LOST, fc_last) or 0.0) - fc_last)
        back = time.monotonic()
        peers.gcs_beating = peers.fc_beating = True
        if not peers.run_until(lambda b=back: (peers.said_since(GCS_BACK, b) is not None
                                               and peers.said_since(FC_BACK, b) is not None),
                               DEADLINE_S):
            out.error = "the links never came back"
            return out
    return out


# ---------------------------------------------------------------------------- the floor


def run_floor(gcs_url: str, fc_url: str, timeout_s: float) -> None:
    """The baseline SUT (its own process): the failsafe texts and nothing else."""
    gcs = open_link(gcs_url, source_system=1, source_component=1, name="gcs")
    fc = open_link(fc_url, source_system=255, source_component=190, name="fc")
    texts = {gcs: (GCS_LOST, GCS_BACK), fc: (FC_LOST, FC_BACK)}
    seen: dict[Link, float | None] = {gcs: None, fc: None}
    lost = {gcs: True, fc: True}  # (the first HEARTBEAT says the link is up)
    for link in (gcs, fc):
        send_gcs_heartbeat(link.mav)  # hello: the peers answer what they heard

    def say(text: str) -> None:
        gcs.mav.statustext_send(mavlink.MAV_SEVERITY_CRITICAL, text.encode())

    with selectors.DefaultSelector() as selector:
        for link in (gcs, fc):
            selector.register(link.fileno(), selectors.EVENT_READ, link)
        while True:
            due = min((s + timeout_s for link, s in seen.items()
                       if s is not None and not lost[link]), default=time.monotonic() + 1.0)
            for key, _ in selector.select(max(0.0, due - time.monotonic())):
                link = key.data
                if any(m.get_type() == "HEARTBEAT" for m in link.read()):
                    seen[link] = time.monotonic()
                    if lost[link]:
                        lost[link] = False
                        say(texts[link][1])
            now = time.monotonic()
            for link, s in seen.items():
                if s is not None and not lost[link] and now - s > timeout_s:
                    lost[link] = True
                    say(texts[link][0])


@contextmanager
def floor_process(peers: Peers) -> Iterator[subprocess.Popen[bytes]]:
    proc = subprocess.Popen([sys.executable, __file__, "--floor", peers.url(peers.gcs),
                             peers.url(peers.fc)])
    try:
        yield proc
    finally:
        proc.kill()
        proc.wait()


def companion_settings() -> list[str]:
    return ["--set", f"FS_GCS_TMO={TIMEOUT_S}", "--set", f"FS_FC_TMO={TIMEOUT_S}"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    parser.add_argument("--trials", type=int, default=30)
    parser.add_argument("--floor", nargs=2, metavar=("GCS_URL", "FC_URL"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.floor:
        run_floor(*args.floor, TIMEOUT_S)
        return 0
    results: dict[str, Trials] = {}
    for name in ("floor", "companion"):
        peers = Peers()
        try:
            if name == "floor":
                with floor_process(peers):
                    results[name] = run_trials(peers, args.trials)
            else:
                with tempfile.TemporaryDirectory() as tmp, CompanionProcess(
                        peers.url(peers.gcs), peers.url(peers.fc), Path(tmp),
                        *companion_settings()):
                    results[name] = run_trials(peers, args.trials)
        finally:
            peers.close()
        if results[name].error:
            print(f"{name}: {results[name].error}")
            return 2
    print(f"{args.trials} trials each, timeouts {TIMEOUT_S} s; python {sys.version.split()[0]}")
    for name, trials in results.items():
        late = trials.lateness_s()
        print(f"{name:9s}: lateness best {min(late) * 1e3:.1f} ms, worst {max(late) * 1e3:.1f} ms "
              f"(GCS worst {max(trials.gcs):.3f} s, FC worst {max(trials.fc):.3f} s)")
    ratio = max(results["companion"].lateness_s()) / max(results["floor"].lateness_s())
    print(f"ratio companion/floor: worst lateness {ratio:.2f}")
    delays = results["companion"].gcs + results["companion"].fc
    met = all(TIMEOUT_S < d <= TIMEOUT_S + GOAL_MARGIN_S for d in delays)
    print(f"every failsafe after its timeout and within +{GOAL_MARGIN_S} s: "
          f"{max(delays):.3f} s worst: {'met' if met else 'NOT MET'}")
    return 0 if met else 1


if __name__ == "__main__":
    sys.exit(main())
