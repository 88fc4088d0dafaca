"""Each refused packet is counted and told as its own kind (protocol/signing.py): a ground
station without the key is told it must sign, not that its signature is wrong."""

from __future__ import annotations

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.signing import Check, SignatureCheck

KEY = bytes(range(32))


def unsigned_packet() -> bytes:
    """A MAVLink 2 COMMAND_LONG without a signature, longer than a signed packet's minimum."""
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    packet = bytes(mav.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0).pack(mav))
    assert packet[0] == 0xFD and not packet[2] & 0x01 and len(packet) > 25
    return packet


def test_a_long_unsigned_packet_is_refused_as_unsigned_not_as_a_bad_signature():
    check = SignatureCheck(KEY, now_ticks=0)
    assert check.check(unsigned_packet()) is Check.UNSIGNED
    assert check.take_rejections() == {Check.UNSIGNED: 1}
    assert check.new_rejections == 0  # (the loop's cheap test: nothing new since)
    assert check.take_rejections() == {}
    assert check.summary() == "unsigned 1"  # (the total, kept)
