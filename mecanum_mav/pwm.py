"""``mecanum_mav.pwm``, the documented import path of the PWM edge.

The code lives in :mod:`mecanum_mav.control.pwm` (see docs/architecture.md);
this module re-exports its public names.
"""

from mecanum_mav.control.pwm import *  # noqa: F403
from mecanum_mav.control.pwm import __all__  # noqa: F401
