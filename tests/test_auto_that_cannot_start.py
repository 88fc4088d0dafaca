"""AUTO entered with a runnable mission, then given one it cannot run before it starts (a
global mission without an origin, uploaded while disarmed): arming does not drive, it
switches to HOLD and says why (control/core.py, the lockstep harness)."""

from __future__ import annotations

from conftest import lockstep
from missionitems import GLOBAL_REL, local_wp, renumber

from mecanum_mav.io.links import mavlink
from mecanum_mav.protocol.mission import MissionItem
from mecanum_mav.protocol.modes import Mode

ACCEPTED = mavlink.MAV_MISSION_ACCEPTED
HOME = local_wp(0, 0.0, 0.0)


def test_arming_in_auto_with_a_mission_that_cannot_start_switches_to_hold_and_says_why():
    h = lockstep()
    gcs = h.gcs
    assert gcs.upload(renumber([HOME, local_wp(0, 1.0, 0.0)])).type == ACCEPTED
    assert gcs.set_mode(Mode.AUTO) == mavlink.MAV_RESULT_ACCEPTED  # disarmed: nothing runs
    global_wp = MissionItem(0, GLOBAL_REL, mavlink.MAV_CMD_NAV_WAYPOINT, x=473977420,
                           y=85455940)  # (degrees * 1e7)
    assert gcs.upload(renumber([HOME, global_wp])).type == ACCEPTED  # and no origin set
    since = gcs.mark()
    gcs.arm()
    held = h.run_until(lambda: h.core.vehicle.mode is Mode.HOLD, 1.0)
    assert held, "the rover stayed in AUTO with a mission it cannot run"
    said = "".join(m.text for m in gcs.received("STATUSTEXT", since))  # (a long one is cut)
    assert "AUTO: global item and no origin" in said and "): HOLD" in said, said
    assert all(o.channels[:4] == [1500] * 4 for o in h.overrides_since(0.0))
