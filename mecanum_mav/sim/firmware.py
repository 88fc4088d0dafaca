"""Real ArduPilot Rover firmware (SITL, ``ardurover``) as a process: the twin's flight
controller, and the tests'.

:class:`Firmware` starts ``ardurover --model JSON:127.0.0.1`` (its physics is the twin's
bridge, on the UDP port ``--sim-port-out`` names) in a temporary working directory of its own
(it writes ``eeprom.bin`` and ``logs/`` there) and a process group of its own, killed on every
way out, its parent's end included (``kill -9`` of the twin: SIGKILL by the parent-death
signal, :func:`~mecanum_mav.sim.process.dies_with_this_thread`). Its serial ports are UDP
clients on ports from :func:`~mecanum_mav.sim.process.free_port`: SERIAL0 for the
companion's flight-controller link (:attr:`Firmware.fc_url`), SERIAL1 for a ground station
or monitor talking to the firmware directly (:attr:`Firmware.gcs_url`), so that several
firmwares run side by side.

It starts without ``-w``: the directory is new, so there is no stored parameter yet, and a
reboot (``setup-fc --apply --reboot``; SITL re-executes itself with the same arguments) keeps
what was stored. Its defaults are ArduPilot's ``rover.parm`` (beside the binary, if there)
and the given parameters, written to a file in its directory.

See ../shared/ardupilot-sitl/README.md (from the repository root) for what it does.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any, TypeVar

from mecanum_mav.sim.process import dies_with_this_thread, free_port

__all__ = ["ENV_SITL", "Firmware", "Started", "kill_group", "parm_text", "sitl_from_env"]

ENV_SITL = "MECANUM_SITL"
"""The environment variable naming the ``ardurover`` binary."""


def sitl_from_env() -> Path | None:
    """``$MECANUM_SITL`` as a path, or None when it is unset or empty."""
    value = os.environ.get(ENV_SITL, "")
    return Path(value) if value else None


def kill_group(proc: subprocess.Popen[Any]) -> None:
    """SIGKILL the process group ``proc`` leads (``start_new_session=True``) and reap it."""
    if proc.poll() is None:  # still ours: the group id cannot have been reused
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)
    with contextlib.suppress(subprocess.TimeoutExpired):
        proc.wait(timeout=10)


def parm_text(params: Mapping[str, float]) -> str:
    """A defaults file: ``NAME VALUE`` per line (integers without a decimal point)."""
    return "".join(f"{name} {int(v) if float(v).is_integer() else float(v)!r}\n"
                   for name, v in params.items())


_Started = TypeVar("_Started", bound="Started")


class Started:
    """A context manager for what :meth:`start` starts and :meth:`close` ends: on entry it
    starts, on every way out it closes, also when starting fails half-way (so ``close`` must
    cope with a half-started state, and be idempotent)."""

    def start(self) -> None:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self: _Started) -> _Started:
        try:
            self.start()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class Firmware(Started):
    """``ardurover`` with the JSON physics backend (a context manager; :meth:`start` and
    :meth:`close` otherwise).

    Args:
        binary: the ``ardurover`` executable.
        sim_port: the UDP port on 127.0.0.1 where the physics listens (``--sim-port-out``).
        params: default parameters after ``rover.parm`` (these win).
        extra_defaults: more defaults files, after those.
        speedup: ``--speedup`` (1: real time).
    """

    def __init__(self, binary: Path, sim_port: int, *, params: Mapping[str, float] | None = None,
                 extra_defaults: Sequence[Path] = (), speedup: float = 1.0) -> None:
        self.binary = Path(binary)
        self.sim_port = sim_port
        self.params = dict(params or {})
        self.extra_defaults = tuple(extra_defaults)
        self.speedup = speedup
        self.workdir: Path | None = None
        self.proc: subprocess.Popen[bytes] | None = None
        self.command: list[str] = []
        fc_port, gcs_port = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_DGRAM)
        self.fc_url = f"udpin:127.0.0.1:{fc_port}"
        """The companion's ``--fc``: SERIAL0 sends there and answers whoever talks to it."""
        self.gcs_url = f"udpin:127.0.0.1:{gcs_port}"
        """A ground station's or monitor's link straight to the firmware (SERIAL1)."""
        self._serials = (f"udpclient:127.0.0.1:{fc_port}", f"udpclient:127.0.0.1:{gcs_port}")

    @property
    def log_path(self) -> Path:
        if self.workdir is None:
            raise RuntimeError("the firmware has not started")
        return self.workdir / "ardurover.log"

    def log(self, tail: int = 3000) -> str:
        """The last ``tail`` characters of its output ("" before it started)."""
        try:
            return self.log_path.read_text(errors="replace")[-tail:]
        except (OSError, RuntimeError):
            return ""

    def start(self) -> None:
        """Start the process (it waits for its physics; it is not ready until then).

        Raises:
            FileNotFoundError: the binary is not an executable file.
        """
        if not (self.binary.is_file() and os.access(self.binary, os.X_OK)):
            raise FileNotFoundError(f"ArduPilot SITL binary {self.binary} is not an executable "
                                    "file")
        self.workdir = Path(tempfile.mkdtemp(prefix="mecanum-firmware-"))
        rover_parm = self.binary.with_name("rover.parm")
        defaults = [rover_parm] if rover_parm.is_file() else []
        defaults += list(self.extra_defaults)
        if self.params:
            own = self.workdir / "twin.parm"
            own.write_text(parm_text(self.params))
            defaults.append(own)
        self.command = [str(self.binary), "--model", "JSON:127.0.0.1",
                        "--speedup", f"{self.speedup:g}", "--sim-port-out", str(self.sim_port),
                        *(["--defaults", ",".join(str(d) for d in defaults)] if defaults else []),
                        "--serial0", self._serials[0], "--serial1", self._serials[1],
                        "--serial2", "none"]
        with self.log_path.open("wb") as log:
            self.proc = subprocess.Popen(self.command, cwd=self.workdir, stdin=subprocess.DEVNULL,
                                         stdout=log, stderr=subprocess.STDOUT,
                                         start_new_session=True,
                                         preexec_fn=dies_with_this_thread(signal.SIGKILL))

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def close(self) -> None:
        """Kill the process group and remove its directory; idempotent."""
        if self.proc is not None:
            kill_group(self.proc)
        if self.workdir is not None:
            shutil.rmtree(self.workdir, ignore_errors=True)
            self.workdir = None

