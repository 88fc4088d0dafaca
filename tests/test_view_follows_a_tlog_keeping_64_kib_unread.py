"""A tlog followed as it grows (mecanum_mav.app.view.TlogFollower): a record cut short by the
writer waits for its rest, with at most ``_MAX_TAIL`` (64 KiB) of the file kept unread; more
unread than that is dropped, so damage in a followed file never grows the memory held."""

from __future__ import annotations

from pathlib import Path

from mecanum_mav.app.view import _MAX_TAIL, TlogFollower
from mecanum_mav.io.tlog import tlog_record
from mecanum_mav.protocol.dialect import mavlink

BASE_US = 1_800_000_000_000_000
CUT = 12
"""Bytes of a record written before the rest: its stamp and the packet's first bytes."""


def _record(k: int) -> bytes:
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    packet = mav.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,
                                  mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, k, 3).pack(mav)
    return tlog_record(BASE_US + k * 100_000, packet)


def _junk(n: int) -> bytes:
    """``n`` bytes that are no MAVLink (no start byte)."""
    return bytes(n)


def _times(follower: TlogFollower) -> list[float]:
    return [t for t, _ in follower.poll()]


def test_a_record_cut_short_after_exactly_64_kib_unread_waits_for_its_rest(
        tmp_path: Path) -> None:
    assert _MAX_TAIL == 64 * 1024
    one, two = _record(1), _record(2)
    path = tmp_path / "live.tlog"
    path.write_bytes(_junk(_MAX_TAIL - CUT) + one[:CUT])  # 64 KiB unread, nothing complete
    follower = TlogFollower(path)
    try:
        assert follower.poll() == []
        with path.open("ab") as f:  # (after the record: 64 KiB unread again)
            f.write(one[CUT:] + _junk(_MAX_TAIL - CUT) + two[:CUT])
        assert _times(follower) == [BASE_US / 1e6 + 0.1]
        with path.open("ab") as f:
            f.write(two[CUT:])
        assert _times(follower) == [BASE_US / 1e6 + 0.2]
    finally:
        follower.close()


def test_more_than_64_kib_unread_is_dropped_and_what_follows_is_read(tmp_path: Path) -> None:
    one, two = _record(1), _record(2)
    path = tmp_path / "live.tlog"
    path.write_bytes(_junk(_MAX_TAIL + 1 - CUT) + one[:CUT])  # one byte too many unread
    follower = TlogFollower(path)
    try:
        assert follower.poll() == []
        with path.open("ab") as f:
            f.write(one[CUT:])  # the dropped record's rest: junk now, kept unread
        assert follower.poll() == []
        rest = len(one) - CUT
        with path.open("ab") as f:  # 64 KiB unread with it
            f.write(_junk(_MAX_TAIL - rest - CUT) + two[:CUT])
        assert follower.poll() == []
        with path.open("ab") as f:
            f.write(two[CUT:])
        assert _times(follower) == [BASE_US / 1e6 + 0.2]
    finally:
        follower.close()
