"""Sanity limits on what a message may ask of the rover: the one definition of each.

These are not driving limits (the ``GUID_*`` and ``WP_*`` parameters are): they tell a
command a rover could follow, however slowly, from a corrupt or absurd one, which is refused
with a reason instead of being clamped into motion. GUIDED setpoints
(:mod:`mecanum_mav.control.guided`) and mission items (:mod:`mecanum_mav.protocol.mission`)
both check against them. Where the two paths accept different bounds today, each has its own
constant, named for the path that uses it; units are in the names.
"""

from __future__ import annotations

from typing import Final

__all__ = [
    "MAX_MISSION_HOLD_S",
    "MAX_MISSION_LOCAL_M",
    "MAX_MISSION_RADIUS_M",
    "MAX_MISSION_YAW_RATE_DPS",
    "MAX_SETPOINT_POSITION_M",
    "MAX_SETPOINT_YAW_RATE_RADPS",
    "MAX_SPEED_MPS",
]

MAX_SPEED_MPS: Final[float] = 50.0
"""Largest speed a message may ask for, m/s: the length of a GUIDED velocity setpoint
(SET_POSITION_TARGET_LOCAL_NED vx, vy) and a mission's DO_CHANGE_SPEED param2. Faster is
refused; slower is then limited by ``GUID_SPD_MAX``."""

MAX_SETPOINT_POSITION_M: Final[float] = 10_000.0
"""Largest distance of a GUIDED position setpoint (x, y of SET_POSITION_TARGET_LOCAL_NED),
metres: from the local origin, or from the rover in the offset frames."""

MAX_SETPOINT_YAW_RATE_RADPS: Final[float] = 20.0
"""Largest |yaw rate| a GUIDED setpoint may ask for, rad/s (SET_POSITION_TARGET_LOCAL_NED
yaw_rate); beyond is not a rover command. Slower is then limited by ``GUID_YAW_RATE``."""

MAX_MISSION_LOCAL_M: Final[float] = 100_000.0
"""Largest |x| and |y| of a mission item in MAV_FRAME_LOCAL_NED, metres north and east of
the local origin (100 km; the item carries metres * 1e4)."""

MAX_MISSION_YAW_RATE_DPS: Final[float] = 3600.0
"""Largest yaw rate a mission's CONDITION_YAW (param2) may ask for, degrees per second."""

MAX_MISSION_HOLD_S: Final[float] = 86_400.0
"""Longest hold time of a mission's NAV_WAYPOINT or NAV_LOITER_TIME (param1), seconds (a day)."""

MAX_MISSION_RADIUS_M: Final[float] = 1000.0
"""Largest acceptance radius of a mission's NAV_WAYPOINT (param2), metres."""
