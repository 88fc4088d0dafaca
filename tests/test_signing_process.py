"""Signing in the real process: ``mecanum-mav run --signing-key FILE`` between a signed pymavlink
ground station and a flight-controller peer on UDP loopback, and the key file's errors."""

from __future__ import annotations

import itertools
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
from sitl import CompanionProcess, free_port

from mecanum_mav.io.links import Link, open_link
from mecanum_mav.protocol.dialect import mavlink, mavutil
from mecanum_mav.protocol.signing import Check, SignatureCheck, key_from_text, ticks_from_unix

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
    flight controller that records the overrides it receives.

    Args:
        gcs_url: the ground station's own URL (it listens on a port of its own by default).
        signed: whether the ground station has the key.
    """

    def __init__(self, gcs_url: str = "udpin:127.0.0.1:0", *, signed: bool = True) -> None:
        self.gcs: Any = mavutil.mavlink_connection(gcs_url, source_system=255,
                                                   source_component=190)
        if signed:
            self.gcs.setup_signing(KEY, sign_outgoing=True)
        self.fc: Link = open_link("udpin:127.0.0.1:0", source_system=1, source_component=1,
                                  name="test-fc")
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.gcs.fd, selectors.EVENT_READ, "gcs")
        self.selector.register(self.fc.fileno(), selectors.EVENT_READ, "fc")
        self.received: list[Any] = []
        self.arrived_s: list[float] = []
        """When each of :attr:`received` arrived (monotonic s)."""
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
                        self.arrived_s.append(time.monotonic())
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


def test_an_unsigned_station_on_a_signed_udpin_link_hears_a_1_hz_heartbeat_and_why_until_it_signs(
        tmp_path):
    """The companion listens (``--gcs udpin:``) with a key; a pymavlink station without it
    sends heartbeats and an arm command. It is told, with a signed HEARTBEAT once a second,
    why nothing it sends is taken, and gets nothing else; its arm does not arm. Once it signs
    with the key it is a peer: streams, parameters, and no more hints."""
    port = free_port()
    peers = SignedPeers(f"udpout:127.0.0.1:{port}", signed=False)
    key = private_key_file(tmp_path)
    station = peers.gcs.mav
    reason = "Unsigned packet refused: signing required"
    next_beat = [0.0]

    def beating(done: Callable[[], object]) -> Callable[[], object]:
        def check() -> object:  # the station's heartbeat at 5 Hz: the hints stay at 1 Hz
            if time.monotonic() >= next_beat[0]:
                next_beat[0] = time.monotonic() + 0.2
                station.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID,
                                       0, 0, 0)
            return done()
        return check

    def arrived(kind: str, since: int = 0) -> list[float]:
        return [t for t, m in zip(peers.arrived_s[since:], peers.received[since:], strict=True)
                if m.get_type() == kind]
    try:
        with CompanionProcess(f"udpin:127.0.0.1:{port}", peers.fc_url, tmp_path / "run",
                              "--signing-key", str(key)) as companion:
            assert peers.pump(beating(lambda: peers.seen("HEARTBEAT")), 15.0), companion.log()
            station.command_long_send(1, 1, ARM, 0, 1, 21196, 0, 0, 0, 0, 0)  # forced, even
            station.param_request_list_send(1, 1)
            assert peers.pump(beating(lambda: len(peers.seen("HEARTBEAT")) >= 5), 10.0), (
                companion.log())
            told = list(peers.received)
            assert {m.get_type() for m in told} == {"HEARTBEAT", "STATUSTEXT"}
            assert {m.text for m in peers.seen("STATUSTEXT")} == {reason}
            check = SignatureCheck(KEY, ticks_from_unix(time.time()) - 10**7)
            assert all(check.check(m.get_msgbuf()) is Check.ACCEPTED for m in told)
            beats = arrived("HEARTBEAT")
            gaps = [b - a for a, b in itertools.pairwise(beats)]
            assert min(gaps) > 0.5 and 0.8 < sum(gaps) / len(gaps) < 1.2, gaps
            assert not any(m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED
                           for m in peers.seen("HEARTBEAT"))
            assert all(channels == [1500] * 4 for channels in peers.overrides)
            # with the key it is a peer: streams and answers, and no more hints
            peers.gcs.setup_signing(KEY, sign_outgoing=True)
            signed_s, since = time.monotonic(), len(peers.received)

            def answered() -> bool:
                station.param_request_read_send(1, 1, b"OUT_RATE", -1)
                return peers.pump(lambda: peers.seen("PARAM_VALUE", since), 0.3)
            assert peers.pump(beating(answered), 10.0), companion.log()
            assert peers.pump(beating(lambda: peers.seen("ODOMETRY", since)), 5.0)
            more = time.monotonic() + 2.0
            assert peers.pump(beating(lambda: time.monotonic() > more), 5.0)
            assert [t for t, m in zip(peers.arrived_s[since:], peers.received[since:],
                                      strict=True)
                    if m.get_type() == "STATUSTEXT" and m.text == reason
                    and t > signed_s + 1.5] == []
            assert len(arrived("HEARTBEAT", since)) <= 5  # one a second: hints stopped
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
