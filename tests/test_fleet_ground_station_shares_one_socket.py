"""The fleet's ground station (mecanum_mav/sim/groundstation.py's :class:`SharedUdpPort` and
:func:`fleet_ground_station`): one UDP socket on 127.0.0.1 for several vehicles, each
vehicle's port waiting up to its timeout for what that vehicle sent (returning early) while
the others' messages wait in their inboxes, and each vehicle's ground station addressing its
own system, component 1. The vehicles here are a plain UDP socket sending as each system."""

from __future__ import annotations

import select
import socket
import threading
import time
from typing import Any

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.groundstation import SharedUdpPort, fleet_ground_station


def _heartbeat(sysid: int) -> bytes:
    mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=1)
    return bytes(mav.heartbeat_encode(10, 3, 0, 0, 3).pack(mav))


def _heard(rovers: socket.socket, kind: str, deadline_s: float = 2.0) -> list[Any]:
    """The messages of ``kind`` in what ``rovers`` receives until one of them came."""
    parser = mavlink.MAVLink(None)
    deadline = time.monotonic() + deadline_s
    while time.monotonic() < deadline:
        if not select.select([rovers], [], [], max(0.0, deadline - time.monotonic()))[0]:
            break
        found = [m for m in parser.parse_buffer(rovers.recv(2048)) or ()
                 if m.get_type() == kind]
        if found:
            return found
    return []


def test_a_vehicles_port_waits_its_whole_timeout_for_that_vehicle_and_returns_early_on_it():
    port = SharedUdpPort()  # by default a socket of its own on 127.0.0.1
    address = ("127.0.0.1", port.udp.link.local_port)
    assert port.url == f"udpout:127.0.0.1:{address[1]}"
    first, second = port.view(1), port.view(2)
    done = threading.Event()

    def unstick() -> None:  # a wait that never ends gets something after 2 s
        if not done.wait(2.0):
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as late:
                late.sendto(_heartbeat(1), address)

    guard = threading.Thread(target=unstick, daemon=True)
    guard.start()
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rovers:
            start = time.monotonic()
            assert first.pump(0.1) == []  # nothing came: the whole 0.1 s, then nothing
            assert 0.1 <= time.monotonic() - start < 0.6
            for sysid in (9, 8, 2, 1):  # two strangers, the other vehicle, then this one
                rovers.sendto(_heartbeat(sysid), address)
            start = time.monotonic()
            assert [m.get_srcSystem() for m in first.pump(2.0)] == [1]
            assert time.monotonic() - start < 1.0  # returned when it came
            assert [m.get_srcSystem() for m in second.pump(0.0)] == [2]  # it waited
            assert port.unclaimed == 2  # the strangers', dropped
    finally:
        done.set()
        guard.join()
        port.close()


def test_each_vehicles_ground_station_addresses_its_system_component_1():
    stations, port = fleet_ground_station([1, 2])
    address = ("127.0.0.1", port.udp.link.local_port)
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rovers:
            rovers.sendto(_heartbeat(2), address)  # the socket learns where the rovers are
            assert stations[2].wait("HEARTBEAT", timeout_s=2.0, since=0) is not None
            for sysid in (2, 1):
                stations[sysid].command(mavlink.MAV_CMD_REQUEST_MESSAGE, 0, timeout_s=0.0)
                (command,) = _heard(rovers, "COMMAND_LONG")
                assert (command.target_system, command.target_component) == (sysid, 1)
    finally:
        port.close()
