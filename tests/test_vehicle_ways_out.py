"""Ways out of driving that the lockstep scenarios do not reach: the vehicle state machine
(control/vehicle.py) on its own, time passed in (seconds)."""

from __future__ import annotations

from mecanum_mav.config.params import Params
from mecanum_mav.control.vehicle import Vehicle


def driving_vehicle() -> Vehicle:
    """Armed in MANUAL with a fresh stick, the flight controller heard, no ground-station
    HEARTBEAT ever (a script that only sends sticks)."""
    v = Vehicle(Params())
    v.on_fc_heartbeat(0.0)
    assert v.request_arm(0.0).accepted
    v.on_stick_input(0.1)
    assert v.driving()
    return v


def test_a_broken_ground_station_link_stops_the_wheels_at_once_without_a_heartbeat_seen():
    v = driving_vehicle()
    v.on_gcs_link_down(0.2)  # long before FS_INPUT_TMO (0.5 s) after the last stick
    assert v.input_stale and not v.driving()
    v.on_stick_input(0.3)  # the link is back and the pilot pushes again
    assert v.driving()


def test_a_forced_arm_with_a_fresh_deflected_stick_waits_for_the_next_stick():
    v = Vehicle(Params())
    v.on_fc_heartbeat(0.0)
    v.on_stick_input(0.1)  # the stick, deflected, arrived before arming
    assert v.request_arm(0.2, ["sticks not centred (y +0.80)"], force=True).accepted
    assert v.armed and not v.driving()  # the stick from before arming never drives
    v.on_stick_input(0.25)
    assert v.driving()
