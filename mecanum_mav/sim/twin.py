"""The twin: the real ArduPilot Rover firmware (SITL) driving the MuJoCo chassis, with the
companion unchanged in the loop.

::

    ground station --gcs_url--> companion (python -m mecanum_mav run) --fc--> ardurover SERIAL0
    ground station --firmware_url--> ardurover SERIAL1
    ardurover --JSON servo packets--> bridge (MuJoCo chassis) --JSON sensors--> ardurover

:class:`Twin` starts the three (a context manager: :meth:`Twin.__enter__` returns once
everything is ready, :meth:`Twin.close` ends everything on every way out):

1. the bridge (:mod:`mecanum_mav.sim.twinbridge`) on a UDP port from the OS, in a process
   of its own (:class:`~mecanum_mav.sim.twinbridge.BridgeProcess`; measured: busy 25-35 % of
   each 0.83 ms frame; in a thread of the caller's process, a CPU-bound Python thread beside
   it brought the twin down to 0.17x real time), its truth and counters in shared memory;
2. the firmware (:class:`~mecanum_mav.sim.firmware.Firmware`) with ArduPilot's ``rover.parm``
   and ``firmware_params``; with a companion, ``SIM_RC_FAIL 1`` too: a board whose only RC
   input is the companion, no receiver (the simulated hardware, not a setting of the board);
3. ``frame="companion"``: the companion's user path, as a person sets up a new board:
   ``setup-fc --apply --reboot`` on the firmware, then ``run`` with ``--fc`` on its SERIAL0
   and ``--gcs`` on :attr:`Twin.gcs_url`; ``frame="ardupilot-omni"``: no companion (the
   firmware drives the wheels itself; ``firmware_params`` and ``wheel_map`` say how).

The truth (:class:`~mecanum_mav.sim.twinrecord.TruthSample`) is the chassis' state at each
frame the bridge answered; with ``truth=URL`` a thread of this process sends it, and the
wheels' contacts, to a view (:class:`~mecanum_mav.sim.truthsender.TruthPublisher`: the
bridge's process, which paces the lockstep, sends nothing more).
"""

from __future__ import annotations

import math
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from mecanum_mav.config.params import Params
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.sim.firmware import Firmware, Started
from mecanum_mav.sim.process import CompanionProcess, free_port
from mecanum_mav.sim.truthsender import TruthPublisher
from mecanum_mav.sim.twinbridge import DEFAULT_WHEEL_MAP, BridgeProcess
from mecanum_mav.sim.twinrecord import BridgeStats, TruthSample, TwinRecord

__all__ = ["FRAMES", "NO_RECEIVER", "READY_TIMEOUT_S", "TruthSample", "Twin", "TwinError",
           "describe"]

FRAMES = ("companion", "ardupilot-omni")
"""Who drives the wheels: the companion through the firmware's pass-through, or ArduPilot
Rover's own omni frame."""
READY_TIMEOUT_S = 60.0
"""How long the firmware may take to boot, and setup-fc to set it up."""
NO_RECEIVER = {"SIM_RC_FAIL": 1.0}
"""The simulated hardware of a board whose only RC input is the companion: no receiver."""
COMPANION_RUNNING = "mecanum-mav: rover system"
"""How the companion's output begins once both its links are open: where a ground station
already listens, the twin waits for this line (or the companion's end) instead of a
HEARTBEAT."""
SETUP_OK = "the flight controller is set up safely"
"""What setup-fc says when the board is safe."""


class TwinError(RuntimeError):
    """The twin could not start (the message says what failed, with the logs' tails)."""


class Twin(Started):
    """The firmware, the MuJoCo chassis and (by default) the companion, together.

    Args:
        sitl: the ``ardurover`` binary.
        friction: the floor's friction coefficient (``SIM_FRICTION``).
        params: the companion's parameters and the chassis' ``SIM_*`` (default: defaults);
            ``friction`` wins over its ``SIM_FRICTION``.
        frame: ``"companion"`` or ``"ardupilot-omni"`` (:data:`FRAMES`).
        wheel_map: per wheel FL, FR, RL, RR ``(servo channel 1-based, sign)``; default
            SERVO1..4, as the companion's pass-through puts them.
        firmware_params: extra defaults for the firmware (after ``rover.parm``).
        companion: start the companion (only with ``frame="companion"``).
        gcs_port: the UDP port on 127.0.0.1 a ground station listens on for the companion
            (default: a free one); :attr:`gcs_url` is what it passes to pymavlink.
        gcs: instead, the companion's ``--gcs`` URL itself (e.g. ``udpout:127.0.0.1:14550``
            for a ground station listening on 14550).
        workdir: where the companion's log goes (default: a temporary directory, removed on
            close).
        tlog: the companion records both of its links there (``run --tlog``): the firmware's
            SIMSTATE and SIM_STATE on its link are the chassis's truth as the firmware has it.
        truth: ``udpout:HOST:PORT``: the chassis's truth (SIM_STATE 20 Hz, the wheels'
            contacts 10 Hz) is sent there from a thread of this process
            (:class:`~mecanum_mav.sim.truthsender.TruthPublisher`; what ``twin --view`` shows
            as the true path); None: not sent.
    """

    def __init__(self, sitl: Path, *, friction: float = 0.8, params: Params | None = None,
                 frame: str = "companion",
                 wheel_map: Sequence[tuple[int, float]] | None = None,
                 firmware_params: Mapping[str, float] | None = None,
                 companion: bool = True, gcs_port: int | None = None,
                 gcs: str | None = None, workdir: Path | None = None,
                 tlog: Path | None = None, truth: str | None = None) -> None:
        if frame not in FRAMES:
            raise ValueError(f"unknown frame {frame!r}: one of {', '.join(FRAMES)}")
        self.sitl = Path(sitl)
        self.frame = frame
        self.params = params.copy() if params is not None else Params()
        self.params.set("SIM_FRICTION", friction)
        self.with_companion = companion and frame == "companion"
        self.wheel_map = tuple(wheel_map or DEFAULT_WHEEL_MAP)
        self.firmware_params: dict[str, float] = {
            **(NO_RECEIVER if self.with_companion else {}), **(firmware_params or {})}
        self._wait_on_gcs = gcs is None and gcs_port is None
        """The twin chose the ground station's port: nobody listens there yet, so it can wait
        there for the companion's HEARTBEAT (else it must not take the port)."""
        if gcs is None:
            port = gcs_port if gcs_port is not None else free_port(socket.SOCK_DGRAM)
            gcs = f"udpout:127.0.0.1:{port}"
        self._companion_gcs = gcs
        self.gcs_url = gcs.replace("udpout:", "udpin:", 1) if gcs.startswith("udpout:") else ""
        """What a ground station passes to pymavlink to talk to the companion (the companion
        sends to ``udpout:HOST:PORT``, the ground station listens with ``udpin:HOST:PORT``;
        "" for another kind of ``gcs``)."""
        self.firmware_url = ""
        """What a ground station passes to pymavlink to talk to the firmware (SERIAL1)."""
        self.companion_pid: int | None = None
        self.setup_output = ""
        """What ``setup-fc --apply --reboot`` printed (with a companion)."""
        self.tlog = tlog
        self.truth_url = truth
        self.truth_publisher: TruthPublisher | None = None
        self._own_workdir = workdir is None
        self.workdir = Path(workdir) if workdir is not None else Path(
            tempfile.mkdtemp(prefix="mecanum-twin-"))
        self.bridge: BridgeProcess | None = None
        self.firmware: Firmware | None = None
        self.companion: CompanionProcess | None = None

    # ------------------------------------------------------------------ start and stop

    def start(self, timeout_s: float = READY_TIMEOUT_S) -> None:
        """Start everything and wait until it is ready (the firmware's HEARTBEAT on its
        second port; with a companion, setup-fc done and the companion's HEARTBEAT).

        Raises:
            PhysicsUnavailableError: without the physics extra (mujoco).
            FileNotFoundError: ``sitl`` is not an executable file.
            TwinError: something did not come up within ``timeout_s``.
        """
        self.bridge = BridgeProcess(self.params.as_dict(), self.wheel_map)
        if self.truth_url is not None:
            origin = GlobalOrigin.from_degrees(float(self.params["ORIGIN_LAT"]),
                                               float(self.params["ORIGIN_LON"]))
            self.truth_publisher = TruthPublisher(self.bridge.record, self.truth_url, origin)
        self.firmware = Firmware(self.sitl, self.bridge.port, params=self.firmware_params)
        self.firmware_url = self.firmware.gcs_url
        self.firmware.start()
        self._wait_heartbeat(self.firmware_url, timeout_s, "the firmware")
        if not self.with_companion:
            return
        self._setup_fc(timeout_s)
        tlog = ["--tlog", str(self.tlog)] if self.tlog is not None else []
        self.companion = CompanionProcess(self._companion_gcs, self.firmware.fc_url,
                                          self.workdir, *self._param_args(), *tlog)
        self.companion_pid = self.companion.pid
        if self._wait_on_gcs:
            self._wait_heartbeat(self.gcs_url, timeout_s, "the companion")
        else:  # (a ground station listens there: it sees the companion come up)
            self._wait_running(timeout_s)

    def _param_args(self) -> list[str]:
        """``--set NAME=VALUE`` for every parameter not at its default."""
        args: list[str] = []
        for name in self.params.changed():
            args += ["--set", f"{name}={self.params[name]}"]
        return args

    def _setup_fc(self, timeout_s: float) -> None:
        """``mecanum-mav setup-fc --apply --reboot`` on the firmware, as a user runs it."""
        assert self.firmware is not None
        command = [sys.executable, "-m", "mecanum_mav", "setup-fc", "--fc", self.firmware.fc_url,
                   "--apply", "--reboot", *self._param_args()]
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=timeout_s,
                                  check=False)
        except subprocess.TimeoutExpired as exc:
            raise TwinError(f"setup-fc did not end within {timeout_s:g} s\n"
                            f"{self.why()}") from exc
        self.setup_output = done.stdout
        if done.returncode != 0 or SETUP_OK not in done.stdout:
            raise TwinError(f"setup-fc --apply --reboot failed ({done.returncode}):\n"
                            f"{done.stdout}{done.stderr}\nfirmware:\n{self.firmware.log()}")

    def _wait_heartbeat(self, url: str, timeout_s: float, who: str) -> None:
        """Listen on ``url`` (a ``udpin:``) until a HEARTBEAT comes, then let the port go."""
        from pymavlink import mavutil

        conn = mavutil.mavlink_connection(url, source_system=254, source_component=190)
        try:
            deadline = time.monotonic() + timeout_s
            while (left := deadline - time.monotonic()) > 0.0:
                if conn.recv_match(type="HEARTBEAT", blocking=True, timeout=min(left, 1.0)):
                    return
                self._check_alive()
        finally:
            conn.close()
        raise TwinError(f"no HEARTBEAT from {who} within {timeout_s:g} s\n{self.why()}")

    def _wait_running(self, timeout_s: float) -> None:
        """Check every 0.1 s that nothing died until the companion says it runs
        (:data:`COMPANION_RUNNING`: its links are open), at most ``timeout_s``."""
        assert self.companion is not None
        deadline = time.monotonic() + timeout_s
        while COMPANION_RUNNING not in self.companion.log(tail=1 << 20):  # (from its start)
            self._check_alive()
            if time.monotonic() >= deadline:
                raise TwinError(f"the companion did not start within {timeout_s:g} s\n"
                                f"{self.why()}")
            time.sleep(0.1)
        self._check_alive()

    def _check_alive(self) -> None:
        dead = self.dead()
        if dead:
            raise TwinError(f"{dead}\n{self.why()}")

    def dead(self) -> str:
        """What has died ("the firmware exited (-9)"), or "" while all runs (a companion
        killed by :meth:`kill_companion` counts)."""
        for name, part in (("the firmware", self.firmware), ("the companion", self.companion)):
            proc = getattr(part, "proc", None)
            if proc is not None and proc.poll() is not None:
                return f"{name} exited ({proc.returncode})"
        if self.bridge is not None and not self.bridge.alive():
            return "the bridge (physics) process exited"
        return ""

    def why(self) -> str:
        """The tails of the firmware's and the companion's output and what the bridge has
        answered (for error messages)."""
        parts = [f"firmware: {self.firmware.log() if self.firmware else ''}"]
        if self.companion is not None:
            parts.append(f"companion: {self.companion.log()}")
        parts.append(f"bridge: {self.bridge_summary()}")
        return "\n".join(parts)

    def bridge_summary(self) -> str:
        """One line: whether the physics process runs and what it has answered, e.g.
        ``running; 12034 frames (1 restart, 0 malformed), last 0.0 s ago``: a firmware that
        says "No JSON sensor message received" while the count stands still was not answered."""
        if self.bridge is None:
            return "not started"
        state = "running" if self.bridge.alive() else "exited"
        stats = self.bridge.record.stats()
        line = (f"{state}; {stats.frames} frames ({stats.restarts} restart"
                f"{'' if stats.restarts == 1 else 's'}, {stats.malformed} malformed)")
        if stats.frames:
            line += f", last {time.monotonic() - self.bridge.record.truth_now().wall_s:.1f} s ago"
        return line

    @property
    def firmware_pid(self) -> int | None:
        """The firmware's process id (None before it started)."""
        proc = self.firmware.proc if self.firmware is not None else None
        return proc.pid if proc is not None else None

    def kill_companion(self) -> None:
        """SIGKILL the companion's process group, as a crash would (no shutdown path)."""
        if self.companion is not None:
            self.companion.kill()

    def close(self) -> None:
        """End the companion, the firmware and the bridge; idempotent."""
        if self.companion is not None:
            self.companion.kill()
        if self.firmware is not None:
            self.firmware.close()
        if self.truth_publisher is not None:
            self.truth_publisher.close()
        if self.bridge is not None:
            self.bridge.close()
        if self._own_workdir:
            shutil.rmtree(self.workdir, ignore_errors=True)

    # ------------------------------------------------------------------ what happened

    def _record(self) -> TwinRecord:
        if self.bridge is None:
            raise RuntimeError("the twin has not started")
        return self.bridge.record

    def truth(self) -> list[TruthSample]:
        """The chassis' true state at every frame so far (the last
        :data:`~mecanum_mav.sim.twinrecord.TRUTH_CAPACITY`), oldest first (a copy)."""
        return self._record().truth()

    def truth_array(self) -> np.ndarray:
        """:meth:`truth` as an array, one row per frame: the fields of
        :class:`~mecanum_mav.sim.twinrecord.TruthSample` in order (faster for long runs)."""
        return self._record().truth_array()

    def truth_now(self) -> TruthSample:
        """The chassis' true state at the last frame."""
        return self._record().truth_now()

    def stats(self) -> BridgeStats:
        """The bridge's counters (frames, dropped, repeated, busy time)."""
        return self._record().stats()


def describe(stats: BridgeStats) -> str:
    """One line of the bridge's figures, for the twin command and the tests' output."""
    busy = stats.busy_fraction
    return (f"real-time factor {stats.real_time_factor:.3f}, {stats.frames} frames at "
            f"{stats.frame_rate} Hz, dropped {stats.dropped}, repeated {stats.repeated}, "
            f"bridge busy {busy * 100:.0f} % of each frame" if not math.isnan(busy)
            else "no frame yet")

