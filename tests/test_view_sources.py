"""What the live view reads (mecanum_mav.app.view's sources): a batch holds every message
that has arrived, an idle source waits its time before an empty batch (the view never spins),
several sources share that wait and are merged in time order, ties included.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Generator
from pathlib import Path
from typing import Any

import pytest

from mecanum_mav.app import view
from mecanum_mav.io.tlog import tlog_record
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.process import free_port

BASE_US = 1_800_000_000_000_000


def _heartbeat(mav: Any) -> bytes:
    return bytes(mav.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,
                                      mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3).pack(mav))


def _tlog(path: Path, sysid: int, count: int = 3) -> Path:
    mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=1)
    path.write_bytes(b"".join(tlog_record(BASE_US + k * 100_000, _heartbeat(mav))
                              for k in range(count)))
    return path


def test_a_batch_from_a_link_holds_every_message_that_has_arrived() -> None:
    port = free_port(socket.SOCK_DGRAM)
    batches = view._messages(f"udpin:127.0.0.1:{port}", 0.05)
    try:
        assert next(batches) == []  # listening now
        mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            for seq in range(3):
                mav.seq = seq
                sender.sendto(_heartbeat(mav), ("127.0.0.1", port))
        batch = next(batches)
        deadline = time.monotonic() + 5.0
        while not batch and time.monotonic() < deadline:
            batch = next(batches)
    finally:
        batches.close()
    assert [msg.get_seq() for _, msg in batch] == [0, 1, 2]  # one batch, in order


@pytest.mark.parametrize("source", ["link", "tlog"])
def test_an_idle_source_waits_its_time_before_an_empty_batch(
        source: str, tmp_path: Path) -> None:
    wait_s = 0.2
    if source == "link":
        connect = f"udpin:127.0.0.1:{free_port(socket.SOCK_DGRAM)}"
    else:
        connect = str(_tlog(tmp_path / "drive.tlog", 1))
    batches = view._messages(connect, wait_s)
    try:
        next(batches)  # (open; a tlog's records so far)
        started = time.monotonic()
        assert next(batches) == []
        assert time.monotonic() - started >= wait_s * 0.95
    finally:
        batches.close()


def test_a_tlogs_records_come_at_once_without_a_wait(tmp_path: Path) -> None:
    batches = view._messages(str(_tlog(tmp_path / "drive.tlog", 1)), 4.0)
    try:
        started = time.monotonic()
        assert len(next(batches)) == 3
        assert time.monotonic() - started < 2.0  # not the idle wait
    finally:
        batches.close()


def test_several_sources_share_the_wait_of_one(monkeypatch: pytest.MonkeyPatch) -> None:
    waits: list[tuple[str, float]] = []

    def source(connect: str, wait_s: float = view._WAIT_S
               ) -> Generator[list[tuple[float, Any]], None, None]:
        waits.append((connect, wait_s))
        while True:
            yield []

    monkeypatch.setattr(view, "_messages", source)
    batches = view.merged(["a", "b", "c"])
    assert next(batches) == []
    batches.close()
    assert waits == [(c, view._WAIT_S / 3) for c in "abc"]


def test_sources_are_merged_in_time_order_and_messages_at_the_same_time_are_both_kept(
        tmp_path: Path) -> None:
    a = _tlog(tmp_path / "a.tlog", sysid=1)
    b = _tlog(tmp_path / "b.tlog", sysid=2)  # the same stamps
    batches = view.merged([str(a), str(b)])
    try:
        batch = next(batches)
    finally:
        batches.close()
    times = [t for t, _ in batch]
    assert times == sorted(times) and len(batch) == 6
    assert sorted(msg.get_srcSystem() for _, msg in batch) == [1, 1, 1, 2, 2, 2]
