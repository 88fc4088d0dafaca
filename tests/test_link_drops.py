"""Links that drop and come back: what the core decides, in virtual time (issue 11.2).

The shell finds a link broken (a serial device that vanished, a TCP connection the peer
closed) and tells the core once (``RoverCore.link_down``), and again when it reopened it
(``RoverCore.link_up``); the lockstep harness does the same (``Lockstep.link_down``, ``link_up``).
The I/O itself (ptys, sockets, the process's CPU) is tested in test_link_reconnect.py.
"""

from __future__ import annotations

from support import status_texts
from test_end_to_end import NEUTRAL, WHEELS, stream_sticks

from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.rcoverride import override_fields
from mecanum_mav.sim.lockstep import Lockstep

FORWARD = override_fields(WHEELS, [2000] * 4)


def drive_forward(h: Lockstep) -> None:
    h.gcs.arm()
    assert stream_sticks(h, lambda: h.overrides and h.overrides[-1].channels == FORWARD, 1000)


def test_an_unplugged_flight_controller_is_reported_once_and_disarms_at_once(harness):
    h = harness
    drive_forward(h)
    since = h.gcs.mark()
    h.link_down("fc")  # by default as a pulled USB cable: the serial link's "device gone"
    unplugged_s = h.now_s
    # the pilot keeps pushing the stick for 5 s (longer than FS_FC_TMO, 3 s)
    stream_sticks(h, lambda: None, 1000, timeout_s=5.0)
    said = status_texts(h, since)
    assert said.count("FC link down: device gone; reconnecting") == 1
    assert said.count("Flight controller link lost") == 1
    assert said.count("Disarmed: flight controller link lost") == 1
    assert [t for t in said if "link" in t] == said[:3], said
    assert not h.core.vehicle.armed
    lost = h.gcs.wait("STATUSTEXT", lambda m: m.text == "Flight controller link lost", 0.0,
                      since)
    assert lost is not None  # at the next wake-up, not at FS_FC_TMO:
    assert h.gcs.arrived_s[h.gcs.messages.index(lost)] <= unplugged_s + h.dt_s + 1e-9
    assert h.core.pulses_us == h.core.pwm.neutral()


def test_after_replugging_the_first_override_is_neutral_and_driving_needs_arming_again(harness):
    h = harness
    drive_forward(h)
    h.link_down("fc")
    stream_sticks(h, lambda: None, 1000, timeout_s=1.0)  # unplugged for less than FS_FC_TMO
    since = h.gcs.mark()
    replugged_s = h.now_s
    h.link_up("fc")
    # the stick is still pushed: nothing but neutral until the pilot arms again
    stream_sticks(h, lambda: None, 1000, timeout_s=1.0)
    after = h.overrides_since(replugged_s)
    assert after and all(o.channels == NEUTRAL for o in after)
    assert "FC link reconnected" in status_texts(h, since)
    assert "Flight controller link up" in status_texts(h, since)
    h.gcs.arm()
    assert stream_sticks(h, lambda: h.overrides[-1].channels == FORWARD, 1000, timeout_s=1.0)


def test_a_broken_ground_station_link_brings_the_wheels_to_neutral_at_once_and_holds(harness):
    h = harness
    drive_forward(h)
    since = h.gcs.mark()
    broken_s = h.now_s
    h.link_down("gcs", "closed by the peer")
    h.step()
    assert [o.channels for o in h.overrides if o.time_s > broken_s] == [NEUTRAL]
    assert h.core.vehicle.mode is Mode.HOLD  # FS_GCS_ACTION 0: HOLD, as a lost heartbeat
    said = status_texts(h, since)
    assert said[0] == "GCS link down: closed by the peer; reconnecting"
    assert "GCS link lost: failsafe" in said


def test_a_ground_station_link_back_is_said_and_changes_no_output(harness):
    """(A tcp: or serial ground-station link that broke and came back: said once; the
    wheels keep their output, which the GCS failsafe governs, not the link's return.)"""
    h = harness
    outbox = h.core.link_up("gcs", h.now_s)
    assert outbox.override is None
    assert [m.text for m in outbox.gcs] == ["GCS link reconnected"]
