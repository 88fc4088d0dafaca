"""A fast MAVLink codec: struct + the native CRC instead of pymavlink's pure-Python framing.

pymavlink 2.4.50 parses and packs in pure Python: about 10-20 us to parse and 6.5 us to pack one
message with warm caches, and several times that at 50 Hz, when every message arrives to cold
caches. Everything here uses one ``struct`` call for the payload and the native CRC (fastcrc,
the one pymavlink uses); everything it needs (struct format, wire order, array lengths,
``crc_extra``) is read from pymavlink's own generated message classes, so the wire format
cannot drift from the dialect, and tests compare it with pymavlink byte for byte.

Two messages of the control path have their own, leanest forms: :func:`decode_manual_control`
(a slot object, not a pymavlink message) and :func:`encode_rc_override` (no message object).
The rest of the dialect takes the generic pair:

- :func:`decode_datagram`: every packet of one UDP datagram (one or several whole MAVLink 2 or
  MAVLink 1 packets back to back) as the real pymavlink message objects pymavlink's parser
  would return (same class, fields, header, CRC, ``get_msgbuf()``), or ``None`` for anything
  unusual (an unknown message id, a bad CRC, a truncated packet or stray bytes, an
  incompatibility flag other than "signed"), which then takes pymavlink's general path, which
  also counts the bad ones.
- :func:`pack_message` (``msg.pack(mav)``) and :func:`send_message` (``mav.send(msg)``): the
  packet byte for byte as pymavlink packs it, MAVLink 2 payload truncation and signing
  included, with the same effects on ``mav`` and on the message; anything unusual (a class of
  another dialect, a value pymavlink would refuse) is handed to pymavlink itself.

A signed packet's signature is checked by the caller, for fast and general paths alike
(:class:`~mecanum_mav.protocol.signing.SignatureCheck`, on ``get_msgbuf()``): the decoders
take a signed packet as a keyless pymavlink parser does. The encoders sign when the link does
(one SHA-256, as pymavlink, with the link's own signing state).
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from operator import attrgetter, itemgetter
from typing import Any, NamedTuple

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.signing import IFLAG_SIGNED, SIGNATURE_BLOCK_LEN, signature_block

__all__ = [
    "STICK_WIRE",
    "ManualControl",
    "StickWire",
    "decode_datagram",
    "decode_manual_control",
    "encode_rc_override",
    "pack_message",
    "send_message",
]

_mcrf4xx: Callable[[bytes | bytearray, int], int] | None
try:  # pymavlink's fast CRC; the same function its x25crc uses when available
    from fastcrc.crc16 import mcrf4xx as _mcrf4xx
except ImportError:  # pragma: no cover - pymavlink depends on fastcrc
    _mcrf4xx = None

_MAGIC = mavlink.PROTOCOL_MARKER_V2
_MAGIC_V1 = mavlink.PROTOCOL_MARKER_V1
_HEADER = struct.Struct("<BBBBBBBHB")  # magic len incompat compat seq sys comp msgid(24 bit)
_HEADER_V1 = struct.Struct("<BBBBBB")  # magic len seq sys comp msgid
_CRC = struct.Struct("<H")
_HEADER_LEN = 10
_HEADER_LEN_V1 = 6
_MIN_PACKET_V1 = _HEADER_LEN_V1 + 2

_MANUAL = mavlink.MAVLink_manual_control_message
_MANUAL_ID = _MANUAL.id
_MANUAL_CRC_EXTRA = bytes((_MANUAL.crc_extra,))
_MANUAL_SIZE = _MANUAL.unpacker.size

_OVERRIDE = mavlink.MAVLink_rc_channels_override_message
_OVERRIDE_ID = _OVERRIDE.id
_OVERRIDE_CRC_EXTRA = bytes((_OVERRIDE.crc_extra,))

_Header = mavlink.MAVLink_header
_FAST = _mcrf4xx is not None and not mavlink.MAVLINK_IGNORE_CRC
"""The generic codec runs (else pymavlink does it all): the native CRC is there, and
pymavlink checks CRCs (``MAV_IGNORE_CRC`` unset)."""
_PACKS_V2 = float(mavlink.WIRE_PROTOCOL_VERSION) == 2.0
"""The dialect's classes pack MAVLink 2 (``pymavlink`` decides by the module's version)."""


def _slow_crc16(data: bytes | bytearray, crc: int) -> int:
    x25 = mavlink.x25crc()
    x25.crc = crc
    x25.accumulate(data)
    return int(x25.crc)


_crc16: Callable[[bytes | bytearray, int], int] = _mcrf4xx or _slow_crc16
"""CRC-16/MCRF4XX (MAVLink's X.25) of ``data`` continued from ``crc`` (0xFFFF starts one):
fastcrc's, or pymavlink's pure-Python one (then only the two hot messages take this codec)."""


def _crc(data: bytes | bytearray, extra: bytes) -> int:
    return _crc16(extra, _crc16(data, 0xFFFF))


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


class StickWire(NamedTuple):
    """What a one-call stick lane (:mod:`mecanum_mav.control.lane`) needs to read a
    MANUAL_CONTROL datagram and pack its RC_CHANNELS_OVERRIDE without this module's calls:
    the same structs, ids, ``crc_extra`` bytes and CRC function as :func:`decode_manual_control`
    and :func:`encode_rc_override` (tests hold the lane to them byte for byte)."""

    crc16: Callable[[bytes | bytearray, int], int]
    """CRC-16/MCRF4XX continued from a CRC (0xFFFF starts one)."""
    magic: int
    header: struct.Struct
    """MAVLink 2 header: magic len incompat compat seq sys comp msgid (16 + 8 bit)."""
    crc: struct.Struct
    manual_id: int
    manual_crc_extra: bytes
    manual_size: int
    """The MANUAL_CONTROL payload's full size in this dialect (a packet may truncate it)."""
    manual_axes: struct.Struct
    """The payload's first fields in wire order: x, y, z, r, buttons, target."""
    override_id: int
    override_crc_extra: bytes
    override_pack: Callable[..., bytes]
    """chan1..8, target system, target component, chan9..18 -> the full payload."""


STICK_WIRE = StickWire(_crc16, _MAGIC, _HEADER, _CRC, _MANUAL_ID, _MANUAL_CRC_EXTRA,
                       _MANUAL_SIZE, struct.Struct("<hhhhHB"), _OVERRIDE_ID,
                       _OVERRIDE_CRC_EXTRA, _OVERRIDE.unpacker.pack)


def _frame(mav: Any, msgid: int, crc_extra: bytes, payload: bytes,
           signed: bool) -> tuple[bytes, int, int]:
    """A MAVLink 2 packet as pymavlink packs it with ``mav``'s sequence number, source ids
    and signing (its timestamp then advances by one); ``mav.seq`` is left alone.

    Returns:
        The packet, the (truncated) payload length and the CRC.
    """
    # MAVLink 2 payload truncation: trailing zero bytes go, the first byte always stays
    length = len(payload.rstrip(b"\x00")) or min(len(payload), 1)
    body = _HEADER.pack(_MAGIC, length, IFLAG_SIGNED if signed else 0, 0, mav.seq,
                        mav.srcSystem, mav.srcComponent, msgid & 0xFFFF, msgid >> 16)
    body += payload[:length]
    crc = _crc16(crc_extra, _crc16(body[1:], 0xFFFF))
    packet = body + _CRC.pack(crc)
    if signed:
        signing = mav.signing
        packet += signature_block(signing.secret_key, packet, signing.link_id, signing.timestamp)
        signing.timestamp += 1
    return packet, length, crc


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
    payload = _OVERRIDE.unpacker.pack(*channels[:8], target_system, target_component,
                                      *channels[8:])
    packet = _frame(mav, _OVERRIDE_ID, _OVERRIDE_CRC_EXTRA, payload,
                    mav.signing.sign_outgoing)[0]
    mav.seq = (mav.seq + 1) % 256
    return packet


# ------------------------------------------------------------------------ generic decoding

_Convert = Callable[[tuple[Any, ...]], Sequence[Any]] | None
"""Unpacked payload (wire order, arrays flat) -> the class's constructor arguments; None: the
unpacked tuple already is."""
_Decoder = tuple[Any, bytes, Callable[..., tuple[Any, ...]], Callable[..., tuple[Any, ...]],
                 int, _Convert]
"""Message class, crc_extra byte, unpack, unpack_from, payload size, conversion."""


def _strings_rstripped(values: Sequence[Any], strings: tuple[int, ...]) -> list[Any]:
    out = list(values)
    for i in strings:
        out[i] = out[i].rstrip(b"\x00")
    return out


def _converter(cls: Any) -> _Convert:
    """What pymavlink's ``MAVLink.decode`` does between ``unpack`` and the constructor, planned
    once per class: the fields in declaration order, arrays as lists (char arrays stay one
    ``bytes``), strings without their trailing NULs."""
    zero = cls.unpacker.unpack(bytes(cls.unpacker.size))
    lengths, orders = cls.lengths, cls.orders
    picks: list[tuple[int, int]] = []  # (index into the unpacked tuple, array length or 0)
    flat = sum(lengths) == len(lengths)  # no arrays: one value per field
    for order in orders:
        if flat:
            picks.append((order, 0))
            continue
        tip, n = sum(lengths[:order]), lengths[order]
        picks.append((tip, 0 if n == 1 or isinstance(zero[tip], bytes) else n))
    strings = tuple(i for i, (tip, n) in enumerate(picks)
                    if n == 0 and isinstance(zero[tip], bytes))
    if any(n for _, n in picks):
        def with_arrays(t: tuple[Any, ...]) -> list[Any]:
            out = [t[tip] if n == 0 else list(t[tip:tip + n]) for tip, n in picks]
            return _strings_rstripped(out, strings) if strings else out
        return with_arrays
    tips = [tip for tip, _ in picks]
    if tips == list(range(len(zero))):
        if not strings:
            return None
        return lambda t: _strings_rstripped(t, strings)
    pick = itemgetter(*tips)  # (two or more: a lone field is always in its place)
    if not strings:
        return pick
    return lambda t: _strings_rstripped(pick(t), strings)


_decoders: dict[int, _Decoder] = {}


def _decoder(msgid: int) -> _Decoder | None:
    """The decoding plan of a message id, built on first use; None: not in the dialect (not
    kept: hostile datagrams could name millions of ids)."""
    cls = mavlink.mavlink_map.get(msgid)
    if cls is None:
        return None
    unpacker = cls.unpacker
    plan = _decoders[msgid] = (cls, bytes((cls.crc_extra,)), unpacker.unpack,
                               unpacker.unpack_from, unpacker.size, _converter(cls))
    return plan


def decode_datagram(datagram: bytes) -> list[Any] | None:
    """Every message of one datagram, as pymavlink's parser returns them, or None.

    Args:
        datagram: one UDP datagram: one or several whole MAVLink 2 (or MAVLink 1) packets.

    Returns:
        The pymavlink message objects, oldest first, equal to what a keyless pymavlink parser
        returns for the same bytes (a signed packet's signature is not checked, and
        ``get_signed()`` is False, as there); None when any byte of the datagram is not part
        of a well-formed packet of a known message with a good CRC, or it holds none: the
        caller then takes pymavlink's general path. Never raises.
    """
    if not _FAST:
        return None  # pragma: no cover
    try:
        return _decode_packets(bytearray(datagram))
    except Exception:  # never seen; pymavlink's path has its own way with whatever this is
        return None


def _decode_packets(buf: bytearray) -> list[Any] | None:
    size = len(buf)
    decoders = _decoders
    crc16 = _crc16
    messages = []
    pos = 0
    while pos < size:
        magic = buf[pos]
        if magic == _MAGIC:
            if size - pos < _HEADER_LEN + 2:
                return None
            (_, length, incompat, compat, seq, system, component, low,
             high) = _HEADER.unpack_from(buf, pos)
            if incompat == 0:
                tail = 2
            elif incompat == IFLAG_SIGNED:
                tail = 2 + SIGNATURE_BLOCK_LEN
            else:
                return None
            msgid = low | high << 16
            start = pos + _HEADER_LEN
        elif magic == _MAGIC_V1:
            if size - pos < _MIN_PACKET_V1:
                return None
            _, length, seq, system, component, msgid = _HEADER_V1.unpack_from(buf, pos)
            incompat = compat = 0
            tail = 2
            start = pos + _HEADER_LEN_V1
        else:
            return None
        crc_at = start + length
        end = crc_at + tail
        if end > size:
            return None
        plan = decoders[msgid] if msgid in decoders else _decoder(msgid)
        if plan is None:
            return None
        cls, crc_extra, unpack, unpack_from, payload_size, convert = plan
        crc = _CRC.unpack_from(buf, crc_at)[0]
        if crc != crc16(crc_extra, crc16(buf[pos + 1:crc_at], 0xFFFF)):
            return None
        if length >= payload_size:  # longer than this dialect knows: pymavlink cuts it
            values = unpack_from(buf, start)
        else:  # MAVLink 2 drops trailing zero bytes: put them back
            values = unpack(buf[start:crc_at] + bytes(payload_size - length))
        msg = cls(*values) if convert is None else cls(*convert(values))
        msgbuf = buf[pos:end]
        msg._msgbuf = msgbuf
        msg._payload = msgbuf[6:crc_at - pos]  # pymavlink's slice, from byte 6 on MAVLink 2 too
        msg._crc = crc
        msg._header = _Header(msgid, incompat, compat, length, seq, system, component)
        messages.append(msg)
        pos = end
    return messages or None


# ------------------------------------------------------------------------ generic encoding

_Encoder = tuple[int, bytes, Callable[..., bytes], Callable[[Any], Any],
                 tuple[tuple[int, int], ...]]
"""Message id, crc_extra byte, pack, the getter of the packed attributes (wire order), the
arrays among them (index, length; last first)."""


def _encoder(cls: type) -> _Encoder | None:
    """The packing plan of a message class (None: not one of this dialect's), built on first
    use: the attributes its generated ``pack`` passes to ``struct``, in wire order (a string's
    raw bytes, each element of an array)."""
    msgid = getattr(cls, "id", None)
    plan: _Encoder | None = None
    if _PACKS_V2 and isinstance(msgid, int) and mavlink.mavlink_map.get(msgid) is cls:
        types = dict(zip(cls.fieldnames, cls.fieldtypes, strict=True))
        names = []
        arrays = []
        for i, (name, n) in enumerate(zip(cls.ordered_fieldnames, cls.array_lengths,
                                          strict=True)):
            if types[name] == "char":
                names.append(f"_{name}_raw")
            else:
                names.append(name)
                if n:
                    arrays.append((i, n))
        getter = attrgetter(*names) if len(names) > 1 else (lambda m: (getattr(m, names[0]),))
        plan = (msgid, bytes((cls.crc_extra,)), cls.unpacker.pack, getter,
                tuple(reversed(arrays)))
    _encoders[cls] = plan
    return plan


_encoders: dict[type, _Encoder | None] = {}


def _flatten(values: tuple[Any, ...], arrays: tuple[tuple[int, int], ...]) -> list[Any]:
    """The packed attributes with each array's first ``n`` elements in its place (``arrays``
    last first)."""
    out = list(values)
    for i, n in arrays:
        out[i:i + 1] = out[i][:n]  # a shorter one makes a wrong count: struct refuses it
    return out


def pack_message(msg: Any, mav: Any) -> bytes:
    """``msg.pack(mav)``, byte for byte, faster.

    Args:
        msg: a pymavlink message object of this dialect.
        mav: the link's pymavlink ``MAVLink`` object: its ``seq`` (left alone, as
            ``msg.pack`` does: :func:`send_message` advances it), source ids and signing (the
            timestamp advances by one per signed packet).

    Returns:
        The packet; ``msg`` then holds what pymavlink's ``pack`` leaves in it (header,
        payload, CRC, ``get_msgbuf()``). Anything unusual is packed by pymavlink itself, which
        raises what it raises (a value out of range, a missing field).
    """
    cls = type(msg)
    plan = _encoders[cls] if cls in _encoders else _encoder(cls)
    signing = mav.signing
    signed = signing.sign_outgoing
    if plan is None or not _FAST or (signed and signing.secret_key is None):
        return bytes(msg.pack(mav))
    msgid, crc_extra, pack, getter, arrays = plan
    try:
        values = getter(msg)
        payload = pack(*_flatten(values, arrays)) if arrays else pack(*values)
    except Exception:  # pymavlink refuses it too, with its own exception
        return bytes(msg.pack(mav))
    packet, length, crc = _frame(mav, msgid, crc_extra, payload, signed)
    msg._payload = payload[:length]
    msg._header = _Header(msgid, IFLAG_SIGNED if signed else 0, 0, length, mav.seq,
                          mav.srcSystem, mav.srcComponent)
    msg._msgbuf = bytearray(packet)
    msg._crc = crc
    return packet


_MAVLINK_SEND = mavlink.MAVLink.send


def send_message(mav: Any, msg: Any) -> None:
    """``mav.send(msg)`` with :func:`pack_message`: the packet goes to ``mav.file.write``,
    then ``mav.seq`` and the send totals advance and the send callback runs, as pymavlink
    does (a write that raises leaves them alone). A ``mav`` whose class has its own ``send``
    is left to it."""
    if type(mav).send is not _MAVLINK_SEND:
        mav.send(msg)
        return
    packet = pack_message(msg, mav)
    mav.file.write(packet)
    mav.seq = (mav.seq + 1) % 256
    mav.total_packets_sent += 1
    mav.total_bytes_sent += len(packet)
    callback = mav.send_callback
    if (callback is not None and mav.send_callback_args is not None
            and mav.send_callback_kwargs is not None):
        callback(msg, *mav.send_callback_args, **mav.send_callback_kwargs)
