"""A fast MAVLink 2 codec for the two messages on the control path.

pymavlink 2.4.50 parses and packs in pure Python: about 10 us to parse and 6.5 us to pack one
message with warm caches, and several times that at 50 Hz, when every message arrives to cold
caches. This module decodes ``MANUAL_CONTROL`` and encodes ``RC_CHANNELS_OVERRIDE`` with one
``struct`` call and the native CRC (fastcrc, the one pymavlink uses). Everything it needs
(struct format, wire order, ``crc_extra``) is read from pymavlink's own generated message
classes, so the wire format cannot drift from the dialect, and tests compare it byte for byte
with pymavlink.

The fast decoder takes exactly one MAVLink 2 packet per datagram (what ground stations send over
UDP), signed or not: it checks the CRC, and a signed packet's signature is checked by the
caller, for fast and general paths alike (:class:`~mecanum_mav.protocol.signing.
SignatureCheck`). Anything else (another message, a MAVLink 1 packet, a bad CRC, a payload
longer than this dialect knows, several packets in one datagram) returns ``None`` and takes
pymavlink's general path, which also counts the bad ones. The encoder signs when the link does
(one SHA-256, as pymavlink, with the link's own signing state).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.signing import IFLAG_SIGNED, SIGNATURE_BLOCK_LEN, signature_block

__all__ = ["ManualControl", "decode_manual_control", "encode_rc_override"]

_mcrf4xx: Callable[[bytes, int], int] | None
try:  # pymavlink's fast CRC; the same function its x25crc uses when available
    from fastcrc.crc16 import mcrf4xx as _mcrf4xx
except ImportError:  # pragma: no cover - pymavlink depends on fastcrc
    _mcrf4xx = None

_MAGIC = mavlink.PROTOCOL_MARKER_V2
_HEADER = struct.Struct("<BBBBBBBHB")  # magic len incompat compat seq sys comp msgid(24 bit)
_CRC = struct.Struct("<H")
_HEADER_LEN = 10

_MANUAL = mavlink.MAVLink_manual_control_message
_MANUAL_ID = _MANUAL.id
_MANUAL_CRC_EXTRA = bytes((_MANUAL.crc_extra,))
_MANUAL_SIZE = _MANUAL.unpacker.size

_OVERRIDE = mavlink.MAVLink_rc_channels_override_message
_OVERRIDE_ID = _OVERRIDE.id
_OVERRIDE_CRC_EXTRA = bytes((_OVERRIDE.crc_extra,))


def _crc(data: bytes, extra: bytes) -> int:
    if _mcrf4xx is not None:
        return int(_mcrf4xx(extra, _mcrf4xx(data, 0xFFFF)))
    crc = mavlink.x25crc(data)  # pragma: no cover
    crc.accumulate(extra)  # pragma: no cover
    return int(crc.crc)  # pragma: no cover


class ManualControl:
    """A decoded MANUAL_CONTROL with the attributes and methods the companion reads.

    Axes as on the wire: x forward, y right, r clockwise in -1000..1000 (0x7FFF invalid),
    z 0..1000; ``target`` is the addressed system id.
    """

    __slots__ = ("_buf", "_src", "buttons", "r", "target", "x", "y", "z")

    def __init__(self, values: tuple[int, ...], src: tuple[int, int], buf: bytes) -> None:
        self.x, self.y, self.z, self.r, self.buttons, self.target = values[:6]
        self._src = src
        self._buf = buf

    def get_type(self) -> str:
        return "MANUAL_CONTROL"

    def get_srcSystem(self) -> int:
        return self._src[0]

    def get_srcComponent(self) -> int:
        return self._src[1]

    def get_msgbuf(self) -> bytes:
        return self._buf


def decode_manual_control(datagram: bytes) -> ManualControl | None:
    """Decode a datagram holding exactly one MAVLink 2 MANUAL_CONTROL, else None.

    A signed one is decoded with its signature unchecked: the caller checks it."""
    size = len(datagram)
    if size < _HEADER_LEN + 3 or datagram[0] != _MAGIC:
        return None
    flags = datagram[2]
    if flags == 0:
        signature_len = 0
    elif flags == IFLAG_SIGNED:
        signature_len = SIGNATURE_BLOCK_LEN
    else:
        return None
    length = datagram[1]
    if size != _HEADER_LEN + length + 2 + signature_len or length > _MANUAL_SIZE:
        return None
    if datagram[7] | datagram[8] << 8 | datagram[9] << 16 != _MANUAL_ID:
        return None
    end = _HEADER_LEN + length
    if _CRC.unpack_from(datagram, end)[0] != _crc(datagram[1:end], _MANUAL_CRC_EXTRA):
        return None
    payload = datagram[_HEADER_LEN:end]
    if length < _MANUAL_SIZE:  # MAVLink 2 drops trailing zero bytes: put them back
        payload = payload + bytes(_MANUAL_SIZE - length)
    values = _MANUAL.unpacker.unpack(payload)
    return ManualControl(values, (datagram[5], datagram[6]), bytes(datagram))


def encode_rc_override(mav: Any, target_system: int, target_component: int,
                       channels: list[int]) -> bytes:
    """Pack RC_CHANNELS_OVERRIDE exactly as pymavlink would, advancing ``mav.seq``.

    Args:
        mav: the link's pymavlink ``MAVLink`` object (sequence number, source ids).
        target_system, target_component: the flight controller.
        channels: the 18 ``chanN_raw`` fields, channel 1 first.

    Returns:
        The packet; signed when ``mav.signing.sign_outgoing`` (its timestamp then advances by
        one, as pymavlink's does).
    """
    signing = mav.signing
    signed = signing.sign_outgoing
    payload = _OVERRIDE.unpacker.pack(*channels[:8], target_system, target_component,
                                      *channels[8:])
    length = len(payload)
    while length > 1 and payload[length - 1] == 0:  # MAVLink 2 payload truncation
        length -= 1
    seq = mav.seq
    header = _HEADER.pack(_MAGIC, length, IFLAG_SIGNED if signed else 0, 0, seq, mav.srcSystem,
                          mav.srcComponent, _OVERRIDE_ID & 0xFFFF, _OVERRIDE_ID >> 16)
    body: bytes = header + payload[:length]
    mav.seq = (seq + 1) % 256
    packet = body + _CRC.pack(_crc(body[1:], _OVERRIDE_CRC_EXTRA))
    if signed:
        packet += signature_block(signing.secret_key, packet, signing.link_id, signing.timestamp)
        signing.timestamp += 1
    return packet
