"""Shared fixtures: a companion between a real ground-station peer and a flight-controller peer."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import pytest
from mavpeers import Peer, flight_controller, ground_station

from mecanum_mav.app.companion import Companion
from mecanum_mav.config.params import Params
from mecanum_mav.io.links import mavlink
from mecanum_mav.sim.lockstep import Lockstep
from mecanum_mav.sim.simfc import SimFlightController


@dataclass
class Rig:
    """A running companion with its two peers."""

    companion: Companion
    gcs: Peer
    fc: Peer

    def command(self, command: int, *params: float, timeout_s: float = 1.0):
        """Send COMMAND_LONG to the vehicle and return its COMMAND_ACK (or None)."""
        p = [*params, *([0.0] * (7 - len(params)))]
        since = self.gcs.mark()
        self.gcs.mav.command_long_send(1, 1, command, 0, *p)
        return self.gcs.wait("COMMAND_ACK", lambda m: m.command == command, timeout_s, since)

    def arm(self) -> None:
        ack = self.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED

    def sticks(self, x: int = 0, y: int = 0, r: int = 0, z: int = 500, target: int = 1) -> int:
        """Send MANUAL_CONTROL; returns the FC peer's mark from just before it."""
        since = self.fc.mark()
        self.gcs.mav.manual_control_send(target, x, y, z, r, 0)
        return since

    def wait_override(self, predicate, since: int = 0, timeout_s: float = 2.0):
        from mavpeers import channels

        return self.fc.wait("RC_CHANNELS_OVERRIDE", lambda m: predicate(channels(m)),
                            timeout_s, since)


def make_rig(params: Params | None = None) -> Rig:
    params = params or Params()
    gcs = ground_station()
    fc = flight_controller()
    companion = Companion(params, gcs.url, fc.url)
    companion.start()
    assert gcs.wait("HEARTBEAT", timeout_s=3.0) is not None, "companion never sent a heartbeat"
    assert fc.wait("HEARTBEAT", timeout_s=3.0) is not None
    # The FC link is up once the companion has heard the FC's heartbeat.
    assert gcs.wait("STATUSTEXT", lambda m: "Flight controller link up" in m.text, 3.0)
    return Rig(companion, gcs, fc)


@pytest.fixture
def rig() -> Iterator[Rig]:
    r = make_rig()
    yield r
    r.companion.close()
    r.gcs.close()
    r.fc.close()


@pytest.fixture
def rig_factory() -> Iterator:
    made: list[Rig] = []

    def factory(params: Params | None = None) -> Rig:
        made.append(make_rig(params))
        return made[-1]

    yield factory
    for r in made:
        r.companion.close()
        r.gcs.close()
        r.fc.close()


@contextmanager
def simulated_rover(params: Params | None = None, **companion_options) -> Iterator[tuple]:
    """Companion and simulator in this process with a real UDP link between them, and a
    ground-station peer: yields (simulator, gcs peer, companion). ``companion_options`` go to
    :class:`Companion` (``param_path=`` ...)."""
    params = params or Params()
    sim = SimFlightController("udpin:127.0.0.1:0", params)
    sim.start()
    gcs = ground_station()
    companion = Companion(params, gcs.url, f"udpout:127.0.0.1:{sim.local_port}",
                          **companion_options)
    companion.start()
    try:
        assert gcs.wait("HEARTBEAT", timeout_s=3.0)
        yield sim, gcs, companion
    finally:
        companion.close()
        sim.stop()
        gcs.close()


@pytest.fixture
def rover(request) -> Iterator[tuple]:
    """A simulated rover (see :func:`simulated_rover`); parametrize indirectly with a dict of
    parameter values."""
    params = Params()
    params.update(getattr(request, "param", {}))
    with simulated_rover(params) as parts:
        yield parts


# --------------------------------------------------------------------------- virtual time


def lockstep(params: Params | dict | None = None, **options) -> Lockstep:
    """A :class:`Lockstep` harness (core + simulated board + scripted ground station) whose
    flight-controller link is up (the board's first heartbeat has been heard)."""
    if isinstance(params, dict) or params is None:
        values, params = params or {}, Params()
        params.update(values)
    h = Lockstep(params, **options)
    assert h.run_until(lambda: not h.core.vehicle.fc_lost, 3.0), "no flight-controller heartbeat"
    return h


@pytest.fixture
def harness(request) -> Lockstep:
    """A lockstep harness; parametrize indirectly with a dict of parameter values."""
    return lockstep(getattr(request, "param", None))
