"""The companion's loop (:class:`~mecanum_mav.runtime.loop.ControlLoop`) as the lockstep harness
steps it: the pass the companion runs, wake for wake."""

from __future__ import annotations

import contextlib
import math
import select
import selectors
import socket
from typing import Any, cast

import pytest
from conftest import lockstep

from mecanum_mav.control.core import COMPANION_COMPID
from mecanum_mav.io.links import open_link
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.signing import REFUSED_TEXTS, Check, SignatureCheck
from mecanum_mav.runtime.loop import ControlLoop
from mecanum_mav.sim.wires import SIGNING_START_TICKS, VirtualPoller


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


def _stick(pilot: Any, x: int) -> bytes:
    return bytes(pilot.manual_control_encode(1, x, 0, 500, 0, 0).pack(pilot))


def test_a_stick_right_after_a_stick_in_its_lane_is_the_whole_pass():
    """Sticks one per wake (1 kHz from a joystick): after a stick the lane answered, with the
    core settled, the next wake that is a stick alone is answered in the lane and the pass
    ends there, without looking at the timers again (the core's ``next_due_s`` not asked)."""
    h = lockstep()
    h.gcs.arm()
    h.gcs.sticks(500)
    h.run_for(0.2)  # driving: the lane is open
    pilot = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    asked: list[float] = []
    next_due_s = h.core.next_due_s

    def watched_next_due_s() -> float:
        asked.append(h.now_s)
        return next_due_s()

    h.core.next_due_s = watched_next_due_s  # type: ignore[method-assign]
    answered = h.lane_answers
    for i in range(50):
        h.inject(_stick(pilot, 400 + i))
        h.step()
    assert h.lane_answers >= answered + 50  # every stick in its lane, in its own step
    assert len(asked) < 25  # most passes were the stick alone (the board's messages and
    # the core's own timers take the rest)


def test_what_arrives_behind_a_stick_in_a_pass_of_sticks_is_read_at_once():
    """A pass that is a stick alone reads only the stick; what waits behind it (a heartbeat of
    the ground station, or the flight controller's message) is read and handled in the same
    step: the loop's next wait returns at once, as the companion's level-triggered epoll
    does, and the harness runs that pass in the step."""
    h = lockstep()
    h.gcs.arm()
    h.gcs.sticks(500)
    h.run_for(0.2)
    pilot = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    board = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    passes_of_sticks = 0
    for i in range(20):
        h.inject(_stick(pilot, 400 + i))
        h.step()  # a stick in its lane: the next pass may be a stick alone
        passes_of_sticks += h.loop._sticks_until_s > -math.inf
        answered = h.lane_answers
        h.inject(_stick(pilot, 300 + i))
        h.inject(bytes(pilot.heartbeat_encode(6, 8, 0, 0, 4).pack(pilot)))
        h.step()
        assert h.lane_answers == answered + 1
        assert h.core.vehicle.gcs_seen_s == h.now_s  # the heartbeat, read behind it
        h.inject(_stick(pilot, 200 + i))
        h.step()
        h.inject(_stick(pilot, 100 + i))
        h.inject(bytes(board.heartbeat_encode(10, 3, 0, 0, 4).pack(board)), from_fc=True)
        h.step()
        assert h.core.vehicle.fc_seen_s == h.now_s  # the flight controller's, in the same step
    assert passes_of_sticks >= 10  # (the case this test is about was there)


def test_sticks_every_wake_leave_the_telemetry_and_heartbeats_their_rates():
    """A pass that is a stick alone ends only while the core has nothing else to do: with a
    stick in every wake for a second, the ground station gets the companion's heartbeats and
    telemetry as often as with a stick in every tenth."""
    h = lockstep()
    h.gcs.arm()
    h.gcs.sticks(500)
    h.run_for(0.2)
    pilot = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    h.fc_link_up = False  # only the sticks wake the loop (for less than FS_FC_TMO)

    def counts(since: int) -> dict[str, int]:
        kinds = [m.get_type() for m in h.gcs.messages[since:]]
        return {kind: kinds.count(kind) for kind in ("HEARTBEAT", "LOCAL_POSITION_NED",
                                                      "ATTITUDE", "SYS_STATUS")}

    since = h.gcs.mark()
    for i in range(500):  # 1 s, a stick in every tenth wake (50 Hz)
        if i % 10 == 0:
            h.inject(_stick(pilot, 400 + i % 100))
        h.step()
    calm = counts(since)
    since, answered = h.gcs.mark(), h.lane_answers
    for i in range(500):  # 1 s, a stick in every wake
        h.inject(_stick(pilot, 400 + i % 100))
        h.step()
    assert h.lane_answers >= answered + 500
    busy = counts(since)
    assert all(calm[kind] >= 1 for kind in calm), calm
    for kind, n in calm.items():
        assert abs(busy[kind] - n) <= 1, (kind, busy, calm)


def test_a_lane_write_the_kernel_took_in_part_is_followed_in_that_pass():
    """A serial board's link that took only part of the lane's packet (its kernel buffer
    full) has the rest waiting: the pass of sticks ends there and the rest of the pass
    watches the link for writing at once, not after the next stick."""
    h = lockstep()
    fc = h.loop.fc
    fc.steady = False  # (a stream link's way: a serial board)
    poller = VirtualPoller()
    h.loop = ControlLoop(h.core, h.loop.gcs, fc, clock=h.loop.clock, poller=poller)
    h.gcs.arm()
    h.gcs.sticks(500)
    h.run_for(0.2)
    pilot = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    for i in range(100):  # until the next pass may be a stick alone
        h.inject(_stick(pilot, 400 + i))
        h.step()
        if h.loop._sticks_until_s > -math.inf:
            break
    assert h.loop._sticks_until_s > -math.inf
    send = fc.send_packet

    def sent_in_part(packet: bytes) -> None:
        send(packet)
        fc.pending = fc.wants_write = True  # the rest waits in the link

    fc.send_packet = sent_in_part  # type: ignore[method-assign]
    answered = h.lane_answers
    h.inject(_stick(pilot, 300))
    h.step()
    assert h.lane_answers == answered + 1
    assert poller.get_key(fc.wait_fd()).events == selectors.EVENT_READ | selectors.EVENT_WRITE


def test_a_pass_that_answered_a_stick_yields_the_cpu_before_its_housekeeping_and_only_then():
    """A pty delivers the stick's override from a kernel worker on the writer's CPU, which
    runs only when the companion sleeps or yields: a pass that answered a stick in its lane
    and goes on to housekeeping (telemetry: a few hundred microseconds) yields first, so the
    override is not held behind it, whether the stick woke a whole pass or a pass of sticks
    alone. Passes without a stick in the lane never yield."""
    h = lockstep()
    h.gcs.arm()
    h.gcs.sticks(500)
    h.run_for(0.2)
    pilot = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    events: list[str] = []
    housekeeping, answered = h.core.housekeeping, h.loop._answer_first

    def watched_housekeeping(now_s: float) -> Any:
        events.append("housekeeping")
        return housekeeping(now_s)

    def watched_answer_first(link: Any, now_s: float) -> bool:
        laned = answered(link, now_s)
        if laned:
            events.append("stick")
        return laned

    h.core.housekeeping = watched_housekeeping  # type: ignore[method-assign]
    h.loop._answer_first = watched_answer_first  # type: ignore[method-assign]
    h.loop.poller.yield_cpu = lambda: events.append("yield")  # type: ignore[method-assign]
    for i in range(1000):  # 1 s at 50 Hz (a stick every tenth 2 ms step), then 1 s at 500 Hz
        if i % 10 == 0 or i >= 500:  # (passes of sticks alone: ControlLoop._next_stick)
            h.inject(_stick(pilot, 400 + i % 100))
        events.append("pass")
        h.step()
    passes = [p.split() for p in " ".join(events).split("pass")[1:]]
    with_stick = [p for p in passes if "stick" in p and "housekeeping" in p]
    without = [p for p in passes if "stick" not in p and "housekeeping" in p]
    assert len(with_stick) >= 3 and len(without) >= 3  # (both kinds were there)
    assert all(p.index("yield") < p.index("housekeeping") for p in with_stick), with_stick
    assert all("yield" not in p for p in passes if "stick" not in p)


@pytest.mark.parametrize("timer", ["next_reopen_s", "next_send_s"])
@pytest.mark.parametrize("name", ["gcs", "fc"])
def test_the_loop_sleeps_until_a_links_timer_when_it_comes_before_the_cores(name: str,
                                                                             timer: str):
    """Module docstring, step 1: the pass waits until the earliest thing due, the core's next
    timer or a link's own: a broken link is reopened at its ``next_reopen_s``, a packet
    waiting for the wire goes at its ``next_send_s``. Waking only at the core's timer would
    leave a serial board unplugged and plugged back in unopened, or an override paced behind
    another waiting, until the core had something to do."""
    h = lockstep()
    h.run_for(1.0)
    core_due = h.core.next_due_s()
    assert h.now_s + 2 * h.dt_s < core_due < math.inf
    link_due = (h.now_s + core_due) / 2
    setattr(getattr(h.loop, name), timer, link_due)  # (the virtual links' timers: inf)
    timeouts: list[float] = []
    wait = h.loop.poller.wait

    def watched_wait(timeout_s: float) -> list[tuple[Any, int]]:
        timeouts.append(timeout_s)
        return wait(timeout_s)

    h.loop.poller.wait = watched_wait  # type: ignore[method-assign]
    h.step()
    assert timeouts[0] == pytest.approx(link_due - h.now_s)


def test_packets_the_flight_controller_link_refuses_unsigned_are_said_as_the_boards():
    """With ``--fc-signing-key`` the flight controller's link drops the board's unsigned
    packets; the ground station is told they were the board's (a board without the key,
    :data:`~mecanum_mav.control.refusals.FC_SIGNATURE_REFUSED`), not that its own packets
    were refused."""
    h = lockstep()
    fc = h.loop.fc
    check = SignatureCheck(bytes(range(32)), SIGNING_START_TICKS)
    fc.inbound.parser.check = check  # the board's link checks signatures from now on
    fc.signature_check = check
    since = h.gcs.mark()
    h.run_for(1.5)  # (the board's heartbeats, unsigned)
    said = [m.text for m in h.gcs.received("STATUSTEXT", since)]
    assert "FC sent unsigned: board has no signing key" in said
    assert REFUSED_TEXTS[Check.UNSIGNED] not in said


def test_a_wake_of_the_ground_stations_datagram_link_with_no_datagram_answers_no_stick():
    """``_answer_first``: with no datagram waiting (the read found none: a wake it was not
    for, or the link's break) nothing was answered in the lane: the pass goes on as one
    without a stick (its housekeeping: the core was told of the break) and never yields the
    CPU as after a stick (see the test above)."""
    h = lockstep()
    h.gcs.arm()
    h.gcs.sticks(500)
    h.run_for(0.2)
    events: list[str] = []
    housekeeping = h.core.housekeeping

    def watched_housekeeping(now_s: float) -> Any:
        events.append("housekeeping")
        return housekeeping(now_s)

    h.core.housekeeping = watched_housekeeping  # type: ignore[method-assign]
    h.loop.poller.yield_cpu = lambda: events.append("yield")  # type: ignore[method-assign]
    h.link_down("gcs", "connection closed")  # the link's descriptor wakes, no datagram
    h.step()
    assert events == ["housekeeping"]


@pytest.mark.parametrize("way", ["general", "lane"])
def test_a_udpin_ground_station_link_answers_whoever_sent_the_datagram_the_loop_read(way: str):
    """``udpin:`` (mecanum_mav.io.links.udpin): the link answers the peers it heard a valid
    message from. The loop reads the ground station's first datagram itself (its stick may
    take the lane), so it hands the link each datagram's sender, read the general way (a
    heartbeat) or answered in the lane (a stick): a pilot on a new port is answered from
    then on (the rover's heartbeats reach it)."""
    h = lockstep()
    h.gcs.arm()
    h.gcs.sticks(500)
    h.run_for(0.2)  # driving: the lane is open
    gcs = open_link("udpin:127.0.0.1:0", source_system=1, source_component=COMPANION_COMPID,
                    name="gcs", clock=h.loop.clock)
    pilot = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        pilot.bind(("127.0.0.1", 0))
        pilot.setblocking(False)

        def readable() -> bool:
            return bool(select.select([gcs.wait_fd()], [], [], 0)[0])

        gcs.readable = readable  # type: ignore[attr-defined]  # (the virtual poller asks it)
        h.loop = ControlLoop(h.core, cast(Any, gcs), h.loop.fc, clock=h.loop.clock,
                             poller=VirtualPoller())
        answer_first = h.loop._answer_first
        answers: list[bool] = []

        def watched_answer_first(link: Any, now_s: float) -> bool:
            answers.append(answer_first(link, now_s))
            return answers[-1]

        h.loop._answer_first = watched_answer_first  # type: ignore[method-assign]
        mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        datagram = (_stick(mav, 400) if way == "lane"
                    else bytes(mav.heartbeat_encode(6, 8, 0, 0, 4).pack(mav)))
        pilot.sendto(datagram, ("127.0.0.1", gcs.conn.port.getsockname()[1]))
        h.step()
        assert answers == [way == "lane"]
        h.run_for(1.1)  # (the rover's heartbeat, once a second)
        heard = mavlink.MAVLink(None)
        got: list[str] = []
        with contextlib.suppress(BlockingIOError):
            while True:
                got += [m.get_type() for m in heard.parse_buffer(pilot.recv(4096)) or []]
        assert "HEARTBEAT" in got
    finally:
        pilot.close()
        gcs.close()


def test_failed_sends_on_both_links_are_counted_together_in_the_status_line_and_sys_status():
    """``link_counts``: what both links counted, for the status line (SIGUSR1 and at exit:
    ``received N, malformed N, send failures N, refused N (...)``) and SYS_STATUS
    ``errors_comm`` (malformed + refused + failed sends): 3 failed sends to the ground
    station and 2 to the flight controller are 5."""
    h = lockstep()
    h.run_for(1.0)
    gcs, fc = h.loop.gcs, h.loop.fc
    gcs.send_errors, fc.send_errors = 3, 2  # type: ignore[misc]
    assert h.core.status_line() == (f"received {gcs.received + fc.received}, malformed 0, "
                                    "send failures 5, refused 0 (none)")
    since = h.gcs.mark()
    h.run_for(1.5)
    assert [m.errors_comm for m in h.gcs.received("SYS_STATUS", since)][-1] == 5


def test_a_ground_station_on_a_stream_link_drives_without_the_stick_lane():
    """Module docstring, step 2: only a datagram link from the ground station has its first
    datagram answered in the stick lane; on a stream link (``tcp:``, serial) the stick takes
    the general way, read with the rest, and the rover drives all the same."""
    h = lockstep()
    gcs = h.loop.gcs
    gcs.steady = False  # (a stream link's way)
    h.loop = ControlLoop(h.core, gcs, h.loop.fc, clock=h.loop.clock, poller=VirtualPoller())
    h.gcs.arm()
    h.gcs.sticks(500)
    h.run_for(0.5)
    pilot = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    for i in range(20):
        h.inject(_stick(pilot, 400 + i))
        h.step()
    assert h.lane_answers == 0
    assert h.core.vehicle.armed and any(p != 1500 for p in h.core.pulses_us)


def _stream_fc() -> Any:
    """The harness with the flight controller on a stream link (a serial board)."""
    h = lockstep()
    fc = h.loop.fc
    fc.steady = False
    h.loop = ControlLoop(h.core, h.loop.gcs, fc, clock=h.loop.clock, poller=VirtualPoller())
    return h


def test_a_broken_stream_link_is_reopened_on_its_timer_and_the_core_told_before_anything_goes():
    """Module docstring: a broken link is reopened on its own timer (``next_reopen_s``,
    ``reopen``); when it is back the core is told (``core.link_up``: "FC link reconnected")
    before anything else is sent, so the flight controller's first override is neutral."""
    h = _stream_fc()
    fc = h.loop.fc
    h.gcs.arm()
    h.gcs.sticks(500)
    h.run_for(0.5)
    h.link_down("fc", "device gone")
    h.run_for(0.3)
    assert not fc.up
    back_s = h.now_s + 0.5

    def reopen(now_s: float) -> bool:  # (the device is there again at back_s)
        if now_s >= back_s:
            fc.down_reason, fc.next_reopen_s, h.fc_link_up = None, math.inf, True
        return bool(fc.up)

    fc.reopen = reopen  # type: ignore[method-assign]
    fc.next_reopen_s = back_s
    since = h.gcs.mark()
    h.run_for(1.0)
    said = [m.text for m in h.gcs.received("STATUSTEXT", since)]
    assert "FC link reconnected" in said
    first = h.overrides_since(back_s)[0]
    assert first.time_s == pytest.approx(back_s, abs=h.dt_s)
    assert set(first.channels[:4]) == {1500}


def test_a_stream_link_that_breaks_on_a_send_is_reported_with_the_time_of_the_pass():
    """A link that breaks while the pass sends on it (serial device gone, peer closed) is
    reported to the core once, at the end of that pass (``core.link_down`` at that time): said
    once as a WARNING, and the flight controller's failsafe fires."""
    h = _stream_fc()
    fc = h.loop.fc
    h.run_for(1.0)
    send_all = fc.send_all
    broke: list[float] = []

    def breaking_send_all(messages: Any) -> None:
        send_all(messages)
        if not broke:  # the write failed: the link is down (not readable: no read finds it)
            broke.append(h.now_s)
            fc.down_reason = "device gone"

    fc.send_all = breaking_send_all  # type: ignore[method-assign]
    since = h.gcs.mark()
    h.run_for(1.5)
    said = [m.text for m in h.gcs.received("STATUSTEXT", since)]
    assert said.count("FC link down: device gone; reconnecting") == 1
    assert h.core.vehicle.fc_lost


def test_an_idle_rovers_refresh_wake_is_the_tick_alone_with_a_stream_link_too():
    """Module docstring, step 3: housekeeping is skipped while the core is settled and the
    stream links are idle: an idle rover's refresh wake is its override alone, with the
    flight controller on a stream link (a serial board) as on a datagram one."""
    h = _stream_fc()
    h.run_for(2.0)
    events: list[str] = []
    tick, housekeeping = h.core.tick, h.core.housekeeping

    def watched_tick(now_s: float) -> Any:
        events.append("tick")
        return tick(now_s)

    def watched_housekeeping(now_s: float) -> Any:
        events.append("housekeeping")
        return housekeeping(now_s)

    h.core.tick = watched_tick  # type: ignore[method-assign]
    h.core.housekeeping = watched_housekeeping  # type: ignore[method-assign]
    for _ in range(1000):
        events.append("pass")
        h.step()
    passes = [p.split() for p in " ".join(events).split("pass")[1:]]
    assert sum(p == ["tick"] for p in passes) >= 10  # the refreshes, nothing else
    assert sum(p == ["tick", "housekeeping"] for p in passes) >= 10  # (its telemetry)


def test_a_wake_for_writing_alone_hands_over_and_reads_nothing():
    """Module docstring, steps 2 and 4: a stream link watched for writing (the kernel refused
    more) that wakes the loop only for writing has nothing to read: what waits in it is handed
    over (``follow``), and it is not read (a read that finds nothing is a syscall and a raised
    ``BlockingIOError`` wasted, on every such wake)."""
    h = lockstep()
    fc = h.loop.fc
    fc.steady = False

    class WritablePoller(VirtualPoller):
        def wait(self, timeout_s: float) -> list[tuple[Any, int]]:
            ready = super().wait(timeout_s)
            if fc.wants_write and not fc.readable():
                ready.append((fc, select.EPOLLOUT))  # (the kernel takes more now)
            return ready

    h.loop = ControlLoop(h.core, h.loop.gcs, fc, clock=h.loop.clock, poller=WritablePoller())
    h.run_for(1.0)
    reads: list[bool] = []  # per read of the board's link: whether anything was there
    read = fc.read

    def watched_read() -> list[Any]:
        reads.append(fc.readable())
        return read()

    fc.read = watched_read  # type: ignore[method-assign]
    fc.pending = fc.wants_write = True  # the kernel refused more: something waits
    h.run_for(0.2)
    fc.pending = fc.wants_write = False
    h.run_for(0.5)
    assert reads and all(reads)
