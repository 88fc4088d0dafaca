"""The links' tlog recorder (mecanum_mav/io/links/parts.py): each packet stamped with the wall
clock in Unix microseconds, as MAVProxy and Mission Planner write and read tlogs; a write that
fails (a full disk, a closed file) is dropped and never stops the link."""

from __future__ import annotations

import io
import time
from pathlib import Path

from mecanum_mav.io.links.parts import Recorder
from mecanum_mav.io.tlog import parse_tlog
from mecanum_mav.protocol.dialect import mavlink


def heartbeat() -> bytes:
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    return bytes(mav.heartbeat_encode(10, 3, 0, 0, 3).pack(mav))


def test_each_packet_is_stamped_with_the_wall_clock_in_unix_microseconds():
    tlog = io.BytesIO()
    before = time.time()
    Recorder(tlog).packet(heartbeat())
    after = time.time()
    [entry] = parse_tlog(tlog.getvalue()).entries
    assert before - 1e-6 <= entry.time_s <= after + 1e-6
    assert entry.msg.get_type() == "HEARTBEAT"


def test_a_full_disk_or_a_closed_log_drops_the_record_and_never_raises():
    with Path("/dev/full").open("wb", buffering=0) as full:  # (every write: ENOSPC)
        Recorder(full).packet(heartbeat())
    closed = io.BytesIO()
    closed.close()
    Recorder(closed).packet(heartbeat())  # (ValueError: I/O on a closed file)
