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
from collections.abc import Callable, Sequence
from typing import Any

import pytest
from support import not_installed, png_size_and_dpi

from mecanum_mav.app.cli import main
from mecanum_mav.app.loganalysis import INPUT_TIMEOUT_S, OVERRIDE_TIMEOUT_S, analyse
from mecanum_mav.app.logview import log_figure, run_log, summary
from mecanum_mav.control.pathfollow import Leg
from mecanum_mav.io.tlog import parse_tlog, read_tlog
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.dialect import mavlink, mavutil
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.statustext import Severity, statustext_messages
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
    other = tmp_path / "out" / "drives" / "x.png"  # (folders made as needed)
    assert main(["log", str(path), "--png", str(other)]) == 0
    assert other.stat().st_size > 10_000
    assert png_size_and_dpi(other)[2] == pytest.approx(80, abs=0.1)


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


def test_the_leg_table_labels_its_north_east_columns_and_the_path_plot_has_east_on_x(tmp_path):
    data, _ = ardupilot_rover_tlog()  # its one leg goes 5 m east
    read = parse_tlog(data, "rover.tlog")
    a = analyse(read.entries)
    lines = summary(read, a).splitlines()
    header = next(line for line in lines if "worst cross-track cm" in line)
    assert "from (N, E) m -> to (N, E) m" in header
    row = lines[lines.index(header) + 1]
    assert "(0.00, 0.05) -> (0.00, 5.00)" in row  # from where AUTO began
    fig = log_figure(a, "rover")
    ax_path = fig.axes[0]
    assert (ax_path.get_xlabel(), ax_path.get_ylabel()) == ("east m", "north m")
    planned = next(line for line in ax_path.lines if line.get_label() == "planned mission")
    assert list(planned.get_xdata()) == pytest.approx([5.0], abs=0.02)  # east
    assert list(planned.get_ydata()) == pytest.approx([0.0], abs=0.02)  # north


# ---------------------------------------------------------------------- RC overrides


FORWARD_WHEELS = [1600, 1600, 1600, 1600]
LEAVE_REST = [65535] * 4 + [0] * 10
"""The companion's override: its four wheel channels, every other channel left alone."""
PILOT_RC = ([0, 0, 1700, 0, 0, 0, 0, 0], [0, 0, 1700, 2000, 0, 0, 0, 0],
            [1250, 0, 1700, 2000, 0, 0, 0, 0])
"""What MAVProxy sends after ``rc 3 1700``, then ``rc 4 2000``, then ``rc 1 1250`` (the
channels it did not set released: 0)."""
PILOT_RC_1_TO_4 = tuple([v or 1500 for v in rc[:4]] + [65535] * 4 for rc in PILOT_RC)
"""The same sticks from a script that sets channels 1-4 and leaves the rest alone."""
PILOT_STICKS = ((0.4, 0.0, 0.0), (0.4, 1.0, 0.0), (0.4, 1.0, -0.5))
"""PILOT_RC read as the rover reads it by default: x forward, y right, r clockwise."""
WHEELS_1_TO_4 = (1, 2, 3, 4)


def rc_pilot_tlog(pilot_compid: int, pilot_rc: Sequence[list[int]] = PILOT_RC,
                  vehicle_sysid: int = 1, wheels: Sequence[int] = WHEELS_1_TO_4) -> bytes:
    """A companion (``vehicle_sysid``/1) driven by a pilot's RC overrides, recorded by
    ``--tlog``: the pilot (system 255, component ``pilot_compid``, to the companion) sends
    each of ``pilot_rc`` (channels 1-8) for 1 s at 10 Hz from t = 0 and then stops; the
    companion (255/190, to the flight controller 1/1) sends its PWM on channels ``wheels`` at
    20 Hz for 5 s, forward while the pilot drives, every other channel left alone."""
    rec = _Recorder()
    vehicle = mavlink.MAVLink(rec, srcSystem=vehicle_sysid, srcComponent=1)
    pilot = mavlink.MAVLink(rec, srcSystem=255, srcComponent=pilot_compid)
    companion = mavlink.MAVLink(rec, srcSystem=255, srcComponent=190)
    start = rec.now_s
    for step in range(100):
        t = step / 20
        rec.now_s = start + t
        if step % 20 == 0:
            vehicle.heartbeat_send(
                mavlink.MAV_TYPE_GROUND_ROVER, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_SAFETY_ARMED,
                Mode.MANUAL, mavlink.MAV_STATE_ACTIVE)
        driving = t < len(pilot_rc)
        if driving and step % 2 == 0:
            pilot.rc_channels_override_send(vehicle_sysid, 1, *pilot_rc[int(t)], *([0] * 10))
        fields = [65535] * 8 + [0] * 10
        for channel, pulse in zip(wheels, FORWARD_WHEELS if driving else [1500] * 4,
                                  strict=True):
            fields[channel - 1] = pulse
        companion.rc_channels_override_send(1, 1, *fields)
    return bytes(rec.buf)


@pytest.mark.parametrize(("pilot_compid", "pilot_rc", "vehicle_sysid", "wheels"), [
    (230, PILOT_RC, 1, WHEELS_1_TO_4),  # MAVProxy (component 230; 0 in older versions)
    (190, PILOT_RC, 1, WHEELS_1_TO_4),  # a Mission Planner-like pilot: the companion's ids
    (230, PILOT_RC_1_TO_4, 1, WHEELS_1_TO_4),  # a script: the channels the companion sets
    (190, PILOT_RC, 2, (5, 6, 7, 8)),  # SYSID_THISMAV 2, the wheels on channels 5-8
], ids=["mavproxy", "same-ids", "script-1-4", "sysid-2"])
def test_the_pilots_and_the_companions_rc_overrides_are_separate_series(
        pilot_compid, pilot_rc, vehicle_sysid, wheels):
    a = analyse(parse_tlog(rc_pilot_tlog(pilot_compid, pilot_rc, vehicle_sysid,
                                         wheels)).entries)
    assert list(a.overrides) == ["255/190 -> 1/1"]
    companion = a.overrides["255/190 -> 1/1"]
    assert len(companion) == 100
    assert all([channels[n - 1] for n in wheels] in (FORWARD_WHEELS, [1500] * 4)
               for _, channels in companion)
    assert list(a.pilot_overrides) == [f"255/{pilot_compid}"]
    pilot = a.pilot_overrides[f"255/{pilot_compid}"]
    assert [channels[:8] for _, channels in pilot] == [rc for rc in pilot_rc for _ in range(10)]
    sticks = a.pilot_sticks[f"255/{pilot_compid}"][::10]
    assert [value for stick in sticks for value in stick[1:]] == pytest.approx(
        [value for stick in PILOT_STICKS for value in stick])
    pwm_labels = {line.get_label() for line in log_figure(a, "rc").axes[2].lines}
    assert pwm_labels == {f"companion override 255/190 -> 1/1 ch{n}" for n in wheels}


def test_the_sample_drives_overrides_are_all_the_companions_pwm(drive):
    """Its ground station (255/190, as the companion's flight-controller link) drives with
    MANUAL_CONTROL and sends no override."""
    result, data = drive
    a = analyse(parse_tlog(data).entries)
    assert a.pilot_overrides == {} and a.pilot_sticks == {}
    assert list(a.overrides) == ["255/190 -> 1/1"]
    assert len(a.overrides["255/190 -> 1/1"]) == len(result.harness.overrides)


def test_the_pilots_rc_override_is_drawn_as_sticks_labelled_by_its_source():
    a = analyse(parse_tlog(rc_pilot_tlog(230)).entries)
    assert a.sticks == []
    sticks = a.pilot_sticks["255/230"]
    assert len(sticks) == 30
    for k, expected in enumerate(PILOT_STICKS):
        assert sticks[10 * k][0] == pytest.approx(k)
        assert sticks[10 * k][1:] == pytest.approx(expected)
    ax_stick = log_figure(a, "rc").axes[1]
    lines = {line.get_label(): line for line in ax_stick.lines}
    assert set(lines) == {"x forward (RC override 255/230)", "y right (RC override 255/230)",
                          "r clockwise (RC override 255/230)"}
    y = lines["y right (RC override 255/230)"]
    assert [v for t, v in zip(y.get_xdata(), y.get_ydata(), strict=True)
            if 1.0 <= t < 2.0] == pytest.approx([1.0] * 10)


def bursts_tlog(bursts: Sequence[tuple[float, float]],
                send: Callable[[Any, float], None]) -> bytes:
    """``send(mav, t)`` from system 255 component 190 at 20 Hz during each (start s, end s)
    of ``bursts``, silence between them; a vehicle HEARTBEAT (1/1) every second to the last
    burst's end + 2 s."""
    rec = _Recorder()
    vehicle = mavlink.MAVLink(rec, srcSystem=1, srcComponent=1)
    mav = mavlink.MAVLink(rec, srcSystem=255, srcComponent=190)
    start = rec.now_s
    end = bursts[-1][1] + 2.0
    for step in range(round(end * 20)):
        t = step / 20
        rec.now_s = start + t
        if step % 20 == 0:
            vehicle.heartbeat_send(mavlink.MAV_TYPE_GROUND_ROVER,
                                   mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                   mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, Mode.MANUAL,
                                   mavlink.MAV_STATE_ACTIVE)
        if any(t0 <= t < t1 for t0, t1 in bursts):
            send(mav, t)
    return bytes(rec.buf)


def drawn_spans(line: Any) -> list[tuple[float, float]]:
    """The (start, end) times over which a step line (``where="post"``) draws a value."""
    t, v = line.get_xdata(), line.get_ydata()
    return [(t[k], t[k + 1]) for k in range(len(t) - 1) if math.isfinite(v[k])]


def test_a_stick_series_breaks_where_its_samples_stop_for_longer_than_the_input_timeout():
    data = bursts_tlog([(0.0, 1.0), (4.0, 5.0)],
                       lambda mav, _t: mav.manual_control_send(1, 500, 0, 500, 0, 0))
    a = analyse(parse_tlog(data).entries)
    ax_stick = log_figure(a, "sticks").axes[1]
    x = next(line for line in ax_stick.lines if line.get_label() == "x forward (MANUAL_CONTROL)")
    spans = drawn_spans(x)
    assert all(end - begin <= INPUT_TIMEOUT_S + 1e-9 for begin, end in spans)
    assert not any(begin < 3.0 and end > 2.0 for begin, end in spans)  # nothing in the gap
    assert max(end for begin, end in spans if begin < 2.0) == pytest.approx(0.95 + INPUT_TIMEOUT_S)
    assert max(end for _, end in spans) == pytest.approx(4.95 + INPUT_TIMEOUT_S)
    # The pilot's RC override stops at 2.95 s: its sticks are drawn to 2.95 s + the timeout.
    a = analyse(parse_tlog(rc_pilot_tlog(230)).entries)
    for line in log_figure(a, "rc").axes[1].lines:
        assert max(end for _, end in drawn_spans(line)) == pytest.approx(2.9 + INPUT_TIMEOUT_S)


def test_the_companions_pwm_breaks_where_its_overrides_stop_for_the_override_timeout():
    """A flight controller holds an override OVERRIDE_TIMEOUT_S (ArduPilot RC_OVERRIDE_TIME,
    3 s): a companion silent for 5 s (restarted) is drawn for that long, then not."""
    def wheels(mav: Any, t: float) -> None:
        mav.rc_channels_override_send(1, 1, *([1500 + round(100 * t)] * 4), *LEAVE_REST)

    a = analyse(parse_tlog(bursts_tlog([(0.0, 1.0), (6.0, 7.0)], wheels)).entries)
    lines = log_figure(a, "pwm").axes[2].lines
    assert len(lines) == 4
    for line in lines:
        spans = drawn_spans(line)
        assert not any(begin < 5.0 and end > 4.0 for begin, end in spans)
        assert max(end for begin, end in spans if begin < 4.0) == pytest.approx(
            0.95 + OVERRIDE_TIMEOUT_S)


# ---------------------------------------------------------------------- STATUSTEXT


def test_statustext_chunks_are_joined_per_sender_and_id_into_one_message():
    rec = _Recorder()
    companion = mavlink.MAVLink(rec, srcSystem=1, srcComponent=1)
    board = mavlink.MAVLink(rec, srcSystem=1, srcComponent=2)
    lost = "Radio failsafe: no RC_CHANNELS from the flight controller for 0.5 s, wheels neutral"
    notice = "Mission saved to storage: 12 items, the last a return to launch at the origin"
    first = statustext_messages(Severity.CRITICAL, lost, chunk_id=7)
    second = statustext_messages(Severity.NOTICE, notice, chunk_id=7)  # the same id
    exact = "x" * 100  # two full chunks, no shorter one to end it: ended by its id's next
    # text (its chunk_seq 0 again) or the log's end
    assert len(first) == len(second) == 2
    for k in range(2):
        companion.send(first[k])
        rec.now_s += 0.01
        board.send(second[k])
        rec.now_s += 0.01
    companion.statustext_send(Severity.INFO, b"Mode HOLD")
    for _ in range(2):
        for msg in statustext_messages(Severity.INFO, exact, chunk_id=8):
            companion.send(msg)
        rec.now_s += 0.01
    shuffled = "a" * 50 + "b" * 50 + "c" * 20
    chunks = statustext_messages(Severity.WARNING, shuffled, chunk_id=9)
    for k in (1, 0, 2):  # chunk_seq order, not arrival order; the short last ends it
        companion.send(chunks[k])
    rec.now_s += 0.01
    tail = "d" * 150 + "f" * 10
    companion.send(statustext_messages(Severity.WARNING, tail, chunk_id=9)[3])  # 0-2 lost
    read = parse_tlog(bytes(rec.buf), "chunks.tlog")
    a = analyse(read.entries)
    assert [(round(e.time_s, 2), e.text) for e in a.events] == [
        (0.0, lost), (0.01, notice), (0.04, "Mode HOLD"), (0.04, exact), (0.05, exact),
        (0.06, shuffled), (0.07, "f" * 10)]
    assert [e.text for e in a.failsafes] == [lost]
    assert f"CRITICAL  {lost}\n" in summary(read, a) + "\n"


def test_pre_arm_refusals_and_clearances_are_not_counted_as_failsafes():
    said = [  # (severity, text, whether it starts a failsafe)
        (Severity.CRITICAL, "PreArm: Radio failsafe on", False),  # ArduPilot's pre-arm
        (Severity.WARNING, "PreArm: radio failsafe (receiver)", False),  # the companion's
        (Severity.CRITICAL, "Arm: Throttle below failsafe", False),
        (Severity.WARNING, "Radio Failsafe", True),  # ArduPilot Rover
        (Severity.INFO, "Radio Failsafe Cleared", False),
        (Severity.WARNING, "GCS Failsafe", True),
        (Severity.INFO, "GCS Failsafe Cleared", False),
        (Severity.CRITICAL, "GCS link lost: failsafe", True),  # the companion
        (Severity.INFO, "Disarmed: GCS failsafe", False),
        (Severity.NOTICE, "GCS link regained, mode HOLD", False),
        (Severity.WARNING, "Manual input lost: wheels neutral", True),
        (Severity.INFO, "Manual input resumed", False),
        (Severity.CRITICAL, "Flight controller link lost", True),
        (Severity.NOTICE, "Flight controller link up", False),
        (Severity.CRITICAL, "Radio failsafe: RSSI 0", True),
        (Severity.NOTICE, "Radio receiver OK, mode MANUAL", False),
        (Severity.EMERGENCY, "Crash: Disarming", True),
        (Severity.WARNING, "AUTO: no position: HOLD", False),
    ]
    rec = _Recorder()
    vehicle = mavlink.MAVLink(rec, srcSystem=1, srcComponent=1)
    for severity, text, _ in said:
        vehicle.statustext_send(severity, text.encode())
        rec.now_s += 0.1
    read = parse_tlog(bytes(rec.buf), "said.tlog")
    a = analyse(read.entries)
    assert [e.text for e in a.events] == [text for _, text, _ in said]
    assert [e.text for e in a.failsafes] == [text for _, text, fs in said if fs]
    assert "failsafes: 7\n" in summary(read, a)


def test_a_png_asked_for_that_cannot_be_written_is_said_and_exit_status_1(
        drive, tmp_path, capsys):
    """``log --png FILE``: a script that asked for the figure learns it is missing (the
    summary is printed all the same); the default PNG beside the tlog is a courtesy, so
    failing it leaves the status 0."""
    _, data = drive
    path = tmp_path / "drive.tlog"
    path.write_bytes(data)
    unwritable = path / "x.png"  # (under a file: no folder can be made there)
    assert main(["log", str(path), "--png", str(unwritable)]) == 1
    out, err = capsys.readouterr()
    assert "distance " in out
    assert err.startswith(f"mecanum-mav log: cannot write {unwritable}: ")
    (tmp_path / "drive.png").mkdir()  # (where the default PNG goes: a folder)
    assert main(["log", str(path)]) == 0
    assert capsys.readouterr().err.startswith(
        f"mecanum-mav log: cannot write {tmp_path / 'drive.png'}: ")


def test_log_without_matplotlib_prints_the_summary_and_fails_only_a_png_asked_for(
        drive, tmp_path, capsys, monkeypatch):
    _, data = drive
    path = tmp_path / "drive.tlog"
    path.write_bytes(data)
    not_installed(monkeypatch, "matplotlib")
    hint = "mecanum-mav log: no PNG: plotting needs matplotlib: pip install 'mecanum-mav[plot]'"
    assert main(["log", str(path)]) == 0
    out, err = capsys.readouterr()
    assert "distance " in out and err.strip() == hint
    assert main(["log", str(path), "--png", str(tmp_path / "asked.png")]) == 1
    assert capsys.readouterr().err.strip() == hint
