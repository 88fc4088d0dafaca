"""`mecanum-mav log`: a tlog read, summarized and drawn; damaged files read as far as they go.

The sample drive (mecanum_mav.sim.sampledrive) runs in the lockstep harness and records its
wires as a tlog; its analysis is compared with what the harness saw (the true path, when the
modes began, when the items were reached). A synthetic tlog of an ArduPilot Rover (no
companion: no ODOMETRY, no simulator) checks that a real flight controller's log is summarized
from what it has.
"""

from __future__ import annotations

import io
import itertools
import math
import struct

import pytest

from mecanum_mav.app.cli import main
from mecanum_mav.app.loganalysis import analyse
from mecanum_mav.app.logview import run_log
from mecanum_mav.control.pathfollow import Leg
from mecanum_mav.io.tlog import parse_tlog, read_tlog
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.dialect import mavlink, mavutil
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.lockstep import TLOG_EPOCH_S
from mecanum_mav.sim.sampledrive import SampleDrive, sample_drive

STAMP = struct.Struct(">Q")
HEARTBEAT_PERIOD_S = 1.0


@pytest.fixture(scope="module")
def drive() -> tuple[SampleDrive, bytes]:
    buf = io.BytesIO()
    result = sample_drive(buf)
    return result, buf.getvalue()


def offsets(data: bytes) -> list[int]:
    return [e.offset for e in parse_tlog(data).entries]


def test_the_harness_tlog_is_read_as_pymavlink_reads_a_mavproxy_tlog(drive, tmp_path):
    _, data = drive
    path = tmp_path / "drive.tlog"
    path.write_bytes(data)
    conn = mavutil.mavlink_connection(str(path))
    theirs = []
    while (msg := conn.recv_match()) is not None:
        theirs.append((msg.get_type(), round(msg._timestamp, 6)))
    conn.close()
    read = read_tlog(path)
    assert read.problems == [] and read.unknown == 0
    assert [(e.msg.get_type(), round(e.time_s, 6)) for e in read.entries] == theirs


def test_the_sample_drive_summary_has_the_harness_distance_modes_and_failsafes(drive):
    result, data = drive
    a = analyse(parse_tlog(data).entries)
    true_length = math.fsum(math.dist(p[1:], q[1:])
                            for p, q in itertools.pairwise(result.true_path))
    assert a.path_source == "ODOMETRY"
    assert a.distance_m == pytest.approx(true_length, rel=0.01)
    assert a.true_distance_m == pytest.approx(true_length, rel=0.01)
    # Time per mode: the harness's mode changes, to the HEARTBEAT's period.
    offset = a.start_unix_s - TLOG_EPOCH_S
    expected: dict[str, float] = {}
    starts = [*result.mode_starts, (result.end_s, None)]
    for (t, mode), (t_next, _) in itertools.pairwise(starts):
        expected[mode.name] = expected.get(mode.name, 0.0) + t_next - t
    per_mode = a.time_per_mode()
    assert list(per_mode) == ["MANUAL", "AUTO", "HOLD"]
    for mode, seconds in expected.items():
        assert per_mode[mode] == pytest.approx(seconds, abs=HEARTBEAT_PERIOD_S + 0.01), mode
    assert [(e.text, e.time_s > 0) for e in a.failsafes] == [
        ("Manual input lost: wheels neutral", True), ("GCS link lost: failsafe", True)]
    gcs_lost = a.failsafes[1].time_s + offset
    hold = next(t for t, m in result.mode_starts if m == Mode.HOLD)
    assert gcs_lost == pytest.approx(hold, abs=0.01)


def test_the_worst_cross_track_per_leg_is_the_true_paths_while_each_leg_was_current(drive):
    result, data = drive
    a = analyse(parse_tlog(data).entries)
    offset = a.start_unix_s - TLOG_EPOCH_S
    gcs = result.harness.gcs
    reached = {m.seq: t for m, t in zip(gcs.messages, gcs.arrived_s, strict=True)
               if m.get_type() == "MISSION_ITEM_REACHED"}
    auto = [(t, nxt) for (t, m), (nxt, _)
            in itertools.pairwise([*result.mode_starts, (1e9, None)]) if m == Mode.AUTO]
    positions = {it.seq: (it.x / 1e4, it.y / 1e4) for it in result.items[1:]}
    assert [leg.seq for leg in a.legs] == [1, 2, 3, 4]
    previous_end = auto[0][0]
    for leg in a.legs:
        end = reached[leg.seq]
        window = [p for p in result.true_path if previous_end <= p[0] < end
                  and any(t0 <= p[0] < t1 for t0, t1 in auto)]
        assert leg.goal == pytest.approx(positions[leg.seq])
        truth = max(Leg(leg.start, leg.goal).distance_m(p[1:]) for p in window)
        assert leg.max_cross_track_m == pytest.approx(truth, abs=0.01), leg
        previous_end = end
    first_leg_start = next(p for p in result.true_path if p[0] >= auto[0][0])
    assert a.legs[0].start == pytest.approx(first_leg_start[1:], abs=0.01)
    assert offset == pytest.approx(result.true_path[0][0], abs=0.01)


def test_mecanum_mav_log_prints_the_summary_and_writes_the_png_beside_the_tlog(
        drive, tmp_path, capsys):
    _, data = drive
    path = tmp_path / "drive.tlog"
    path.write_bytes(data)
    assert main(["log", str(path)]) == 0
    out = capsys.readouterr()
    assert out.err == ""
    assert "distance " in out.out and "modes: MANUAL" in out.out and "failsafes: 2" in out.out
    assert "worst cross-track cm" in out.out
    png = tmp_path / "drive.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    other = tmp_path / "out" / "x.png"
    assert main(["log", str(path), "--png", str(other)]) == 0
    assert other.stat().st_size > 10_000


def test_a_truncated_tlog_names_the_byte_it_stops_at_and_the_rest_is_summarized(
        drive, tmp_path, capsys):
    _, data = drive
    starts = offsets(data)
    cut = starts[-1] + 13  # inside the last record's packet
    path = tmp_path / "cut.tlog"
    path.write_bytes(data[:cut])
    read = read_tlog(path)
    assert read.problems == [f"{path}: truncated at byte {starts[-1]} (last record "
                             f"incomplete, 13 bytes)"]
    assert len(read.entries) == len(starts) - 1
    assert run_log(path, tmp_path / "cut.png") == 0
    err = capsys.readouterr().err
    assert f"truncated at byte {starts[-1]}" in err
    assert (tmp_path / "cut.png").exists()


def test_garbage_and_a_bad_crc_are_reported_by_byte_range_and_the_rest_is_read(drive):
    _, data = drive
    starts = offsets(data)
    k = len(starts) // 2
    junk = bytes(range(50))  # no MAVLink start byte in it
    damaged = bytearray(data[:starts[k]] + junk + data[starts[k]:])
    # A flipped payload byte in the record after next: its CRC no longer checks.
    bad_at = starts[k + 2] + len(junk)
    bad_end = starts[k + 3] + len(junk)
    damaged[bad_at + 8 + 11] ^= 0xFF
    read = parse_tlog(bytes(damaged), "x.tlog")
    assert read.problems == [
        f"x.tlog: bytes {starts[k]}-{starts[k] + 49} not MAVLink (skipped)",
        f"x.tlog: bytes {bad_at}-{bad_end - 1} not MAVLink (skipped)",
    ]
    assert len(read.entries) == len(starts) - 1


@pytest.mark.parametrize(("content", "why"), [
    (b"", "no MAVLink messages read"),
    (b"this is not a telemetry log\n" * 40, "no MAVLink messages read"),
    (None, "cannot read"),
])
def test_an_empty_missing_or_foreign_file_is_exit_status_2_with_the_reason(
        tmp_path, capsys, content, why):
    path = tmp_path / "x.tlog"
    if content is not None:
        path.write_bytes(content)
    assert run_log(path, tmp_path / "x.png") == 2
    assert why in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()


# ---------------------------------------------------------------------- a real FC's log


class _Recorder:
    def __init__(self) -> None:
        self.buf = bytearray()
        self.now_s = 1_700_000_000.0

    def write(self, data: bytes) -> None:
        self.buf += STAMP.pack(round(self.now_s * 1e6)) + bytes(data)


def ardupilot_rover_tlog() -> tuple[bytes, dict[str, float]]:
    """What MAVProxy records in front of an ArduPilot Rover: 20 s, MANUAL 5 s, AUTO 10 s
    (east at 0.5 m/s along a mission), then RTL after a radio failsafe; GLOBAL_POSITION_INT,
    SERVO_OUTPUT_RAW, STATUSTEXT, a MAVProxy heartbeat, and a packet of another dialect."""
    rec = _Recorder()
    fc = mavlink.MAVLink(rec, srcSystem=1, srcComponent=1)
    gcs = mavlink.MAVLink(rec, srcSystem=255, srcComponent=0)
    origin = GlobalOrigin.from_degrees(47.3977, 8.5456)
    start = rec.now_s
    east = 0.0
    wp = origin.to_global(0.0, 5.0)
    gcs.mission_count_send(1, 1, 2, 0)
    gcs.mission_item_int_send(1, 1, 0, 0, 16, 0, 1, 0, 0, 0, 0, origin.lat_e7, origin.lon_e7,
                              0, 0)
    gcs.mission_item_int_send(1, 1, 1, 3, 16, 0, 1, 0, 0, 0, 0, wp[0], wp[1], 0, 0)
    for step in range(200):  # 10 Hz
        t = step / 10
        rec.now_s = start + t
        mode = 0 if t < 5 else (10 if t < 15 else 11)
        if mode == 10:
            east += 0.05
        if step % 10 == 0:
            armed = mavlink.MAV_MODE_FLAG_SAFETY_ARMED
            fc.heartbeat_send(mavlink.MAV_TYPE_GROUND_ROVER, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                              mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | armed, mode,
                              mavlink.MAV_STATE_ACTIVE)
            gcs.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            fc.mission_current_send(1)
        lat, lon = origin.to_global(0.0, east)
        fc.global_position_int_send(int(t * 1000), lat, lon, 0, 0, 0, 50 if mode == 10 else 0,
                                    0, 0)
        fc.servo_output_raw_send(int(t * 1e6), 0, 1500, 1500, 1700 if mode == 10 else 1500,
                                 1500, *([0] * 12))
        if step == 150:
            fc.statustext_send(mavlink.MAV_SEVERITY_WARNING, b"Radio Failsafe")
    rec.now_s += 0.1
    # A packet of a message id the ArduPilot dialect does not know (id 0xFFFF00).
    packet = bytes([0xFD, 1, 0, 0, 9, 1, 1, 0x00, 0xFF, 0xFF, 7, 0xAB, 0xCD])
    rec.write(packet)
    return bytes(rec.buf), {"MANUAL": 5.0, "AUTO": 10.0, "RTL": 5.0}


def test_an_ardupilot_rover_tlog_is_summarized_from_what_it_has(tmp_path, capsys):
    data, modes = ardupilot_rover_tlog()
    read = parse_tlog(data, "rover.tlog")
    assert read.problems == [] and read.unknown == 1
    a = analyse(read.entries)
    assert a.vehicle == (1, 1)
    assert a.path_source == "GLOBAL_POSITION_INT"
    assert a.distance_m == pytest.approx(5.0, abs=0.02)
    assert a.true_path == [] and a.sticks == []
    per_mode = a.time_per_mode()
    assert list(per_mode) == list(modes)
    for mode, seconds in modes.items():
        assert per_mode[mode] == pytest.approx(seconds, abs=0.11), mode
    assert [e.text for e in a.failsafes] == ["Radio Failsafe"]
    assert [p[0] for p in a.planned] == [1]
    assert a.planned[0][1:] == pytest.approx((0.0, 5.0), abs=0.02)
    assert [leg.seq for leg in a.legs] == [1]
    assert a.legs[0].max_cross_track_m < 0.02
    path = tmp_path / "rover.tlog"
    path.write_bytes(data)
    assert run_log(path, tmp_path / "rover.png") == 0
    out = capsys.readouterr()
    assert out.err == ""
    assert "(GLOBAL_POSITION_INT)" in out.out and "RTL 4.9 s" in out.out
    assert (tmp_path / "rover.png").exists()
