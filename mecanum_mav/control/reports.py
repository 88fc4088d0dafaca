"""What the rover reports on its own clock: telemetry (the streams of
:mod:`mecanum_mav.protocol.telemetry`, built from one :class:`TelemetryState`), the two
heartbeats (the rover's to the ground station, a ground station's to the flight controller),
SYS_STATUS's link figures, and the status line for people.

The core decides when (:meth:`~mecanum_mav.control.core.RoverCore.housekeeping`); this module
says what. The link figures are the shell's (:class:`LinkCounts`, passed in as a callable).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

from mecanum_mav.control.fclink import FcLink
from mecanum_mav.control.output import OutputStage
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.health import sensor_bits
from mecanum_mav.protocol.heartbeat import send_gcs_heartbeat, send_rover_heartbeat
from mecanum_mav.protocol.telemetry import TelemetryState, build

__all__ = ["LinkCounts", "Reports", "no_link_counts"]


class LinkCounts(NamedTuple):
    """What the links counted, over both (the shell's; SYS_STATUS and the status line)."""

    received: int = 0
    """Messages received (parsed whole)."""
    malformed: int = 0
    """Packets dropped before they became messages: bad CRC, truncated, unknown."""
    send_failed: int = 0
    """Sends that failed (peer gone, no route)."""


def no_link_counts() -> LinkCounts:
    """No links (a core on its own): nothing counted."""
    return LinkCounts()


class Reports:
    """The rover's reports (module docstring).

    Args:
        rover: the core's output stage and context (pose, pulses, vehicle, outboxes).
        fc: the flight controller's observations (its battery).
        origin: where local (0, 0) is on the earth, now.
        link_counts: what the links counted.
    """

    def __init__(self, rover: OutputStage, fc: FcLink,
                 origin: Callable[[], GlobalOrigin | None],
                 link_counts: Callable[[], LinkCounts]) -> None:
        self.rover = rover
        self.fc = fc
        self.origin = origin
        self.link_counts = link_counts
        self._drop_window = (0, 0)  # (received + malformed, dropped) at the last heartbeat
        self._drop_rate_cpct = 0

    def telemetry_state(self, now_s: float) -> TelemetryState:
        """What telemetry is built from at ``now_s``."""
        rover = self.rover
        est = rover.estimator
        counts = self.link_counts()
        errors = counts.malformed + rover.refusals.total + counts.send_failed
        battery, fresh = self.fc.battery(now_s)
        sensors = sensor_bits(fc_link_up=not rover.vehicle.fc_lost, battery_known=fresh)
        return TelemetryState(now_s, rover.boot_s, est.pose, est.velocity_body, est.yaw_rate,
                              est.reset_counter, est.wheel_distances_m, rover.pwm.channels,
                              rover.pulses_us, errors, self._drop_rate_cpct, self.origin(),
                              sensors, battery)

    def send_streams(self, names: Sequence[str], now_s: float) -> None:
        """The telemetry messages ``names`` (streams due), to the ground station."""
        state = self.telemetry_state(now_s)
        for name in names:
            build(name, self.rover.to_gcs, state)

    def send_heartbeats(self) -> None:
        """The rover's HEARTBEAT to the ground station and a ground station's to the flight
        controller; the drop rate is taken over the time since the last ones."""
        self._update_drop_rate()
        rover = self.rover
        vehicle = rover.vehicle
        send_rover_heartbeat(rover.to_gcs, vehicle.mode, armed=vehicle.armed,
                             failsafe=vehicle.failsafe)
        send_gcs_heartbeat(rover.to_fc)

    def _update_drop_rate(self) -> None:
        """SYS_STATUS ``drop_rate_comm`` (c%): of the packets that arrived since the last
        heartbeat, the share dropped as malformed or refused."""
        counts = self.link_counts()
        arrived = counts.received + counts.malformed
        dropped = counts.malformed + self.rover.refusals.total
        arrived_before, dropped_before = self._drop_window
        self._drop_window = arrived, dropped
        if arrived > arrived_before:
            share = (dropped - dropped_before) / (arrived - arrived_before)
            self._drop_rate_cpct = min(10_000, round(10_000 * share))
        else:
            self._drop_rate_cpct = 0

    def status_line(self) -> str:
        """One line of counts for people: messages received, packets dropped as malformed,
        failed sends, and the refusals per kind."""
        c = self.link_counts()
        refusals = self.rover.refusals
        return (f"received {c.received}, malformed {c.malformed}, send failures "
                f"{c.send_failed}, refused {refusals.total} ({refusals.summary()})")
