"""``mecanum-mav run --fc-signing-key`` against real ArduPilot firmware that requires signing.

The test sets the key on ``ardurover`` with SETUP_SIGNING from the monitor on SERIAL0, the one
port where ArduPilot still takes unsigned packets once it has a key, and runs the companion
(a real process) on SERIAL1, where it takes only correctly signed ones (see
../shared/ardupilot-sitl/README.md and tests/sitl.py). Skipped when the firmware is not there.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from sitl import Rig, Sitl, find_sitl, free_port
from support import ClosedOnExit, write_key_file

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.signing import key_from_text, ticks_from_unix

BINARY, WHY_NOT = find_sitl()
pytestmark = [pytest.mark.sitl, pytest.mark.skipif(BINARY is None, reason=WHY_NOT)]

PASSPHRASE = "rover-and-its-flight-controller"
KEY = key_from_text(PASSPHRASE)
RECEIVER = (1600, 1600, 1600, 1600)  # the simulated radio: what the outputs show unless obeyed
FORWARD = (2000, 2000, 2000, 2000)
STRAFE_RIGHT = (2000, 1000, 1000, 2000)
BOOT_S = 20.0  # generous deadlines: the suite must hold on a loaded 2-core machine
REACT_S = 10.0
RELEASE_LIMIT_S = 0.5  # as tests/test_sitl.py; unreleased overrides lapse after 3 s
IGNORED_WINDOW_S = 2.0
"""How long the unsigned companion streams full forward: signed, SERVO1..4 follow the sticks
within a few hundred ms even on a loaded machine."""


def key_file(tmp_path: Path) -> Path:
    return write_key_file(tmp_path / "fc.key", PASSPHRASE + "\n")


@pytest.fixture
def board() -> Iterator[Sitl]:
    """Firmware with its companion port on SERIAL1, no key yet (:func:`set_key`)."""
    assert BINARY is not None
    with Sitl(BINARY, "udp", receiver=RECEIVER, boot_timeout_s=BOOT_S, fc_serial=1) as fc:
        fc.set_up()  # the user's path: the board set up by setup-fc --apply, then signing
        yield fc


def set_key(board: Sitl, ahead_s: float = 0.0) -> None:
    """SETUP_SIGNING with KEY and an initial timestamp ``ahead_s`` ahead of the clock (0: as
    MAVProxy's ``signing setup`` sends it), until the firmware's HEARTBEATs come signed."""
    assert board.monitor is not None
    started = time.monotonic()
    board.monitor.setup_signing(KEY, ticks_from_unix(time.time() + ahead_s), BOOT_S)
    print(f"boot {board.boot_s:.2f} s, SETUP_SIGNING -> signed HEARTBEAT "
          f"{time.monotonic() - started:.2f} s")


class Companion(Rig):
    """A companion process on the board and a ground station on the companion."""

    def arm(self) -> None:
        """Wait for the companion's flight-controller link (the firmware's signed HEARTBEATs
        accepted), then arm it."""
        assert self.said("Flight controller link up"), (
            f"the companion never heard the firmware\n{self.why()}")
        super().arm()

    def drive(self, x: int, y: int, r: int, expected: tuple[int, ...]) -> float:
        """Stream the sticks until SERVO1..4 read ``expected``; how long that took (s)."""
        started = time.monotonic()
        return super().drive(x, y, r, expected) - started

    def stop(self) -> float:
        """SIGTERM, and wait for exit status 0; when the signal was sent (monotonic s)."""
        sent = self.companion.terminate()
        assert self.companion.wait(REACT_S) == 0, self.why()
        return sent


@contextlib.contextmanager
def run_companion(fc: Sitl, workdir: Path, *extra: str,
                  fc_url: str | None = None) -> Iterator[Companion]:
    """The companion on ``fc`` (on ``fc_url`` instead of the board's own: a :class:`FcTap`)."""
    with Companion.on(fc, workdir, *extra, fc_url=fc_url) as companion:
        yield companion


@dataclass(frozen=True)
class Override:
    """One RC_CHANNELS_OVERRIDE the companion sent the board: from which system, to which,
    whether signed, and channels 1-4 (us)."""

    source_system: int
    target_system: int
    signed: bool
    channels: tuple[int, int, int, int]


class FcTap(ClosedOnExit):
    """A UDP relay in the flight-controller link that reads what the companion sends.

    The firmware sends to the board's port (``udpclient:``; the tap binds it, where the
    companion's ``udpin:`` would); the tap forwards to the companion on :attr:`url` and the
    companion's answers back to the firmware, parsing them on the way: :attr:`overrides`.
    """

    def __init__(self, board: Sitl) -> None:
        board_port = int(board.fc_url.rsplit(":", 1)[1])
        self.companion = ("127.0.0.1", free_port(socket.SOCK_DGRAM))
        self.url = f"udpin:{self.companion[0]}:{self.companion[1]}"
        self.overrides: list[Override] = []
        self._parser = mavlink.MAVLink(None)
        self._parser.robust_parsing = True
        self._board_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._board_side.bind(("127.0.0.1", board_port))
        self._companion_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._companion_side.bind(("127.0.0.1", 0))
        self._board: tuple[str, int] | None = None  # the firmware's address, once it sent
        self._lock = threading.Lock()
        self._stop_r, self._stop_w = os.pipe()
        self._thread = threading.Thread(target=self._run, name="fc-tap", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        sockets = [self._board_side, self._companion_side]
        while self._stop_r not in (ready := select.select([*sockets, self._stop_r], [], [])[0]):
            for sock in ready:
                with contextlib.suppress(OSError):  # ICMP: the companion not listening yet
                    data, address = sock.recvfrom(65536)
                    if sock is self._board_side:
                        self._board = address
                        self._companion_side.sendto(data, self.companion)
                    elif self._board is not None:
                        self._board_side.sendto(data, self._board)
                        self._read(data)

    def _read(self, data: bytes) -> None:
        for msg in self._parser.parse_buffer(data) or []:
            if msg.get_type() == "RC_CHANNELS_OVERRIDE":
                override = Override(msg.get_srcSystem(), msg.target_system,
                                    bool(msg.get_msgbuf()[2] & 1),  # the signed flag
                                    (msg.chan1_raw, msg.chan2_raw, msg.chan3_raw,
                                     msg.chan4_raw))
                with self._lock:
                    self.overrides.append(override)

    def sent(self, since: int = 0) -> list[Override]:
        """The overrides the companion sent from index ``since`` on."""
        with self._lock:
            return self.overrides[since:]

    def close(self) -> None:
        os.write(self._stop_w, b"x")
        self._thread.join(timeout=2)
        for fd in (self._stop_r, self._stop_w):
            os.close(fd)
        self._board_side.close()
        self._companion_side.close()


def test_a_board_that_requires_signing_obeys_the_companion_only_with_fc_signing_key(
        board, tmp_path):
    """Before the board has the key, the companion with --fc-signing-key refuses its unsigned
    HEARTBEATs, says so and will not arm. The key is set as MAVProxy's ``signing setup`` sets
    it (initial timestamp: now). Without --fc-signing-key the companion still hears the board
    (its HEARTBEATs are signed, not encrypted) and arms, but ArduPilot drops its unsigned
    overrides (SERVO1..4 stay at the receiver's pulse while it streams full forward) and
    parameter requests; what it sent is read in the link (:class:`FcTap`): full forward from
    the board's ground-station id, unsigned. With the key it drives."""
    monitor = board.monitor
    assert monitor is not None
    key = str(key_file(tmp_path))
    with run_companion(board, tmp_path / "no-key-yet", "--fc-signing-key", key) as companion:
        assert companion.said("FC sent unsigned: board has no signing key"), companion.why()
        ack = companion.gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, timeout_s=REACT_S)
        assert ack is not None and ack.result == mavlink.MAV_RESULT_DENIED, companion.why()
        assert not any(m.get_type() == "STATUSTEXT" and m.text == "Flight controller link up"
                       for m in companion.gcs.messages)
        companion.stop()
    set_key(board)
    # setup-fc on that port reads the board only with the key too
    unsigned, signed = board.setup_fc(), board.setup_fc("--fc-signing-key", key)
    assert unsigned.returncode == 1 and "not confirmed: no answer for" in unsigned.stdout
    assert signed.returncode == 0, signed.stdout + signed.stderr
    with FcTap(board) as tap, run_companion(board, tmp_path / "unsigned",
                                            fc_url=tap.url) as companion:
        companion.arm()
        since, sent = monitor.mark(), len(tap.sent())
        obeyed = monitor.wait_servos(lambda s: s != RECEIVER, IGNORED_WINDOW_S, since=since,
                                     tick=lambda: companion.gcs.sticks(1000, 0, 0))
        assert obeyed is None, f"the board obeyed an unsigned override\n{companion.why()}"
        assert monitor.mark() - since >= 10 * IGNORED_WINDOW_S, companion.why()  # 40/s
        # ... while the companion streamed full forward, as the board obeys it signed below:
        # from the board's ground-station id, to the board; only the signature is missing
        forward = [o for o in tap.sent(sent) if o.channels == FORWARD]
        assert len(forward) >= 10 * IGNORED_WINDOW_S, (
            f"the companion did not stream its overrides: {tap.sent(sent)[-5:]}\n"
            f"{companion.why()}")
        assert {(o.source_system, o.target_system, o.signed) for o in forward} == {
            (255, 1, False)}, forward[:3]
        # its parameter requests went unanswered too
        assert companion.said("FC setup not checked: no parameters from the")
        companion.stop()
    with run_companion(board, tmp_path / "signed", "--fc-signing-key", key) as companion:
        companion.arm()
        forward_s = companion.drive(1000, 0, 0, FORWARD)
        strafe_s = companion.drive(0, 1000, 0, STRAFE_RIGHT)
        # the parameter protocol works signed: the companion read the board's setup
        assert companion.said("FC setup checked: safe for the companion")
        since = monitor.mark()
        sent = companion.stop()
        released = monitor.wait_servos(lambda s: s == RECEIVER, REACT_S, since=since)
        assert released is not None, companion.why()
        print(f"signed: sticks -> SERVO1..4 forward {forward_s * 1000:.0f} ms, strafe "
              f"{strafe_s * 1000:.0f} ms; SIGTERM -> receiver {(released.t - sent) * 1000:.0f} ms")
        # the release on the way out is signed too: not the overrides lapsing (3 s)
        assert released.t - sent < RELEASE_LIMIT_S, companion.why()


def test_a_board_whose_signing_clock_is_ahead_obeys_the_companion_and_its_restart(
        board, tmp_path):
    """ArduPilot signs from its stored timestamp + 60 s (after every reboot too) and drops a
    new stream more than a minute behind its own timestamp; here it is 11 minutes ahead of the
    companion's clock. The companion sends with the newest timestamp of the firmware's
    verified packets, as the MAVLink C library and pymavlink do, so ArduPilot takes it; so
    does a restarted companion, whose stream ArduPilot already knows."""
    set_key(board, ahead_s=600.0)
    key = str(key_file(tmp_path))
    for run in ("first", "restarted"):
        with run_companion(board, tmp_path / run, "--fc-signing-key", key) as companion:
            companion.arm()
            forward_s = companion.drive(1000, 0, 0, FORWARD)
            companion.drive(0, 1000, 0, STRAFE_RIGHT)
            print(f"{run}: sticks -> SERVO1..4 forward {forward_s * 1000:.0f} ms")
            companion.stop()
