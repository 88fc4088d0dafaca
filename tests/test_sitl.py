"""Integration tests against real ArduPilot Rover firmware (SITL, see tests/sitl.py).

The companion runs as its own process (``python -m mecanum_mav run``) between a scripted
ground station on UDP and ``ardurover`` configured as a pass-through board; what ArduPilot
really does with the overrides is read on the firmware's second port (SERVO_OUTPUT_RAW).
Skipped when the firmware is not there (../shared/ardupilot-sitl/ardurover or
$MECANUM_SITL).
"""

from __future__ import annotations

import signal
import time
from collections.abc import Iterator

import pytest
from sitl import CompanionProcess, Rig, Sitl, find_sitl

from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.fcsetup import SAFE_OVERRIDE_TIME_S
from mecanum_mav.sim.groundstation import udp_ground_station

BINARY, WHY_NOT = find_sitl()
pytestmark = [pytest.mark.sitl, pytest.mark.skipif(BINARY is None, reason=WHY_NOT)]

RECEIVER = (1600, 1600, 1600, 1600)  # the simulated radio: "released" is not "neutral"
TRIM = (1500, 1500, 1500, 1500)
FORWARD = (2000, 2000, 2000, 2000)
STRAFE_RIGHT = (2000, 1000, 1000, 2000)
CLOCKWISE = (2000, 1000, 2000, 1000)
BOOT_S = 20.0  # generous deadlines: the suite must hold on a loaded 2-core machine
REACT_S = 10.0
LAPSE_S = SAFE_OVERRIDE_TIME_S
"""The board's own override timeout (setup-fc --apply set RC_OVERRIDE_TIME to it). The
channels go back to the receiver either way: released by the companion, or let go by the
board this long after the last override it received. Only a release reaching the board
brings them back before that, so that is the causal bound of the shutdown tests (measured:
released 140-158 ms after the signal, 0.1 s of it the neutral's hold, NEUTRAL_HOLD_S; with
no release sent, the board's lapse 560 ms)."""


@pytest.fixture(scope="module", params=["udp", "tcp", "serial"])
def sitl(request) -> Iterator[Sitl]:
    """One firmware per transport, shared by the tests of that transport."""
    assert BINARY is not None
    with Sitl(BINARY, request.param, receiver=RECEIVER, boot_timeout_s=BOOT_S) as fc:
        fc.set_up()  # the user's path: setup-fc --apply on the plain pass-through board
        yield fc


@pytest.fixture
def rig(sitl, tmp_path) -> Iterator[Rig]:
    assert sitl.alive(), sitl.log()
    gcs, port = udp_ground_station()
    try:
        # The default parameters and every pre-arm check, as a user runs it; the board has
        # a receiver (what SIGTERM releases to) and was set up by setup-fc --apply.
        with CompanionProcess(port.url, sitl.fc_url, tmp_path) as companion:
            yield Rig(sitl, gcs, companion)
    finally:
        port.close()


def only(transport: str):
    return pytest.mark.parametrize("sitl", [transport], indirect=True)


def test_sticks_drive_ardupilot_outputs(rig):
    rig.arm()
    rig.drive(1000, 0, 0, FORWARD)
    rig.drive(0, 1000, 0, STRAFE_RIGHT)
    rig.drive(0, 0, 1000, CLOCKWISE)


@only("udp")
def test_disarm_gives_trim_on_the_firmware_while_the_sticks_keep_coming(rig):
    rig.arm()
    rig.drive(1000, 0, 0, FORWARD)
    since = rig.monitor.mark()
    ack = rig.gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, timeout_s=REACT_S)
    acked = time.monotonic()
    assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED, rig.why()
    trim = rig.monitor.wait_servos(lambda s: s == TRIM, REACT_S, since=since,
                                   tick=lambda: rig.gcs.sticks(1000, 0, 0))
    assert trim is not None, f"never trim after disarming\n{rig.why()}"
    # (the pushed stick keeps the override fresh: nothing but the companion's trim gives it)
    print(f"disarm: COMMAND_ACK -> trim on SERVO1..4 {(trim.t - acked) * 1000:.0f} ms")


def test_sigterm_releases_the_channels_to_the_receiver(rig):
    # Over TCP this needs the companion to flush its last packets before it closes the
    # socket (FC_CLOSE_LINGER_S): without that the release is lost and the channels only
    # fall back after RC_OVERRIDE_TIME (measured: 3.0 s).
    rig.arm()
    rig.drive(0, 1000, 0, STRAFE_RIGHT)
    since = rig.monitor.mark()
    sent = rig.companion.terminate()
    released = rig.monitor.wait_servos(lambda s: s == RECEIVER, REACT_S, since=since,
                                       tick=lambda: rig.gcs.sticks(0, 1000, 0))
    code = rig.companion.wait(REACT_S)
    assert released is not None, f"never back to the receiver's {RECEIVER}\n{rig.why()}"
    delay = released.t - sent
    print(f"{rig.fc.transport}: SIGTERM -> receiver's pulse on SERVO1..4 {delay * 1000:.0f} ms")
    assert code == 0, rig.why()
    assert delay < LAPSE_S, f"the board let go by itself: the release was lost\n{rig.why()}"


def test_two_ctrl_c_10_ms_apart_still_release_the_channels_to_the_receiver(rig):
    """The second Ctrl-C must not cut the shutdown short (over TCP and serial the release
    waits in the link's linger: cut, the board holds the last override until
    RC_OVERRIDE_TIME)."""
    rig.arm()
    rig.drive(0, 1000, 0, STRAFE_RIGHT)
    since = rig.monitor.mark()
    sent = time.monotonic()
    rig.companion.proc.send_signal(signal.SIGINT)
    time.sleep(0.01)  # the second Ctrl-C, 10 ms after the first
    rig.companion.proc.send_signal(signal.SIGINT)
    released = rig.monitor.wait_servos(lambda s: s == RECEIVER, REACT_S, since=since,
                                       tick=lambda: rig.gcs.sticks(0, 1000, 0))
    code = rig.companion.wait(REACT_S)
    assert released is not None, f"never back to the receiver's {RECEIVER}\n{rig.why()}"
    delay = released.t - sent
    print(f"{rig.fc.transport}: 2 x SIGINT -> receiver's pulse on SERVO1..4 "
          f"{delay * 1000:.0f} ms")
    assert code == 0, rig.why()
    assert "Traceback" not in rig.companion.log(), rig.why()
    assert delay < LAPSE_S, f"the board let go by itself: the release was lost\n{rig.why()}"


# --------------------------------------------------------------------------- setup-fc


def test_setup_fc_finds_the_hazards_and_after_apply_a_killed_companion_stops_the_wheels(
        tmp_path):
    """A board with no receiver, set up as the README used to recommend (plain RCIN
    pass-through): setup-fc reports that a dead companion leaves the wheels turning; after
    --apply, kill -9 of the companion brings SERVO1..4 to trim (the board's own override
    timeout, RC_OVERRIDE_TIME; the delay is printed), and a 1600 us command comes out as
    1600 +/- 2."""
    assert BINARY is not None
    with Sitl(BINARY, "udp", receiver=None, boot_timeout_s=BOOT_S) as fc:
        before = fc.setup_fc()
        print(before.stdout)
        assert before.returncode == 1, before.stdout + before.stderr
        assert "SERVO_RC_FS_MSK bit 0" in before.stdout and "HAZARD" in before.stdout
        gcs, port = udp_ground_station()
        try:  # the companion finds the same hazards itself, says so, and will not arm
            with CompanionProcess(port.url, fc.fc_url, tmp_path / "unsafe") as companion:
                warning = gcs.wait("STATUSTEXT", lambda m: "FC setup unsafe" in m.text,
                                   BOOT_S, 0)
                assert warning is not None, companion.log()
                assert warning.severity == mavlink.MAV_SEVERITY_WARNING
                ack = gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, timeout_s=REACT_S)
                assert ack is not None and ack.result == mavlink.MAV_RESULT_DENIED
                assert gcs.wait("STATUSTEXT", lambda m: "PreArm: FC setup unsafe" in m.text,
                                REACT_S, 0)
        finally:
            port.close()
        applied = fc.setup_fc("--apply")
        print(applied.stdout)
        assert applied.returncode == 0, applied.stdout + applied.stderr
        assert "the flight controller is set up safely" in applied.stdout
        gcs, port = udp_ground_station()
        try:
            with CompanionProcess(port.url, fc.fc_url, tmp_path,
                                  "--set", "INP_DEADBAND=0") as companion:
                rig = Rig(fc, gcs, companion)
                rig.arm()
                rig.drive(200, 0, 0, (1600, 1600, 1600, 1600))  # 0.2 of full: 1600 us
                rig.drive(1000, 0, 0, FORWARD)
                since = rig.monitor.mark()
                killed = time.monotonic()
                companion.proc.kill()  # SIGKILL: no shutdown path at all
                trim = rig.monitor.wait_servos(lambda s: s == TRIM, REACT_S, since=since)
                assert trim is not None, f"the wheels kept turning\n{rig.why()}"
                print(f"kill -9 -> trim on SERVO1..4 {(trim.t - killed) * 1000:.0f} ms")
        finally:
            port.close()


@only("udp")
def test_the_battery_the_firmware_measures_reaches_the_ground_station(rig):
    """The companion asks ArduPilot for SYS_STATUS and relays its battery, and says the
    truth about its sensors (battery present; fence, GPS and AHRS bits healthy)."""
    status = rig.gcs.wait("SYS_STATUS", lambda m: m.voltage_battery != 65535, BOOT_S, 0)
    assert status is not None, rig.why()
    assert 10_000 < status.voltage_battery < 14_000 and 0 <= status.battery_remaining <= 100
    assert status.onboard_control_sensors_present & mavlink.MAV_SYS_STATUS_SENSOR_BATTERY
    healthy = (mavlink.MAV_SYS_STATUS_GEOFENCE | mavlink.MAV_SYS_STATUS_SENSOR_GPS
               | mavlink.MAV_SYS_STATUS_AHRS)
    assert status.onboard_control_sensors_health & healthy == healthy
