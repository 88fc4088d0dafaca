"""The fuzz kit's picture of each message on the wire (``mecanum_mav.sim.fuzz``) is MAVLink's:
the fields in wire order at their byte offsets (the MAVLink serialization spec: base fields
sorted by type size, extensions after them in declaration order), the payload's full size
with the extensions, and the CRC_EXTRA, for every message of the dialect. What the fuzzer
builds from it (a field put at its offset, the target system patched in) is then what
pymavlink, the reference decoder, reads.

The kit computes these tables when it is imported; the tests call its builders themselves.
"""

from __future__ import annotations

import struct
from typing import Any

import pytest

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.fuzz import MESSAGE_IDS, _info, _wire_layout, frame_v2

_FORMATS = {"char": "s", "float": "f", "double": "d", "uint8_t": "B", "int8_t": "b",
            "uint16_t": "H", "int16_t": "h", "uint32_t": "I", "int32_t": "i",
            "uint64_t": "Q", "int64_t": "q"}


def _element(kind: str, index: int) -> Any:
    """A value of ``kind`` for the field at wire ``index``, none of whose bytes is zero (so
    that MAVLink 2 does not trim the payload) and which differs from its neighbours'."""
    b = index % 120 + 1
    if kind == "float":
        return struct.unpack("<f", bytes((b, b, b, 0x41)))[0]
    if kind == "double":
        return struct.unpack("<d", bytes((b,) * 7 + (0x40,)))[0]
    size = struct.calcsize(_FORMATS[kind])
    return int.from_bytes(bytes((b,) * size), "little")  # (below 0x80 a byte: positive)


def _value(kind: str, count: int, index: int) -> Any:
    """pymavlink's value of a field: bytes for char arrays, a list for other arrays."""
    if kind == "char":
        return bytes((ord("A") + index % 26,)) * count
    if count > 1:
        return [_element(kind, index + k) for k in range(count)]
    return _element(kind, index)


def _field_values(cls: Any) -> dict[str, Any]:
    kinds = dict(zip(cls.fieldnames, cls.fieldtypes, strict=True))
    counts = dict(zip(cls.ordered_fieldnames, cls.array_lengths, strict=True))
    return {name: _value(kinds[name], max(1, counts[name]), i)
            for i, name in enumerate(cls.ordered_fieldnames)}


def _read(payload: bytes, where: tuple[int, str, int]) -> Any:
    offset, kind, count = where
    found = struct.unpack_from(f"<{count}{_FORMATS[kind]}", payload, offset)
    if kind == "char":
        return found[0]
    return list(found) if count > 1 else found[0]


def _payload(frame: bytes) -> bytes:
    """A MAVLink 2 frame's payload (10 header bytes, its length in the second)."""
    assert frame[0] == mavlink.PROTOCOL_MARKER_V2
    return frame[10:10 + frame[1]]


def test_each_field_is_read_at_its_wire_offset_from_what_pymavlink_sends() -> None:
    sender = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    for msgid in MESSAGE_IDS:
        cls = mavlink.mavlink_map[msgid]
        values = _field_values(cls)
        payload = _payload(cls(**values).pack(sender))
        layout, size = _wire_layout(cls)
        # no zero byte at the end: the full payload, extensions too
        assert size == len(payload), cls.msgname
        assert sorted(layout) == sorted(cls.fieldnames), cls.msgname
        assert {name: _read(payload, layout[name]) for name in layout} == values, cls.msgname


def test_a_frame_built_from_a_messages_info_decodes_in_pymavlink_to_its_values() -> None:
    receiver = mavlink.MAVLink(None)
    for msgid in MESSAGE_IDS:
        info = _info(msgid)
        values = _field_values(info.cls)
        flat: list[Any] = []
        for name in info.names:  # the order info.pack takes them, arrays flattened
            value = values[name]
            flat += value if isinstance(value, list) else [value]
        payload = info.pack(*flat)
        assert len(payload) == info.size, info.cls.msgname
        assert {name: _read(payload, info.layout[name]) for name in info.names} == values
        frame = frame_v2(info.msgid, payload, seq=7, sysid=255, compid=190,
                         crc_extra=info.crc_extra)
        decoded = receiver.decode(bytearray(frame))  # (it checks the CRC)
        assert decoded.get_type() == info.cls.msgname and decoded.get_msgId() == msgid
        assert {name: getattr(decoded, name) for name in values} == {
            name: value.decode("ascii") if isinstance(value, bytes) else value  # (char: str)
            for name, value in values.items()}


# A message's CRC_EXTRA and payload length as the MAVLink spec's generated headers give them
# (MAVLINK_MSG_ID_<NAME>_CRC and _LEN, the length with the extensions).
SPEC = {"HEARTBEAT": (50, 9), "ATTITUDE": (39, 28), "PARAM_SET": (168, 23),
        "COMMAND_LONG": (152, 33), "MANUAL_CONTROL": (243, 30),
        "SET_POSITION_TARGET_LOCAL_NED": (143, 53), "SET_MODE": (89, 6)}
WITHOUT_EXTENSIONS = ("HEARTBEAT", "ATTITUDE", "PARAM_SET", "COMMAND_LONG",
                      "SET_POSITION_TARGET_LOCAL_NED", "SET_MODE")


@pytest.mark.parametrize("name", sorted(SPEC))
def test_a_messages_crc_extra_and_length_are_the_specs(name: str) -> None:
    info = _info(getattr(mavlink, f"MAVLINK_MSG_ID_{name}"))
    assert (info.crc_extra, info.size) == SPEC[name]
    if name in WITHOUT_EXTENSIONS:
        # the spec's algorithm: the name, then each field's type and name (and array
        # length) in wire order, all through the X.25 CRC; its two bytes XORed
        text = f"{name} ".encode()
        for field in info.names:
            _, kind, count = info.layout[field]
            text += f"{kind} {field} ".encode() + (bytes((count,)) if count > 1 else b"")
        crc = mavlink.x25crc(text).crc
        assert info.crc_extra == (crc & 0xFF) ^ (crc >> 8)
