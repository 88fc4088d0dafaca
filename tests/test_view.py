"""The Rerun view (mecanum_mav.app.rerunview, app.view): a scripted drive's recording, read
back with Rerun's own reader (rerun.chunk.RrdReader), holds the entities and values the drive
had; the mapping never raises on odd messages; a tlog being written is followed."""

from __future__ import annotations

import io
import math
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

rr = pytest.importorskip("rerun", reason="the view extra (rerun-sdk) is not installed")
from rerun.chunk import RrdReader  # noqa: E402

from mecanum_mav.app.cli import main  # noqa: E402
from mecanum_mav.app.rerunview import ENTITIES, ViewMapping, to_map  # noqa: E402
from mecanum_mav.app.view import TlogFollower  # noqa: E402
from mecanum_mav.config.params import Params  # noqa: E402
from mecanum_mav.control.pwm import PwmMap  # noqa: E402
from mecanum_mav.io.tlog import read_tlog, tlog_record  # noqa: E402
from mecanum_mav.protocol.dialect import mavlink  # noqa: E402
from mecanum_mav.protocol.mission import LOCAL_XY_SCALE  # noqa: E402
from mecanum_mav.protocol.modes import Mode  # noqa: E402
from mecanum_mav.sim.sampledrive import MANUAL_SEGMENTS, sample_drive  # noqa: E402


def read_rrd(path: Path) -> tuple[dict[str, list[tuple[int, dict]]], dict[str, dict]]:
    """Entity -> (time ns, row) of every temporal row, in time order; entity -> static row."""
    temporal: dict[str, list[tuple[int, dict]]] = defaultdict(list)
    static: dict[str, dict] = {}
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        names = [n for n in batch.schema.names if ":" in n]
        columns = {n: batch.column(n).to_pylist() for n in names}
        entity = chunk.entity_path.lstrip("/")
        if chunk.is_static:
            static.setdefault(entity, {}).update({n: v[-1] for n, v in columns.items()})
            continue
        times = batch.column("time").cast("int64").to_pylist()
        for k, t in enumerate(times):
            temporal[entity].append((t, {n: v[k] for n, v in columns.items()}))
    for rows in temporal.values():
        rows.sort(key=lambda row: row[0])
    return temporal, static


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """The sample drive (MANUAL sticks, failsafes, an AUTO square) recorded to a tlog and
    turned into a view with ``mecanum-mav log --rerun``."""
    folder = tmp_path_factory.mktemp("view")
    tlog = folder / "drive.tlog"
    with tlog.open("wb") as f:
        result = sample_drive(f)
    rrd = folder / "drive.rrd"
    assert main(["log", str(tlog), "--png", str(folder / "drive.png"), "--rerun", str(rrd)]) == 0
    temporal, static = read_rrd(rrd)
    return result, temporal, static, tlog


def scalars(temporal, entity) -> list[tuple[int, float]]:
    return [(t, row["Scalars:scalars"][0]) for t, row in temporal[entity]]


def test_the_recording_of_a_drive_holds_every_entity_of_the_view(drive):
    _, temporal, static, _ = drive
    missing = [e for e in ENTITIES if e not in temporal and e not in static]
    assert missing == []


def test_the_sticks_are_the_scripted_manual_control_segments(drive):
    _, temporal, _, _ = drive
    for axis, k in (("x", 0), ("y", 1), ("r", 2)):
        values = {v for _, v in scalars(temporal, f"sticks/{axis}")}
        assert max(values) == pytest.approx(max(s[k] for s in MANUAL_SEGMENTS) / 1000.0)
        assert 0.0 in values


def test_the_wheel_commands_follow_the_x_roller_mixing_while_driving_right(drive):
    # Strafing right (y 0.5, the second segment): FL and RR forward, FR and RL backward,
    # each the PWM read back through the PWM map. Kills: command_from_pulse not used (PWM
    # shown as commands), wheel order or reverse lost in the mapping.
    _, temporal, _, _ = drive
    sticks = scalars(temporal, "sticks/y")
    right = [t for t, v in sticks if v == pytest.approx(0.5)]
    start, end = right[len(right) // 3], right[-1]
    pwm = PwmMap.from_params(Params())
    for name, wheel, sign in zip(("FL", "FR", "RL", "RR"), pwm.wheels, (1, -1, -1, 1),
                                 strict=True):
        commands = [v for t, v in scalars(temporal, f"wheels/command/{name}")
                    if start <= t <= end]
        pulses = [v for t, v in scalars(temporal, f"wheels/pwm/{name}") if start <= t <= end]
        assert commands and all(sign * c > 0.2 for c in commands), name
        assert commands == pytest.approx([wheel.command_from_pulse(p) for p in pulses]), name
    # Each wheel's arrow points forward (map -y, nose up) by its command, GEO_HALF_LEN long
    # at full command.
    half_len = Params()["GEO_HALF_LEN"]
    arrows = [np.array(row["Arrows2D:vectors"]) for t, row in temporal["map/rover/wheels"]
              if start <= t <= end]
    assert arrows
    for vectors in arrows:
        np.testing.assert_allclose(vectors[:, 0], 0.0)
        assert list(np.sign(-vectors[:, 1])) == [1, -1, -1, 1]
        assert np.abs(vectors[:, 1]).max() <= half_len + 1e-6


def test_the_map_holds_the_planned_square_and_the_true_path_where_the_simulator_was(drive):
    result, temporal, static, _ = drive
    plan = np.array(static["map/plan/items"]["Points2D:positions"])
    side = result.items[1].x / LOCAL_XY_SCALE  # north 1.5 m: the square's first corner
    # North up: (north, east) is drawn at (east, -north) in Rerun's y-down 2D view.
    np.testing.assert_allclose(plan, [(0, -side), (side, -side), (side, 0), (0, 0)], atol=1e-6)
    truth = temporal["map/truth"]
    last = truth[-1][1]["LineStrips2D:strips"][0][1]  # the last segment's end
    _, n, e = result.true_path[-1]
    assert last == pytest.approx(list(to_map(n, e)), abs=0.02)
    path = temporal["map/path"]
    end = path[-1][1]["LineStrips2D:strips"][0][1]
    assert math.dist(end, last) < 0.1  # the estimate ends near the truth


def test_the_rover_pose_is_a_transform_with_the_estimated_heading(drive):
    result, temporal, _, _ = drive
    poses = temporal["map/rover"]
    path_ends = [row["LineStrips2D:strips"][0][1] for _, row in temporal["map/path"]]
    translation = poses[-1][1]["Transform3D:translation"][0]
    assert translation[:2] == pytest.approx(path_ends[-1], abs=1e-4)
    quaternions = [row["Transform3D:quaternion"][0] for _, row in poses]
    yaws = [2 * math.atan2(q[2], q[3]) for q in quaternions]
    assert len({round(y, 2) for y in yaws}) > 3  # it turned (the clockwise stick segment)
    # Clockwise from north, as the map's y-down frame turns: the true heading at the end.
    true_yaw = result.harness.truth().pose.yaw_rad
    assert math.remainder(yaws[-1] - true_yaw, math.tau) == pytest.approx(0.0, abs=0.05)
    assert abs(true_yaw) > 0.2


def test_modes_arming_and_failsafes_are_on_the_timeline(drive):
    result, temporal, _, _ = drive
    modes = [row["StateChange:state"][0] for _, row in temporal["state/mode"]]
    expected = [m.name for _, m in result.mode_starts]
    assert modes == expected
    armed = [row["StateChange:state"][0] for _, row in temporal["state/armed"]]
    assert armed == ["disarmed", "armed", "disarmed"]
    events = [(row["TextLog:text"][0], row["TextLog:level"][0]) for _, row in temporal["events"]]
    failsafes = [text for text, level in events if level == "ERROR"]
    assert any("Manual input lost" in text for text in failsafes)
    assert any("GCS link lost" in text for text in failsafes)
    assert (f"mode {Mode.AUTO.name}", "INFO") in events


def test_cross_track_is_logged_only_in_auto_and_stays_small_on_the_square(drive):
    _, temporal, _, _ = drive
    modes = temporal["state/mode"]
    auto_from = next(t for t, row in modes if row["StateChange:state"][0] == "AUTO")
    track = scalars(temporal, "track/cross_track")
    assert track and all(t >= auto_from for t, _ in track)
    assert max(v for _, v in track) < 0.3


def _message(build, *args):
    mav = mavlink.MAVLink(io.BytesIO(), srcSystem=1, srcComponent=1)
    msg = getattr(mav, f"{build}_encode")(*args)
    msg.pack(mav)
    return mav.decode(bytearray(msg.get_msgbuf()))


def test_odd_messages_never_raise_and_a_non_finite_position_draws_nothing():
    mapping = ViewMapping()
    mapping.feed(1.0, object())
    mapping.feed(1.0, None)
    nan = float("nan")
    mapping.feed(2.0, _message("local_position_ned", 0, nan, 1.0, 0.0, nan, 0.0, 0.0))
    mapping.feed(2.0, _message("local_position_ned", 0, 1.0, math.inf, 0.0, 0.0, 0.0, 0.0))
    assert mapping.pending() == 0
    mapping.feed(3.0, _message("local_position_ned", 0, 1.0, 2.0, 0.0, 0.0, 0.0, 0.0))
    assert mapping.pending() == 2  # the pose and the speed, no segment yet


def test_the_chassis_size_follows_param_value_on_the_stream():
    mapping = ViewMapping()
    mapping.feed(1.0, _message("param_value", b"GEO_HALF_LEN", 0.4,
                               mavlink.MAV_PARAM_TYPE_REAL32, 100, 1))
    assert mapping.params["GEO_HALF_LEN"] == pytest.approx(0.4)
    mapping.feed(1.0, _message("param_value", b"GEO_HALF_LEN", -3.0,
                               mavlink.MAV_PARAM_TYPE_REAL32, 100, 1))
    assert mapping.params["GEO_HALF_LEN"] == pytest.approx(0.4)  # out of range: kept


def test_a_tlog_being_written_is_followed_a_record_cut_short_waiting_for_its_rest(tmp_path):
    path = tmp_path / "live.tlog"
    records = [tlog_record(1_800_000_000_000_000 + k * 100_000,
                           _message("heartbeat", 10, 3, 0, 0, 0, 3).get_msgbuf())
               for k in range(3)]
    path.write_bytes(records[0] + records[1][:7])
    follower = TlogFollower(path)
    try:
        assert [t for t, _ in follower.poll()] == [1_800_000_000.0]
        with path.open("ab") as f:
            f.write(records[1][7:] + records[2])
        assert [t for t, _ in follower.poll()] == pytest.approx([1_800_000_000.1,
                                                                  1_800_000_000.2])
        assert follower.poll() == []
    finally:
        follower.close()


def test_the_live_view_of_a_tlog_being_written_records_what_the_log_view_has(drive, tmp_path):
    # One mapping: 'view --connect FILE.tlog --save' (the web viewer served, no display)
    # records the same modes and path as 'log --rerun', half of the tlog written while it
    # runs. Kills: the live loop not flushing its last rows, the file not followed.
    import time

    from mecanum_mav.app.view import run_view

    _, temporal, _, tlog = drive
    data = tlog.read_bytes()
    entries = read_tlog(tlog).entries
    half = entries[len(entries) // 2].offset
    source = tmp_path / "live.tlog"
    source.write_bytes(data[:half])  # the rest is written while the view runs
    saved = tmp_path / "live.rrd"
    out = io.StringIO()
    deadline = time.monotonic() + 60.0

    def stop(mapping) -> bool:
        if mapping.messages >= len(entries) // 2 and source.stat().st_size == half:
            with source.open("ab") as f:
                f.write(data[half:])
        return mapping.messages >= len(entries) or time.monotonic() > deadline

    status = run_view(str(source), Params(), save=saved, web_port=0, out=out, stop_when=stop)
    assert status == 0
    assert "http://127.0.0.1:" in out.getvalue()
    live, _ = read_rrd(saved)
    assert [row["StateChange:state"] for _, row in live["state/mode"]] == \
        [row["StateChange:state"] for _, row in temporal["state/mode"]]
    assert len(live["map/path"]) == len(temporal["map/path"])


# --------------------------------------------------------------------------- wheel contacts


@pytest.fixture(scope="module")
def contact_drive(tmp_path_factory):
    """A drive on the MuJoCo chassis on friction 0.4 (lockstep, its tlog of both links): at
    rest, a full-stick launch forward for 1.5 s, at rest again; made a view with ``log
    --rerun``. Returns the tlog's contacts from the flight controller and the recording."""
    pytest.importorskip("mujoco")
    from mecanum_mav.sim.lockstep import Lockstep

    folder = tmp_path_factory.mktemp("contacts")
    tlog = folder / "mujoco.tlog"
    params = Params()
    params.update({"SIM_FRICTION": 0.4})
    with tlog.open("wb") as f:
        h = Lockstep(params, physics="mujoco", tlog=f)
        assert h.gcs.wait("STATUSTEXT", lambda m: m.text.startswith("FC setup checked"), 5.0,
                          since=0)
        h.run_for(0.5)
        h.gcs.arm()
        stop = h.every(0.05, lambda _t: h.gcs.mav.manual_control_send(1, 1000, 0, 500, 0, 0))
        h.run_for(1.5)
        stop()
        h.run_for(1.5)
    rrd = folder / "mujoco.rrd"
    assert main(["log", str(tlog), "--rerun", str(rrd)]) == 0
    sent = [(e.time_s, e.msg) for e in read_tlog(tlog).entries
            if e.msg.get_type() == "DEBUG_VECT"]
    temporal, static = read_rrd(rrd)
    return sent, temporal, static


def test_the_view_of_a_mujoco_drive_holds_each_wheels_contact_normal_force(contact_drive):
    # Kills: the contacts not mapped; a wheel's force filed under another wheel.
    sent, temporal, _ = contact_drive
    weight = Params()["SIM_MASS"] * 9.81
    for name in ("FL", "FR", "RL", "RR"):
        series = [v for _, v in scalars(temporal, f"contacts/normal/{name}")]
        board = [m.x for _, m in sent if m.name == f"CONTACT_{name}"]
        assert len(board) >= 30  # 10 Hz for 3.5 s
        assert series == pytest.approx(board), name
        assert series[0] == pytest.approx(weight / 4, rel=0.05)  # at rest: a quarter each
    first = [scalars(temporal, f"contacts/normal/{w}")[0][1] for w in ("FL", "FR", "RL", "RR")]
    assert sum(first) == pytest.approx(weight, rel=0.02)


def test_the_chassis_close_up_marks_a_wheel_red_while_it_slips(contact_drive):
    # Kills: the slip flag ignored (every box stays green), or the colours not per wheel.
    from mecanum_mav.app.rerunview import _GRIP_COLOUR, _SLIP_COLOUR

    sent, temporal, static = contact_drive
    assert len(static["map/rover/slip"]["Boxes2D:centers"]) == 4

    def packed(rgba) -> int:
        r, g, b, a = rgba
        return (r << 24) | (g << 16) | (b << 8) | a

    rows = [row["Boxes2D:colors"] for _, row in temporal["map/rover/slip"]]
    assert rows[0] == [packed(_GRIP_COLOUR)] * 4
    slipped = {k for row in rows for k, c in enumerate(row) if c == packed(_SLIP_COLOUR)}
    on_board = {["CONTACT_FL", "CONTACT_FR", "CONTACT_RL", "CONTACT_RR"].index(m.name)
                for _, m in sent if m.z == 1.0}
    assert slipped == on_board and slipped  # the launch on 0.4 slips
    assert rows[-1] == [packed(_GRIP_COLOUR)] * 4  # at rest again


def test_contacts_under_the_flight_controllers_ids_from_the_companion_are_not_mapped():
    # The companion and its flight controller share 1/1: a CONTACT_FL from the sender of
    # ODOMETRY (the companion), or from another system, is not a contact; the flight
    # controller's (its own sequence numbers) is. Kills: the sender not checked.
    companion = mavlink.MAVLink(io.BytesIO(), srcSystem=1, srcComponent=1)
    fc = mavlink.MAVLink(io.BytesIO(), srcSystem=1, srcComponent=1)
    fc.seq = 100
    other = mavlink.MAVLink(io.BytesIO(), srcSystem=7, srcComponent=1)

    def message(mav, build, *args):
        msg = getattr(mav, f"{build}_encode")(*args)
        msg.pack(mav)
        mav.seq = (mav.seq + 1) % 256
        return mav.decode(bytearray(msg.get_msgbuf()))

    mapping = ViewMapping()
    mapping.feed(1.0, message(companion, "odometry", 0, 1, 1, 0.0, 0.0, 0.0,
                              [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                              [math.nan] * 21, [math.nan] * 21))
    before = mapping.pending()
    mapping.feed(1.1, message(companion, "debug_vect", b"CONTACT_FL", 0, 5.0, 0.0, 1.0))
    mapping.feed(1.1, message(other, "debug_vect", b"CONTACT_FL", 0, 5.0, 0.0, 1.0))
    assert mapping.pending() == before
    mapping.feed(1.2, message(fc, "debug_vect", b"CONTACT_FL", 0, 9.8, 0.0, 0.0))
    assert mapping.pending() == before + 2  # the force and the first slip row


def test_log_with_a_view_draws_the_png_only_when_asked(drive, tmp_path):
    """``log --rerun`` (or ``--view``) writes the view and no PNG unless ``--png`` is given
    (drawing it takes most of a long log's time); ``--png`` too writes both."""
    tlog = tmp_path / "drive.tlog"
    tlog.write_bytes(drive[3].read_bytes())
    rrd = tmp_path / "only.rrd"
    assert main(["log", str(tlog), "--rerun", str(rrd)]) == 0
    assert rrd.stat().st_size > 0 and not tlog.with_suffix(".png").exists()
    png = tmp_path / "asked.png"
    assert main(["log", str(tlog), "--rerun", str(tmp_path / "both.rrd"), "--png", str(png)]) == 0
    assert png.stat().st_size > 10_000


# --------------------------------------------------------------------------- the twin's truth


def _sent(mav) -> list:
    """The messages ``mav`` (a MAVLink on a BytesIO) has written so far, decoded."""
    data = mav.file.getvalue()
    mav.file.seek(0)
    mav.file.truncate()
    return mavlink.MAVLink(None).parse_buffer(data) or []


def _flushed(mapping: ViewMapping, path: Path) -> dict:
    recording = rr.RecordingStream("test")
    recording.save(str(path))
    mapping.flush(recording)
    recording.flush()
    recording.disconnect()
    return read_rrd(path)[0]


def test_once_the_twins_truth_came_the_true_path_and_contacts_are_its_alone(tmp_path):
    # The firmware's SIMSTATE (about its own home, far from 0, 0) then the twin's truth
    # (TRUTH_SOURCE, about 0, 0): the true path starts again at the twin's first, about its
    # origin; later SIMSTATEs and the firmware's contacts are not drawn. Kills: every
    # sender's truth drawn; the origin guessed from the firmware's kept.
    from mecanum_mav.mecanum.geo import GlobalOrigin
    from mecanum_mav.sim.physics import WheelContact
    from mecanum_mav.sim.truthsender import TRUTH_SOURCE, send_contacts, send_sim_state

    firmware = mavlink.MAVLink(io.BytesIO(), srcSystem=1, srcComponent=1)
    twin = mavlink.MAVLink(io.BytesIO(), srcSystem=TRUTH_SOURCE[0], srcComponent=TRUTH_SOURCE[1])
    contacts = [WheelContact(10.0 + k, 0.0, False) for k in range(4)]
    mapping = ViewMapping()
    fed = []
    for mav, send in (
            (firmware, lambda: firmware.simstate_send(0, 0, 0, 0, 0, 0, 0, 0, 0, -353632621,
                                                      1491652374)),
            (twin, lambda: send_sim_state(twin, GlobalOrigin(0, 0), 1.0, 2.0, 0, 0, 0, 0)),
            (firmware, lambda: firmware.simstate_send(0, 0, 0, 0, 0, 0, 0, 0, 0, -353632000,
                                                      1491652374)),
            (twin, lambda: send_sim_state(twin, GlobalOrigin(0, 0), 1.5, 2.0, 0, 0, 0, 0)),
            (twin, lambda: send_contacts(twin, 0, contacts)),
            (firmware, lambda: send_contacts(firmware, 0, [WheelContact(99.0, 0, True)] * 4))):
        send()
        fed += _sent(mav)
    mapping.feed_all((1.0 + k, msg) for k, msg in enumerate(fed))
    temporal = _flushed(mapping, tmp_path / "truth.rrd")
    strips = [row["LineStrips2D:strips"] for _, row in temporal["map/truth"]]
    assert len(strips) == 1
    assert np.asarray(strips[0][0]) == pytest.approx(
        np.array([to_map(1.0, 2.0), to_map(1.5, 2.0)]), abs=0.02)
    forces = [scalars(temporal, f"contacts/normal/{w}") for w in ("FL", "FR", "RL", "RR")]
    assert [[v for _, v in series] for series in forces] == [[10.0], [11.0], [12.0], [13.0]]


def test_several_sources_are_merged_in_time_order(tmp_path):
    # 'view --connect A --connect B': each round's messages of every source, by time.
    # Kills: the sources' batches chained instead of merged.
    from mecanum_mav.app.view import merged

    base = 1_800_000_000_000_000
    paths = []
    for name, times in (("a", (0, 2, 4)), ("b", (1, 3, 5))):
        path = tmp_path / f"{name}.tlog"
        path.write_bytes(b"".join(
            tlog_record(base + t * 100_000, _message("heartbeat", 10, 3, 0, 0, 0, 3)
                        .get_msgbuf()) for t in times))
        paths.append(str(path))
    batches = merged(paths)
    try:
        first = next(batches)
    finally:
        batches.close()
    assert [round(t - base / 1e6, 1) for t, _ in first] == [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]


def test_the_live_view_of_a_tlog_and_a_twins_truth_records_both(drive, tmp_path):
    # 'view --connect FILE.tlog --connect udpin:...' with the twin's truth publisher sending
    # to the second: the recording holds the tlog's estimated path and the twin's true path
    # and contact forces. Kills: a second --connect ignored, the twin's truth not drawn.
    import time

    from mecanum_mav.app.view import run_view
    from mecanum_mav.mecanum.geo import GlobalOrigin
    from mecanum_mav.sim.physics import WheelContact
    from mecanum_mav.sim.process import free_port
    from mecanum_mav.sim.truthsender import TruthPublisher
    from mecanum_mav.sim.twinrecord import TruthSample, TwinRecord

    _, temporal, _, tlog = drive
    entries = len(read_tlog(tlog).entries)
    record = TwinRecord.local(capacity=100)
    port = free_port(__import__("socket").SOCK_DGRAM)
    publisher = TruthPublisher(record, f"udpout:127.0.0.1:{port}", GlobalOrigin(0, 0))
    saved = tmp_path / "both.rrd"
    started = time.time()
    deadline = time.monotonic() + 20.0

    def stop(mapping) -> bool:  # the twin's physics moves on as the view runs
        t = time.monotonic()
        record.add(TruthSample(t, t, 5.0 + 0.01 * record.count, -3.0, 0.0, 0.5, 0.0))
        record.set_contacts(t, [WheelContact(20.0, 0.0, False)] * 4)
        return mapping.messages >= entries + 40 or time.monotonic() > deadline

    try:
        status = run_view([str(tlog), f"udpin:127.0.0.1:{port}"], Params(), save=saved,
                          web_port=0, out=io.StringIO(), stop_when=stop)
    finally:
        publisher.close()
    assert status == 0
    live, _ = read_rrd(saved)
    assert len(live["map/path"]) == len(temporal["map/path"])
    twin_rows = [row["LineStrips2D:strips"][0] for t, row in live["map/truth"]
                 if t / 1e9 >= started]
    assert len(twin_rows) >= 5
    assert all(east == pytest.approx(-3.0, abs=0.02) and -north >= 5.0 - 0.02
               for east, north in (p for strip in twin_rows for p in strip))
    assert [v for _, v in scalars(live, "contacts/normal/RR")][-1] == 20.0
