"""Record the sample drive to a tlog and draw it with ``mecanum-mav log``: docs/log.png.

    python tools/log_example.py [--tlog sample.tlog] [--png docs/log.png]

The drive (:mod:`mecanum_mav.sim.sampledrive`) runs in the lockstep harness in virtual time:
MANUAL sticks, the manual-input failsafe, an AUTO square interrupted by the GCS failsafe,
resumed, finished, disarmed. The summary is printed as ``mecanum-mav log`` prints it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mecanum_mav.app.logview import run_log
from mecanum_mav.sim.sampledrive import sample_drive


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tlog", type=Path, default=Path("sample.tlog"))
    parser.add_argument("--png", type=Path, default=Path("docs/log.png"))
    args = parser.parse_args()
    with args.tlog.open("wb") as tlog:
        sample_drive(tlog)
    return run_log(args.tlog, args.png)


if __name__ == "__main__":
    sys.exit(main())
