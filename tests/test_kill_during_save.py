"""kill -9 inside a write of the parameter file: the file survives (issue 11.3).

The real companion runs with ``--params FILE`` (a hand-written file with comments); a ground
station on UDP sends a stream of PARAM_SETs, each of which makes the companion save the file
(the previous one kept as FILE.bak). The companion's file writes are instrumented (its
``open``, in the child process only): every write to the parameter file, its .bak or their
temporaries is reported over a pipe with the bytes it writes, and the ``k``-th one writes half
its bytes to the disk, reports "inside" and waits; the test then sends SIGKILL. So each kill
lands inside a write, and the test knows it did: the half-written bytes are on the disk, in a
temporary file beside FILE, never in FILE or FILE.bak, which each hold a complete version
(one they held before or one a finished write gave them) and load with the hand-written
comments. The next start removes the temporary. Trials run back to back on the same file,
each starting where the previous kill left it, and ``k`` goes through the .bak write and the
FILE write of successive saves.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from mecanum_mav.io.paramfile import load
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.groundstation import ScriptedGroundStation, udp_ground_station

REPO_ROOT = Path(__file__).resolve().parent.parent
PAUSES = (1, 2, 3, 4, 5, 6)
"""The write each trial is killed inside: odd = a save's FILE.bak, even = its FILE."""
SENT = {  # parameter -> the values the stream cycles through
    "OUT_RATE": (20.0, 25.0, 30.0),
    "FS_INPUT_TMO": (0.5, 0.6, 0.7),
    "WP_SPEED": (0.5, 0.4, 0.3),
    "GUID_SPD_MAX": (0.7, 0.6),
}
HAND_WRITTEN = """\
# my rover: bench setup
OUT_RATE 20
# inputs
FS_INPUT_TMO 0.5
WP_SPEED 0.5
"""
REACT_S = 15.0  # generous: the suite must hold on a loaded 2-core machine

INSTRUMENTED = r'''
"""python -c INSTRUMENTED ARGS = python -m mecanum_mav ARGS, every write to a file whose name
contains $PAUSE_NAME reported on pipe $PAUSE_PIPE (one JSON line: event, n, path, data hex),
the $PAUSE_AT-th cut in half: half its bytes written and flushed, "inside" reported, then it
waits for the SIGKILL."""
import builtins, io, json, os, runpy, sys, time

PIPE, AT = int(os.environ["PAUSE_PIPE"]), int(os.environ["PAUSE_AT"])
NAME = os.environ["PAUSE_NAME"]
real_open = io.open
writes = 0


def report(event, path, data):
    os.write(PIPE, (json.dumps({"event": event, "n": writes, "path": path,
                                "data": bytes(data).hex()}) + "\n").encode())


class Watched:
    def __init__(self, stream, path):
        self._stream, self._path = stream, path

    def write(self, data):
        global writes
        if not data:
            return self._stream.write(data)
        writes += 1
        raw = data.encode() if isinstance(data, str) else data
        if writes == AT:
            self._stream.write(data[:len(data) // 2])
            self._stream.flush()
            report("inside", self._path, raw)
            while True:
                time.sleep(60)
        report("write", self._path, raw)
        return self._stream.write(data)

    def __getattr__(self, name):
        return getattr(self._stream, name)

    def __enter__(self):
        self._stream.__enter__()
        return self

    def __exit__(self, *exc):
        return self._stream.__exit__(*exc)


def watched_open(file, mode="r", *args, **kwargs):
    stream = real_open(file, mode, *args, **kwargs)
    if any(c in mode for c in "wax+"):
        path = os.readlink(f"/proc/self/fd/{stream.fileno()}")
        if NAME in os.path.basename(path):
            return Watched(stream, path)
    return stream


io.open = builtins.open = watched_open  # os.fdopen and Path.open call io.open
sys.argv[0] = "mecanum_mav"
runpy.run_module("mecanum_mav", run_name="__main__", alter_sys=True)
'''


@dataclass(frozen=True)
class Write:
    """One write the companion reported: ``n``-th, into ``path``, of ``data``."""

    event: str
    n: int
    path: Path
    data: bytes


class PausingCompanion:
    """``mecanum-mav run`` in its own process group, its parameter-file writes reported on a
    pipe and the ``pause_at``-th one cut in half (see :data:`INSTRUMENTED`)."""

    def __init__(self, gcs_url: str, fc_url: str, params: Path, workdir: Path,
                 pause_at: int) -> None:
        workdir.mkdir(parents=True, exist_ok=True)
        self.log_path = workdir / "companion.log"
        self._read_end, write_end = os.pipe()
        env = dict(os.environ, PAUSE_PIPE=str(write_end), PAUSE_AT=str(pause_at),
                   PAUSE_NAME=params.name)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO_ROOT),
                                                          env.get("PYTHONPATH")]))
        try:
            with self.log_path.open("wb") as log:
                self.proc = subprocess.Popen(
                    [sys.executable, "-c", INSTRUMENTED, "run", "--gcs", gcs_url, "--fc", fc_url,
                     "--params", str(params)], cwd=workdir, env=env, stdin=subprocess.DEVNULL,
                    stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
                    pass_fds=(write_end,))
        finally:
            os.close(write_end)  # the child's copy alone: EOF once it is gone
        self.writes: list[Write] = []
        self._pending = b""

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")[-3000:]

    def read(self, timeout_s: float) -> bool:
        """Take in what the pipe holds, waiting up to ``timeout_s`` for something; False at
        its end (the child is gone)."""
        if not select.select([self._read_end], [], [], timeout_s)[0]:
            return True
        chunk = os.read(self._read_end, 65536)
        self._pending += chunk
        *lines, self._pending = self._pending.split(b"\n")
        for line in lines:
            record = json.loads(line)
            self.writes.append(Write(record["event"], record["n"], Path(record["path"]),
                                     bytes.fromhex(record["data"])))
        return bool(chunk)

    def inside(self) -> Write | None:
        return next((w for w in self.writes if w.event == "inside"), None)

    def kill(self) -> int:
        """SIGKILL to the group (if it still runs); its exit status."""
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
        return self.proc.wait(timeout=10)

    def close(self) -> None:
        self.kill()
        while self.read(0.0):  # the rest of the pipe, up to its end
            pass
        os.close(self._read_end)


@contextlib.contextmanager
def pausing_companion(fc_url: str, params: Path, workdir: Path,
                      pause_at: int) -> Iterator[tuple[ScriptedGroundStation, PausingCompanion]]:
    gcs, port = udp_ground_station()
    companion = PausingCompanion(port.url, fc_url, params, workdir, pause_at)
    try:
        assert gcs.wait("HEARTBEAT", timeout_s=REACT_S), companion.log()
        yield gcs, companion
    finally:
        companion.close()
        port.close()


def param_sets() -> Iterator[tuple[str, float]]:
    """PARAM_SETs for ever: the parameters in turn, each cycling through its values."""
    items = list(SENT.items())
    i = 0
    while True:
        name, values = items[i % len(items)]
        yield name, values[(i // len(items)) % len(values)]
        i += 1


def stray_temporaries(directory: Path) -> list[Path]:
    return sorted(p for p in directory.iterdir() if p.name.endswith(".tmp"))


def contents(path: Path) -> bytes | None:
    return path.read_bytes() if path.exists() else None


def check_survivor(path: Path) -> None:
    """The file loads, keeps the comments, and holds an old or a sent value of each."""
    text = path.read_text()
    assert text.startswith("# my rover: bench setup\n") and "# inputs\n" in text, text
    params = load(path)
    for name, values in SENT.items():
        assert any(abs(float(params[name]) - v) < 1e-6 for v in values), (path, name,
                                                                          params[name])


def test_kill_9_inside_a_write_of_the_parameter_file_leaves_complete_files(
        tmp_path: Path) -> None:
    path = tmp_path / "rover.parm"
    bak = path.with_name(path.name + ".bak")
    path.write_text(HAND_WRITTEN)
    fc = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    fc.bind(("127.0.0.1", 0))
    fc_url = f"udpout:127.0.0.1:{fc.getsockname()[1]}"
    stream = param_sets()
    try:
        for pause_at in PAUSES:
            before = {contents(path), contents(bak)}  # what FILE and FILE.bak held
            with pausing_companion(fc_url, path, tmp_path / f"run{pause_at}",
                                   pause_at) as (gcs, companion):
                # the start removed what the previous kill left
                assert stray_temporaries(tmp_path) == [], companion.log()
                deadline = time.monotonic() + REACT_S
                while companion.inside() is None:
                    assert time.monotonic() < deadline, (companion.writes, companion.log())
                    name, value = next(stream)
                    gcs.mav.param_set_send(1, 1, name.encode(), value,
                                           mavlink.MAV_PARAM_TYPE_REAL32)
                    gcs.pump(0.005)
                    companion.read(0.02)
                assert companion.kill() == -signal.SIGKILL
            cut = companion.inside()
            assert cut is not None and cut.n == pause_at, companion.writes
            # the file and its .bak are each a complete version: one they held, or one that
            # a finished write gave them
            complete = before | {w.data for w in companion.writes if w.event == "write"}
            assert contents(path) in complete, (cut, contents(path), complete)
            assert contents(bak) in complete, (cut, contents(bak), complete)
            # the kill landed inside the write: half its bytes are on the disk, in a temporary
            # beside the file, which a reader never loads
            assert cut.path.read_bytes() == cut.data[:len(cut.data) // 2], cut
            assert cut.path.parent == tmp_path and cut.path in stray_temporaries(tmp_path), cut
            check_survivor(path)
            if bak.exists():
                check_survivor(bak)
            print(f"kill inside write {cut.n} ({cut.path.name}, {len(cut.data) // 2} of "
                  f"{len(cut.data)} bytes written): {path.name} and {bak.name} complete")
        # one more start: whatever the last kill left is removed
        with pausing_companion(fc_url, path, tmp_path / "last", 0) as (_, companion):
            assert stray_temporaries(tmp_path) == [], companion.log()
    finally:
        fc.close()
