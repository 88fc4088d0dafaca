"""Signing in the real process: ``mecanum-mav run --signing-key FILE`` between a signed pymavlink
ground station and a flight-controller peer on UDP loopback, and the key file's errors."""

from __future__ import annotations

import math
import os
import selectors
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from sitl import CompanionProcess

from mecanum_mav.io.links import Link, open_link
from mecanum_mav.protocol.dialect import mavlink, mavutil
from mecanum_mav.protocol.signing import key_from_text

PASSPHRASE = "rover-on-a-shared-radio"
KEY = key_from_text(PASSPHRASE)
FORWARD = [2000, 2000, 2000, 2000]
ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM


def private_key_file(tmp_path: Path, text: str = PASSPHRASE + "\n", mode: int = 0o600) -> Path:
    path = tmp_path / "rover.key"
    path.write_text(text)
    path.chmod(mode)
    return path


class SignedPeers:
    """A pymavlink ground station signing with KEY (as a script would set it up) and a
    flight controller that records the overrides it receives."""

    def __init__(self) -> None:
        self.gcs: Any = mavutil.mavlink_connection("udpin:127.0.0.1:0", source_system=255,
                                                   source_component=190)
        self.gcs.setup_signing(KEY, sign_outgoing=True)
        self.fc: Link = open_link("udpin:127.0.0.1:0", source_system=1, source_component=1,
                                  name="test-fc")
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.gcs.fd, selectors.EVENT_READ, "gcs")
        self.selector.register(self.fc.fileno(), selectors.EVENT_READ, "fc")
        self.received: list[Any] = []
        self.overrides: list[list[int]] = []
        self._fc_heard = False
        self._fc_beat_s = -1.0
        self._gcs_beat_s = -math.inf

    @property
    def gcs_url(self) -> str:
        return f"udpout:127.0.0.1:{self.gcs.port.getsockname()[1]}"

    @property
    def fc_url(self) -> str:
        return f"udpout:127.0.0.1:{self.fc.local_port}"

    def pump(self, done: Callable[[], object], timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while not done():
            now = time.monotonic()
            if now > deadline:
                return False
            if now - self._gcs_beat_s > 1.0:  # a ground station's heartbeat, signed
                self._gcs_beat_s = now
                self.gcs.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID,
                                            0, 0, mavlink.MAV_STATE_ACTIVE)
            if self._fc_heard and now - self._fc_beat_s > 0.1:
                self._fc_beat_s = now
                self.fc.mav.heartbeat_send(mavlink.MAV_TYPE_GROUND_ROVER,
                                           mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0,
                                           mavlink.MAV_STATE_STANDBY)
            for key, _ in self.selector.select(0.02):
                if key.data == "fc":
                    self._fc_heard = True
                    for msg in self.fc.read():
                        if msg.get_type() == "RC_CHANNELS_OVERRIDE":
                            self.overrides.append([getattr(msg, f"chan{i}_raw")
                                                   for i in range(1, 5)])
                else:
                    while (msg := self.gcs.recv_msg()) is not None:
                        self.received.append(msg)
        return True

    def seen(self, kind: str, since: int = 0,
             predicate: Callable[[Any], bool] = lambda m: True) -> list[Any]:
        return [m for m in self.received[since:] if m.get_type() == kind and predicate(m)]

    def close(self) -> None:
        self.selector.close()
        self.gcs.close()
        self.fc.close()


def test_a_signed_pymavlink_ground_station_arms_and_drives_and_unsigned_commands_do_nothing(
        tmp_path):
    peers = SignedPeers()
    key = private_key_file(tmp_path)
    try:
        with CompanionProcess(peers.gcs_url, peers.fc_url, tmp_path / "run",
                              "--signing-key", str(key)) as companion:
            assert peers.pump(lambda: peers.seen("HEARTBEAT"), 15.0), companion.log()
            peers.gcs.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID,
                                         0, 0, 0)
            # an unsigned arm (a stranger on the radio) is refused and said so
            stranger = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
            since = len(peers.received)
            peers.gcs.write(mavlink.MAVLink_command_long_message(
                1, 1, ARM, 0, 1, 21196, 0, 0, 0, 0, 0).pack(stranger))
            assert peers.pump(lambda: peers.seen(
                "STATUSTEXT", since, lambda m: "Unsigned packet refused" in m.text), 5.0), (
                companion.log())
            assert peers.seen("COMMAND_ACK", since) == []
            # the signed ground station arms and drives
            def armed() -> bool:
                peers.gcs.mav.command_long_send(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
                return peers.pump(lambda: peers.seen(
                    "COMMAND_ACK", since, lambda m: m.result == 0), 0.3)
            assert peers.pump(armed, 10.0), companion.log()
            driving_since = len(peers.overrides)

            def forward() -> bool:
                peers.gcs.mav.manual_control_send(1, 1000, 0, 500, 0, 0)
                return FORWARD in peers.overrides[driving_since:]
            assert peers.pump(forward, 5.0), companion.log()
            # a stranger's unsigned stick, alone on the link while the pilot drives, moves
            # nothing (two refreshes after the pilot's last stick, nothing else is waiting)
            def refreshed(count: int) -> Callable[[], bool]:
                seen = len(peers.overrides)
                return lambda: len(peers.overrides) >= seen + count
            assert peers.pump(refreshed(2), 2.0), companion.log()
            since_stranger = len(peers.overrides)
            peers.gcs.write(mavlink.MAVLink_manual_control_message(
                1, -1000, 0, 500, 0, 0).pack(stranger))
            assert peers.pump(refreshed(2), 2.0), companion.log()
            assert peers.overrides[since_stranger:] == [FORWARD] * (
                len(peers.overrides) - since_stranger)
            # everything the rover sent was signed (pymavlink with the key verified it)
            assert peers.received and all(m._signed for m in peers.received)
            companion.terminate()
            assert companion.wait(10.0) == 0
        assert "signature 2" in companion.log()  # the status line at exit: both refused
    finally:
        peers.close()


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "mecanum_mav", *args], capture_output=True,
                          text=True, timeout=60, stdin=subprocess.DEVNULL,
                          env={**os.environ, "PYTHONPATH": str(Path(__file__).parent.parent)})


@pytest.mark.parametrize(("text", "mode", "why"), [
    (PASSPHRASE, 0o644, "readable by group (mode 0644); protect it with: chmod 600"),
    (PASSPHRASE, 0o604, "readable by others"),
    ("abc123\n", 0o600, "6 hex digits: a key is exactly 64"),
    ("", 0o600, "empty: expected 64 hex digits or a passphrase"),
])
def test_a_key_file_with_bad_contents_or_loose_permissions_exits_2_with_the_reason(
        tmp_path, text, mode, why):
    key = private_key_file(tmp_path, text, mode)
    for command in (["run", "--fc", "udpout:127.0.0.1:9", "--signing-key", str(key)],
                    ["run", "--fc", "udpout:127.0.0.1:9", "--fc-signing-key", str(key)],
                    ["sim", "--signing-key", str(key)]):
        done = run_cli(*command)
        assert done.returncode == 2, (command, done.stderr)
        assert f"mecanum-mav: signing key {key}: " in done.stderr
        assert why in done.stderr
