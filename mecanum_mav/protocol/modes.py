"""Rover mode numbers: the one definition of what ``custom_mode`` means on the wire.

The companion speaks ArduPilot Rover's dialect, so a mode travels as Rover's ``custom_mode``
(HEARTBEAT, SET_MODE, COMMAND_LONG DO_SET_MODE param2): MANUAL 0, HOLD 4, AUTO 10, GUIDED 15.
The numbers are those of the ArduPilot dialect's ``ROVER_MODE`` enumeration (ardupilotmega.xml;
tests/test_modes.py checks them against pymavlink's). No imports from the package or pymavlink:
anything may import this module. The vehicle's state machine, the heartbeat, the simulated
flight controller and the demo's ground station all import :class:`Mode` from here.
"""

from __future__ import annotations

from enum import IntEnum

__all__ = ["Mode"]


class Mode(IntEnum):
    """Rover modes, numbered as ArduPilot Rover's ``custom_mode`` (``ROVER_MODE``)."""

    MANUAL = 0
    HOLD = 4
    AUTO = 10
    GUIDED = 15
