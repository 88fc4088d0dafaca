"""Signing in the real process: ``mecanum-mav run --signing-key FILE`` between a signed pymavlink
ground station and a flight-controller peer on UDP loopback, and the key file's errors."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from sitl import CompanionProcess, free_port
from support import PeerPump, at_most_every, write_key_file

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.signing import Check, SignatureCheck, key_from_text, ticks_from_unix

PASSPHRASE = "rover-on-a-shared-radio"
KEY = key_from_text(PASSPHRASE)
FORWARD = [2000, 2000, 2000, 2000]
ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM


def private_key_file(tmp_path: Path, text: str = PASSPHRASE + "\n", mode: int = 0o600) -> Path:
    return write_key_file(tmp_path / "rover.key", text, mode)


def test_a_signed_pymavlink_ground_station_arms_and_drives_and_unsigned_commands_do_nothing(
        tmp_path):
    peers = PeerPump(gcs_key=KEY)  # a ground station signing with KEY, as a script sets it up
    key = private_key_file(tmp_path)
    try:
        with CompanionProcess(peers.gcs_url, peers.fc_url, tmp_path / "run",
                              "--signing-key", str(key)) as companion:
            assert peers.run_until(lambda: peers.seen("HEARTBEAT"), 15.0), companion.log()
            peers.gcs.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID,
                                         0, 0, 0)
            # an unsigned arm (a stranger on the radio) is refused and said so
            stranger = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
            since = len(peers.received)
            peers.gcs.write(mavlink.MAVLink_command_long_message(
                1, 1, ARM, 0, 1, 21196, 0, 0, 0, 0, 0).pack(stranger))
            assert peers.run_until(lambda: peers.seen(
                "STATUSTEXT", since, lambda m: "Unsigned packet refused" in m.text), 5.0), (
                companion.log())
            assert peers.seen("COMMAND_ACK", since) == []
            # the signed ground station arms and drives
            def armed() -> bool:
                peers.gcs.mav.command_long_send(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
                return peers.run_until(lambda: peers.seen(
                    "COMMAND_ACK", since, lambda m: m.result == 0), 0.3)
            assert peers.run_until(armed, 10.0), companion.log()
            driving_since = len(peers.overrides)

            def forward() -> bool:
                peers.gcs.mav.manual_control_send(1, 1000, 0, 500, 0, 0)
                return FORWARD in peers.overrides[driving_since:]
            assert peers.run_until(forward, 5.0), companion.log()
            # a stranger's unsigned stick, alone on the link while the pilot drives, moves
            # nothing (two refreshes after the pilot's last stick, nothing else is waiting)
            def refreshed(count: int) -> Callable[[], bool]:
                seen = len(peers.overrides)
                return lambda: len(peers.overrides) >= seen + count
            assert peers.run_until(refreshed(2), 2.0), companion.log()
            since_stranger = len(peers.overrides)
            peers.gcs.write(mavlink.MAVLink_manual_control_message(
                1, -1000, 0, 500, 0, 0).pack(stranger))
            assert peers.run_until(refreshed(2), 2.0), companion.log()
            assert peers.overrides[since_stranger:] == [FORWARD] * (
                len(peers.overrides) - since_stranger)
            # everything the rover sent was signed (pymavlink with the key verified it)
            assert peers.received and all(m._signed for m in peers.received)
            companion.terminate()
            assert companion.wait(10.0) == 0
        assert "signature 2" in companion.log()  # the status line at exit: both refused
    finally:
        peers.close()


@pytest.mark.slow
def test_an_unsigned_station_on_a_signed_udpin_link_hears_a_1_hz_heartbeat_and_why_until_it_signs(
        tmp_path):
    """The companion listens (``--gcs udpin:``) with a key; a pymavlink station without it
    sends heartbeats and an arm command. It is told, with a signed HEARTBEAT once a second,
    why nothing it sends is taken, and gets nothing else; its arm does not arm. Once it signs
    with the key it is a peer: streams, parameters, and no more hints."""
    port = free_port()
    peers = PeerPump(f"udpout:127.0.0.1:{port}")
    key = private_key_file(tmp_path)
    station = peers.gcs.mav
    reason = "Unsigned packet refused: signing required"
    beat = at_most_every(0.2, lambda: station.heartbeat_send(  # 5 Hz: the hints stay at 1 Hz
        mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0))

    def beating(done: Callable[[], object]) -> Callable[[], object]:
        def check() -> object:  # the station's own heartbeat
            beat()
            return done()
        return check

    def arrived(kind: str, since: int = 0) -> list[float]:
        return [t for t, m in zip(peers.arrived_s[since:], peers.received[since:], strict=True)
                if m.get_type() == kind]
    try:
        with CompanionProcess(f"udpin:127.0.0.1:{port}", peers.fc_url, tmp_path / "run",
                              "--signing-key", str(key)) as companion:
            assert peers.run_until(beating(lambda: peers.seen("HEARTBEAT")), 15.0), companion.log()
            station.command_long_send(1, 1, ARM, 0, 1, 21196, 0, 0, 0, 0, 0)  # forced, even
            station.param_request_list_send(1, 1)
            assert peers.run_until(beating(lambda: len(peers.seen("HEARTBEAT")) >= 5), 10.0), (
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
                return peers.run_until(lambda: peers.seen("PARAM_VALUE", since), 0.3)
            assert peers.run_until(beating(answered), 10.0), companion.log()
            assert peers.run_until(beating(lambda: peers.seen("ODOMETRY", since)), 5.0)
            more = time.monotonic() + 2.0
            assert peers.run_until(beating(lambda: time.monotonic() > more), 5.0)
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
