"""The scripted mission run (mecanum_mav.sim.missionrun.fly, used by the demo, the twin and the
control benchmark) raises RuntimeError naming the step that failed, rather than wait for a
mission that cannot come: no companion, an upload refused, no flight controller, arming
refused, AUTO refused. The companion and the board in the lockstep harness (virtual time),
and a ground station that hears nothing."""

from __future__ import annotations

import io
import math
from typing import Any

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.sim.board import SimState
from mecanum_mav.sim.groundstation import ScriptedGroundStation
from mecanum_mav.sim.lockstep import Lockstep
from mecanum_mav.sim.missionrun import fly, waypoint_mission

ITEMS, WAYPOINTS = waypoint_mission([(0.5, 0.0)])
DT_S = 2.0**-9


class SilentPort:
    """A ground station's port that nothing ever arrives on (virtual time)."""

    def __init__(self) -> None:
        self.now_s = 0.0
        self.mav = mavlink.MAVLink(io.BytesIO(), srcSystem=255, srcComponent=190)

    def now(self) -> float:
        return self.now_s

    def pump(self, timeout_s: float) -> list[Any]:
        self.now_s += max(timeout_s, 0.01)
        return []


def no_truth() -> SimState:
    raise AssertionError("not watched: the script failed before AUTO")


def harness() -> Lockstep:
    """The lockstep harness stepped by a binary fraction of a second, so that virtual time
    adds up exactly: with 0.002 s steps a ground station's wait can end 1e-13 s short of
    its deadline, which the harness's port no longer steps toward (it waits for ever)."""
    return Lockstep(Params(), dt_s=DT_S)


def fly_on(h: Lockstep, items: list[MissionItem]) -> None:
    fly(h.gcs, h.truth, items, WAYPOINTS, timeout_s=30.0)


def test_without_a_companion_the_run_fails_for_want_of_its_heartbeat():
    gcs = ScriptedGroundStation(SilentPort())
    with pytest.raises(RuntimeError, match=r"^no heartbeat from the companion$"):
        fly(gcs, no_truth, ITEMS, WAYPOINTS, timeout_s=30.0)
    assert 5.0 <= gcs.port.now() < 5.5  # (it waited 5 s for it)


def test_a_mission_the_companion_refuses_fails_the_run_with_its_mission_ack():
    h = harness()
    bad = [*ITEMS[:-1], MissionItem(ITEMS[-1].seq, mavlink.MAV_FRAME_LOCAL_NED,
                                    mavlink.MAV_CMD_NAV_WAYPOINT, x=5000, y=0, z=math.nan)]
    with pytest.raises(RuntimeError, match=r"^mission upload refused \(MISSION_ACK "
                       f"{mavlink.MAV_MISSION_INVALID_PARAM7}\\)$"):
        fly_on(h, bad)


def test_a_companion_without_its_flight_controller_fails_the_run_before_arming():
    h = harness()
    h.fc_link_up = False  # the board is never heard
    with pytest.raises(RuntimeError, match=r"^no flight controller link$"):
        fly_on(h, ITEMS)
    assert not h.core.vehicle.armed


def test_a_companion_that_refuses_to_arm_fails_the_run():
    """A board that never answers one of the settings the companion checks: arming waits
    for it (refused) longer than the script tries."""
    h = harness()
    del h.board.parameters["RC4_DZ"]
    with pytest.raises(RuntimeError, match=r"^arming refused$"):
        fly_on(h, ITEMS)
    assert not h.core.vehicle.armed


def test_a_companion_that_refuses_auto_fails_the_run():
    """A mission in a global frame and no origin: AUTO cannot start."""
    h = harness()
    global_item = MissionItem(ITEMS[-1].seq, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                              mavlink.MAV_CMD_NAV_WAYPOINT, x=473977420, y=85455940)
    with pytest.raises(RuntimeError, match=r"^AUTO refused$"):
        fly_on(h, [*ITEMS[:-1], global_item])
    assert h.core.vehicle.armed  # it got as far as arming
