"""The tlog reader's fast path (the companion's codec) against pymavlink's decode alone: the
same entries (messages, fields, times, offsets), problems and unknown count, on a sample
drive's tlog, on one with signed, MAVLink 1, unknown and odd-flagged packets, and on either
damaged anyhow."""

from __future__ import annotations

import io
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support import mavlink_sender

from mecanum_mav.io import tlog
from mecanum_mav.io.tlog import TlogRead, parse_tlog, tlog_record
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.sampledrive import sample_drive

KEY = bytes(range(32))
T0_US = 1_700_000_000_000_000


@pytest.fixture(scope="module")
def drive() -> bytes:
    buf = io.BytesIO()
    sample_drive(buf)
    return buf.getvalue()


def odd_packets() -> list[bytes]:
    """Packets of every kind the fast path leaves to pymavlink or takes beside plain MAVLink
    2: signed, MAVLink 1, an id this dialect does not know, an incompat flag it does not
    know, a payload longer than the dialect's."""
    plain = mavlink_sender(sysid=1, compid=1)
    signed = mavlink_sender(KEY, sysid=255, compid=190, link_id=2, timestamp=10**12)
    heartbeat = bytes(plain.heartbeat_encode(10, 3, 0x81, 15, 4).pack(plain))
    unknown = bytearray(heartbeat)
    unknown[7] = 0xFF  # message id 255: not in the dialect
    flagged = bytearray(heartbeat)
    flagged[2] = 0x02  # an incompat flag pymavlink ignores and the codec does not take
    crc = mavlink.x25crc(bytes(flagged[1:-2]))
    crc.accumulate(bytes((mavlink.MAVLink_heartbeat_message.crc_extra,)))
    flagged[-2:] = crc.crc.to_bytes(2, "little")
    return [
        heartbeat,
        bytes(signed.manual_control_encode(1, 500, -200, 500, 300, 0).pack(signed)),
        bytes(signed.statustext_encode(4, b"signed and long enough").pack(signed)),
        bytes(plain.attitude_encode(1000, 0.1, -0.2, 1.5, 0.0, 0.0, 0.1).pack(
            plain, force_mavlink1=True)),
        bytes(unknown),
        bytes(flagged),
        bytes(plain.odometry_encode(1, 1, 1, 0.5, -0.25, 0.0, [1.0, 0.0, 0.0, 0.0], 0.1, 0.2,
                                    0.0, 0.0, 0.0, 0.3, [float("nan")] * 21,
                                    [float("nan")] * 21, 0, 0, 0).pack(plain)),
    ]


def odd_tlog() -> bytes:
    return b"".join(tlog_record(T0_US + 20_000 * k, packet)
                    for k, packet in enumerate(odd_packets() * 3))


def slow_read(data: bytes, monkeypatch: pytest.MonkeyPatch) -> TlogRead:
    """The reader as it was: every packet through pymavlink's decode."""
    with monkeypatch.context() as m:
        m.setattr(tlog, "decode_datagram", lambda datagram: None)
        return parse_tlog(data, "x.tlog")


def held(msg: Any) -> str:
    """Everything a message object holds, its header's fields included (repr: NaN equals
    NaN, -0.0 is not 0.0, bytes and bytearray differ)."""
    state = dict(vars(msg))
    state["_header"] = vars(state["_header"])
    return f"{type(msg).__name__} {sorted(state.items())!r}"


def snapshot(read: TlogRead) -> tuple[Any, ...]:
    return (read.name, read.size, read.problems, read.unknown,
            [(e.time_s.hex(), e.offset, held(e.msg)) for e in read.entries])


def test_the_fast_read_of_a_sample_drive_equals_pymavlinks_entry_for_entry(
        drive, monkeypatch):
    fast = parse_tlog(drive, "x.tlog")
    assert len(fast.entries) > 3000 and fast.problems == []
    assert snapshot(fast) == snapshot(slow_read(drive, monkeypatch))


def test_signed_mavlink1_and_odd_packets_read_as_pymavlink_reads_them(monkeypatch):
    data = odd_tlog()
    fast = parse_tlog(data, "x.tlog")
    assert fast.unknown == 3 and fast.problems == []
    assert {e.msg.get_type() for e in fast.entries} == {
        "HEARTBEAT", "MANUAL_CONTROL", "STATUSTEXT", "ATTITUDE", "ODOMETRY"}
    assert snapshot(fast) == snapshot(slow_read(data, monkeypatch))


def test_only_what_the_codec_cannot_take_goes_through_pymavlinks_decode(drive, monkeypatch):
    calls = []
    decode = mavlink.MAVLink.decode

    def counted(self: Any, msgbuf: bytearray) -> Any:
        calls.append(bytes(msgbuf))
        return decode(self, msgbuf)

    monkeypatch.setattr(mavlink.MAVLink, "decode", counted)
    parse_tlog(drive)
    assert calls == []  # every packet of the drive, signed and MAVLink 1 alike: the codec's
    parse_tlog(odd_tlog())
    assert [packet[7] for packet in calls] == [0xFF, 0, 0xFF, 0, 0xFF, 0]
    assert [packet[2] for packet in calls] == [0, 2] * 3  # the unknown id, the odd flag


@st.composite
def damage(draw: st.DrawFn, good: bytes) -> bytes:
    """``good`` with a few parts flipped, inserted, deleted or cut off."""
    data = bytearray(good)
    for _ in range(draw(st.integers(1, 4))):
        how = draw(st.sampled_from(["flip", "insert", "delete", "cut", "stamp"]))
        at = draw(st.integers(0, max(len(data) - 1, 0)))
        if how == "flip" and data:
            data[at] ^= draw(st.integers(1, 255))
        elif how == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=40))
        elif how == "delete":
            del data[at:at + draw(st.integers(1, 40))]
        elif how == "cut":
            del data[at:]
        else:  # a plausible stamp and a start byte: what a resync looks for
            data[at:at] = tlog_record(T0_US, draw(st.sampled_from([b"\xfd", b"\xfe", b""])))
    return bytes(data)


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_a_damaged_tlog_reads_as_pymavlink_reads_it(drive, monkeypatch, data):
    sample = data.draw(st.sampled_from(["drive", "odd"]))
    good = odd_tlog() if sample == "odd" else drive[:6000]
    damaged = data.draw(damage(good))
    fast = parse_tlog(damaged, "x.tlog")
    assert snapshot(fast) == snapshot(slow_read(damaged, monkeypatch))


@pytest.mark.parametrize("tail", [b"", b"\xfe", b"\xfd", b"\xfd\x09"], ids=[
    "a timestamp alone", "a MAVLink 1 start byte", "a MAVLink 2 start byte",
    "a MAVLink 2 header begun"])
def test_a_tlog_cut_off_in_its_last_records_header_reads_every_whole_record_and_says_where(
        tail: bytes):
    """(A companion killed mid-write: the file ends in the last record's stamp or header.)"""
    good = odd_tlog()
    whole = parse_tlog(good, "x.tlog")
    cut = good + tlog_record(T0_US, b"")[:8] + tail
    read = parse_tlog(cut, "x.tlog")
    assert len(read.entries) == len(whole.entries) and not whole.problems
    assert read.problems == [f"x.tlog: truncated at byte {len(good)} (last record "
                             f"incomplete, {8 + len(tail)} bytes)"]
