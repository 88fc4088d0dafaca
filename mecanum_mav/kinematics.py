"""``mecanum_mav.kinematics``, the documented import path of mecanum kinematics (SI units).

The code lives in :mod:`mecanum_mav.mecanum.kinematics` (see docs/architecture.md);
this module re-exports its public names.
"""

from mecanum_mav.mecanum.kinematics import *  # noqa: F403
from mecanum_mav.mecanum.kinematics import __all__  # noqa: F401
