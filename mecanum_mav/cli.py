"""``python -m mecanum_mav.cli``: the command line (:mod:`mecanum_mav.app.cli`)."""

import sys

from mecanum_mav.app.cli import main

if __name__ == "__main__":
    sys.exit(main())
