"""Arm the real-hardware path again and again on one real ArduPilot Rover (SITL).

What a user does with a new board, as the README's "Real hardware" steps say, with nothing
switched off: ``mecanum-mav setup-fc --fc URL --apply`` once, then for each run a fresh
``mecanum-mav run --fc URL`` with the default parameters and every pre-arm check; a ground
station arms it (retrying as a pilot would while it says why not), drives forward until
ArduPilot's SERVO1..4 show it, disarms (the outputs at trim), and stops it with SIGTERM (exit
status 0). A run passes when all of that happened within the deadlines. Prints a line per run
and ``N/N`` at the end; exit status 0 only when every run passed.

    python tools/arm_repeat.py                  # 20 runs, over UDP
    python tools/arm_repeat.py --count 5 --transport serial
    stress --cpu 2 & python tools/arm_repeat.py  # under load

The firmware is ../shared/ardupilot-sitl/ardurover (from the repository root) or
``$MECANUM_SITL``; the helpers are the test suite's (tests/sitl.py).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))  # tests/sitl.py

from sitl import CompanionProcess, Rig, Sitl, find_sitl

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.groundstation import udp_ground_station

FORWARD = (2000, 2000, 2000, 2000)
TRIM = (1500, 1500, 1500, 1500)


def one_run(fc: Sitl, workdir: Path) -> tuple[bool, str]:
    """One companion process from start to SIGTERM; (passed, what happened)."""
    gcs, port = udp_ground_station()
    try:
        with CompanionProcess(port.url, fc.fc_url, workdir) as companion:
            rig = Rig(fc, gcs, companion)
            started = time.monotonic()
            try:
                rig.arm()
            except AssertionError:
                refusals = [m.text for m in gcs.received("STATUSTEXT")
                            if m.text.startswith("PreArm")]
                return False, f"never armed ({refusals[-3:]})\n{companion.log()}"
            armed_s = time.monotonic() - started
            refused = sum(m.text.startswith("PreArm") for m in gcs.received("STATUSTEXT"))
            sent = time.monotonic()
            moved = rig.monitor.wait_servos(lambda s: s == FORWARD, rig.react_s,
                                            tick=lambda: gcs.sticks(1000, 0, 0))
            if moved is None:
                return False, f"sticks never drove SERVO1..4\n{rig.why()}"
            forward_ms = (moved.t - sent) * 1000
            ack = gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, timeout_s=rig.react_s)
            if ack is None or ack.result != mavlink.MAV_RESULT_ACCEPTED:
                return False, f"disarm not accepted ({ack})"
            if rig.monitor.wait_servos(lambda s: s == TRIM, rig.react_s) is None:
                return False, f"not at trim after disarming\n{rig.why()}"
            companion.terminate()
            code = companion.wait(rig.react_s)
            if code != 0:
                return False, f"exit status {code} after SIGTERM\n{companion.log()}"
            return True, (f"armed {armed_s:.2f} s after start ({refused} pre-arm refusals "
                          f"meanwhile), forward on SERVO1..4 in {forward_ms:.0f} ms, trim "
                          f"after disarm, exit 0 on SIGTERM")
    finally:
        port.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=20, help="runs (default 20)")
    parser.add_argument("--transport", choices=("udp", "tcp", "serial"), default="udp")
    args = parser.parse_args(argv)
    binary, why = find_sitl()
    if binary is None:
        print(f"arm_repeat: {why}", file=sys.stderr)
        return 2
    passed = 0
    with Sitl(binary, args.transport, receiver=None, boot_timeout_s=Rig.boot_s) as fc, \
            tempfile.TemporaryDirectory(prefix="arm-repeat-") as tmp:
        setup = fc.setup_fc("--apply")
        print(f"setup-fc --apply: exit {setup.returncode}: {setup.stdout.strip().splitlines()[-1]}",
              flush=True)
        if setup.returncode != 0:
            print(setup.stdout + setup.stderr, file=sys.stderr)
            return 1
        for run in range(1, args.count + 1):
            ok, what = one_run(fc, Path(tmp) / f"run{run}")
            passed += ok
            print(f"run {run:2d}: {'ok  ' if ok else 'FAIL'} {what}", flush=True)
    print(f"{passed}/{args.count}")
    return 0 if passed == args.count else 1


if __name__ == "__main__":
    sys.exit(main())
