"""The last words at shutdown over a stream link: neutral, then the release, go before anything
else waiting in the link (dropped: it would come out of sequence), in order, none replaced,
and the close waits for the wire to carry them, however slow the baud rate
(docs/companion.md: every way out ends at neutral, then the channels go back to the radio)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

from support import PtyFlightController, override_channels
from test_link_timing import START_S, serial
from test_links import FakeClock

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.runtime.loop import NEUTRAL_HOLD_S
from mecanum_mav.sim.groundstation import udp_ground_station

NEUTRAL, RELEASE, DRIVE = [1500] * 4, [0] * 4, [1700] * 4


def fields(wheels: list[int]) -> list[int]:
    return wheels + [65535] * 4 + [0] * 10


def test_the_last_words_pass_what_waits_in_order_and_none_replaces_another(tmp_path: Path):
    clock = FakeClock()
    with serial(tmp_path, 9600, clock) as (link, pty):
        link.send_rc_override(1, 1, fields(DRIVE))  # on the wire
        link.mav.heartbeat_send(6, 8, 0, 0, 0)  # waiting: a heartbeat, then a newer drive
        link.send_rc_override(1, 1, fields(DRIVE))
        link.send_rc_override(1, 1, fields(NEUTRAL), replace=False)
        link.send_rc_override(1, 1, fields(NEUTRAL), replace=False)
        link.send_rc_override(1, 1, fields(RELEASE), replace=False)
        link.send_rc_override(1, 1, fields(DRIVE))  # (a late tick's: after them)
        seen = []
        for step in range(1, 40):
            clock.now = START_S + 0.05 * step  # an override is ~52 ms on the wire at 9600
            link.flush()
            seen += pty.messages()
        kinds = [override_channels(m)[:4] if m.get_type() == "RC_CHANNELS_OVERRIDE"
                 else m.get_type() for m in seen]
        # the waiting heartbeat was numbered before the neutrals: dropped, not sent after them
        assert kinds == [DRIVE, NEUTRAL, NEUTRAL, RELEASE, DRIVE], kinds
        seqs = [m.get_seq() for m in seen]
        assert seqs == sorted(seqs)  # in the order they were numbered
        assert link.unsent == 1  # the heartbeat: the board sees one number missing
        assert seqs[-1] - seqs[0] + 1 == len(seqs) + link.unsent
        assert link.superseded == 1  # the waiting drive, by the first neutral


def shutdown_seen(baud: int) -> tuple[list[tuple[float, list[int]]], float]:
    """(When each override arrived, relative to the start of ``close()``, and its wheels) for
    a companion on a serial board at ``baud``, closed while it sends its steady overrides;
    and how long ``close()`` took."""
    fc = PtyFlightController()
    _gcs, port = udp_ground_station()  # (the companion's ground-station end)
    companion = Companion(Params(), port.url, f"{fc.path},{baud}")
    seen: list[tuple[float, list[int]]] = []
    stop = threading.Event()

    def board() -> None:
        while not stop.is_set():
            before = len(fc.messages)
            fc.pump(0.005)
            now = time.monotonic()
            seen.extend((now, override_channels(m)[:4]) for m in fc.messages[before:]
                        if m.get_type() == "RC_CHANNELS_OVERRIDE")

    thread = threading.Thread(target=board, daemon=True)
    thread.start()
    try:
        companion.start()
        deadline = time.monotonic() + 10.0
        while len(seen) < 3 and time.monotonic() < deadline:  # (its steady overrides flow)
            time.sleep(0.01)
        assert len(seen) >= 3, "no overrides reached the board"
        start = time.monotonic()
        companion.close()
        took = time.monotonic() - start
        deadline = time.monotonic() + 3.0
        while (not seen or seen[-1][1] != RELEASE) and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        stop.set()
        thread.join(2.0)
        port.close()
        fc.close()
    return [(t - start, wheels) for t, wheels in seen], took


def test_at_2400_baud_the_neutrals_and_the_release_all_reach_the_board_before_it_closes():
    """At 2400 baud an override is 0.2 s on the wire, longer than the close's linger: the
    last words still all arrive, after whatever was queued for the flight controller."""
    seen, took = shutdown_seen(2400)
    after = [wheels for t, wheels in seen if t >= 0.0]
    assert after[-3:] == [NEUTRAL, NEUTRAL, RELEASE], after
    assert took < 2.5


def test_at_a_fast_baud_the_release_comes_the_neutral_hold_after_the_first_neutral():
    seen, _ = shutdown_seen(921600)
    after = [(t, wheels) for t, wheels in seen if t >= 0.0]
    assert [wheels for _, wheels in after[-3:]] == [NEUTRAL, NEUTRAL, RELEASE], after
    first_neutral, release = after[-3][0], after[-1][0]
    assert NEUTRAL_HOLD_S - 0.01 <= release - first_neutral < NEUTRAL_HOLD_S + 0.1
