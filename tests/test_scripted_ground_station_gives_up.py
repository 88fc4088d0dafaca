"""The scripted ground station (mecanum_mav/sim/groundstation.py) against a vehicle that does
not cooperate: it restarts a mission upload after the protocol's 1.5 s of silence and gives
up at its timeout, a download the vehicle stops answering is None (and not acknowledged)
after its timeout, a download of every item ends with the mission's MISSION_ACK accepted,
arming that the vehicle keeps refusing raises, a message that arrived by a wait's deadline is
seen, and a shared socket drops what a system without a view sent.

The vehicle here is the test's own :class:`~mecanum_mav.sim.groundstation.Port` in virtual
time: it hears what the ground station sends and answers as the test says."""

from __future__ import annotations

import select
import socket
from collections.abc import Callable
from itertools import pairwise
from typing import Any

import pytest

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.sim.groundstation import (
    GCS_COMPID,
    GCS_SYSID,
    MISSION_TIMEOUT_S,
    ScriptedGroundStation,
    fleet_ground_station,
)

PUMP_S = 0.05
"""How long the ground station lets pass between looks while it uploads (its pump)."""
ITEMS = [MissionItem(0, mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_CMD_NAV_WAYPOINT),
         MissionItem(1, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                     mavlink.MAV_CMD_NAV_WAYPOINT, x=473977420, y=85455940)]


class Vehicle:
    """The vehicle's end of the ground station's port, in virtual time: what the ground
    station sends is heard (with the time) and answered by ``answer``; the answers arrive at
    the next pump, which otherwise lets its whole timeout pass."""

    def __init__(self, answer: Callable[[Any], list[Any]] = lambda msg: []) -> None:
        self.time_s = 0.0
        self.heard: list[tuple[float, Any]] = []
        self.answer = answer
        self.outbox: list[Any] = []
        self.mav = mavlink.MAVLink(self, srcSystem=GCS_SYSID, srcComponent=GCS_COMPID)
        self.own = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self._hear = mavlink.MAVLink(None)
        self._decode = mavlink.MAVLink(None)

    def write(self, data: bytes) -> None:
        for msg in self._hear.parse_buffer(data) or ():
            self.heard.append((self.time_s, msg))
            self.send(*self.answer(msg))

    def send(self, *messages: Any) -> None:
        """Messages from the vehicle, delivered at the next pump."""
        for msg in messages:
            self.outbox += self._decode.parse_buffer(msg.pack(self.own)) or ()

    def times(self, kind: str) -> list[float]:
        return [t for t, msg in self.heard if msg.get_type() == kind]

    def now(self) -> float:
        return self.time_s

    def pump(self, timeout_s: float) -> list[Any]:
        if self.outbox:
            out, self.outbox = self.outbox, []
            return out
        self.time_s += timeout_s
        return []


def test_an_upload_the_vehicle_never_answers_restarts_after_each_silence_and_then_times_out():
    vehicle = Vehicle()
    gcs = ScriptedGroundStation(vehicle)
    with pytest.raises(TimeoutError):
        gcs.upload(ITEMS, timeout_s=5.0)
    counts = vehicle.times("MISSION_COUNT")
    assert counts[0] == 0.0
    gaps = [b - a for a, b in pairwise(counts)]
    assert len(gaps) == 3  # (5 s: three silences of just over 1.5 s)
    assert all(MISSION_TIMEOUT_S < gap <= MISSION_TIMEOUT_S + PUMP_S + 1e-9 for gap in gaps)
    assert vehicle.time_s >= 5.0


def answers_list_and_first_item(count: int) -> Callable[[Any], list[Any]]:
    """A vehicle that says it has ``count`` items and answers the request for item 0 only."""
    def answer(msg: Any) -> list[Any]:
        kind = msg.get_type()
        if kind == "MISSION_REQUEST_LIST":
            return [mavlink.MAVLink_mission_count_message(GCS_SYSID, GCS_COMPID, count, 0)]
        if kind == "MISSION_REQUEST_INT" and msg.seq == 0:
            it = ITEMS[0]
            return [mavlink.MAVLink_mission_item_int_message(
                GCS_SYSID, GCS_COMPID, 0, it.frame, it.command, 0, 1, 0.0, 0.0, 0.0, 0.0,
                it.x, it.y, it.z, 0)]
        return []
    return answer


def test_a_download_the_vehicle_never_answers_is_none():
    vehicle = Vehicle()
    assert ScriptedGroundStation(vehicle).download(timeout_s=1.0) is None
    assert vehicle.times("MISSION_REQUEST_LIST") == [0.0]
    assert vehicle.time_s == pytest.approx(1.0)  # it waited its timeout_s for MISSION_COUNT


def test_a_download_whose_item_request_goes_unanswered_is_none_and_not_acknowledged():
    vehicle = Vehicle(answers_list_and_first_item(2))
    assert ScriptedGroundStation(vehicle).download(timeout_s=1.0) is None
    assert [msg.seq for _, msg in vehicle.heard if msg.get_type() == "MISSION_REQUEST_INT"] == [
        0, 1]
    assert vehicle.times("MISSION_ACK") == []  # nothing was accepted


def test_a_download_of_every_item_ends_with_the_missions_mission_ack_accepted():
    # The mission protocol's download: the ground station acknowledges the last item with
    # MISSION_ACK, type MAV_MISSION_ACCEPTED, of the mission type it asked for (the mission).
    vehicle = Vehicle(answers_list_and_first_item(1))
    items = ScriptedGroundStation(vehicle).download(timeout_s=1.0)
    assert items is not None and [it.seq for it in items] == [0]
    (ack,) = [msg for _, msg in vehicle.heard if msg.get_type() == "MISSION_ACK"]
    assert (ack.target_system, ack.target_component) == (1, 1)
    assert ack.type == mavlink.MAV_MISSION_ACCEPTED
    assert ack.mission_type == mavlink.MAV_MISSION_TYPE_MISSION


def test_arming_a_vehicle_that_keeps_refusing_retries_until_the_timeout_then_raises():
    def refuse(msg: Any) -> list[Any]:
        if msg.get_type() == "COMMAND_LONG":
            return [mavlink.MAVLink_command_ack_message(
                msg.command, mavlink.MAV_RESULT_TEMPORARILY_REJECTED, 0, 0, GCS_SYSID,
                GCS_COMPID)]
        return []

    vehicle = Vehicle(refuse)
    with pytest.raises(RuntimeError, match="never accepted arming"):
        ScriptedGroundStation(vehicle).arm(timeout_s=1.0)
    tries = vehicle.times("COMMAND_LONG")
    assert len(tries) > 1 and all(t < 1.0 for t in tries)  # it retried, within the timeout
    assert vehicle.time_s >= 1.0


def test_a_message_that_arrived_by_the_deadline_of_a_wait_is_seen_even_with_no_time_left():
    vehicle = Vehicle()
    gcs = ScriptedGroundStation(vehicle)
    since = gcs.mark()
    vehicle.send(vehicle.own.heartbeat_encode(10, 3, 0, 0, 3))  # arrived, not yet looked at
    msg = gcs.wait("HEARTBEAT", timeout_s=0.0, since=since)
    assert msg is not None and msg.get_srcSystem() == 1
    assert vehicle.time_s == 0.0


def test_a_shared_ground_station_socket_drops_what_a_system_without_a_view_sent():
    stations, port = fleet_ground_station([1])
    senders = {sysid: mavlink.MAVLink(None, srcSystem=sysid, srcComponent=1) for sysid in (9, 1)}
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rovers:
        try:
            for mav in senders.values():  # a stranger first, then the rover
                rovers.sendto(mav.heartbeat_encode(10, 3, 0, 0, 3).pack(mav),
                              ("127.0.0.1", port.udp.link.local_port))
            assert select.select([port.udp.link.fileno()], [], [], 2.0)[0]
            gcs = stations[1]
            gcs.wait("HEARTBEAT", timeout_s=2.0, since=0)
            assert [m.get_srcSystem() for m in gcs.messages] == [1]
            assert port.unclaimed == 1
        finally:
            port.close()


def test_a_wait_in_virtual_time_ends_at_its_deadline_when_the_steps_sum_a_hair_short_of_it():
    """2 ms steps summed from 1.508 s reach 3.5079999999998 s, not 3.508: a wait of 2 s still
    ends (it once stepped no more and looped forever)."""
    from mecanum_mav.config.params import Params
    from mecanum_mav.sim.lockstep import Lockstep

    h = Lockstep(Params())
    h.run_for(1.508)
    start = h.now_s
    assert h.gcs.wait("STATUSTEXT", lambda m: False, 2.0) is None
    assert h.now_s - start == pytest.approx(2.0, abs=1e-6)
