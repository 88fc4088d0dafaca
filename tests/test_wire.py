"""The fast codec against pymavlink, byte for byte."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from mecanum_mav.io.links import mavlink
from mecanum_mav.protocol.codec import decode_manual_control, encode_rc_override

int16 = st.integers(-32768, 32767)
uint16 = st.integers(0, 65535)
uint8 = st.integers(0, 255)


def sender(sysid: int = 255, compid: int = 190):
    return mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)


@given(int16, int16, int16, int16, uint16, uint8, uint8, uint8, uint8)
def test_fast_decode_matches_pymavlink_for_any_manual_control(x, y, z, r, buttons, target,
                                                               sysid, compid, seq):
    mav = sender(sysid, compid)
    mav.seq = seq
    packet = bytes(mav.manual_control_encode(target, x, y, z, r, buttons).pack(mav))
    fast = decode_manual_control(packet)
    ref = mavlink.MAVLink(None).parse_char(packet)
    assert fast is not None
    assert (fast.x, fast.y, fast.z, fast.r, fast.buttons, fast.target) == (
        ref.x, ref.y, ref.z, ref.r, ref.buttons, ref.target)
    assert (fast.get_srcSystem(), fast.get_srcComponent()) == (sysid, compid)
    assert fast.get_type() == "MANUAL_CONTROL" and fast.get_msgbuf() == packet


def test_fast_decode_leaves_everything_else_to_pymavlink():
    mav = sender()
    manual = bytes(mav.manual_control_encode(1, 100, 0, 500, 0, 0).pack(mav))
    heartbeat = bytes(mav.heartbeat_encode(6, 8, 0, 0, 4).pack(mav))
    bad_crc = manual[:-1] + bytes([manual[-1] ^ 0xFF])
    for blob in (heartbeat, bad_crc, manual + manual, manual[:-1], b"", b"\xfe" + manual[1:],
                 manual[:2] + b"\x01" + manual[3:]):  # signed flag
        assert decode_manual_control(blob) is None


@given(uint8, uint8, st.lists(uint16, min_size=18, max_size=18), uint8, uint8, uint8)
def test_fast_encode_matches_pymavlink_byte_for_byte(ts, tc, channels, sysid, compid, seq):
    ours, ref = sender(sysid, compid), sender(sysid, compid)
    ours.seq = ref.seq = seq
    fast = encode_rc_override(ours, ts, tc, channels)
    expected = bytes(ref.rc_channels_override_encode(ts, tc, *channels).pack(ref))
    assert fast == expected
    assert ours.seq == (seq + 1) % 256
    assert mavlink.MAVLink(None).parse_char(fast).get_type() == "RC_CHANNELS_OVERRIDE"


def test_a_signing_link_falls_back_to_pymavlink():
    mav = sender()
    mav.signing.sign_outgoing = True
    assert encode_rc_override(mav, 1, 1, [1500] * 4 + [65535] * 4 + [0] * 10) is None
