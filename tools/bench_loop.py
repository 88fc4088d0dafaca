#!/usr/bin/env python3
"""Benchmark the companion's GUIDED control-loop timing and what telemetry costs.

The companion runs in its own process (so its CPU time is exact and its loop is timed where it
runs); the simulated flight controller and a pymavlink ground station run in this process,
all on 127.0.0.1 with OS-assigned ports. Phases, one after the other:

1. idle, disarmed, telemetry off (``TLM_POS_RATE`` = ``TLM_EXT_RATE`` = 0, set over PARAM_SET):
   the baseline, measured in the same run;
2. idle, disarmed, telemetry at its default rates: the difference from (1) is what the
   telemetry costs;
3. GUIDED, driving on velocity setpoints at 10 Hz: the period between control ticks
   (nominal 1 / ``CTL_RATE`` = 20 ms) as percentiles, and the CPU used.

Goals (issue 4): control loop at ``CTL_RATE`` with its jitter reported (p99 of the period);
telemetry at default rates under 5 % of one core.

    python tools/bench_loop.py [--seconds 5]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import selectors
import sys
import time
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from mecanum_mav.config.params import Params
from mecanum_mav.io.links import Link, mavlink, open_link
from mecanum_mav.sim.simfc import SimFlightController

VELOCITY_ONLY = 1 | 2 | 4 | 32 | 64 | 128 | 256 | 1024 | 2048


def companion_main(gcs_url: str, fc_url: str, ctl: Connection) -> None:
    """Child: run the companion, time its control ticks, answer "cpu"/"ticks"/"stop"."""
    from mecanum_mav.app.companion import Companion
    from mecanum_mav.control.guided import GuidedController

    ticks: list[float] = []
    original = GuidedController.update

    def timed(self: GuidedController, *args: Any) -> Any:
        ticks.append(time.perf_counter())
        return original(self, *args)

    GuidedController.update = timed  # type: ignore[method-assign]
    companion = Companion(Params(), gcs_url, fc_url)
    companion.start()
    while True:
        request = ctl.recv()
        if request == "cpu":
            ctl.send(time.process_time())
        elif request == "ticks":
            ctl.send(list(ticks))
            ticks.clear()
        else:
            companion.close()
            ctl.send("stopped")
            return


class Ground:
    """The ground station: a udpin link and a reader that keeps its socket drained."""

    def __init__(self) -> None:
        self.link: Link = open_link("udpin:127.0.0.1:0", source_system=255,
                                    source_component=190, name="gcs")
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.link.fileno(), selectors.EVENT_READ)
        self.messages: list[Any] = []

    def pump(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            if self.selector.select(left):
                self.messages.extend(self.link.read())

    def beat(self) -> None:
        self.link.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                     4)

    def command(self, command: int, *params: float) -> bool:
        for _ in range(20):
            start = len(self.messages)
            self.beat()
            self.link.mav.command_long_send(1, 1, command, 0, *params,
                                            *([0.0] * (7 - len(params))))
            self.pump(0.25)
            if any(m.get_type() == "COMMAND_ACK" and m.command == command and m.result == 0
                   for m in self.messages[start:]):
                return True
        return False

    def idle(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.beat()
            self.pump(min(0.5, max(0.0, end - time.monotonic())))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="length of each phase")
    args = parser.parse_args()
    sim = SimFlightController("udpin:127.0.0.1:0", Params())
    sim.start()
    ground = Ground()
    parent, child = mp.get_context("spawn").Pipe()
    proc = mp.get_context("spawn").Process(
        target=companion_main, args=(f"udpout:127.0.0.1:{ground.link.local_port}",
                                     f"udpout:127.0.0.1:{sim.local_port}", child), daemon=True)
    proc.start()

    def cpu() -> float:
        parent.send("cpu")
        return float(parent.recv())

    try:
        while not ground.messages:
            ground.pump(0.1)
        ground.idle(1.0)
        results: dict[str, float] = {}
        streamed: dict[str, int] = {}
        for phase, rate_pos, rate_ext in (("telemetry off", 0.0, 0.0),
                                          ("telemetry default", 10.0, 2.0)):
            for name, value in (("TLM_POS_RATE", rate_pos), ("TLM_EXT_RATE", rate_ext)):
                ground.link.mav.param_set_send(1, 1, name.encode(), value,
                                               mavlink.MAV_PARAM_TYPE_REAL32)
            ground.idle(1.0)
            c0, t0, first = cpu(), time.monotonic(), len(ground.messages)
            ground.idle(args.seconds)
            results[phase] = 100.0 * (cpu() - c0) / (time.monotonic() - t0)
            streamed[phase] = sum(1 for m in ground.messages[first:]
                                  if m.get_type() not in ("HEARTBEAT", "PARAM_VALUE"))
        if not (ground.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
                and ground.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 15)):
            print("ERROR: could not arm and enter GUIDED", file=sys.stderr)
            return 1
        parent.send("ticks")
        parent.recv()
        c0, t0 = cpu(), time.monotonic()
        end = t0 + args.seconds
        heading = 1.0
        while time.monotonic() < end:
            heading = -heading if int(time.monotonic() - t0) % 2 else heading
            ground.beat()
            ground.link.mav.set_position_target_local_ned_send(
                0, 1, 1, mavlink.MAV_FRAME_BODY_FRD, VELOCITY_ONLY, 0, 0, 0, 0.4 * heading,
                0.2, 0, 0, 0, 0, 0, 0)
            ground.pump(0.1)
        driving_cpu = 100.0 * (cpu() - c0) / (time.monotonic() - t0)
        parent.send("ticks")
        ticks = np.array(parent.recv())
    finally:
        parent.send("stop")
        parent.recv()
        proc.join(5)
        sim.stop()
    periods_ms = np.diff(ticks) * 1e3
    nominal = 1e3 / float(Params()["CTL_RATE"])
    p50, p90, p99 = np.percentile(periods_ms, [50, 90, 99])
    telemetry = results["telemetry default"] - results["telemetry off"]
    print(f"# bench_loop: companion in its own process, {args.seconds:g} s per phase")
    for phase in ("telemetry off", "telemetry default"):
        print(f"idle, {phase + ':':19s} CPU {results[phase]:.2f} % of a core, "
              f"{streamed[phase] / args.seconds:.1f} telemetry messages/s")
    print(f"telemetry at default rates costs {telemetry:.2f} % of a core (goal < 5 %): "
          f"{'met' if telemetry < 5.0 else 'NOT MET'}")
    print(f"GUIDED driving:           CPU {driving_cpu:.2f} % of a core, {len(ticks)} control "
          f"ticks")
    print(f"control period ms (nominal {nominal:.1f}): p50 {p50:.2f}  p90 {p90:.2f}  "
          f"p99 {p99:.2f}  max {periods_ms.max():.2f}  min {periods_ms.min():.2f}")
    print(f"jitter p99 - nominal: {p99 - nominal:+.2f} ms; achieved rate "
          f"{1e3 / np.mean(periods_ms):.1f} Hz")
    return 0


if __name__ == "__main__":
    sys.exit(main())
