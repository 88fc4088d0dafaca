"""``mecanum_mav.mixing``, the documented import path of normalized mecanum mixing.

The code lives in :mod:`mecanum_mav.mecanum.mixing` (see docs/architecture.md);
this module re-exports its public names.
"""

from mecanum_mav.mecanum.mixing import *  # noqa: F403
from mecanum_mav.mecanum.mixing import __all__  # noqa: F401
