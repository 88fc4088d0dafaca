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
    flagged = manual[:2] + b"\x01" + manual[3:]  # signed flag without a signature block
    for blob in (heartbeat, bad_crc, manual + manual, manual[:-1], b"", b"\xfe" + manual[1:],
                 flagged, manual[:2] + b"\x02" + manual[3:]):  # unknown incompat flag
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


def signing(mav, key: bytes = b"k" * 32, link_id: int = 2, timestamp: int = 10**12):
    mav.signing.secret_key = key
    mav.signing.link_id = link_id
    mav.signing.timestamp = timestamp
    mav.signing.sign_outgoing = True
    return mav


@given(st.lists(uint16, min_size=18, max_size=18), uint8, st.integers(0, 2**47))
def test_fast_encode_signs_byte_for_byte_as_pymavlink(channels, seq, timestamp):
    ours, ref = signing(sender(), timestamp=timestamp), signing(sender(), timestamp=timestamp)
    ours.seq = ref.seq = seq
    fast = encode_rc_override(ours, 1, 1, channels)
    assert fast == bytes(ref.rc_channels_override_encode(1, 1, *channels).pack(ref))
    assert ours.signing.timestamp == ref.signing.timestamp == timestamp + 1


@given(int16, int16, uint8, st.integers(0, 2**47))
def test_fast_decode_takes_a_signed_manual_control_and_keeps_its_signature(x, r, seq, ts):
    mav = signing(sender(), timestamp=ts)
    mav.seq = seq
    packet = bytes(mav.manual_control_encode(1, x, 0, 500, r, 0).pack(mav))
    fast = decode_manual_control(packet)
    assert fast is not None and (fast.x, fast.r) == (x, r)
    assert fast.get_msgbuf() == packet  # whole, so the caller can check the signature
