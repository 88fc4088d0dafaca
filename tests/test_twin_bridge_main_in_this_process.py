"""The bridge process's main (mecanum_mav/sim/twinbridge.py ``bridge_main``), run in this
process with the arguments :class:`~mecanum_mav.sim.twinbridge.BridgeProcess` gives it
(``SETUP.json WATCH_FD``) and a fake firmware on 127.0.0.1: it says ``port N`` on stdout (at
once: its starter reads a pipe), answers the firmware's servo packets with JSON lines into the
shared record, ignores SIGINT (its starter ends it), and once the watch pipe ends removes its
folder and exits 0; without the physics it says ``no-physics MESSAGE`` and exits 2."""

from __future__ import annotations

import json
import os
import signal
import socket
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from support import wait_until

pytest.importorskip("mujoco", reason="the MuJoCo chassis needs the physics extra")

from mecanum_mav.config.params import Params
from mecanum_mav.sim.sitljson import encode_servo_packet
from mecanum_mav.sim.twinbridge import TwinRecord, bridge_main
from mecanum_mav.sim.twinrecord import blank

RATE = 1200
OMNI_MAP = [(4, 1.0), (1, 1.0), (3, 1.0), (2, 1.0)]
"""FL on SERVO4, FR on SERVO1, RL on SERVO3, RR on SERVO2 (the omni frame's wiring)."""


class PipeStdout:
    """stdout as the bridge's starter reads it, through a pipe: only what was flushed
    arrives (``flushed``)."""

    def __init__(self) -> None:
        self._pending = ""
        self.flushed = ""

    def write(self, text: str) -> int:
        self._pending += text
        return len(text)

    def flush(self) -> None:
        self.flushed, self._pending = self.flushed + self._pending, ""

    def first_line(self) -> str | None:
        line, newline, _ = self.flushed.partition("\n")
        return line if newline else None


class Bridge:
    """A bridge's folder as BridgeProcess makes it: the record file (mapped here too:
    :attr:`record`) and SETUP.json; :meth:`run` runs ``bridge_main`` on it."""

    def __init__(self, folder: Path, params: dict[str, float],
                 wheel_map: list[tuple[int, float]]) -> None:
        folder.mkdir()
        self.folder = folder
        record = folder / "record.f64"
        array = np.lib.format.open_memmap(record, mode="w+", dtype=np.float64,
                                          shape=(TwinRecord.size(64),))
        blank(array)
        array.flush()
        self.record = TwinRecord(array)
        self.setup = folder / "bridge.json"
        self.setup.write_text(json.dumps({"params": params, "wheel_map": wheel_map,
                                          "record": str(record)}))
        self.stdout = PipeStdout()
        self.sigint_while_serving: object = None

    def run(self, firmware: Callable[[int], None] = lambda port: None) -> int:
        """``bridge_main`` in this (the main) thread; a thread waits for its ``port N``,
        runs ``firmware(N)`` then ends the watch pipe (as the starter's end closing)."""
        watch_r, watch_w = os.pipe()
        returned = threading.Event()
        failures: list[BaseException] = []

        def starter() -> None:
            try:
                line = wait_until(lambda: self.stdout.first_line() or returned.is_set(), 5.0)
                if isinstance(line, str) and line.startswith("port "):
                    self.sigint_while_serving = signal.getsignal(signal.SIGINT)
                    firmware(int(line.split()[1]))
            except BaseException as exc:  # (raised again in the test's thread)
                failures.append(exc)
            finally:
                os.close(watch_w)

        thread = threading.Thread(target=starter, daemon=True)
        thread.start()
        try:
            code = bridge_main([str(self.setup), str(watch_r)])
        finally:
            returned.set()
            thread.join(timeout=5)
            os.close(watch_r)
        if failures:
            raise failures[0]
        return code


@pytest.fixture
def here(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A working directory of the test's own with a file in it (the bridge removes only its
    folder); stdout and SIGINT's handler as they were afterwards."""
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    (cwd / "keep.txt").write_text("not the bridge's\n")
    monkeypatch.chdir(cwd)
    handler = signal.getsignal(signal.SIGINT)
    try:
        yield cwd
    finally:
        signal.signal(signal.SIGINT, handler)


def bridge(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, **params: float) -> Bridge:
    made = Bridge(tmp_path / "mecanum-bridge-x", {**Params().as_dict(), **params}, OMNI_MAP)
    monkeypatch.setattr(sys, "stdout", made.stdout)
    return made


def exchange(port: int, frames: list[list[int]]) -> list[dict[str, object]]:
    """Frames 1, 2, ... with these servo outputs; the bridge's answers."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as firmware:
        firmware.bind(("127.0.0.1", 0))
        firmware.settimeout(2.0)
        answers = []
        for count, pwm in enumerate(frames, start=1):
            firmware.sendto(encode_servo_packet(RATE, count, pwm), ("127.0.0.1", port))
            answers.append(json.loads(firmware.recv(4096)))
        return answers


def test_the_bridge_process_says_its_port_answers_into_the_shared_record_and_ends_with_the_pipe(
        tmp_path, monkeypatch, here):
    made = bridge(tmp_path, monkeypatch, SIM_ESC_DZ=0.3)
    answers: list[dict[str, object]] = []
    # 1600 us (0.2 of full) is neutral to ESCs with a dead band of 0.3: they arm; then SERVO4
    # (FL under the omni map) at 1900 us, the others at 1700 us
    code = made.run(lambda port: answers.extend(
        exchange(port, [[1600] * 4, [1700, 1700, 1700, 1900]])))
    assert code == 0
    assert made.stdout.flushed.startswith("port ") and made.stdout.flushed.count("\n") == 1
    assert [a["timestamp"] for a in answers] == [pytest.approx(1 / RATE), pytest.approx(2 / RATE)]
    stats = made.record.stats()  # (read through this process's own mapping of the file)
    assert stats.frames == 2
    assert stats.wheel_pulses == (1900, 1700, 1700, 1700)
    assert stats.commands == pytest.approx((0.8, 0.4, 0.4, 0.4))
    assert made.sigint_while_serving == signal.SIG_IGN  # (the parent ends it)
    assert not made.folder.exists()
    assert (here / "keep.txt").exists()


def test_a_bridge_process_whose_folder_is_gone_already_still_ends_with_exit_code_0(
        tmp_path, monkeypatch, here):
    import shutil

    made = bridge(tmp_path, monkeypatch)
    assert made.run(lambda port: shutil.rmtree(made.folder)) == 0
    assert (here / "keep.txt").exists()


def test_a_bridge_process_without_the_physics_says_no_physics_with_the_hint_and_exits_2(
        tmp_path, monkeypatch, here):
    made = bridge(tmp_path, monkeypatch)
    monkeypatch.setitem(sys.modules, "mecanum_mav.sim.mujocochassis", None)  # (no mujoco)
    assert made.run() == 2
    line = made.stdout.first_line()
    assert line is not None and line.startswith("no-physics the MuJoCo chassis needs")
    assert line.endswith("pip install 'mecanum-mav[physics]'")
