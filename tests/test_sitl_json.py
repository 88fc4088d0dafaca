"""ArduPilot SITL's JSON physics protocol as bytes (mecanum_mav.sim.sitljson): the servo packet
the firmware sends and the JSON line it expects back, read the way ArduPilot's own parser
reads it (substring search and ``sscanf("[%f, %f, %f]")`` right after ``"key":``)."""

from __future__ import annotations

import json
import math
import re
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mecanum_mav.sim.sitljson import (
    MAGIC_16,
    MAGIC_32,
    PhysicsState,
    ServoPacket,
    decode_servo_packet,
    encode_servo_packet,
    encode_state,
)

STATE = PhysicsState(time_s=12.5, gyro=(0.01, -0.02, 0.3), accel_body=(0.5, -0.25, -9.81),
                     position_ned=(1.5, -2.0, 0.001), attitude=(0.001, -0.002, 1.2),
                     velocity_ned=(0.9, 0.1, 0.0))


def test_a_16_channel_servo_packet_is_decoded_little_endian_with_its_rate_count_and_pulses():
    raw = struct.pack("<HHI16H", MAGIC_16, 1200, 70000, 1500, 1600, 1400, 1000, *range(12))
    assert decode_servo_packet(raw) == ServoPacket(1200, 70000, (1500, 1600, 1400, 1000,
                                                                 *range(12)))


def test_a_32_channel_servo_packet_has_its_own_magic():
    raw = struct.pack("<HHI32H", MAGIC_32, 400, 3, *range(1000, 1032))
    packet = decode_servo_packet(raw)
    assert packet is not None and packet.pwm == tuple(range(1000, 1032))


@pytest.mark.parametrize("raw", [
    b"",
    b"\x1a\x48",  # half a header
    struct.pack("<HHI16H", 12345, 1200, 1, *[1500] * 16),  # unknown magic
    struct.pack("<HHI15H", MAGIC_16, 1200, 1, *[1500] * 15),  # one channel short
    struct.pack("<HHI16H", MAGIC_16, 1200, 1, *[1500] * 16) + b"\x00",  # a byte too many
    struct.pack("<HHI16H", MAGIC_32, 1200, 1, *[1500] * 16),  # 32-channel magic, 16 channels
    struct.pack("<HHI16H", MAGIC_16, 0, 1, *[1500] * 16),  # no frame rate: no time step
], ids=["empty", "short", "magic", "short-pwm", "long", "magic-size", "rate-0"])
def test_a_malformed_servo_packet_is_none_never_an_exception(raw):
    assert decode_servo_packet(raw) is None


@given(st.binary(max_size=100))
def test_any_bytes_decode_to_a_packet_or_none(raw):
    packet = decode_servo_packet(raw)
    assert packet is None or len(packet.pwm) in (16, 32)


def test_encoding_a_servo_packet_pads_to_16_channels_and_decodes_back():
    raw = encode_servo_packet(1200, 9, [1500, 1600])
    assert len(raw) == 8 + 32
    assert decode_servo_packet(raw) == ServoPacket(1200, 9, (1500, 1600, *[0] * 14))
    assert len(encode_servo_packet(50, 1, [1500] * 17)) == 8 + 64


def _ardupilot_vector(text: str, key: str) -> list[float]:
    """What ArduPilot's parser reads for ``key``: strstr for the key, skip the key and the
    two characters after it (the closing quote and the colon), then "[%f, %f, %f]"."""
    at = text.index(key) + len(key) + 2
    match = re.match(r"\[([^,\]]+),\s*([^,\]]+),\s*([^,\]]+)\]", text[at:])
    assert match is not None, f"{key}: sscanf would fail on {text[at:at + 30]!r}"
    return [float(v) for v in match.groups()]


def test_the_state_line_is_json_between_newlines_with_the_fields_the_firmware_requires():
    raw = encode_state(STATE)
    assert raw.startswith(b"\n") and raw.endswith(b"\n") and raw.count(b"\n") == 2
    document = json.loads(raw)
    assert document == {"timestamp": 12.5,
                        "imu": {"gyro": [0.01, -0.02, 0.3], "accel_body": [0.5, -0.25, -9.81]},
                        "position": [1.5, -2.0, 0.001], "attitude": [0.001, -0.002, 1.2],
                        "velocity": [0.9, 0.1, 0.0]}


def test_the_state_line_reads_right_with_ardupilots_substring_parser():
    text = encode_state(STATE).decode()
    assert _ardupilot_vector(text, "gyro") == [0.01, -0.02, 0.3]
    assert _ardupilot_vector(text, "accel_body") == [0.5, -0.25, -9.81]
    assert _ardupilot_vector(text, "position") == [1.5, -2.0, 0.001]
    assert _ardupilot_vector(text, "attitude") == [0.001, -0.002, 1.2]
    assert _ardupilot_vector(text, "velocity") == [0.9, 0.1, 0.0]
    assert float(text[text.index("timestamp") + len("timestamp") + 2:].split(",")[0]) == 12.5


def test_a_non_finite_value_is_sent_as_0_so_the_line_stays_readable():
    state = PhysicsState(math.nan, (math.inf, 0.0, 0.0), (0.0, 0.0, -9.81), (0.0, 0.0, 0.0),
                         (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    document = json.loads(encode_state(state))
    assert document["timestamp"] == 0.0 and document["imu"]["gyro"] == [0.0, 0.0, 0.0]


def test_a_servo_packet_carries_at_most_32_channels_as_the_firmware_sends_them():
    assert len(encode_servo_packet(400, 1, [1500] * 32)) == len(encode_servo_packet(400, 1,
                                                                                   [1500] * 17))
    with pytest.raises(ValueError, match="at most 32 channels, got 33"):
        encode_servo_packet(400, 1, [1500] * 33)
