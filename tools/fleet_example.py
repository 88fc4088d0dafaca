"""Three rovers behind MAVProxy as a router, driven by system id from one ground station: the
docs/fleet.png.

    python tools/fleet_example.py [--count 3] [--png docs/fleet.png]

Starts ``mecanum-mav sim --instance 0 .. N-1`` and MAVProxy (``pip install '.[test]'``), runs
the drive that tests/test_fleet.py checks (:func:`mecanum_mav.app.fleet.drive_fleet`), prints
how far each rover moved in each phase and when each ran its mission, and draws each rover's
path (its own LOCAL_POSITION_NED as the ground station received it).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

from mecanum_mav.app.fleet import Fleet, drive_fleet, plot_fleet


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=3, help="rovers (at least 3)")
    parser.add_argument("--png", type=Path, default=Path("docs/fleet.png"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as workdir, Fleet(args.count, Path(workdir)) as fleet:
        drive = drive_fleet(fleet.stations)
    ids = sorted(drive.paths)
    print(f"{'phase':<22}" + "".join(f"{f'rover {s} moved m':>18}" for s in ids))
    for name, moved in drive.moved.items():
        print(f"{name:<22}" + "".join(f"{math.hypot(*moved[s]):18.3f}" for s in ids))
    for sysid, (start, end) in drive.auto.items():
        print(f"rover {sysid}: AUTO from {start:.1f} s to its last waypoint at {end:.1f} s")
    print(f"wrote {plot_fleet(drive, args.png)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
