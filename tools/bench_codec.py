#!/usr/bin/env python3
"""Benchmark the fast codec against pymavlink, per message type, in the same run.

Decode: one datagram holding one packet of the message -> message objects, pymavlink's
``parse_buffer`` (a keyless, robust parser, as framing.MessageParser uses) against
:func:`mecanum_mav.protocol.codec.decode_datagram`. Encode: ``msg.pack(mav)`` against
:func:`mecanum_mav.protocol.codec.pack_message` (the same bytes; ``mav.seq`` held still).
The two hot messages' own forms (``decode_manual_control``, ``encode_rc_override``) and a
datagram of several packets get rows too.

Microseconds per message: the best and the median of ``--blocks`` blocks of ``--calls``
calls each (warm caches: a lower bound for the loop at 50 Hz, where every message meets cold
caches), and the ratio pymavlink / fast of the best. ``--signed`` signs every packet (the
SHA-256 is then common to both sides).

    python tools/bench_codec.py [--blocks 200] [--calls 50] [--signed]
"""

from __future__ import annotations

import argparse
import importlib.metadata
import platform
import statistics
import sys
import time
from collections.abc import Callable
from typing import Any

from mecanum_mav.protocol.codec import (
    decode_datagram,
    decode_manual_control,
    encode_rc_override,
    pack_message,
)
from mecanum_mav.protocol.dialect import mavlink

KEY = bytes(range(32))


def messages(mav: Any) -> dict[str, list[tuple[str, Any]]]:
    """Typical messages of the companion's traffic, by group (realistic values: real payloads
    keep some trailing zeros, as on the wire)."""
    return {
        "control": [
            ("MANUAL_CONTROL", mav.manual_control_encode(1, 500, -200, 500, 300, 0)),
            ("SET_POSITION_TARGET_LOCAL_NED", mav.set_position_target_local_ned_encode(
                0, 1, 1, 8, 0b110111000111, 0, 0, 0, 0.5, 0.2, 0, 0, 0, 0, 0, 0.3)),
            ("RC_CHANNELS_OVERRIDE", mav.rc_channels_override_encode(
                1, 1, 1600, 1400, 1500, 1550, 65535, 65535, 65535, 65535)),
            ("COMMAND_LONG", mav.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)),
        ],
        "telemetry": [
            ("HEARTBEAT", mav.heartbeat_encode(10, 3, 0x81, 15, 4)),
            ("SYS_STATUS", mav.sys_status_encode(0x20, 0x20, 0x20, 250, 12100, -1, 90, 0,
                                                 0, 0, 0, 0, 0)),
            ("ATTITUDE", mav.attitude_encode(123456, 0.0, 0.0, 1.25, 0.0, 0.0, 0.1)),
            ("LOCAL_POSITION_NED", mav.local_position_ned_encode(123456, 1.5, -2.0, 0.0,
                                                                 0.4, 0.1, 0.0)),
            ("GLOBAL_POSITION_INT", mav.global_position_int_encode(
                123456, -353632610, 1491652370, 584000, 0, 40, 10, 0, 12500)),
            ("SERVO_OUTPUT_RAW", mav.servo_output_raw_encode(123456789, 0, 1600, 1400, 1550,
                                                             1450, 0, 0, 0, 0)),
            ("RC_CHANNELS", mav.rc_channels_encode(123456, 8, 1500, 1500, 1500, 1500, 1000,
                                                   1000, 1000, 1000, 0, 0, 0, 0, 0, 0, 0,
                                                   0, 0, 0, 255)),
            ("WHEEL_DISTANCE", mav.wheel_distance_encode(123456789, 4, [0.5, 0.51, 0.49,
                                                                        0.5] + [0.0] * 12)),
        ],
        "arrays": [
            ("ODOMETRY", mav.odometry_encode(123456789, 1, 8, 1.5, -2.0, 0.0,
                                             [0.98, 0.0, 0.0, 0.2], 0.4, 0.1, 0.0, 0.0,
                                             0.0, 0.1, [0.01] + [0.0] * 20,
                                             [0.01] + [0.0] * 20, 0, 0, 90)),
            ("FILE_TRANSFER_PROTOCOL", mav.file_transfer_protocol_encode(
                0, 255, 190, list(range(1, 60)) + [0] * 192)),
            ("AUTOPILOT_VERSION", mav.autopilot_version_encode(
                0xFFFF, 0x04050000, 0, 0, 0, [1] * 8, [0] * 8, [0] * 8, 0x1209, 0x5740, 42)),
        ],
        "strings": [
            ("STATUSTEXT", mav.statustext_encode(4, b"Failsafe: GCS heartbeat lost")),
            ("PARAM_VALUE", mav.param_value_encode(b"WHL_MAX_SPD", 1.5, 9, 40, 3)),
            ("PARAM_SET", mav.param_set_encode(1, 1, b"WHL_MAX_SPD", 1.2, 9)),
        ],
        "mission": [
            ("MISSION_ITEM_INT", mav.mission_item_int_encode(
                1, 1, 3, 3, 16, 0, 1, 0, 0.5, 0, 0, -353632610, 1491652370, 0.0, 0)),
            ("MISSION_REQUEST_INT", mav.mission_request_int_encode(255, 190, 3, 0)),
            ("MISSION_CURRENT", mav.mission_current_encode(3, 7, 2, 0)),
        ],
    }


def per_call_us(fn: Callable[[], object], blocks: int, calls: int) -> list[float]:
    """Microseconds per call, one sample per block of ``calls`` calls."""
    samples = []
    for _ in range(blocks):
        start = time.perf_counter_ns()
        for _ in range(calls):
            fn()
        samples.append((time.perf_counter_ns() - start) / calls / 1000.0)
    return samples


def link_mav(signed: bool) -> Any:
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    if signed:
        mav.signing.secret_key = KEY
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = 10**12
    return mav


def pymavlink_parse(data: bytes) -> Callable[[], object]:
    parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    return lambda: parser.parse_buffer(data)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--blocks", type=int, default=200)
    ap.add_argument("--calls", type=int, default=50)
    ap.add_argument("--signed", action="store_true", help="sign every packet")
    args = ap.parse_args(argv)
    blocks, calls = args.blocks, args.calls

    def row(name: str, slow: Callable[[], object], fast: Callable[[], object]) -> str:
        ref, ours = per_call_us(slow, blocks, calls), per_call_us(fast, blocks, calls)
        return (f"  {name:<32} {min(ref):6.2f} {statistics.median(ref):6.2f}   "
                f"{min(ours):6.2f} {statistics.median(ours):6.2f}   "
                f"{min(ref) / min(ours):5.1f}x")

    mav = link_mav(args.signed)
    print(f"python {platform.python_version()} on {platform.machine()}, pymavlink "
          f"{importlib.metadata.version('pymavlink')}; us per message, best / median of "
          f"{blocks} blocks of {calls}; {'signed' if args.signed else 'unsigned'} packets")
    head = f"  {'':<32} {'pymavlink':>13}   {'fast':>13}   ratio"
    groups = messages(mav)
    every = []
    print(f"\ndecode (one datagram -> message objects)\n{head}")
    for group, entries in groups.items():
        print(f" {group}")
        for name, msg in entries:
            packet = bytes(msg.pack(link_mav(args.signed)))
            assert decode_datagram(packet) is not None, name
            every.append(packet)
            print(row(name, pymavlink_parse(packet), lambda p=packet: decode_datagram(p)))
    print(f"\nencode (message object -> packet)\n{head}")
    for group, entries in groups.items():
        print(f" {group}")
        for name, msg in entries:
            if not args.signed:  # the same bytes (signed: the timestamps move on)
                assert pack_message(msg, mav) == bytes(msg.pack(mav)), name
            print(row(name, lambda m=msg: m.pack(mav), lambda m=msg: pack_message(m, mav)))
    print("\nthe two hot messages' own forms, and several packets in one datagram\n" + head)
    manual = bytes(groups["control"][0][1].pack(link_mav(args.signed)))
    print(row("decode_manual_control", pymavlink_parse(manual),
              lambda: decode_manual_control(manual)))
    channels = [1600, 1400, 1500, 1550] + [65535] * 4 + [0] * 10
    override = groups["control"][2][1]
    print(row("encode_rc_override", lambda: override.pack(mav),
              lambda: encode_rc_override(mav, 1, 1, channels)))
    burst = b"".join(every[:5])
    n = len(every[:5])
    slow_burst, fast_burst = per_call_us(pymavlink_parse(burst), blocks, calls), per_call_us(
        lambda: decode_datagram(burst), blocks, calls)
    print(f"  {f'datagram of {n} packets (per packet)':<32} {min(slow_burst) / n:6.2f} "
          f"{statistics.median(slow_burst) / n:6.2f}   {min(fast_burst) / n:6.2f} "
          f"{statistics.median(fast_burst) / n:6.2f}   {min(slow_burst) / min(fast_burst):5.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
