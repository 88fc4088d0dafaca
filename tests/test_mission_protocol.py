"""The mission protocol state machine (protocol.missionservice): fake time, no sockets."""

from __future__ import annotations

import math

import pytest

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import (
    MAX_ITEMS,
    MissionItem,
    command_name,
    item_from_fields,
)
from mecanum_mav.protocol.missionservice import (
    ITEM_TIMEOUT_S,
    MAX_RETRIES,
    MissionService,
    Outgoing,
)

GCS = (255, 190)
OTHER = (254, 1)
T = ITEM_TIMEOUT_S

MISSION = mavlink.MAV_MISSION_TYPE_MISSION
FENCE = mavlink.MAV_MISSION_TYPE_FENCE
RALLY = mavlink.MAV_MISSION_TYPE_RALLY
ACCEPTED = mavlink.MAV_MISSION_ACCEPTED
CANCELLED = mavlink.MAV_MISSION_OPERATION_CANCELLED
UNSUPPORTED = mavlink.MAV_MISSION_UNSUPPORTED
REL_ALT_INT = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
REL_ALT = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT
LOCAL_NED = mavlink.MAV_FRAME_LOCAL_NED
WAYPOINT = mavlink.MAV_CMD_NAV_WAYPOINT
DO_JUMP = mavlink.MAV_CMD_DO_JUMP

LAT, LON = 47.3977419, 8.5455938


def fields(seq: int, x: float = round(LAT * 1e7), y: float = round(LON * 1e7), *,
           z: float = 0.0, frame: int = REL_ALT_INT, command: int = WAYPOINT,
           params: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)) -> dict:
    """The fields of a MISSION_ITEM(_INT) message."""
    p1, p2, p3, p4 = params
    return {"seq": seq, "frame": frame, "command": command, "current": 0, "autocontinue": 1,
            "param1": p1, "param2": p2, "param3": p3, "param4": p4, "x": x, "y": y, "z": z}


def wp(seq: int, north_deg: float = 0.0) -> dict:
    """A MISSION_ITEM_INT waypoint ``north_deg`` degrees north of (LAT, LON)."""
    return fields(seq, round((LAT + north_deg) * 1e7))


def stored(f: dict, *, encoded: bool = True) -> MissionItem:
    """The item the vehicle should store for message fields ``f``."""
    return item_from_fields(f["seq"], f["frame"], f["command"], f["current"], f["autocontinue"],
                            (f["param1"], f["param2"], f["param3"], f["param4"]),
                            f["x"], f["y"], f["z"], encoded=encoded)


OLD = (stored(wp(0)), stored(wp(1, 0.001)))


def request(seq: int, target: tuple[int, int] = GCS, kind: str = "MISSION_REQUEST_INT"):
    return Outgoing(kind, target, seq=seq)


def ack(result: int, target: tuple[int, int] = GCS, mission_type: int = MISSION):
    return Outgoing("MISSION_ACK", target, result=result, mission_type=mission_type)


def item(svc: MissionService, f: dict, now: float = 0.0, src=GCS, *, encoded: bool = True):
    return svc.on_item(src, f, encoded=encoded, mission_type=MISSION, now=now)


def upload(svc: MissionService, items: list[dict], src=GCS, now: float = 0.0) -> list[Outgoing]:
    """A whole upload without loss; every message the vehicle sent."""
    out = svc.on_count(src, len(items), MISSION, now)
    for f in items:
        out += item(svc, f, now, src)
    return out


# ------------------------------------------------------------------ upload


def test_upload_replaces_the_mission_only_after_the_last_item():
    svc = MissionService(OLD)
    new = [wp(0), wp(1, 0.01), wp(2, 0.02)]
    assert svc.on_count(GCS, 3, MISSION, 0.0) == [request(0)]
    assert svc.uploading
    assert item(svc, new[0]) == [request(1)]
    assert item(svc, new[1]) == [request(2)]
    assert svc.items == OLD and svc.version == 0 and svc.take_events() == []
    assert item(svc, new[2]) == [ack(ACCEPTED)]
    assert svc.items == tuple(stored(f) for f in new)
    assert svc.version == 1 and not svc.uploading
    assert [kind for kind, _ in svc.take_events()] == ["replaced"]


def test_lost_item_is_requested_again_after_250_ms():
    svc = MissionService()
    svc.on_count(GCS, 2, MISSION, 10.0)
    assert svc.next_due_s() == 10.25
    assert svc.tick(10.24) == []
    assert svc.tick(10.25) == [request(0)]
    assert svc.next_due_s() == 10.5
    assert svc.tick(10.49) == []
    assert item(svc, wp(0), 10.6) == [request(1)]
    assert svc.next_due_s() == pytest.approx(10.85)


def test_upload_is_cancelled_after_five_retries_and_the_old_mission_is_kept():
    svc = MissionService(OLD)
    svc.on_count(GCS, 3, MISSION, 0.0)
    item(svc, wp(0), 0.0)  # item 1 is requested at t = 0 and never comes
    for n in range(1, 6):  # five retries, 250 ms apart
        assert svc.tick(n * 0.25 - 0.001) == []
        assert svc.tick(n * 0.25) == [request(1)]
    assert svc.tick(1.499) == []
    assert svc.tick(1.5) == [ack(CANCELLED)]
    assert not svc.uploading and svc.next_due_s() == math.inf
    assert svc.items == OLD and svc.version == 0
    assert svc.take_events() == [("error", "Mission upload timed out at item 1")]
    assert svc.tick(10.0) == []


def test_retries_start_again_after_each_received_item():
    svc = MissionService()
    svc.on_count(GCS, 3, MISSION, 0.0)
    now = 0.0
    for _ in range(MAX_RETRIES):
        now += T
        assert svc.tick(now) == [request(0)]
    assert item(svc, wp(0), now) == [request(1)]
    for _ in range(MAX_RETRIES):
        now += T
        assert svc.tick(now) == [request(1)]
    assert svc.uploading


def test_out_of_sequence_item_is_dropped_and_the_expected_one_requested():
    svc = MissionService(OLD)
    new = [wp(0), wp(1, 0.01), wp(2, 0.02)]
    svc.on_count(GCS, 3, MISSION, 0.0)
    item(svc, new[0], 0.0)
    assert item(svc, wp(2, 0.5), 0.1) == [request(1)]  # at once, not after the timeout
    assert svc.next_due_s() == pytest.approx(0.1 + T)
    assert item(svc, fields(7), 0.1) == [request(1)]  # beyond the end: dropped too
    assert svc.take_events() == []  # not an error
    assert item(svc, new[1]) == [request(2)]
    assert item(svc, new[2]) == [ack(ACCEPTED)]
    assert svc.items == tuple(stored(f) for f in new)


def test_duplicated_item_is_ignored():
    svc = MissionService()
    new = [wp(0), wp(1, 0.01), wp(2, 0.02)]
    svc.on_count(GCS, 3, MISSION, 0.0)
    item(svc, new[0])
    item(svc, new[1])
    # a duplicating link (or a slow ground station) delivers item 1 again: dropped silently,
    # the request for item 2 is already out (and the timer re-sends it if it was lost)
    assert item(svc, wp(1, 0.9)) == []
    assert svc.tick(T) == [request(2)]
    assert item(svc, new[2]) == [ack(ACCEPTED)]
    assert svc.items[1] == stored(new[1])


def test_a_ground_station_that_keeps_sending_the_wrong_item_is_cancelled():
    svc = MissionService(OLD)
    svc.on_count(GCS, 3, MISSION, 0.0)
    item(svc, wp(0))
    for _ in range(MAX_RETRIES):
        assert item(svc, wp(2)) == [request(1)]
    assert item(svc, wp(2)) == [ack(CANCELLED)]
    assert not svc.uploading and svc.items == OLD
    assert svc.take_events() == [("error", "Mission upload stalled at item 1")]


@pytest.mark.parametrize(("bad", "encoded", "result"), [
    pytest.param(fields(1, 0, 0, frame=mavlink.MAV_FRAME_MISSION, command=DO_JUMP,
                        params=(1.0, 1.0, 0.0, 0.0)),
                 True, mavlink.MAV_MISSION_INVALID_PARAM1, id="jump-to-itself"),
    pytest.param(fields(1, math.nan, LON, frame=REL_ALT), False,
                 mavlink.MAV_MISSION_INVALID_PARAM5_X, id="legacy-nan-x"),
    pytest.param(fields(1, z=math.nan), True, mavlink.MAV_MISSION_INVALID_PARAM7, id="nan-z"),
    pytest.param(fields(1, 10_000, 0, frame=mavlink.MAV_FRAME_BODY_FRD), True,
                 mavlink.MAV_MISSION_UNSUPPORTED_FRAME, id="body-frame"),
])
def test_invalid_item_aborts_with_its_result_code_and_keeps_the_old_mission(bad, encoded,
                                                                             result):
    svc = MissionService(OLD)
    svc.on_count(GCS, 3, MISSION, 0.0)
    item(svc, wp(0))
    assert item(svc, bad, encoded=encoded) == [ack(result)]
    assert not svc.uploading and svc.next_due_s() == math.inf
    assert svc.items == OLD and svc.version == 0
    (kind, text), = svc.take_events()
    assert kind == "error" and text.startswith("item 1: ") and len(text) <= 50
    assert svc.tick(5.0) == []


def test_error_texts_are_cut_to_fit_a_statustext():
    svc = MissionService()
    last = MAX_ITEMS - 1
    svc.on_count(GCS, MAX_ITEMS, MISSION, 0.0)
    for seq in range(last):
        item(svc, wp(seq))
    jump = fields(last, 0, 0, frame=mavlink.MAV_FRAME_MISSION, command=DO_JUMP,
                  params=(float(last), 1.0, 0.0, 0.0))
    assert item(svc, jump) == [ack(mavlink.MAV_MISSION_INVALID_PARAM1)]
    (kind, text), = svc.take_events()
    assert kind == "error" and text.startswith(f"item {last}: jump") and len(text) == 50


def test_count_zero_clears():
    svc = MissionService(OLD)
    assert svc.on_count(GCS, 0, MISSION, 0.0) == [ack(ACCEPTED)]
    assert svc.items == () and svc.version == 1 and not svc.uploading
    assert [kind for kind, _ in svc.take_events()] == ["cleared"]


def test_count_beyond_max_items_gets_no_space():
    svc = MissionService(OLD)
    assert svc.on_count(GCS, MAX_ITEMS + 1, MISSION, 0.0) == [ack(mavlink.MAV_MISSION_NO_SPACE)]
    assert not svc.uploading and svc.items == OLD and svc.version == 0
    (kind, text), = svc.take_events()
    assert kind == "error" and str(MAX_ITEMS) in text
    assert svc.on_count(GCS, MAX_ITEMS, MISSION, 0.0) == [request(0)]


def test_clear_all_empties_the_mission():
    svc = MissionService(OLD)
    assert svc.on_clear_all(GCS, MISSION, 0.0) == [ack(ACCEPTED)]
    assert svc.items == () and svc.version == 1
    assert [kind for kind, _ in svc.take_events()] == ["cleared"]


def test_clear_all_cancels_an_upload():
    svc = MissionService(OLD)
    svc.on_count(GCS, 3, MISSION, 0.0)
    item(svc, wp(0))
    # another ground station clears: the uploader is told its upload is over
    svc.take_events()
    assert svc.on_clear_all(OTHER, MISSION, 0.1) == [ack(CANCELLED), ack(ACCEPTED, OTHER)]
    events = svc.take_events()
    assert events[0] == ("error", "Mission upload cancelled: mission cleared")
    assert [kind for kind, _ in events[1:]] == ["cleared"]
    assert not svc.uploading and svc.next_due_s() == math.inf
    assert svc.items == () and svc.version == 1
    assert item(svc, wp(1)) == [ack(CANCELLED)]  # the uploader goes on: still cancelled
    assert svc.items == ()
    # the uploader itself clears: its ACK says it all
    svc.on_count(GCS, 2, MISSION, 1.0)
    assert svc.on_clear_all(GCS, MISSION, 1.1) == [ack(ACCEPTED)]
    assert not svc.uploading


def test_clear_all_of_all_mission_types_clears_the_mission():
    svc = MissionService(OLD)
    all_types = mavlink.MAV_MISSION_TYPE_ALL
    assert svc.on_clear_all(GCS, all_types, 0.0) == [ack(ACCEPTED, mission_type=all_types)]
    assert svc.items == ()


def test_legacy_upload_switches_to_mission_request():
    svc = MissionService()
    legacy = [fields(0, LAT, LON, frame=REL_ALT), fields(1, LAT + 0.001, LON, frame=REL_ALT),
              fields(2, 12.5, -3.25, frame=LOCAL_NED)]
    assert svc.on_count(GCS, 3, MISSION, 0.0) == [request(0)]
    assert item(svc, legacy[0], encoded=False) == [request(1, kind="MISSION_REQUEST")]
    assert svc.tick(T) == [request(1, kind="MISSION_REQUEST")]
    assert item(svc, wp(2), encoded=True) == [request(1, kind="MISSION_REQUEST")]
    assert item(svc, legacy[1], encoded=False) == [request(2, kind="MISSION_REQUEST")]
    assert item(svc, legacy[2], encoded=False) == [ack(ACCEPTED)]
    assert [(it.x, it.y) for it in svc.items] == [
        (round(LAT * 1e7), round(LON * 1e7)), (round((LAT + 0.001) * 1e7), round(LON * 1e7)),
        (125_000, -32_500)]
    # a new transfer starts with MISSION_REQUEST_INT again
    assert svc.on_count(GCS, 1, MISSION, 1.0) == [request(0)]


def test_a_new_count_from_the_uploader_restarts_the_upload():
    svc = MissionService(OLD)
    svc.on_count(GCS, 3, MISSION, 0.0)
    item(svc, wp(0))
    item(svc, wp(1))
    assert svc.on_count(GCS, 2, MISSION, 0.1) == [request(0)]
    assert svc.next_due_s() == pytest.approx(0.1 + T)
    assert item(svc, wp(0, 0.3)) == [request(1)]
    assert item(svc, wp(1, 0.4)) == [ack(ACCEPTED)]
    assert svc.items == (stored(wp(0, 0.3)), stored(wp(1, 0.4)))
    assert svc.version == 1


def test_a_second_ground_station_is_denied_mid_upload():
    svc = MissionService(OLD)
    svc.on_count(GCS, 2, MISSION, 0.0)
    item(svc, wp(0), 0.1)
    due = svc.next_due_s()
    denied = ack(mavlink.MAV_MISSION_DENIED, OTHER)
    assert svc.on_count(OTHER, 1, MISSION, 0.2) == [denied]
    assert item(svc, wp(1, 0.7), 0.2, OTHER) == [denied]
    assert svc.on_ack(OTHER, CANCELLED, MISSION, 0.2) is None
    assert svc.uploading and svc.next_due_s() == due
    assert [kind for kind, _ in svc.take_events()] == ["error"]
    assert item(svc, wp(1), 0.2) == [ack(ACCEPTED)]
    assert svc.items == (stored(wp(0)), stored(wp(1)))


def test_another_component_of_the_same_system_is_another_ground_station():
    svc = MissionService()
    svc.on_count((255, 190), 2, MISSION, 0.0)
    assert svc.on_count((255, 1), 2, MISSION, 0.0) == [ack(mavlink.MAV_MISSION_DENIED, (255, 1))]


def test_lost_final_ack_is_sent_again_when_the_last_item_is_repeated():
    svc = MissionService()
    upload(svc, [wp(0), wp(1)])
    assert item(svc, wp(1), 1.0) == [ack(ACCEPTED)]
    assert svc.version == 1 and len(svc.items) == 2


def test_item_without_an_upload_is_refused():
    svc = MissionService(OLD)
    assert item(svc, wp(0), src=OTHER) == [ack(mavlink.MAV_MISSION_ERROR, OTHER)]
    assert svc.items == OLD and not svc.uploading


def test_an_error_ack_from_the_uploader_cancels_its_upload():
    svc = MissionService(OLD)
    svc.on_count(GCS, 3, MISSION, 0.0)
    assert svc.on_ack(GCS, ACCEPTED, MISSION, 0.1) is None  # not a cancellation
    assert svc.uploading
    assert svc.on_ack(GCS, CANCELLED, MISSION, 0.1) is None
    assert not svc.uploading and svc.tick(5.0) == [] and svc.items == OLD
    assert [kind for kind, _ in svc.take_events()] == ["error"]


def test_version_increments_each_time_the_mission_is_replaced_or_cleared():
    svc = MissionService(OLD)
    assert svc.version == 0
    upload(svc, [wp(0)])
    assert svc.version == 1
    svc.on_clear_all(GCS, MISSION, 0.0)
    assert svc.version == 2
    svc.on_clear_all(GCS, MISSION, 0.0)  # already empty: cleared all the same
    assert svc.version == 3
    svc.on_count(GCS, 0, MISSION, 0.0)
    assert svc.version == 4
    svc.on_count(GCS, 2, MISSION, 0.0)
    svc.on_count(GCS, 2, MISSION, 0.0)
    item(svc, fields(0, z=math.inf))  # failed uploads do not count
    assert svc.version == 4
    assert [kind for kind, _ in svc.take_events()] == [
        "replaced", "cleared", "cleared", "cleared", "error"]
    assert svc.take_events() == []


def test_next_due_s_is_inf_when_idle():
    svc = MissionService(OLD)
    assert svc.next_due_s() == math.inf and svc.tick(1.0) == []
    svc.on_count(GCS, 1, MISSION, 3.0)
    assert svc.next_due_s() == 3.0 + T
    item(svc, wp(0), 3.1)
    assert svc.next_due_s() == math.inf


# ------------------------------------------------------------------ download

DOWNLOADED = (
    stored(fields(0, LAT, LON, frame=REL_ALT), encoded=False),
    stored(fields(1, LAT + 0.0012345, LON - 0.5, z=3.0, frame=REL_ALT), encoded=False),
    stored(fields(2, 12.5, -3.25, frame=LOCAL_NED), encoded=False),
    stored(fields(3, 0, 0, frame=mavlink.MAV_FRAME_MISSION, command=DO_JUMP,
                  params=(1.0, 2.0, 0.0, 0.0))),
)


def test_download_sends_the_count_then_every_item_as_mission_item_int():
    svc = MissionService(DOWNLOADED)
    assert svc.on_request_list(GCS, MISSION, 0.0) == [Outgoing("MISSION_COUNT", GCS, count=4)]
    for seq, it in enumerate(DOWNLOADED):
        out, = svc.on_request(GCS, seq, legacy=False, mission_type=MISSION, now=0.0)
        assert out == Outgoing("MISSION_ITEM_INT", GCS, seq=seq, item=it)
        assert out.xy == (it.x, it.y)
    assert svc.on_ack(GCS, ACCEPTED, MISSION, 0.0) is None
    assert svc.items == DOWNLOADED and svc.version == 0 and svc.take_events() == []


def test_legacy_download_sends_mission_item_with_degrees_and_metres():
    svc = MissionService(DOWNLOADED)
    got = [svc.on_request(OTHER, seq, legacy=True, mission_type=MISSION, now=0.0)[0]
           for seq in range(4)]
    assert [(o.kind, o.target, o.seq, o.item) for o in got] == [
        ("MISSION_ITEM", OTHER, seq, it) for seq, it in enumerate(DOWNLOADED)]
    assert got[0].xy == pytest.approx((LAT, LON), abs=1e-9)
    assert got[1].xy == pytest.approx((LAT + 0.0012345, LON - 0.5), abs=1e-9)
    assert got[2].xy == (12.5, -3.25)
    assert got[3].xy == (0.0, 0.0)


def test_download_requests_may_come_in_any_order_and_repeat_without_a_request_list():
    svc = MissionService(DOWNLOADED)
    for seq in (2, 0, 2, 3, 1, 1):
        out, = svc.on_request(GCS, seq, legacy=False, mission_type=MISSION, now=0.0)
        assert (out.seq, out.item) == (seq, DOWNLOADED[seq])


@pytest.mark.parametrize("seq", [4, 65535, -1])
def test_out_of_range_download_request_gets_invalid_sequence(seq):
    svc = MissionService(DOWNLOADED)
    for legacy in (False, True):
        assert svc.on_request(GCS, seq, legacy=legacy, mission_type=MISSION, now=0.0) == [
            ack(mavlink.MAV_MISSION_INVALID_SEQUENCE)]


def test_an_empty_mission_downloads_as_count_zero():
    svc = MissionService()
    assert svc.on_request_list(GCS, MISSION, 0.0) == [Outgoing("MISSION_COUNT", GCS, count=0)]
    assert svc.on_request(GCS, 0, legacy=False, mission_type=MISSION, now=0.0) == [
        ack(mavlink.MAV_MISSION_INVALID_SEQUENCE)]


def test_downloads_serve_the_old_mission_during_an_upload():
    svc = MissionService(DOWNLOADED)
    svc.on_count(GCS, 2, MISSION, 0.0)
    item(svc, wp(0))
    assert svc.on_request_list(OTHER, MISSION, 0.1) == [Outgoing("MISSION_COUNT", OTHER, count=4)]
    out, = svc.on_request(OTHER, 0, legacy=False, mission_type=MISSION, now=0.1)
    assert out.item == DOWNLOADED[0]
    assert svc.on_ack(OTHER, ACCEPTED, MISSION, 0.1) is None
    assert svc.uploading
    assert item(svc, wp(1)) == [ack(ACCEPTED)]


def test_an_outgoing_without_item_has_no_xy():
    with pytest.raises(ValueError, match="MISSION_ACK"):
        _ = ack(ACCEPTED).xy


# ------------------------------------------------------------------ mission types


@pytest.mark.parametrize("kind", [FENCE, RALLY])
def test_fence_and_rally_are_empty_and_cannot_be_changed(kind):
    svc = MissionService(OLD)
    assert svc.on_request_list(GCS, kind, 0.0) == [
        Outgoing("MISSION_COUNT", GCS, count=0, mission_type=kind)]
    unsupported = ack(UNSUPPORTED, mission_type=kind)
    assert svc.on_count(GCS, 3, kind, 0.0) == [unsupported]
    assert svc.on_clear_all(GCS, kind, 0.0) == [unsupported]
    assert svc.on_request(GCS, 0, legacy=False, mission_type=kind, now=0.0) == [unsupported]
    assert svc.on_item(GCS, wp(0), encoded=True, mission_type=kind, now=0.0) == [unsupported]
    assert not svc.uploading and svc.items == OLD and svc.version == 0


@pytest.mark.parametrize("kind", [3, 7, mavlink.MAV_MISSION_TYPE_ALL])
def test_unknown_mission_types_are_unsupported(kind):
    svc = MissionService(OLD)
    unsupported = ack(UNSUPPORTED, OTHER, mission_type=kind)
    assert svc.on_request_list(OTHER, kind, 0.0) == [unsupported]
    assert svc.on_count(OTHER, 1, kind, 0.0) == [unsupported]
    assert svc.on_request(OTHER, 0, legacy=True, mission_type=kind, now=0.0) == [unsupported]
    assert svc.items == OLD


def test_fence_messages_do_not_disturb_an_upload_in_progress():
    svc = MissionService()
    svc.on_count(GCS, 2, MISSION, 0.0)
    item(svc, wp(0))
    assert svc.on_count(GCS, 1, FENCE, 0.1) == [ack(UNSUPPORTED, mission_type=FENCE)]
    assert svc.on_clear_all(GCS, FENCE, 0.1) == [ack(UNSUPPORTED, mission_type=FENCE)]
    assert svc.on_ack(GCS, CANCELLED, FENCE, 0.1) is None
    assert svc.uploading
    assert item(svc, wp(1)) == [ack(ACCEPTED)]
    assert len(svc.items) == 2


def test_a_command_is_named_as_mavlink_names_it_and_a_number_without_a_name_as_a_number():
    """(The names STATUSTEXTs and `mecanum-mav log` give items: MAV_CMD without its prefix.
    MAV_CMD_ENUM_END is the dialect's end marker, not a command.)"""
    assert command_name(mavlink.MAV_CMD_NAV_WAYPOINT) == "NAV_WAYPOINT"
    assert command_name(mavlink.MAV_CMD_DO_CHANGE_SPEED) == "DO_CHANGE_SPEED"
    assert command_name(mavlink.MAV_CMD_ENUM_END) == f"command {mavlink.MAV_CMD_ENUM_END}"
    assert command_name(12345) == "command 12345"
