"""``mecanum_mav.geometry``, the documented import path of poses, twists and frame rotations.

The code lives in :mod:`mecanum_mav.mecanum.geometry` (see docs/architecture.md);
this module re-exports its public names.
"""

from mecanum_mav.mecanum.geometry import *  # noqa: F403
from mecanum_mav.mecanum.geometry import __all__  # noqa: F401
