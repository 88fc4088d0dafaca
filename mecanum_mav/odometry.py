"""``mecanum_mav.odometry``, the documented import path of wheel odometry.

The code lives in :mod:`mecanum_mav.mecanum.odometry` (see docs/architecture.md);
this module re-exports its public names.
"""

from mecanum_mav.mecanum.odometry import *  # noqa: F403
from mecanum_mav.mecanum.odometry import __all__  # noqa: F401
