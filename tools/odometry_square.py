#!/usr/bin/env python3
"""Drive a square in GUIDED in the simulator and compare the companion's odometry with the
simulator's true pose.

The companion and the simulated flight controller run in this process with a real UDP link
between them; a pymavlink ground station arms, switches to GUIDED and sends the four corners
as position targets (heading held north). At the end it prints, per run, the distance
driven, the odometry's position error (metres and % of distance), its yaw error, and how close
the rover itself came to the last corner. Runs: no slip, and wheel slip noise
(``SIM_SLIP``) of 2 % and 5 %.

    python tools/odometry_square.py [--side 10] [--speed 2.5] [--slip 0 0.02 0.05]
"""

from __future__ import annotations

import argparse
import math
import selectors
import sys
import time
from dataclasses import dataclass

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.io.links import Link, mavlink, open_link
from mecanum_mav.sim.simfc import SimFlightController

POSITION_ONLY = 8 | 16 | 32 | 64 | 128 | 256 | 2048  # ignore velocity, accel, yaw rate


@dataclass
class SquareResult:
    """Figures of one square."""

    slip: float
    distance_m: float
    odom_error_m: float
    odom_yaw_error_deg: float
    final_error_m: float
    seconds: float

    @property
    def odom_error_pct(self) -> float:
        return 100.0 * self.odom_error_m / self.distance_m


def _command(gcs: Link, selector: selectors.BaseSelector, command: int, *params: float
             ) -> bool:
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        gcs.mav.command_long_send(1, 1, command, 0, *params, *([0.0] * (7 - len(params))))
        end = time.monotonic() + 0.3
        while time.monotonic() < end:
            if selector.select(0.05):
                for msg in gcs.read():
                    if (msg.get_type() == "COMMAND_ACK" and msg.command == command
                            and msg.result == mavlink.MAV_RESULT_ACCEPTED):
                        return True
    return False


def run_square(side_m: float = 10.0, speed_mps: float = 2.5, slip: float = 0.0,
               seed: int = 1) -> SquareResult:
    """Drive one square of ``side_m`` metres at up to ``speed_mps`` and measure."""
    params = Params()
    params.update({"WHL_MAX_SPD": max(speed_mps * 1.3, 1.0), "GUID_SPD_MAX": speed_mps,
                   "GUID_ACC_MAX": 3.0, "SIM_SLIP": slip, "SIM_SEED": seed})
    sim = SimFlightController("udpin:127.0.0.1:0", params)
    sim.start()
    gcs = open_link("udpin:127.0.0.1:0", source_system=255, source_component=190, name="gcs")
    companion = Companion(params, f"udpout:127.0.0.1:{gcs.local_port}",
                          f"udpout:127.0.0.1:{sim.local_port}")
    companion.start()
    selector = selectors.DefaultSelector()
    selector.register(gcs.fileno(), selectors.EVENT_READ)
    try:
        while not selector.select(0.1):  # the companion's first heartbeat tells us its address
            pass
        gcs.read()
        gcs.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 4)
        if not (_command(gcs, selector, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
                and _command(gcs, selector, mavlink.MAV_CMD_DO_SET_MODE, 1, 15)):
            raise RuntimeError("could not arm and enter GUIDED")
        start = time.monotonic()
        corner = (0.0, 0.0)
        for corner in ((side_m, 0.0), (side_m, side_m), (0.0, side_m), (0.0, 0.0)):
            deadline = time.monotonic() + 4.0 * side_m / speed_mps + 10.0
            while time.monotonic() < deadline:
                gcs.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0,
                                       0, 4)
                gcs.mav.set_position_target_local_ned_send(
                    0, 1, 1, mavlink.MAV_FRAME_LOCAL_NED, POSITION_ONLY, corner[0], corner[1],
                    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
                if selector.select(0.1):
                    gcs.read()
                truth = sim.snapshot()
                active = companion.core.autopilot.guided.setpoint
                if (active is not None and active.position_ned == corner
                        and companion.core.autopilot.guided.arrived(
                            companion.core.estimator.pose, 0.03)
                        and math.hypot(*truth.velocity_body) < 0.01):
                    break
        truth = sim.snapshot().pose
        odom = companion.core.estimator.pose
        yaw_error = (odom.yaw_rad - truth.yaw_rad + math.pi) % (2 * math.pi) - math.pi
        return SquareResult(slip, 4.0 * side_m,
                            math.hypot(odom.x_m - truth.x_m, odom.y_m - truth.y_m),
                            abs(math.degrees(yaw_error)),
                            math.hypot(truth.x_m - corner[0], truth.y_m - corner[1]),
                            time.monotonic() - start)
    finally:
        selector.close()
        companion.close()
        sim.stop()
        gcs.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--side", type=float, default=10.0, help="side of the square, m")
    parser.add_argument("--speed", type=float, default=2.5, help="GUIDED speed limit, m/s")
    parser.add_argument("--slip", type=float, nargs="+", default=[0.0, 0.02, 0.05],
                        help="SIM_SLIP values to run")
    args = parser.parse_args()
    print(f"# odometry_square: {args.side:g} m square in GUIDED, speed limit {args.speed:g} m/s,"
          f" odometry = WHEEL_DISTANCE + ATTITUDE yaw (defaults)")
    print(f"{'slip':>6} {'dist m':>7} {'odom err m':>11} {'% dist':>7} {'yaw err deg':>12} "
          f"{'rover off corner m':>19} {'time s':>7}")
    worst = 0.0
    for slip in args.slip:
        r = run_square(args.side, args.speed, slip)
        print(f"{slip:6.2f} {r.distance_m:7.1f} {r.odom_error_m:11.3f} {r.odom_error_pct:7.2f} "
              f"{r.odom_yaw_error_deg:12.2f} {r.final_error_m:19.3f} {r.seconds:7.1f}")
        if slip == 0.0:
            worst = max(worst, r.odom_error_pct)
    print(f"goal without slip: odometry error < 1 % of distance and < 1 deg yaw "
          f"(worst {worst:.2f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
