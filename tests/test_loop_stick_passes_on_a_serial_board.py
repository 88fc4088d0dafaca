"""A pass that is a stick alone (:meth:`~mecanum_mav.runtime.loop.ControlLoop._next_stick`) with
the flight controller on a stream link (a serial board) and the ground station on datagrams:
while the board's link is up with nothing waiting, a stick right after a stick in its lane is
the whole pass, as with a datagram board; the ground station's link is not read again for
what might wait behind it (a read that finds nothing: 14 % of the companion's CPU per stick
at 1 kHz)."""

from __future__ import annotations

from typing import Any

from conftest import lockstep

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.runtime.loop import ControlLoop
from mecanum_mav.sim.wires import VirtualPoller


def test_on_a_serial_board_a_stick_right_after_a_stick_in_its_lane_is_the_whole_pass():
    h = lockstep()
    fc = h.loop.fc
    fc.steady = False  # (a stream link's way: a serial board)
    h.loop = ControlLoop(h.core, h.loop.gcs, fc, clock=h.loop.clock, poller=VirtualPoller())
    h.gcs.arm()
    h.gcs.sticks(500)
    h.run_for(0.2)  # driving: the lane is open
    pilot = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    gcs = h.loop.gcs
    reads: list[Any] = []
    receive = gcs.receive_datagram

    def watched_receive() -> Any:
        got = receive()
        reads.append(got)
        return got

    gcs.receive_datagram = watched_receive
    answered = h.lane_answers
    for i in range(50):
        h.inject(bytes(pilot.manual_control_encode(1, 400 + i, 0, 500, 0, 0).pack(pilot)))
        h.step()
    assert h.lane_answers >= answered + 50  # every stick in its lane, in its own step
    empty = sum(got is None for got in reads)
    assert empty < 25, (empty, len(reads))
