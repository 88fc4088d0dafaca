"""The tlog reader's promises about damage (mecanum_mav/io/tlog.py's docstring): a last record
cut short is "truncated at byte N", anything else that is not a record (an implausible
timestamp, no MAVLink start byte after the stamp, a packet whose CRC does not check) is "not
MAVLink (skipped)", records are timestamped from 1995 to 2100 inclusive, and after damage the
reader goes on at the very next valid record: MAVLink 1 as MAVLink 2, and whatever bytes the
damage or the next record's own timestamp hold."""

from __future__ import annotations

import pytest
from support import mavlink_sender

from mecanum_mav.io.tlog import EARLIEST_US, LATEST_US, parse_tlog, tlog_record

T0_US = 1_700_000_000_000_000


def heartbeat(*, mavlink1: bool = False) -> bytes:
    mav = mavlink_sender(sysid=1, compid=1)
    return bytes(mav.heartbeat_encode(10, 3, 0x81, 15, 4).pack(mav, force_mavlink1=mavlink1))


def good_log(n: int = 3, *, mavlink1: bool = False) -> bytes:
    return b"".join(tlog_record(T0_US + 20_000 * k, heartbeat(mavlink1=mavlink1))
                    for k in range(n))


def truncated(at: int, size: int) -> str:
    return f"x.tlog: truncated at byte {at} (last record incomplete, {size - at} bytes)"


def skipped(start: int, end: int) -> str:
    return f"x.tlog: bytes {start}-{end - 1} not MAVLink (skipped)"


@pytest.mark.parametrize("cut", range(1, 8))
def test_a_log_ending_inside_a_records_timestamp_is_truncated_there(cut: int):
    good = good_log()
    data = good + tlog_record(T0_US + 100_000, heartbeat())[:cut]
    read = parse_tlog(data, "x.tlog")
    assert len(read.entries) == 3
    assert read.problems == [truncated(len(good), len(data))]


@pytest.mark.parametrize("stamp_us", [EARLIEST_US - 1, LATEST_US + 1, 0])
@pytest.mark.parametrize("after", [b"", b"\x00\x00\x00", b"\xfd\x09", b"\xfe\x09\x00"])
def test_a_tail_with_a_timestamp_outside_1995_to_2100_is_not_mavlink_not_a_cut_record(
        stamp_us: int, after: bytes):
    good = good_log()
    data = good + stamp_us.to_bytes(8, "big") + after
    read = parse_tlog(data, "x.tlog")
    assert len(read.entries) == 3
    assert read.problems == [skipped(len(good), len(data))]


@pytest.mark.parametrize("stamp_us", [EARLIEST_US, LATEST_US])
def test_records_stamped_on_the_first_and_last_plausible_microsecond_are_read(stamp_us: int):
    data = good_log() + tlog_record(stamp_us, heartbeat()) + good_log(1)
    read = parse_tlog(data, "x.tlog")
    assert read.problems == []
    assert [e.time_s for e in read.entries][3] == stamp_us / 1e6


@pytest.mark.parametrize("stamp_us", [EARLIEST_US, LATEST_US])
def test_a_last_record_stamped_on_a_plausible_limit_and_cut_short_is_truncated(stamp_us: int):
    good = good_log()
    data = good + tlog_record(stamp_us, heartbeat())[:12]
    assert parse_tlog(data, "x.tlog").problems == [truncated(len(good), len(data))]


@pytest.mark.parametrize("after", [b"\x00", b"\x55\x09\x00\x00"])
def test_a_plausible_timestamp_followed_by_no_start_byte_at_the_end_is_not_mavlink(
        after: bytes):
    good = good_log()
    data = good + (T0_US + 100_000).to_bytes(8, "big") + after
    assert parse_tlog(data, "x.tlog").problems == [skipped(len(good), len(data))]


@pytest.mark.parametrize("mavlink1", [False, True], ids=["MAVLink 2", "MAVLink 1"])
def test_a_whole_last_packet_whose_crc_does_not_check_is_damage_not_a_cut_record(
        mavlink1: bool):
    good = good_log(mavlink1=mavlink1)
    bad = bytearray(heartbeat(mavlink1=mavlink1))
    bad[-1] ^= 0xFF
    data = good + tlog_record(T0_US + 100_000, bytes(bad))
    read = parse_tlog(data, "x.tlog")
    assert len(read.entries) == 3
    assert read.problems == [skipped(len(good), len(data))]


@pytest.mark.parametrize("junk", [b"\x00\x11\x22\x33", b"\x00"], ids=["4-bytes", "1-byte"])
@pytest.mark.parametrize("mavlink1", [False, True], ids=["MAVLink 2", "MAVLink 1"])
def test_after_damage_the_reader_resumes_at_the_first_of_several_good_records(mavlink1: bool,
                                                                             junk: bytes):
    """(Each of the records after the damage has a start byte: the first one found is the
    one to resume at, not a later one; one stray byte is all that is skipped.)"""
    good = good_log(mavlink1=mavlink1)
    data = good + junk + good_log(4, mavlink1=mavlink1)
    read = parse_tlog(data, "x.tlog")
    assert read.problems == [skipped(len(good), len(good) + len(junk))]
    assert len(read.entries) == 7
    assert read.entries[3].offset == len(good) + len(junk)


@pytest.mark.parametrize("start_byte", [0xFD, 0xFE])
def test_a_good_record_whose_timestamp_ends_in_a_start_byte_is_not_lost_after_damage(
        start_byte: int):
    """The damage ends with a false start one byte before the good record's own: the
    reader, having refused it, must look again from the next byte."""
    good = good_log()
    stamp_us = (T0_US + 100_000) & ~0xFF | start_byte  # the stamp's last byte: a start byte
    record = tlog_record(stamp_us, heartbeat())
    junk = b"\x00" * 9
    data = good + junk + record + good_log(1)
    read = parse_tlog(data, "x.tlog")
    assert read.problems == [skipped(len(good), len(good) + len(junk))]
    assert [e.offset for e in read.entries][3] == len(good) + len(junk)
    assert read.entries[3].time_s == stamp_us / 1e6


def test_a_tlog_read_names_its_file_and_size_in_what_it_says():
    data = good_log(2) + b"\x00" * 9
    read = parse_tlog(data)
    assert (read.name, read.size, len(read.entries)) == ("tlog", len(data), 2)
    assert read.problems[0].startswith("tlog: ")  # (no file name given: "tlog")


def test_a_tlog_that_cannot_be_read_is_no_entries_and_one_problem_naming_it(tmp_path):
    from mecanum_mav.io.tlog import read_tlog

    path = tmp_path / "gone.tlog"
    read = read_tlog(path)
    assert (read.name, read.size, read.entries) == (str(path), 0, [])
    assert read.problems == [f"{path}: cannot read: No such file or directory"]
