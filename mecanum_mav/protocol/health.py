"""What SYS_STATUS says about the rover's health and battery.

Sensor bits, as ArduPilot fills them and MAVProxy and QGroundControl read them: ``present``
and ``enabled`` name what this vehicle has; ``health`` is 1 for everything that is not
failing, present or not (a clear health bit is an alarm: MAVProxy says "fence breach" for a
clear GEOFENCE bit). The companion has:

- motor outputs (the four wheels through the flight controller): healthy while the
  flight-controller link is up;
- an AHRS (heading from the flight controller's gyro, or from the wheels): healthy while the
  flight-controller link is up;
- a battery, when the flight controller measures one (its SYS_STATUS is relayed); absent
  otherwise.

Battery values are the flight controller's, relayed while fresh (:data:`BATTERY_FRESH_S`);
without them they are "unknown" as the specification encodes it: voltage UINT16_MAX mV,
current -1 (cA), remaining -1 (%).
"""

from __future__ import annotations

from typing import NamedTuple

from mecanum_mav.protocol.dialect import mavlink

__all__ = ["BATTERY_FRESH_S", "NO_SENSORS", "UNKNOWN_BATTERY", "Battery", "SensorBits",
           "sensor_bits"]

BATTERY_FRESH_S = 5.0
"""A flight-controller battery report older than this is no longer relayed (s)."""

_MOTORS: int = mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
_AHRS: int = mavlink.MAV_SYS_STATUS_AHRS
_BATTERY: int = mavlink.MAV_SYS_STATUS_SENSOR_BATTERY
_ALL_HEALTHY = 0xFFFFFFFF


class Battery(NamedTuple):
    """A battery reading as SYS_STATUS carries it."""

    voltage_mv: int
    """Millivolts; UINT16_MAX unknown."""
    current_ca: int
    """Centiamperes; -1 unknown."""
    remaining_pct: int
    """Percent; -1 unknown."""


UNKNOWN_BATTERY = Battery(0xFFFF, -1, -1)


class SensorBits(NamedTuple):
    """SYS_STATUS ``onboard_control_sensors_present``, ``_enabled`` and ``_health``."""

    present: int
    enabled: int
    health: int


NO_SENSORS = SensorBits(0, 0, _ALL_HEALTHY)
"""No sensors, nothing failing."""


def sensor_bits(*, fc_link_up: bool, battery_known: bool) -> SensorBits:
    """The rover's sensor bits (see the module docstring)."""
    present = _MOTORS | _AHRS | (_BATTERY if battery_known else 0)
    health = _ALL_HEALTHY if fc_link_up else _ALL_HEALTHY & ~(_MOTORS | _AHRS)
    return SensorBits(present, present, health)
