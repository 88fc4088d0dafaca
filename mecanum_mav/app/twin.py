"""``mecanum-mav twin``: the real ArduPilot Rover firmware (SITL) driving the MuJoCo chassis,
with the companion in the loop, in one command (:class:`mecanum_mav.sim.twin.Twin`).

It prints where a ground station connects (to the companion, and to the firmware directly),
where the chassis's truth is sent (SIM_STATE and the wheels' contacts, for ``mecanum-mav view
--connect``), the real-time factor and the true pose every few seconds, and ends everything
on Ctrl-C or SIGTERM (the first one; start-up is abandoned cleanly too). Exit status: 0 when
stopped so, 1 when the twin did not come up or a part of it died, 2 for a missing firmware or
physics extra or a bad setting.
"""

from __future__ import annotations

import math
import sys
import threading
from pathlib import Path
from typing import TextIO

from mecanum_mav.app.shutdown import terminate_in_order
from mecanum_mav.config.params import Params
from mecanum_mav.sim.physics import PhysicsUnavailableError
from mecanum_mav.sim.twin import Twin, TwinError, describe

__all__ = ["REPORT_PERIOD_S", "run_twin"]

REPORT_PERIOD_S = 5.0
"""How often the real-time factor and the true pose are printed (seconds)."""


def run_twin(params: Params, sitl: Path, *, friction: float, gcs: str,
             report_period_s: float = REPORT_PERIOD_S, out: TextIO | None = None,
             tlog: Path | None = None, truth: str | None = None) -> int:
    """Run the twin until SIGINT/SIGTERM or until a part of it dies; the exit status. The
    figures go to ``out`` (default: standard output), problems to standard error; the
    companion records both of its links to ``tlog`` and the truth is sent to ``truth``
    (``udpout:HOST:PORT``; ``twin --view`` follows both)."""
    out = out if out is not None else sys.stdout
    say = f"mecanum-mav twin: firmware {sitl}, MuJoCo chassis on friction {friction:g}"
    print(f"{say}; starting (setup-fc --apply --reboot, then the companion) ...", file=out,
          flush=True)
    stop = threading.Event()
    with terminate_in_order() as termination:
        try:
            twin = Twin(sitl, friction=friction, params=params, gcs=gcs, tlog=tlog,
                        truth=truth)
            with twin:
                termination.running(stop.set)
                print(f"mecanum-mav twin: ready. Ground station -> companion: the companion "
                      f"sends to {gcs} (pymavlink: {twin.gcs_url}); ground station -> "
                      f"firmware directly: {twin.firmware_url} (firmware pid "
                      f"{twin.firmware_pid}, companion pid {twin.companion_pid})", file=out,
                      flush=True)
                if twin.truth_publisher is not None:
                    print(f"mecanum-mav twin: the truth (SIM_STATE, wheel contacts) goes to "
                          f"{truth}: mecanum-mav view --connect "
                          f"{twin.truth_publisher.view_url}", file=out, flush=True)
                return _watch(twin, stop, report_period_s, out)
        except PhysicsUnavailableError as exc:
            print(f"mecanum-mav twin: {exc}", file=sys.stderr)
            return 2
        except (FileNotFoundError, ValueError) as exc:  # (no binary, a bad --friction)
            print(f"mecanum-mav twin: {exc}", file=sys.stderr)
            return 2
        except TwinError as exc:
            print(f"mecanum-mav twin: {exc}", file=sys.stderr)
            return 1


def _watch(twin: Twin, stop: threading.Event, period_s: float, out: TextIO) -> int:
    """Print the figures every ``period_s`` until ``stop``; 1 if a part died meanwhile."""
    while not stop.wait(period_s):
        truth = twin.truth_now()
        print(f"t {truth.time_s:7.1f} s  {describe(twin.stats())}; true pose N "
              f"{truth.north_m:+.3f} m E {truth.east_m:+.3f} m yaw "
              f"{math.degrees(truth.yaw_rad):+.1f} deg", file=out, flush=True)
        dead = twin.dead()
        if dead:
            print(f"mecanum-mav twin: {dead}\n{twin.why()}", file=sys.stderr, flush=True)
            return 1
    print(f"mecanum-mav twin: stopped; {describe(twin.stats())}", file=out, flush=True)
    return 0
