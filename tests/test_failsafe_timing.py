"""The link failsafes fire in the real process, measured from outside.

The companion runs as its own process (``mecanum-mav run``) between two UDP peers played by the
test: a ground station and a flight controller, each sending HEARTBEAT at 10 Hz. In each trial
both stop (the flight controller 0.25 s after the ground station), each failsafe's STATUSTEXT
("GCS link lost", "Flight controller link lost") reaches the ground station, and not before
the timeout since the last HEARTBEAT sent (a lower bound a loaded machine cannot break: it
only delays); then both beat again until the companion reports both links back. Causal
checks with generous deadlines: when the failsafes fire is asserted exactly, within one step
of the timeout, in virtual time (test_failsafe_deadlines.py, the same scenario in the
lockstep harness); the delays measured here are printed, not judged.
"""

from __future__ import annotations

import selectors
import time
from collections.abc import Callable
from pathlib import Path

from sitl import CompanionProcess

from mecanum_mav.io.links import Link, open_link
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.heartbeat import send_gcs_heartbeat

TRIALS = 5
TIMEOUT_S = 0.5
DEADLINE_S = 10.0
"""How long a trial's failsafe (or a link's return) may take before the test gives up."""
BEAT_PERIOD_S = 0.1
FC_LAG_S = 0.25
"""The flight controller falls silent this long after the ground station."""
GCS_LOST, FC_LOST = "GCS link lost", "Flight controller link lost"
GCS_BACK, FC_BACK = "GCS link regained", "Flight controller link up"


class Peers:
    """The ground station and the flight controller around the companion, on UDP loopback.

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


def test_gcs_and_fc_failsafes_fire_after_their_timeouts_and_both_links_come_back_in_5_trials(
        tmp_path: Path) -> None:
    peers = Peers()
    settings = ["--set", f"FS_GCS_TMO={TIMEOUT_S}", "--set", f"FS_FC_TMO={TIMEOUT_S}"]
    try:
        with CompanionProcess(peers.url(peers.gcs), peers.url(peers.fc), tmp_path,
                              *settings) as companion:
            start = time.monotonic()
            assert peers.run_until(lambda: peers.said_since(FC_BACK, start) is not None, 15.0), (
                companion.log())
            gcs_delays: list[float] = []
            fc_delays: list[float] = []
            for _ in range(TRIALS):
                trial = time.monotonic()
                peers.gcs_beating = peers.fc_beating = True
                assert peers.run_until(lambda t=trial: time.monotonic() - t > 0.3, DEADLINE_S)
                peers.gcs_beating = False
                gcs_last = peers.gcs_beat_s
                assert peers.run_until(lambda g=gcs_last: time.monotonic() - g > FC_LAG_S,
                                       DEADLINE_S)
                peers.fc_beating = False
                fc_last = peers.fc_beat_s
                assert peers.run_until(
                    lambda g=gcs_last, f=fc_last: (peers.said_since(GCS_LOST, g) is not None
                                                   and peers.said_since(FC_LOST, f) is not None),
                    DEADLINE_S), companion.log()
                gcs_fired = peers.said_since(GCS_LOST, gcs_last)
                fc_fired = peers.said_since(FC_LOST, fc_last)
                assert gcs_fired is not None and fc_fired is not None, companion.log()
                gcs_delays.append(gcs_fired - gcs_last)
                fc_delays.append(fc_fired - fc_last)
                back = time.monotonic()
                peers.gcs_beating = peers.fc_beating = True
                assert peers.run_until(
                    lambda b=back: (peers.said_since(GCS_BACK, b) is not None
                                    and peers.said_since(FC_BACK, b) is not None), DEADLINE_S), (
                    companion.log())
            assert companion.proc.poll() is None, companion.log()
    finally:
        peers.close()
    report = (f"GCS worst {max(gcs_delays):.3f} s, FC worst {max(fc_delays):.3f} s, "
              f"best {min(gcs_delays + fc_delays):.3f} s")
    print(report)
    for delays in (gcs_delays, fc_delays):
        assert len(delays) == TRIALS
        assert all(d > TIMEOUT_S for d in delays), (delays, report)  # never early
