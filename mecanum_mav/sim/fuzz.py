"""Hostile datagrams for the companion's two links, from a seed, and the checks that hold
while they arrive (issue 11.1: bad input never crashes the process and never moves a wheel).

:class:`DatagramFuzzer` makes one UDP datagram at a time, each from one *category* (one
method per category, named in :data:`GCS_CATEGORIES` and :data:`FC_CATEGORIES`), the same
datagrams for the same seed. Ground-station link:

- ``random_bytes``: 1-280 random bytes, sometimes starting with a MAVLink magic byte;
- ``random_frame``: a well-formed MAVLink 2 frame with the correct CRC for any message id of
  the dialect (:data:`MESSAGE_IDS`, all of them in turn), random payload bytes of random
  length (MAVLink 2 pads short payloads with zeros), the target system patched to the
  rover's so that it is not simply dropped as "for another system";
- ``manual_control``: MANUAL_CONTROL with axes at -32768, 32767 (0x7FFF, "invalid"), +-1000,
  just outside, 0 or random, random buttons and extensions;
- ``hostile_values``: NaN, +-inf, +-1e38, +-FLT_MAX (and +-1e308 in doubles), -0.0 and
  denormals in the float fields, and the integer limits in the integer fields, of
  SET_POSITION_TARGET_LOCAL_NED, PARAM_SET (real parameter names; NaN, inf and values
  of magnitude 1e9 and more only: a 0 is a legitimate value for many), COMMAND_LONG and
  COMMAND_INT (the commands the rover knows and others), SET_MODE, the mission messages
  (MISSION_ITEM(_INT), MISSION_COUNT, ...), SET_GPS_GLOBAL_ORIGIN and RC_CHANNELS_OVERRIDE.
  An arm command's param1 is never 1 (a well-formed arm request is not bad input);
- ``truncated``: a frame of the categories above cut short;
- ``mavlink1``: MAVLink 1 frames (message ids below 256) with the correct CRC;
- ``signed_garbage``: MAVLink 2 frames flagged as signed with 13 random signature bytes;
- ``several``: two to six frames (sometimes with garbage between them) in one datagram.

The stick lane while the pilot drives (:meth:`DatagramFuzzer.lane_datagram`): datagrams shaped
like the pilot's MANUAL_CONTROL that must move nothing, whatever their axes:

- ``stranger_stick``: MANUAL_CONTROL with any axes, from a system that is not the pilot;
- ``stick_elsewhere``: the pilot's, for another vehicle (neither the rover nor broadcast);
- ``stick_out_of_range``: the pilot's, with x, y or r outside +-1000 (0x7FFF says "unused");
- ``stick_corrupted``: the pilot's valid stick with a payload or CRC byte changed;
- ``stick_truncated``: the pilot's valid stick cut short;
- ``random_bytes``.

Flight-controller link (sent as the flight controller, system ``FC_SYSID``):

- ``fc_sensors``: WHEEL_DISTANCE and ATTITUDE with hostile values in every float and double,
  random counts and times;
- ``fc_foreign_heartbeat``: HEARTBEATs of other systems;
- ``fc_random_frame``: any message id from the flight controller's ids, random payload;
- ``random_bytes``.

:class:`SafetyWatch` holds the checks: every RC_CHANNELS_OVERRIDE the flight controller
receives is neutral (each wheel's trim, other channels left alone) or the release; the
rover's HEARTBEATs reach the ground station with no gap over :data:`MAX_HEARTBEAT_GAP_S`;
every ODOMETRY and LOCAL_POSITION_NED is finite (NaN covariances are the protocol's
"unknown"); no STATUSTEXT says that an exception forced neutral. The tool
(``tools/fuzz.py``, the real process on UDP) and the test (the lockstep harness, virtual time)
use both.
"""

from __future__ import annotations

import math
import random
import re
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from mecanum_mav.config.params import SCHEMA, Params
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.rcoverride import override_fields, release_fields

__all__ = ["FC_CATEGORIES", "GCS_CATEGORIES", "HOSTILE_FLOATS", "LANE_CATEGORIES",
           "MAX_HEARTBEAT_GAP_S", "MESSAGE_IDS", "DatagramFuzzer", "SafetyWatch"]

MAX_HEARTBEAT_GAP_S = 1.5
"""The longest the ground station may go without the rover's HEARTBEAT (s)."""

FLT_MAX = 3.4028234663852886e38
HOSTILE_FLOATS: tuple[float, ...] = (math.nan, -math.nan, math.inf, -math.inf, 1e38, -1e38,
                                     FLT_MAX, -FLT_MAX, 1e-45, -1e-45, -0.0, 1e9, -1e9)
"""Values a float field is given (all representable in float32)."""
HOSTILE_DOUBLES: tuple[float, ...] = (*HOSTILE_FLOATS, 1e308, -1e308, 5e-324)
_HUGE_FLOATS = tuple(v for v in HOSTILE_FLOATS if not abs(v) < 1e9)
"""PARAM_SET gets only these: -0.0 or a denormal is a legitimate 0 for many parameters."""

MESSAGE_IDS: tuple[int, ...] = tuple(sorted(mavlink.mavlink_map))
"""Every message id of the dialect (pymavlink's ardupilotmega)."""

_V1_IDS = tuple(i for i in MESSAGE_IDS if i < 256)
_INT_RANGES = {"uint8_t": (0, 0xFF), "int8_t": (-0x80, 0x7F), "uint16_t": (0, 0xFFFF),
               "int16_t": (-0x8000, 0x7FFF), "uint32_t": (0, 0xFFFFFFFF),
               "int32_t": (-0x80000000, 0x7FFFFFFF), "uint64_t": (0, 0xFFFFFFFFFFFFFFFF),
               "int64_t": (-0x8000000000000000, 0x7FFFFFFFFFFFFFFF)}
_SIZES = {"char": 1, "float": 4, "double": 8, **{t: int(re.sub(r"\D", "", t) or 8) // 8
                                                  for t in _INT_RANGES}}
_HEADER_V2 = struct.Struct("<BBBBBBBHB")
_HEADER_V1 = struct.Struct("<BBBBBB")
_CRC = struct.Struct("<H")
_SIGNATURE_LEN = 13
_TARGET_SYSTEM_FIELDS = ("target_system", "target")

_PARAM_NAMES = tuple(spec.name for spec in SCHEMA)
_KNOWN_COMMANDS = (
    mavlink.MAV_CMD_COMPONENT_ARM_DISARM, mavlink.MAV_CMD_DO_SET_MODE,
    mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAV_CMD_GET_MESSAGE_INTERVAL,
    mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAV_CMD_DO_SET_MISSION_CURRENT,
    mavlink.MAV_CMD_MISSION_START, mavlink.MAV_CMD_DO_SET_HOME, mavlink.MAV_CMD_NAV_WAYPOINT,
    mavlink.MAV_CMD_DO_CHANGE_SPEED, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH,
    mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN)
_STICK_VALUES = (-32768, 32767, 0x7FFF, -32767, -1001, -1000, 1000, 1001, 0, 500, -500)
_FRAMES = (0, 1, 3, 5, 6, 7, 8, 9, 10, 11, 12, 255)
_MASKS = (0, 0xFFFF, 0x0DF8, 0x0DC7, 0x09F8, 0x05C7, 0x0FF8, 0x0007, 0x0038, 0x01C0, 0x0200)


def _wire_layout(cls: Any) -> tuple[dict[str, tuple[int, str, int]], int]:
    """Each field's (byte offset, type, array length) in the wire payload, and its size."""
    types = dict(zip(cls.fieldnames, cls.fieldtypes, strict=True))
    lengths = dict(zip(cls.ordered_fieldnames, cls.array_lengths, strict=True))
    layout, offset = {}, 0
    for name in cls.ordered_fieldnames:
        kind = types[name]
        base = next(t for t in _SIZES if kind.startswith(t))
        count = max(1, lengths[name])
        layout[name] = (offset, base, count)
        offset += _SIZES[base] * count
    return layout, offset


@dataclass(frozen=True)
class _MessageInfo:
    cls: Any
    msgid: int
    crc_extra: int
    size: int
    layout: dict[str, tuple[int, str, int]]
    pack: Callable[..., bytes]
    names: tuple[str, ...]
    """Wire order (the order :attr:`pack` takes the fields, arrays flattened)."""


def _info(msgid: int) -> _MessageInfo:
    cls = mavlink.mavlink_map[msgid]
    layout, size = _wire_layout(cls)
    assert size == cls.unpacker.size, cls.msgname
    return _MessageInfo(cls, msgid, cls.crc_extra, size, layout, cls.unpacker.pack,
                        tuple(cls.ordered_fieldnames))


_INFO: dict[int, _MessageInfo] = {i: _info(i) for i in MESSAGE_IDS}
_BY_NAME: dict[str, _MessageInfo] = {info.cls.msgname: info for info in _INFO.values()}


def frame_v2(msgid: int, payload: bytes, *, seq: int, sysid: int, compid: int,
             signature: bytes = b"", crc_extra: int | None = None) -> bytes:
    """A MAVLink 2 frame with the correct CRC (``signature``: 13 bytes, flags it signed)."""
    extra = _INFO[msgid].crc_extra if crc_extra is None else crc_extra
    header = _HEADER_V2.pack(mavlink.PROTOCOL_MARKER_V2, len(payload), 1 if signature else 0,
                             0, seq & 0xFF, sysid, compid, msgid & 0xFFFF, msgid >> 16)
    crc = mavlink.x25crc(header[1:] + payload + bytes((extra,))).crc
    return header + payload + _CRC.pack(crc) + signature


def frame_v1(msgid: int, payload: bytes, *, seq: int, sysid: int, compid: int) -> bytes:
    """A MAVLink 1 frame (message id below 256) with the correct CRC."""
    header = _HEADER_V1.pack(mavlink.PROTOCOL_MARKER_V1, len(payload), seq & 0xFF, sysid,
                             compid, msgid)
    crc = mavlink.x25crc(header[1:] + payload + bytes((_INFO[msgid].crc_extra,))).crc
    return header + payload + _CRC.pack(crc)


class DatagramFuzzer:
    """Seeded hostile datagrams (see the module docstring).

    Args:
        seed: the same seed gives the same datagrams.
        rover_sysid: the rover's system id (``SYSID_THISMAV``): targets are patched to it.
        gcs_sysid: the system id the ground-station frames mostly come from.
        fc_sysid, fc_compid: the flight controller's ids (``FC_SYSID``, ``FC_COMPID``).
    """

    def __init__(self, seed: int, *, rover_sysid: int = 1, gcs_sysid: int = 255,
                 fc_sysid: int = 1, fc_compid: int = 1) -> None:
        self.rng = random.Random(seed)
        self.rover_sysid = rover_sysid
        self.gcs_sysid = gcs_sysid
        self.fc_sysid = fc_sysid
        self.fc_compid = fc_compid
        self._seq = 0
        self._next_id = 0
        self.counts: dict[str, int] = {}
        """Datagrams made per category."""
        self._gcs = self._weighted(GCS_CATEGORIES)
        self._fc = self._weighted(FC_CATEGORIES)
        self._lane = self._weighted(LANE_CATEGORIES)

    def _weighted(self, table: Sequence[tuple[str, int]]) -> list[Callable[[], bytes]]:
        return [getattr(self, name) for name, weight in table for _ in range(weight)]

    # ------------------------------------------------------------------ drawing

    def gcs_datagram(self) -> bytes:
        """One datagram for the ground-station link, of a category drawn by weight."""
        return self._draw(self._gcs)

    def fc_datagram(self) -> bytes:
        """One datagram for the flight-controller link, of a category drawn by weight."""
        return self._draw(self._fc)

    def lane_datagram(self) -> bytes:
        """One datagram for the stick lane while the pilot (``gcs_sysid``) drives: shaped
        like the pilot's stick, never one that may move a wheel."""
        return self._draw(self._lane)

    def _draw(self, table: list[Callable[[], bytes]]) -> bytes:
        make = table[self.rng.randrange(len(table))]
        name = make.__name__
        self.counts[name] = self.counts.get(name, 0) + 1
        return make()

    def _next_seq(self) -> int:
        self._seq = (self._seq + 1) & 0xFF
        return self._seq

    def _source(self) -> tuple[int, int]:
        """Mostly the ground station; sometimes any system (never the rover's own)."""
        if self.rng.random() < 0.8:
            return self._pilot()
        sysid = self.rng.randrange(256)
        return (sysid if sysid != self.rover_sysid else 0), self.rng.randrange(256)

    def _float(self, doubles: bool = False, hostile: float = 0.5) -> float:
        rng = self.rng
        if rng.random() < hostile:
            return rng.choice(HOSTILE_DOUBLES if doubles else HOSTILE_FLOATS)
        return rng.choice((0.0, 1.0, -1.0, rng.uniform(-1000.0, 1000.0), rng.uniform(-5, 5)))

    def _int(self, kind: str) -> int:
        lo, hi = _INT_RANGES[kind]
        rng = self.rng
        return rng.choice((lo, hi, 0, 1, hi - 1, rng.randint(lo, hi), rng.randint(lo, hi)))

    def _value(self, kind: str, count: int) -> list[Any]:
        if kind == "char":
            return [self.rng.randbytes(count)]
        if kind in ("float", "double"):
            return [self._float(kind == "double") for _ in range(count)]
        return [self._int(kind) for _ in range(count)]

    def _build(self, name: str, source: tuple[int, int], *, signature: bytes = b"",
               **fixed: Any) -> bytes:
        """``name`` with hostile values in every field not in ``fixed``; targets the rover."""
        info = _BY_NAME[name]
        values: list[Any] = []
        for field_name in info.names:
            _, kind, count = info.layout[field_name]
            if field_name in fixed:
                value = fixed[field_name]
                values += value if isinstance(value, list) else [value]
            elif field_name in _TARGET_SYSTEM_FIELDS:
                values.append(self.rover_sysid)
            elif field_name == "target_component":
                values.append(self.rng.choice((0, 1, 1, 1, self.rng.randrange(256))))
            else:
                values += self._value(kind, count)
        payload = info.pack(*values)
        if self.rng.random() < 0.5:  # as MAVLink 2 senders do: trailing zeros stripped
            payload = payload.rstrip(b"\x00") or b"\x00"
        return frame_v2(info.msgid, payload, seq=self._next_seq(), sysid=source[0],
                        compid=source[1], signature=signature)

    def _random_payload(self, info: _MessageInfo) -> bytes:
        rng = self.rng
        roll = rng.random()
        length = (info.size if roll < 0.6 else rng.randint(0, info.size) if roll < 0.9
                  else rng.randint(info.size, 255))
        payload = bytearray(rng.randbytes(length))
        for name in _TARGET_SYSTEM_FIELDS:
            where = info.layout.get(name)
            if where is not None and where[0] < length and rng.random() < 0.9:
                payload[where[0]] = self.rover_sysid
        return bytes(payload)

    def _next_message(self) -> _MessageInfo:
        """Every message id in turn, so that a run of |MESSAGE_IDS| frames covers them all."""
        msgid = MESSAGE_IDS[self._next_id % len(MESSAGE_IDS)]
        self._next_id += 1
        return _INFO[msgid]

    # ------------------------------------------------------------------ ground-station link

    def random_bytes(self) -> bytes:
        """1-280 random bytes; a third start with a MAVLink magic byte."""
        rng = self.rng
        data = rng.randbytes(rng.randint(1, 280))
        if rng.random() < 0.33:
            data = bytes((rng.choice((0xFD, 0xFE)),)) + data
        return data

    def random_frame(self, signature: bytes = b"") -> bytes:
        """A well-formed MAVLink 2 frame of the next message id with a random payload."""
        info = self._next_message()
        sysid, compid = self._source()
        return frame_v2(info.msgid, self._random_payload(info), seq=self._next_seq(),
                        sysid=sysid, compid=compid, signature=signature)

    def manual_control(self) -> bytes:
        """MANUAL_CONTROL with axes at the int16 limits, 0x7FFF, +-1000 and past it."""
        rng = self.rng
        axes: dict[str, Any] = {
            axis: rng.choice(_STICK_VALUES) if rng.random() < 0.8 else self._int("int16_t")
            for axis in ("x", "y", "z", "r")}
        return self._build("MANUAL_CONTROL", self._source(), **axes)

    def hostile_values(self) -> bytes:
        """One of the named messages with NaN, inf and huge values (see the module docstring)."""
        rng = self.rng
        source = self._source()
        kind = rng.randrange(12)
        if kind == 0:
            return self._build("SET_POSITION_TARGET_LOCAL_NED", source,
                               coordinate_frame=rng.choice(_FRAMES), type_mask=rng.choice(
                                   (*_MASKS, self._int("uint16_t"))))
        if kind == 1:
            param_id = rng.choice(_PARAM_NAMES).encode().ljust(16, b"\x00")
            return self._build("PARAM_SET", source, param_id=param_id,
                               param_value=rng.choice(_HUGE_FLOATS))
        if kind in (2, 3):
            command = rng.choice((*_KNOWN_COMMANDS, self._int("uint16_t")))
            first = self._float()
            if command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM and first == 1.0:
                first = rng.choice(HOSTILE_FLOATS)  # an arm request is not bad input
            if kind == 2:
                return self._build("COMMAND_LONG", source, command=command, param1=first)
            return self._build("COMMAND_INT", source, command=command, param1=first,
                               frame=rng.choice(_FRAMES))
        if kind == 4:
            custom = rng.choice((0, 4, 10, 11, 15, 0xFFFFFFFF, 0x80000000, self._int("uint32_t")))
            return self._build("SET_MODE", source, custom_mode=custom)
        if kind in (5, 6):
            name = "MISSION_ITEM_INT" if kind == 5 else "MISSION_ITEM"
            return self._build(name, source, command=rng.choice(
                (16, 17, 19, 20, 21, 177, 178, 179, 189, self._int("uint16_t"))),
                mission_type=rng.choice((0, 0, 1, 2, 255)))
        if kind == 7:
            return self._build(rng.choice(("MISSION_COUNT", "MISSION_REQUEST_INT",
                                           "MISSION_REQUEST", "MISSION_SET_CURRENT",
                                           "MISSION_ACK", "MISSION_CLEAR_ALL",
                                           "MISSION_REQUEST_LIST")), source)
        if kind == 8:
            return self._build("SET_GPS_GLOBAL_ORIGIN", source)
        if kind == 9:
            return self._build("RC_CHANNELS_OVERRIDE", source)
        if kind == 10:
            return self._build(rng.choice(("PARAM_REQUEST_READ", "PING", "SETUP_SIGNING",
                                           "FILE_TRANSFER_PROTOCOL", "PARAM_REQUEST_LIST")),
                               source)
        return self.manual_control()

    def truncated(self) -> bytes:
        """A frame cut short (at least the magic byte remains)."""
        whole = self.hostile_values() if self.rng.random() < 0.5 else self.random_frame()
        return whole[:self.rng.randint(1, len(whole) - 1)]

    def mavlink1(self) -> bytes:
        """A MAVLink 1 frame with the correct CRC and a random (or hostile) payload."""
        rng = self.rng
        msgid = rng.choice((*_V1_IDS, mavlink.MAVLINK_MSG_ID_MANUAL_CONTROL,
                            mavlink.MAVLINK_MSG_ID_COMMAND_LONG, mavlink.MAVLINK_MSG_ID_PARAM_SET))
        info = _INFO[msgid]
        payload = self._random_payload(info)[:255]
        sysid, compid = self._source()
        return frame_v1(msgid, payload, seq=self._next_seq(), sysid=sysid, compid=compid)

    def signed_garbage(self) -> bytes:
        """A MAVLink 2 frame flagged as signed, with 13 random signature bytes."""
        signature = self.rng.randbytes(_SIGNATURE_LEN)
        if self.rng.random() < 0.5:
            return self.random_frame(signature)
        return self._build("MANUAL_CONTROL", self._source(), signature=signature)

    def several(self) -> bytes:
        """Two to six frames in one datagram, sometimes with garbage between them."""
        rng = self.rng
        parts = []
        for _ in range(rng.randint(2, 6)):
            make = rng.choice((self.random_frame, self.hostile_values, self.manual_control,
                               self.mavlink1, self.signed_garbage))
            parts.append(make())
            if rng.random() < 0.15:
                parts.append(rng.randbytes(rng.randint(1, 20)))
        return b"".join(parts)

    # ------------------------------------------------------------------ the stick lane

    def _pilot(self) -> tuple[int, int]:
        """The ground station's ids (``gcs_sysid``: the pilot's while it drives)."""
        return self.gcs_sysid, mavlink.MAV_COMP_ID_MISSIONPLANNER

    def _valid_axes(self) -> dict[str, Any]:
        rng = self.rng
        return {axis: rng.choice((-1000, -500, 0, 500, 1000, rng.randint(-1000, 1000)))
                for axis in ("x", "y", "z", "r")}

    def stranger_stick(self) -> bytes:
        """MANUAL_CONTROL with any axes (valid ones too) from a system not the pilot."""
        rng = self.rng
        sysid = rng.choice([i for i in range(256) if i not in (self.gcs_sysid,
                                                                 self.rover_sysid)])
        axes = self._valid_axes() if rng.random() < 0.5 else {}
        return self._build("MANUAL_CONTROL", (sysid, rng.randrange(256)), **axes)

    def stick_elsewhere(self) -> bytes:
        """The pilot's valid stick for another vehicle (not the rover, not broadcast)."""
        target = self.rng.choice([i for i in range(1, 256) if i != self.rover_sysid])
        return self._build("MANUAL_CONTROL", self._pilot(), target=target, **self._valid_axes())

    def stick_out_of_range(self) -> bytes:
        """The pilot's stick with x, y or r outside +-1000 (not 0x7FFF: "axis unused"), the
        other axes valid."""
        rng = self.rng
        axes = self._valid_axes()
        axes[rng.choice(("x", "y", "r"))] = rng.choice(
            (-32768, 32766, -32767, -1001, 1001, rng.randint(1001, 32766),
             rng.randint(-32768, -1001)))
        return self._build("MANUAL_CONTROL", self._pilot(), **axes)  # (targets the rover)

    def _pilot_stick(self) -> bytes:
        return self._build("MANUAL_CONTROL", self._pilot(), **self._valid_axes())

    def stick_corrupted(self) -> bytes:
        """The pilot's valid stick with one payload or CRC byte changed (a CRC-16 finds
        every such change; the header's length and message id are left alone)."""
        rng = self.rng
        frame = bytearray(self._pilot_stick())
        at = rng.randrange(_HEADER_V2.size, len(frame))
        frame[at] ^= rng.randint(1, 255)
        return bytes(frame)

    def stick_truncated(self) -> bytes:
        """The pilot's valid stick cut short."""
        frame = self._pilot_stick()
        return frame[:self.rng.randint(1, len(frame) - 1)]

    # ------------------------------------------------------------------ flight-controller link

    def fc_sensors(self) -> bytes:
        """WHEEL_DISTANCE or ATTITUDE (half each) from the flight controller, hostile values
        throughout; WHEEL_DISTANCE's count mostly the four wheels, else 0, 1, 3, the array's
        16 or 255 beyond it."""
        rng = self.rng
        source = self.fc_sysid, self.fc_compid
        if rng.random() < 0.5:
            distances = [self._float(doubles=True, hostile=0.3) for _ in range(16)]
            return self._build("WHEEL_DISTANCE", source, distance=distances,
                               count=rng.choice((0, 1, 3, 4, 4, 4, 16, 255)))
        return self._build("ATTITUDE", source)

    def fc_foreign_heartbeat(self) -> bytes:
        """A HEARTBEAT from a system that is not the flight controller."""
        rng = self.rng
        sysid = rng.randrange(256)
        if sysid == self.fc_sysid:
            sysid = (sysid + 1) % 256
        return self._build("HEARTBEAT", (sysid, rng.randrange(256)))

    def fc_random_frame(self) -> bytes:
        """Any message id from the flight controller's ids, random payload."""
        info = self._next_message()
        return frame_v2(info.msgid, self._random_payload(info), seq=self._next_seq(),
                        sysid=self.fc_sysid, compid=self.fc_compid)


GCS_CATEGORIES: tuple[tuple[str, int], ...] = (
    ("random_bytes", 3), ("random_frame", 6), ("manual_control", 2), ("hostile_values", 5),
    ("truncated", 1), ("mavlink1", 1), ("signed_garbage", 1), ("several", 1))
"""Ground-station link: (category, weight)."""
FC_CATEGORIES: tuple[tuple[str, int], ...] = (
    ("fc_sensors", 5), ("fc_foreign_heartbeat", 1), ("fc_random_frame", 2), ("random_bytes", 2))
"""Flight-controller link: (category, weight)."""
LANE_CATEGORIES: tuple[tuple[str, int], ...] = (
    ("stranger_stick", 2), ("stick_elsewhere", 1), ("stick_out_of_range", 2),
    ("stick_corrupted", 2), ("stick_truncated", 1), ("random_bytes", 1))
"""The stick lane while the pilot drives: (category, weight)."""


# --------------------------------------------------------------------------- the checks


_UNKNOWN_ALLOWED = frozenset(("pose_covariance", "velocity_covariance"))
"""ODOMETRY fields where NaN is the protocol's "unknown" (a NaN first element)."""


_FAULT_TEXTS = ("Error handling", "Error computing")
"""How the core says an exception forced neutral (:meth:`RoverCore.handle`, ``tick``)."""


def _finite(msg: Any) -> bool:
    for name in msg.get_fieldnames():
        if name in _UNKNOWN_ALLOWED:
            continue
        value = getattr(msg, name)
        values = value if isinstance(value, list) else [value]
        if any(isinstance(v, float) and not math.isfinite(v) for v in values):
            return False
    return True


@dataclass
class SafetyWatch:
    """What the flight controller and the ground station see, checked as it arrives.

    Args:
        params: the rover's parameters (wheel channels and trims, system id).
        start_s: when watching began (the first heartbeat gap counts from here), s.
    """

    params: Params
    start_s: float
    overrides: int = 0
    """RC_CHANNELS_OVERRIDEs checked."""
    bad_overrides: int = 0
    """Of those, neither neutral nor the release."""
    heartbeats: int = 0
    worst_gap_s: float = 0.0
    telemetry: int = 0
    """ODOMETRY and LOCAL_POSITION_NED checked."""
    non_finite: int = 0
    """Of those, with a NaN or infinite field."""
    faults: int = 0
    """STATUSTEXTs saying an exception forced neutral ("Error handling ...")."""
    examples: list[str] = field(default_factory=list)
    """The first few failures, for the report."""
    _last_beat_s: float | None = None

    def __post_init__(self) -> None:
        pwm = PwmMap.from_params(self.params)
        self._allowed = (override_fields(pwm.channels, pwm.neutral()),
                         release_fields(pwm.channels))
        self._sysid = int(self.params["SYSID_THISMAV"])
        self._last_beat_s = self.start_s

    def on_override(self, channels: Sequence[int]) -> None:
        """An RC_CHANNELS_OVERRIDE's 18 channel fields, as the flight controller got them."""
        self.overrides += 1
        fields = list(channels)
        if fields not in self._allowed:
            self.bad_overrides += 1
            self._example(f"override {fields}")

    def on_gcs_message(self, msg: Any, now_s: float) -> None:
        """A message the ground station received at ``now_s`` (s)."""
        kind = msg.get_type()
        if kind == "HEARTBEAT" and msg.get_srcSystem() == self._sysid:
            self.heartbeats += 1
            assert self._last_beat_s is not None
            self.worst_gap_s = max(self.worst_gap_s, now_s - self._last_beat_s)
            self._last_beat_s = now_s
        elif kind == "STATUSTEXT" and msg.text.startswith(_FAULT_TEXTS):
            self.faults += 1
            self._example(msg.text)
        elif kind in ("ODOMETRY", "LOCAL_POSITION_NED"):
            self.telemetry += 1
            if not _finite(msg):
                self.non_finite += 1
                self._example(str(msg))

    def _example(self, text: str) -> None:
        if len(self.examples) < 5:
            self.examples.append(text)

    def finish(self, now_s: float) -> None:
        """Watching ends at ``now_s``: the time since the last heartbeat is a gap too."""
        assert self._last_beat_s is not None
        self.worst_gap_s = max(self.worst_gap_s, now_s - self._last_beat_s)
        self._last_beat_s = now_s

    def problems(self) -> list[str]:
        """Every check that failed, in words (empty: all passed)."""
        found = []
        if self.bad_overrides:
            found.append(f"{self.bad_overrides} of {self.overrides} overrides neither neutral "
                         f"nor released")
        if self.worst_gap_s >= MAX_HEARTBEAT_GAP_S:
            found.append(f"heartbeat gap {self.worst_gap_s:.3f} s")
        if self.faults:
            found.append(f"{self.faults} exceptions caught by the core")
        if self.non_finite:
            found.append(f"{self.non_finite} of {self.telemetry} ODOMETRY/LOCAL_POSITION_NED "
                         f"not finite")
        return found + self.examples
