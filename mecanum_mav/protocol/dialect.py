"""pymavlink set up for MAVLink 2 and the ArduPilot dialect, imported by everything MAVLink.

Sets ``MAVLINK20=1`` before pymavlink is imported and re-selects the dialect, so MAVLink 2 is
used even when pymavlink was imported first.
"""

from __future__ import annotations

import os
from typing import Any

os.environ["MAVLINK20"] = "1"

from pymavlink import mavutil

mavutil.set_dialect("ardupilotmega")
mavlink: Any = mavutil.mavlink
"""The pymavlink dialect module (MAVLink 2, ardupilotmega): constants and message classes."""

__all__ = ["mavlink", "mavutil"]
