"""``python -m mecanum_mav``: the ``mecanum-mav`` command line."""

import sys

try:
    from mecanum_mav.app.cli import main
except KeyboardInterrupt:  # Ctrl-C while the modules load: no traceback either
    sys.exit(130)

sys.exit(main())
