#!/usr/bin/env python3
"""Benchmark what an unplugged serial flight controller costs the companion (issue 11.2).

Method
    The real companion process (``python -m mecanum_mav run``, default parameters) runs
    between a UDP ground station (1 Hz HEARTBEAT) and a flight controller played by this
    script on the master end of a pty behind a symlink (as udev's /dev/serial/by-id names
    are), 57600 baud, sending HEARTBEAT at 10 Hz and reading what comes. Three phases:

    1. *baseline* (the same run): the device is there, the companion idle (disarmed, its
       20 Hz override refresh, telemetry and heartbeats); its CPU over ``--window`` seconds;
    2. *gone*: the cable pulled (the pty closed, the symlink removed; the companion's end
       reads EIO), after the companion has said "FC link down"; its CPU over the window;
    3. *back*: a new pty behind the same path; how long until its first byte arrives.

    CPU is the kernel's clock of the process (:func:`~mecanum_mav.sim.process.process_cpu_s`,
    all threads), as a share of one core over the window.

Goals
    - gone: under 5 % of one core (a dead descriptor waited on would spin the loop: ~100 %);
    - gone / baseline at most 1.5 (a link that is down costs no more than one that is up,
      with room for the noise of small figures);
    - back: the first byte within 1 s of the plug (a reopen every 0.5 s, and the wake-up).

The exit status is 0 when all goals are met, 1 when one is not, 2 when the companion died or
never came up.

    python tools/bench_link_down.py [--window 3]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import time
import tty
from collections.abc import Callable
from pathlib import Path

from mecanum_mav.io.links import mavlink
from mecanum_mav.sim.groundstation import ScriptedGroundStation, udp_ground_station
from mecanum_mav.sim.process import CompanionProcess, process_cpu_s

BEAT_PERIOD_S = 0.1
GOAL_GONE_CPU = 0.05
GOAL_RATIO = 1.5
GOAL_BACK_S = 1.0


class Cable:
    """A pty behind ``path``: the flight controller's end (HEARTBEAT every 0.1 s when
    pumped; notes when the first byte from the companion arrived)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        path.symlink_to(os.ttyname(self.slave))
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self.first_byte_s: float | None = None
        self._beat_s = -1.0

    def pump(self) -> None:
        now = time.monotonic()
        if now - self._beat_s >= BEAT_PERIOD_S:
            self._beat_s = now
            os.write(self.master, self.mav.heartbeat_encode(
                mavlink.MAV_TYPE_GROUND_ROVER, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0,
                mavlink.MAV_STATE_STANDBY).pack(self.mav))
        with contextlib.suppress(BlockingIOError, InterruptedError):
            if os.read(self.master, 4096) and self.first_byte_s is None:
                self.first_byte_s = time.monotonic()

    def unplug(self) -> None:
        self.path.unlink(missing_ok=True)
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)


def _run(gcs: ScriptedGroundStation, cable: Cable | None, done: Callable[[], object],
         timeout_s: float) -> bool:
    """Pump the ground station and the cable until ``done()`` or ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not done():
        if time.monotonic() > deadline:
            return False
        if cable is not None:
            cable.pump()
        gcs.pump(0.01)
    return True


def _said(gcs: ScriptedGroundStation, text: str, since: int) -> bool:
    return any(text in m.text for m in gcs.received("STATUSTEXT", since))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    parser.add_argument("--window", type=float, default=3.0,
                        help="seconds of each CPU window (default 3)")
    args = parser.parse_args()
    window = args.window
    gcs, port = udp_ground_station()
    with tempfile.TemporaryDirectory() as tmp:
        device = Path(tmp) / "ttyFC"
        cable = Cable(device)
        try:
            with CompanionProcess(port.url, f"{device},57600", Path(tmp)) as companion:
                pid = companion.proc.pid

                def cpu_share(fc: Cable | None) -> float:
                    before = process_cpu_s(pid)
                    end = time.monotonic() + window
                    _run(gcs, fc, lambda: time.monotonic() >= end, window + 1.0)
                    return float(process_cpu_s(pid) - before) / window

                if not _run(gcs, cable, lambda: _said(gcs, "Flight controller link up", 0),
                            20.0):
                    print(f"the companion never heard the flight controller\n{companion.log()}")
                    return 2
                present = cpu_share(cable)
                since = gcs.mark()
                cable.unplug()
                if not _run(gcs, None, lambda: _said(gcs, "FC link down", since), 20.0):
                    print(f"the companion never said the link was down\n{companion.log()}")
                    return 2
                gone = cpu_share(None)
                cable = Cable(device)
                plugged = time.monotonic()
                _run(gcs, cable, lambda: cable.first_byte_s is not None, 20.0)
                back_s = (cable.first_byte_s or float("inf")) - plugged
                alive = companion.proc.poll() is None
                log = companion.log()
        finally:
            cable.unplug()
            port.close()
    if not alive:
        print(f"the companion died\n{log}")
        return 2
    ratio = gone / present if present > 0 else float("inf")
    goals = [
        (f"device gone: CPU < {GOAL_GONE_CPU:.0%} of a core", f"{gone:.2%}",
         gone < GOAL_GONE_CPU),
        (f"gone / present <= {GOAL_RATIO}", f"{ratio:.2f}", ratio <= GOAL_RATIO),
        (f"first byte after the plug < {GOAL_BACK_S:.0f} s", f"{back_s:.3f} s",
         back_s < GOAL_BACK_S),
    ]
    print(f"57600-baud serial flight controller, {window:.0f} s windows; python "
          f"{sys.version.split()[0]}")
    print(f"companion CPU: device present (baseline) {present:.2%} of a core, "
          f"device gone {gone:.2%}; ratio gone/present {ratio:.2f}")
    for goal, value, met in goals:
        print(f"{goal}: {value}: {'met' if met else 'NOT MET'}")
    return 0 if all(met for _, _, met in goals) else 1


if __name__ == "__main__":
    sys.exit(main())
