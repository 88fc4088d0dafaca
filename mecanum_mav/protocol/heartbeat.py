"""HEARTBEAT as the companion sends it: an ArduPilot Rover to the ground station, a ground station
to the flight controller.

To the ground station (the ArduPilot Rover dialect MAVProxy, MAVSDK, QGroundControl and Mission
Planner understand): ``MAV_TYPE_GROUND_ROVER``, ``MAV_AUTOPILOT_ARDUPILOTMEGA``; ``base_mode``
carries ``CUSTOM_MODE_ENABLED`` plus ``SAFETY_ARMED``, ``MANUAL_INPUT_ENABLED`` and
``GUIDED_ENABLED`` as Rover sets them (``GCS_MAVLINK_Rover::base_mode``: the manual input flag
for a mode the sticks drive, the guided flag for an autopilot mode, AUTO included; Rover
never sets ``AUTO_ENABLED``); ``custom_mode`` is Rover's mode number; ``system_status`` is
CRITICAL in a link failsafe, else STANDBY in HOLD and ACTIVE in every other mode, armed or not
(``GCS_MAVLINK_Rover::vehicle_system_status``). Measured with the SITL (ArduPilot master of
July 2025): MANUAL disarmed 0x41 ACTIVE, armed 0xC1; HOLD disarmed 0x01 STANDBY, armed 0x81;
GUIDED disarmed 0x09 ACTIVE.
"""

from __future__ import annotations

from typing import Any

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.modes import Mode

__all__ = ["MODE_FLAGS", "send_gcs_heartbeat", "send_rover_heartbeat"]

MODE_FLAGS: dict[Mode, int] = {
    Mode.MANUAL: mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED,
    Mode.HOLD: 0,
    Mode.GUIDED: mavlink.MAV_MODE_FLAG_GUIDED_ENABLED,
    Mode.AUTO: mavlink.MAV_MODE_FLAG_GUIDED_ENABLED,
}
"""``base_mode`` flags of each mode, as ArduPilot Rover's ``base_mode()`` sets them (with
``STICK_MIXING`` 0, its default: HOLD is not an autopilot mode there, MANUAL has manual
input)."""


def send_rover_heartbeat(mav: Any, mode: Mode, *, armed: bool, failsafe: bool) -> None:
    """The rover's HEARTBEAT on ``mav`` (a pymavlink ``MAVLink`` or a message outbox)."""
    base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | MODE_FLAGS[mode]
    if armed:
        base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    if failsafe:
        status = mavlink.MAV_STATE_CRITICAL
    else:
        status = mavlink.MAV_STATE_STANDBY if mode is Mode.HOLD else mavlink.MAV_STATE_ACTIVE
    mav.heartbeat_send(mavlink.MAV_TYPE_GROUND_ROVER, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, base,
                       int(mode), status)


def send_gcs_heartbeat(mav: Any) -> None:
    """A ground station's HEARTBEAT (the companion's identity on the flight-controller link)."""
    mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                       mavlink.MAV_STATE_ACTIVE)
