"""The picture of the Rerun view for the README: docs/view.png.

    python tools/view_example.py [--png docs/view.png] [--at 0.75]

Records the sample drive (:mod:`mecanum_mav.sim.sampledrive`: MANUAL sticks, failsafes, an
AUTO square) to a tlog, makes its view up to ``--at`` (a fraction of the drive: the rover
mid-mission, its wheels driving), serves it in Rerun's web viewer and takes a screenshot in
Debian's headless chromium (Playwright; ``apt-get install chromium``).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from mecanum_mav.app.view import serve_rrd, write_rrd
from mecanum_mav.config.params import Params
from mecanum_mav.io.tlog import read_tlog
from mecanum_mav.sim.sampledrive import sample_drive

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--png", type=Path, default=Path("docs/view.png"))
    parser.add_argument("--at", type=float, default=0.75,
                        help="how far into the drive the view ends (fraction)")
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as scratch:
        tlog, rrd = Path(scratch) / "drive.tlog", Path(scratch) / "drive.rrd"
        with tlog.open("wb") as f:
            sample_drive(f)
        entries = read_tlog(tlog).entries
        end = entries[0].time_s + args.at * (entries[-1].time_s - entries[0].time_s)
        write_rrd([e for e in entries if e.time_s <= end], Params(), rrd)
        viewer = serve_rrd(rrd, 0, native=False)
        try:
            assert viewer.url is not None
            with sync_playwright() as p:
                context = p.chromium.launch_persistent_context(
                    str(Path(scratch) / "profile"), executable_path=args.chromium,
                    headless=True, args=FLAGS, viewport={"width": 1600, "height": 1000})
                page = context.new_page()
                page.goto(viewer.url)
                time.sleep(20)  # a tool, not a test: the viewer's first frames in software
                args.png.parent.mkdir(parents=True, exist_ok=True)
                page.screenshot(path=str(args.png))
                context.close()
        finally:
            viewer.close()
    print(f"wrote {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
