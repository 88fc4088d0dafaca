"""``python -m mecanum_mav``: the ``mecanum-mav`` command line."""

import sys

from mecanum_mav.app.cli import main

sys.exit(main())
