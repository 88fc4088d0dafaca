"""STATUSTEXT: the length from the dialect, the severities and the chunking of long texts."""

from __future__ import annotations

import pytest

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.statustext import STATUSTEXT_LEN, Severity, statustext_messages


def raw(msg) -> bytes:
    """The text bytes a message packs (pymavlink keeps them as ``_text_raw``; ``text`` is
    their ASCII decoding)."""
    return msg._text_raw


def fields(msg) -> tuple[int, bytes, int, int]:
    """(severity, text bytes, id, chunk_seq) as they go on the wire."""
    return msg.severity, raw(msg), msg.id, msg.chunk_seq


def wire_round_trip(msg):
    """Pack with a real MAVLink 2 encoder and parse back, as a ground station would."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    mav.robust_parsing = True
    packet = msg.pack(mav)
    return mavlink.MAVLink(None).decode(bytearray(packet))


def test_length_is_the_dialects_text_field_50_bytes():
    assert STATUSTEXT_LEN == 50


def test_severity_numbers_are_mav_severity():
    assert [(s.name, int(s)) for s in Severity] == [
        ("EMERGENCY", 0), ("ALERT", 1), ("CRITICAL", 2), ("ERROR", 3), ("WARNING", 4),
        ("NOTICE", 5), ("INFO", 6)]
    for s in Severity:
        assert int(s) == getattr(mavlink, f"MAV_SEVERITY_{s.name}")


@pytest.mark.parametrize("text", ["", "Mode HOLD", "x" * 50])
def test_a_text_that_fits_goes_whole_with_id_0(text):
    (msg,) = statustext_messages(Severity.INFO, text)
    assert msg.get_type() == "STATUSTEXT"
    assert fields(msg) == (6, text.encode(), 0, 0)


def test_a_51_byte_text_goes_in_two_chunks_with_one_id_and_seq_0_1():
    text = "a" * 50 + "b"
    chunks = statustext_messages(Severity.WARNING, text, chunk_id=77)
    assert [fields(m) for m in chunks] == [(4, b"a" * 50, 77, 0), (4, b"b", 77, 1)]


def test_long_text_chunks_are_50_bytes_and_join_back_to_the_text():
    text = "Param refused: " + ", ".join(f"MOT_FL_MIN {i}" for i in range(20))
    chunks = statustext_messages(Severity.ERROR, text)
    data = text.encode()
    assert len(chunks) == -(-len(data) // 50) > 2
    assert all(len(raw(m)) == 50 for m in chunks[:-1]) and 1 <= len(raw(chunks[-1])) <= 50
    assert b"".join(raw(m) for m in chunks) == data
    assert [m.chunk_seq for m in chunks] == list(range(len(chunks)))
    ids = {m.id for m in chunks}
    assert len(ids) == 1 and 1 <= ids.pop() < 0x8000  # derived: non-zero, 15 bits
    assert {m.severity for m in chunks} == {int(Severity.ERROR)}


def test_derived_chunk_id_is_stable_for_a_text():
    text = "z" * 120
    first = {m.id for m in statustext_messages(Severity.INFO, text)}
    assert first == {m.id for m in statustext_messages(Severity.INFO, text)}


def test_exactly_100_bytes_is_two_full_chunks():
    chunks = statustext_messages(Severity.NOTICE, "q" * 100, chunk_id=1)
    assert [fields(m) for m in chunks] == [(5, b"q" * 50, 1, 0), (5, b"q" * 50, 1, 1)]


def test_the_limit_counts_utf8_bytes_not_characters():
    text = "é" * 25  # 50 bytes: fits
    assert [fields(m) for m in statustext_messages(Severity.INFO, text)] == [
        (6, text.encode(), 0, 0)]
    chunks = statustext_messages(Severity.INFO, "é" * 26, chunk_id=9)  # 52 bytes
    assert [len(raw(m)) for m in chunks] == [50, 2]
    assert b"".join(raw(m) for m in chunks).decode() == "é" * 26


@pytest.mark.parametrize("bad", [0, -1, 0x10000])
def test_an_explicit_chunk_id_must_be_1_to_65535(bad):
    with pytest.raises(ValueError, match="chunk id"):
        statustext_messages(Severity.INFO, "x" * 60, chunk_id=bad)


def test_chunks_survive_the_wire():
    text = "0123456789" * 7
    chunks = statustext_messages(Severity.CRITICAL, text, chunk_id=4242)
    back = [wire_round_trip(m) for m in chunks]
    assert [(m.severity, m.id, m.chunk_seq) for m in back] == [(2, 4242, 0), (2, 4242, 1)]
    assert "".join(m.text for m in back) == text


@pytest.mark.parametrize("mavlink1", [False, True])
def test_a_received_text_ends_at_its_nul_and_one_without_a_chunk_id_stands_alone(mavlink1):
    """MAVLink: a char array shorter than its field ends at a NUL; what follows is not text.
    A MAVLink 1 STATUSTEXT carries no id or chunk_seq: a whole text."""
    from mecanum_mav.protocol.statustext import StatusChunks

    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    sent = mavlink.MAVLink_statustext_message(4, b"Mode HOLD\x00left over", 0, 0)
    received = mavlink.MAVLink(None).decode(bytearray(sent.pack(mav, force_mavlink1=mavlink1)))
    assert StatusChunks().add(2.5, received) == [(2.5, 4, "Mode HOLD")]
