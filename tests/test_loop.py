"""The companion's loop (:class:`~mecanum_mav.runtime.loop.ControlLoop`) as the lockstep harness
steps it: the pass the companion runs, wake for wake."""

from __future__ import annotations

import selectors
from typing import Any

from conftest import lockstep

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.runtime.loop import ControlLoop
from mecanum_mav.sim.wires import VirtualPoller


def test_a_pass_that_wakes_before_anything_is_due_with_nothing_to_read_does_nothing():
    """In GUIDED the core never settles, so only the wake rule keeps a pass from ticking: the
    harness steps the loop every 2 ms, the companion would sleep until its next timer."""
    h = lockstep()
    h.gcs.arm()
    h.gcs.set_mode(Mode.GUIDED)
    h.run_for(0.5)
    assert h.core.vehicle.mode is Mode.GUIDED and h.core.vehicle.armed
    passes: list[list[Any]] = []  # per pass: [timeout given to the poller, ready?, ticks]
    wait, tick = h.loop.poller.wait, h.core.tick

    def watched_wait(timeout_s: float) -> list[tuple[Any, int]]:
        ready = wait(timeout_s)
        passes.append([timeout_s, bool(ready), 0])
        return ready

    def watched_tick(now_s: float) -> Any:
        passes[-1][2] += 1
        return tick(now_s)

    h.loop.poller.wait = watched_wait  # type: ignore[method-assign]
    h.core.tick = watched_tick  # type: ignore[method-assign]
    h.run_for(1.0)
    asleep = [p for p in passes if p[0] > 0.0 and not p[1]]
    assert len(asleep) > len(passes) // 2  # most steps fall between the companion's wakes
    assert all(ticks == 0 for _, _, ticks in asleep)
    assert sum(p[2] for p in passes) >= 50  # it ticked at its wakes (control, refresh, board)


def test_the_first_datagram_waiting_takes_the_lane_even_with_more_behind_it():
    """The shipped rule, now the harness's too (its own was "exactly one datagram queued"): a
    stick with the ground station's heartbeat behind it in the same wake is answered in the
    lane, and the heartbeat read after it."""
    h = lockstep()
    h.gcs.arm()
    h.gcs.sticks(500)
    h.run_for(0.1)  # driving: the lane is open
    pilot = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    answered = h.lane_answers
    h.inject(bytes(pilot.manual_control_encode(1, 500, 0, 500, 0, 0).pack(pilot)))
    h.inject(bytes(pilot.heartbeat_encode(6, 8, 0, 0, 4).pack(pilot)))
    h.step()
    assert h.lane_answers == answered + 1
    assert h.core.vehicle.gcs_seen_s == h.now_s  # the heartbeat, read after it


def test_a_settled_pass_still_watches_a_stream_link_on_the_descriptor_it_has_now():
    """A ``tcpin`` link swaps its descriptor in the read when a client connects. The pass
    that read it registers the new one even when nothing else is due (the loop skips the
    rest of an idle pass); else the client's messages would wait for the next timer."""
    h = lockstep()
    gcs = h.loop.gcs
    gcs.steady = False  # (the stream links' way: followed on every pass that is not idle)
    poller = VirtualPoller()
    h.loop = ControlLoop(h.core, gcs, h.loop.fc, clock=h.loop.clock, poller=poller)
    h.run_for(1.0)
    assert h.run_until(lambda: h.core.settled(h.now_s + h.dt_s), 2.0)
    old_fd = gcs.wait_fd()
    gcs._fd = old_fd + 1000  # a client connected: its socket is the link's descriptor now
    gcs.come_back()  # (what the read finds: readable once)
    h.step()
    assert h.core.settled(h.now_s)  # the pass had nothing else to do
    assert poller.get_key(old_fd + 1000).data is gcs


def test_a_settled_pass_stops_watching_for_writing_once_nothing_waits():
    """A stream link the kernel refused is watched for writing too; when what waited went
    out by another way than the loop's follow (a send's own flush), the next pass, idle as
    it is, watches it for reading only again: else every pass would wake at once, forever."""
    h = lockstep()
    gcs = h.loop.gcs
    gcs.steady = False
    poller = VirtualPoller()
    h.loop = ControlLoop(h.core, gcs, h.loop.fc, clock=h.loop.clock, poller=poller)
    h.run_for(1.0)
    gcs.pending = gcs.wants_write = True  # the kernel refused more: something waits
    assert h.run_until(lambda: poller.get_key(gcs.wait_fd()).events
                       == selectors.EVENT_READ | selectors.EVENT_WRITE, 1.0)
    gcs.pending = gcs.wants_write = False  # handed over by a send's flush
    assert h.run_until(lambda: h.core.settled(h.now_s + h.dt_s), 2.0)
    gcs.come_back()  # (something to read: the pass runs)
    h.step()
    assert h.core.settled(h.now_s)
    assert poller.get_key(gcs.wait_fd()).events == selectors.EVENT_READ
