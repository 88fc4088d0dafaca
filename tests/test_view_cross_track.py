"""Cross-track on a leg that runs along no axis, the rover left and right of it.

- The view's ``track/cross_track`` (mecanum_mav.app.rerunview, its module docstring): "the
  estimated position's distance from the current mission leg in AUTO, m (the leg from the
  previous planned position ... to the current item)": a distance, the same on either side.
- ``mecanum-mav log``'s worst cross-track per leg (mecanum_mav.app.logmission.legs_driven):
  "the largest distance of the path from that segment while the item was current".
- Both measure with control.pathfollow.Leg: ``errors`` gives the signed cross-track, "positive
  to the right of the leg", ``distance_m`` the distance to the segment (past an end: to that
  end).

The leg runs from (1, 2) to (4, 6) north/east: 5 m long, direction (0.6, 0.8), so north and
east differ everywhere and swapping them, or a sign in the projection, changes the answer
(on a leg along an axis neither does). Its right is (-0.8, 0.6).
"""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import pytest

from mecanum_mav.app.logmission import legs_driven
from mecanum_mav.app.logresult import LogAnalysis
from mecanum_mav.control.pathfollow import Leg
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.mission import LOCAL_XY_SCALE
from mecanum_mav.protocol.modes import Mode

START, END = (1.0, 2.0), (4.0, 6.0)
ALONG, RIGHT = (0.6, 0.8), (-0.8, 0.6)


def at(along_m: float, right_m: float) -> tuple[float, float]:
    """(north, east) ``along_m`` from START along the leg and ``right_m`` to its right."""
    return (START[0] + along_m * ALONG[0] + right_m * RIGHT[0],
            START[1] + along_m * ALONG[1] + right_m * RIGHT[1])


RIGHT_OF_IT = at(2.5, 0.5)  # (2.1, 4.3)
LEFT_OF_IT = at(2.5, -0.3)  # (2.74, 3.82)
PAST_THE_END = at(5.0 + 0.6, 0.8)  # 1 m from the end
BEFORE_THE_START = at(-0.3, -0.4)  # 0.5 m from the start


def test_the_signed_cross_track_of_a_diagonal_leg_is_positive_to_its_right() -> None:
    leg = Leg(START, END)
    assert leg.errors(RIGHT_OF_IT) == pytest.approx((2.5, 0.5))
    assert leg.errors(LEFT_OF_IT) == pytest.approx((2.5, -0.3))
    assert leg.errors(at(0.0, 1.0)) == pytest.approx((0.0, 1.0))


def test_the_distance_to_a_diagonal_leg_is_the_same_either_side_and_to_an_end_beyond_it() -> None:
    leg = Leg(START, END)
    assert leg.distance_m(RIGHT_OF_IT) == pytest.approx(0.5)
    assert leg.distance_m(LEFT_OF_IT) == pytest.approx(0.3)
    assert leg.distance_m(at(2.5, -0.5)) == pytest.approx(0.5)
    assert leg.distance_m(PAST_THE_END) == pytest.approx(1.0)
    assert leg.distance_m(BEFORE_THE_START) == pytest.approx(0.5)


@pytest.mark.parametrize(("path", "worst_m"), [
    ([RIGHT_OF_IT, at(4.0, 0.1)], 0.5),
    ([at(1.0, -0.1), LEFT_OF_IT], 0.3),
    ([RIGHT_OF_IT, LEFT_OF_IT, at(4.0, -0.7)], 0.7),
])
def test_the_logs_worst_cross_track_of_a_diagonal_leg_is_the_farthest_point_either_side(
        path: list[tuple[float, float]], worst_m: float) -> None:
    result = LogAnalysis(
        path=[(10.0 + k, n, e) for k, (n, e) in enumerate(path)],
        planned=[(1, *START), (2, *END)], mission_current=[(9.0, 2)])
    legs = legs_driven(result)
    assert [(leg.seq, leg.start, leg.goal) for leg in legs] == [(2, START, END)]
    assert legs[0].max_cross_track_m == pytest.approx(worst_m)
    assert legs[0].samples == len(path)


# --------------------------------------------------------------------------- the view


def vehicle_messages(positions: list[tuple[float, float]]) -> list[Any]:
    """What a rover in AUTO sends a ground station: its plan (home, (1, 2), (4, 6) in the
    local frame), item 2 current, then each position (LOCAL_POSITION_NED)."""
    mav = mavlink.MAVLink(io.BytesIO(), srcSystem=1, srcComponent=1)
    sent = [mav.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,
                                 mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                 mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
                                 | mavlink.MAV_MODE_FLAG_SAFETY_ARMED, Mode.AUTO.value,
                                 mavlink.MAV_STATE_ACTIVE),
            mav.mission_count_encode(255, 190, 3, mavlink.MAV_MISSION_TYPE_MISSION)]
    for seq, (n, e) in enumerate([(0.0, 0.0), START, END]):
        sent.append(mav.mission_item_int_encode(
            255, 190, seq, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_CMD_NAV_WAYPOINT, 0, 1,
            0, 0, 0, 0, round(n * LOCAL_XY_SCALE), round(e * LOCAL_XY_SCALE), 0.0,
            mavlink.MAV_MISSION_TYPE_MISSION))
    sent.append(mav.mission_current_encode(2))
    sent += [mav.local_position_ned_encode(0, n, e, 0.0, 0.0, 0.0, 0.0) for n, e in positions]
    out = []
    for msg in sent:
        msg.pack(mav)
        out.append(mav.decode(bytearray(msg.get_msgbuf())))
    return out


def test_the_views_cross_track_of_a_diagonal_leg_is_the_distance_left_or_right_of_it(
        tmp_path: Path) -> None:
    pytest.importorskip("rerun", reason="the view extra (rerun-sdk) is not installed")
    from test_view import _flushed, scalars

    from mecanum_mav.app.rerunview import ViewMapping

    positions = [RIGHT_OF_IT, LEFT_OF_IT, at(2.5, -0.5), PAST_THE_END, at(5.0, 0.0)]
    mapping = ViewMapping()
    messages = vehicle_messages(positions)
    mapping.feed_all((1.0 + 0.1 * k, msg) for k, msg in enumerate(messages))
    assert [(s, pytest.approx(n), pytest.approx(e)) for s, n, e in mapping.plan] == [
        (1, *START), (2, *END)]
    track = [v for _, v in scalars(_flushed(mapping, tmp_path / "x.rrd"), "track/cross_track")]
    assert track == pytest.approx([0.5, 0.3, 0.5, 1.0, 0.0], abs=1e-4)
    assert not math.isclose(track[0], track[1])  # (not one number whatever the position)
