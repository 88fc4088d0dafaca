#!/usr/bin/env python3
"""What real ArduPilot Rover puts in its HEARTBEAT, mode by mode: the reference the
companion's own HEARTBEAT follows (``protocol/heartbeat.py``, docs/companion.md).

Starts the SITL firmware (``../shared/ardupilot-sitl/ardurover`` beside the repository, or
``--sitl PATH``) in a temporary folder, waits for its EKF, asks for HOLD, GUIDED, AUTO (refused
without a mission) and MANUAL disarmed, then force-arms it (a measurement, not a test: no
receiver is attached) and asks for HOLD and GUIDED armed; prints each mode's ``custom_mode``,
``base_mode`` and ``system_status``. Takes about 40 s.

Usage
    python tools/sitl_heartbeat.py [--sitl PATH]

Printed on 2026-11-29 with ArduPilot master of July 2025 (the SITL build described in
../shared/ardupilot-sitl/README.md):

    MANUAL disarmed   base_mode 0x41 system_status 4 (ACTIVE)
    HOLD disarmed     base_mode 0x01 system_status 3 (STANDBY)
    GUIDED disarmed   base_mode 0x09 system_status 4 (ACTIVE)
    MANUAL armed      base_mode 0xc1 system_status 5 (CRITICAL: armed without a receiver
    HOLD armed        base_mode 0x81                  or a ground station, its failsafe)
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

from pymavlink import mavutil

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_SITL = ROOT.parent / "shared" / "ardupilot-sitl" / "ardurover"
MODES = {0: "MANUAL", 4: "HOLD", 10: "AUTO", 15: "GUIDED", 16: "INITIALISING"}
FORCE_ARM = 21196
"""MAV_CMD_COMPONENT_ARM_DISARM's param2 that skips the pre-arm checks (measurement only)."""


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def heartbeat(conn: Any, timeout_s: float = 5.0) -> Any:
    """The firmware's next HEARTBEAT (system 1), or None."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        msg = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=1.0)
        if msg is not None and msg.get_srcSystem() == 1:
            return msg
    return None


def show(conn: Any, label: str) -> None:
    heartbeat(conn)  # (the one after the change)
    beat = heartbeat(conn)
    if beat is None:
        print(f"{label:24s} no HEARTBEAT")
        return
    mode = MODES.get(beat.custom_mode, str(beat.custom_mode))
    print(f"{label:24s} custom_mode {mode:12s} base_mode 0x{beat.base_mode:02x} "
          f"system_status {beat.system_status}")


def set_mode(conn: Any, mode: int) -> int | None:
    conn.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_DO_SET_MODE, 0,
                               mavutil.mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode,
                               0, 0, 0, 0, 0)
    ack = conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=3.0)
    return None if ack is None else int(ack.result)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sitl", type=Path, default=DEFAULT_SITL, help="the ardurover binary")
    args = parser.parse_args()
    sitl: Path = args.sitl
    fc_port, monitor_port = free_udp_port(), free_udp_port()
    with tempfile.TemporaryDirectory() as workdir:
        proc = subprocess.Popen(
            [str(sitl), "-w", "--model", "rover", "--speedup", "1",
             "--defaults", str(sitl.parent / "rover.parm"),
             "--serial0", f"udpclient:127.0.0.1:{fc_port}",
             "--serial1", f"udpclient:127.0.0.1:{monitor_port}", "--serial2", "none"],
            cwd=workdir, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            start_new_session=True)
        conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{fc_port}", source_system=255,
                                          source_component=190)
        try:
            if heartbeat(conn, 30.0) is None:
                print("no HEARTBEAT from the firmware")
                return 1
            time.sleep(20.0)  # (its EKF: GUIDED needs a position)
            show(conn, "at boot")
            for mode in (4, 15, 10, 0):
                result = set_mode(conn, mode)
                show(conn, f"{MODES[mode]} disarmed (ack {result})")
            conn.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                       1, FORCE_ARM, 0, 0, 0, 0, 0)
            show(conn, "MANUAL armed")
            for mode in (4, 15):
                result = set_mode(conn, mode)
                show(conn, f"{MODES[mode]} armed (ack {result})")
        finally:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            conn.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
