"""mecanum-mav: drive a mecanum-wheeled rover over MAVLink.

Conventions (see docs/index.md): body frame FRD (x forward, y right, z down), local frame NED,
positive rotation clockwise seen from above, wheel order FL, FR, RL, RR, SI units inside.
"""

from mecanum_mav.mecanum.wheels import WHEEL_NAMES

__all__ = ["WHEEL_NAMES", "__version__"]

__version__ = "0.1.0"
