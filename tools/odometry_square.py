#!/usr/bin/env python3
"""Drive a square in GUIDED in the simulator and compare the companion's odometry with the
simulator's true pose.

The rover core, the simulated flight controller and a scripted ground station run in the
lockstep harness (:class:`mecanum_mav.sim.Lockstep`): virtual time, every message packed and
parsed as on a real link, so a 10 m square takes well under a second and gives the same figures
every run. The ground station arms, switches to GUIDED and sends the four corners as position
targets at 10 Hz (heading held north). At the end it prints, per run, the distance driven, the
odometry's position error (metres and % of distance), its yaw error, how close the rover
itself came to the last corner, and how long the square took (simulated seconds). Runs: no
slip, and wheel slip noise (``SIM_SLIP``) of 2 % and 5 %.

    python tools/odometry_square.py [--side 10] [--speed 2.5] [--slip 0 0.02 0.05]
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass

from mecanum_mav.config.params import Params
from mecanum_mav.io.links import mavlink
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.sim.lockstep import Lockstep

POSITION_ONLY = 8 | 16 | 32 | 64 | 128 | 256 | 2048  # ignore velocity, accel, yaw rate
SETPOINT_PERIOD_S = 0.1
"""The ground station sends the corner at 10 Hz."""


@dataclass
class SquareResult:
    """Figures of one square."""

    slip: float
    distance_m: float
    odom_error_m: float
    odom_yaw_error_deg: float
    final_error_m: float
    seconds: float
    """Simulated seconds from entering GUIDED to standing at the last corner."""

    @property
    def odom_error_pct(self) -> float:
        return 100.0 * self.odom_error_m / self.distance_m


def run_square(side_m: float = 10.0, speed_mps: float = 2.5, slip: float = 0.0,
               seed: int = 1, dt_s: float = 0.002) -> SquareResult:
    """Drive one square of ``side_m`` metres at up to ``speed_mps`` and measure (in the
    lockstep harness, time step ``dt_s``).

    Raises:
        RuntimeError: no flight-controller link, arming or GUIDED refused, or a corner not
            reached in time.
    """
    params = Params()
    params.update({"WHL_MAX_SPD": max(speed_mps * 1.3, 1.0), "GUID_SPD_MAX": speed_mps,
                   "GUID_ACC_MAX": 3.0, "SIM_SLIP": slip, "SIM_SEED": seed})
    h = Lockstep(params, dt_s=dt_s)
    core, gcs = h.core, h.gcs
    if not h.run_until(lambda: not core.vehicle.fc_lost, 3.0):
        raise RuntimeError("no heartbeat from the simulated flight controller")
    gcs.arm()
    if gcs.set_mode(Mode.GUIDED) != mavlink.MAV_RESULT_ACCEPTED:
        raise RuntimeError("could not enter GUIDED")
    start_s = h.now_s
    corner = (0.0, 0.0)
    for corner in ((side_m, 0.0), (side_m, side_m), (0.0, side_m), (0.0, 0.0)):

        def send(now_s: float, corner: tuple[float, float] = corner) -> None:
            gcs.mav.set_position_target_local_ned_send(
                0, 1, 1, mavlink.MAV_FRAME_LOCAL_NED, POSITION_ONLY, corner[0], corner[1],
                0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

        def there(corner: tuple[float, float] = corner) -> bool:
            guided = core.autopilot.guided
            active = guided.setpoint
            return (active is not None and active.position_ned == corner
                    and guided.arrived(core.estimator.pose, 0.03)
                    and math.hypot(*h.truth().velocity_body) < 0.01)

        stop = h.every(SETPOINT_PERIOD_S, send)
        arrived = h.run_until(there, 4.0 * side_m / speed_mps + 10.0)
        stop()
        if not arrived:
            raise RuntimeError(f"corner {corner} not reached")
    truth = h.truth().pose
    odom = core.estimator.pose
    yaw_error = (odom.yaw_rad - truth.yaw_rad + math.pi) % (2 * math.pi) - math.pi
    return SquareResult(slip, 4.0 * side_m,
                        math.hypot(odom.x_m - truth.x_m, odom.y_m - truth.y_m),
                        abs(math.degrees(yaw_error)),
                        math.hypot(truth.x_m - corner[0], truth.y_m - corner[1]),
                        h.now_s - start_s)


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
