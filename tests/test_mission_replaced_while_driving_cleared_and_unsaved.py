"""What happens to the mission the rover runs when the ground station replaces or clears it,
when it cannot be kept, and when a ground station other than the pilot's sends mission
messages (mecanum_mav.control.missions; docs/companion.md, Missions and AUTO): the companion in
the lockstep harness (virtual time)."""

from __future__ import annotations

import errno
from collections.abc import Sequence

from conftest import lockstep
from missionitems import local_wp, renumber, same

from mecanum_mav.io.links import mavlink
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.lockstep import Lockstep

ACCEPTED = mavlink.MAV_MISSION_ACCEPTED
HOME = local_wp(0, 0.0, 0.0)
LINE = renumber([HOME, local_wp(0, 1.0, 0.0), local_wp(0, 2.0, 0.0), local_wp(0, 3.0, 0.0)])


class FullDisk:
    """Storage whose every save fails as a full disk does; counts the attempts."""

    def __init__(self) -> None:
        self.missions = 0

    def save_params(self, params: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    def save_mission(self, items: Sequence[MissionItem]) -> None:
        self.missions += 1
        raise OSError(errno.ENOSPC, "No space left on device")


def is_line(items: Sequence[MissionItem]) -> bool:
    """Whether ``items`` are :data:`LINE`, field by field (NaN equal to NaN)."""
    return len(items) == len(LINE) and all(same(a, b) for a, b in zip(items, LINE, strict=True))


def driving_item_2(h: Lockstep) -> int:
    """Upload :data:`LINE`, arm, AUTO, and drive until item 2 is current; the index of the
    ground station's messages from then."""
    assert h.gcs.upload(LINE).type == ACCEPTED
    h.gcs.arm()
    assert h.gcs.set_mode(Mode.AUTO) == mavlink.MAV_RESULT_ACCEPTED
    assert h.run_until(lambda: h.core.mission.executor.current == 2, 10.0)
    return h.gcs.mark()


def test_a_mission_uploaded_while_auto_drives_goes_on_from_the_current_item():
    """"an accepted mission replaces the executor's (a running one goes on from its current
    item)": said as a NOTICE, and the rover drives the new mission's item 2, not the old."""
    h = lockstep()
    since = driving_item_2(h)
    new = renumber([HOME, local_wp(0, 1.0, 0.0), local_wp(0, 1.0, 0.5)])
    assert h.gcs.upload(new).type == ACCEPTED
    assert "New mission: continuing at item 2" in h.gcs.texts(since)
    assert h.core.vehicle.mode is Mode.AUTO
    reached = h.gcs.wait("MISSION_ITEM_REACHED", lambda m: m.seq == 2, 10.0, since)
    assert reached is not None
    pose = h.truth().pose
    assert abs(pose.x_m - 1.0) < 0.05 and abs(pose.y_m - 0.5) < 0.05


def test_a_mission_cleared_while_auto_drives_switches_to_hold_with_a_warning():
    h = lockstep()
    since = driving_item_2(h)
    h.gcs.mav.mission_clear_all_send(1, 1, 0)
    ack = h.gcs.wait("MISSION_ACK", timeout_s=1.0, since=since)
    assert ack is not None and ack.type == ACCEPTED
    assert h.run_until(lambda: h.core.vehicle.mode is Mode.HOLD, 0.5)
    warning = h.gcs.wait("STATUSTEXT", lambda m: m.text == "Mission cleared: HOLD", 1.0, since)
    assert warning is not None and warning.severity == mavlink.MAV_SEVERITY_WARNING


def test_a_mission_that_cannot_be_saved_is_still_run_and_the_failure_said():
    """The store raising OSError: the mission is accepted and in force, only not kept; the
    ground station is told (ERROR)."""
    storage = FullDisk()
    h = lockstep(storage=storage)
    since = h.gcs.mark()
    assert h.gcs.upload(LINE).type == ACCEPTED
    assert storage.missions == 1
    failed = h.gcs.wait("STATUSTEXT", lambda m: m.text == "Mission save failed: No space left "
                        "on device", 1.0, since)
    assert failed is not None and failed.severity == mavlink.MAV_SEVERITY_ERROR
    assert is_line(h.core.mission.items)


def test_mission_messages_from_a_ground_station_other_than_sysid_mygcs_are_ignored():
    """With SYSID_MYGCS set only the pilot's ground station's mission messages count: another
    one's MISSION_COUNT and MISSION_CLEAR_ALL get no answer and change nothing."""
    h = lockstep({"SYSID_MYGCS": 255})
    assert h.gcs.upload(LINE).type == ACCEPTED
    stranger = mavlink.MAVLink(None, srcSystem=200, srcComponent=190)
    since = h.gcs.mark()
    h.inject(stranger.mission_count_encode(1, 1, 2, 0).pack(stranger))
    h.inject(stranger.mission_clear_all_encode(1, 1, 0).pack(stranger))
    h.run_for(1.0)
    h.gcs.mark()
    assert h.gcs.received("MISSION_REQUEST_INT", since) == []
    assert h.gcs.received("MISSION_ACK", since) == []
    assert is_line(h.core.mission.items)
