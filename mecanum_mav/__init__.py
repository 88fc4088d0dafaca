"""mecanum-mav: drive a mecanum-wheeled rover over MAVLink.

Conventions (see README): body frame FRD (x forward, y right, z down), local frame NED,
positive rotation clockwise seen from above, wheel order FL, FR, RL, RR, SI units inside.
"""

__version__ = "0.1.0"

WHEEL_NAMES: tuple[str, str, str, str] = ("front_left", "front_right", "rear_left", "rear_right")
"""Wheel order used on the last axis of every wheel array."""
