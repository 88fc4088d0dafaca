"""The twin's truth on a MAVLink stream of its own, for the view (``mecanum-mav view``).

:class:`TruthPublisher` reads the bridge's record (:class:`~mecanum_mav.sim.twinrecord.
TwinRecord`, shared memory) in a thread of the process that holds the twin, never in the
bridge's (which answers the firmware's 1200 Hz frames), and sends to a UDP address:

- SIM_STATE at :data:`SIM_STATE_RATE_HZ` (when the physics moved on): the true pose and
  velocity with the simulated board's fields and conventions (:func:`send_sim_state`:
  latitude and longitude about ``ORIGIN_LAT``/``ORIGIN_LON``, or 0, 0; yaw radians clockwise
  from north; velocity north, east m/s; level);
- DEBUG_VECT ``CONTACT_FL`` .. ``CONTACT_RR`` at 10 Hz (each new reading of the bridge's): x
  the normal force (N), y the slip speed (m/s), z 1 when slipping else 0, ``time_usec`` the
  physics time (:func:`send_contacts`, as the simulated board sends them).

It sends as :data:`TRUTH_SOURCE` (system, component), a sender of its own: neither the
companion nor the firmware (both 1/1), so the view tells its truth from theirs.
"""

from __future__ import annotations

import contextlib
import math
import socket
import threading
from collections.abc import Sequence
from typing import Any

from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.mecanum.geometry import body_to_ned, wrap_pi
from mecanum_mav.mecanum.wheels import WHEEL_KEYS
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.sim.physics import WheelContact
from mecanum_mav.sim.twinrecord import TwinRecord

__all__ = ["CONTACT_NAMES", "SIM_STATE_RATE_HZ", "TRUTH_SOURCE", "TruthPublisher",
           "send_contacts", "send_sim_state", "udp_address", "view_url"]

TRUTH_SOURCE = (1, mavlink.MAV_COMP_ID_USER1)
"""The (system, component) the twin's truth is sent as (the view's truth from a twin)."""
SIM_STATE_RATE_HZ = 20.0
"""How often the true pose is sent (Hz)."""
CONTACT_NAMES = tuple(f"CONTACT_{key.upper()}" for key in WHEEL_KEYS)
"""The DEBUG_VECT names of the wheels' contacts, FL, FR, RL, RR."""
_YAW_RATE_FRAMES = 12
"""Frames the yaw rate is taken over (10 ms at 1200 Hz)."""


def send_sim_state(mav: Any, origin: GlobalOrigin, north_m: float, east_m: float,
                   yaw_rad: float, forward_mps: float, right_mps: float,
                   yaw_rate: float) -> None:
    """SIM_STATE for a true pose (local NED m about ``origin``, yaw rad clockwise from north),
    velocity (body FRD m/s) and yaw rate (rad/s clockwise); level, no accelerations,
    altitude 0."""
    lat_e7, lon_e7 = origin.to_global(north_m, east_m)
    v_north, v_east = body_to_ned(forward_mps, right_mps, yaw_rad)
    mav.sim_state_send(math.cos(yaw_rad / 2), 0.0, 0.0, math.sin(yaw_rad / 2), 0.0, 0.0,
                       yaw_rad, 0.0, 0.0, 0.0, 0.0, 0.0, yaw_rate, lat_e7 / 1e7, lon_e7 / 1e7,
                       0.0, 0.0, 0.0, v_north, v_east, 0.0, lat_e7, lon_e7)


def send_contacts(mav: Any, time_usec: int, contacts: Sequence[WheelContact]) -> None:
    """DEBUG_VECT ``CONTACT_W`` per wheel FL, FR, RL, RR: x normal force N, y slip m/s, z 1
    when slipping else 0."""
    for name, contact in zip(CONTACT_NAMES, contacts, strict=True):
        mav.debug_vect_send(name.encode("ascii"), time_usec, contact.normal_n,
                            contact.slip_mps, 1.0 if contact.slipping else 0.0)


def udp_address(url: str) -> tuple[str, int]:
    """``udpout:HOST:PORT`` (or ``HOST:PORT``) as (host, port).

    Raises:
        ValueError: not that form."""
    host, _, port = url.removeprefix("udpout:").rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536 or ":" in host:
        raise ValueError(f"the truth goes to udpout:HOST:PORT, not {url!r}")
    return host, int(port)


def view_url(url: str) -> str:
    """What ``mecanum-mav view --connect`` takes to show the truth sent to ``url``
    (``udpout:HOST:PORT`` -> ``udpin:HOST:PORT``; ValueError as :func:`udp_address`)."""
    return "udpin:{}:{}".format(*udp_address(url))


class _Datagrams:
    """A file-like sink for pymavlink: each packet written is one datagram to ``address``."""

    def __init__(self, address: tuple[str, int]) -> None:
        self.address = address
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def write(self, data: bytes) -> None:
        with contextlib.suppress(OSError):  # (nobody listening yet: the next one may land)
            self.sock.sendto(data, self.address)


class TruthPublisher:
    """Sends the truth in ``record`` to ``url`` (``udpout:HOST:PORT``; a view listens with
    ``udpin:HOST:PORT``) from a thread of this process until :meth:`close` (see the module
    docstring).

    Args:
        record: the bridge's record.
        url: where to send.
        origin: the global origin the positions are placed about (``ORIGIN_LAT``/``ORIGIN_LON``).
        rate_hz: SIM_STATE per second.

    Raises:
        ValueError: ``url`` is not ``udpout:HOST:PORT``.
    """

    def __init__(self, record: TwinRecord, url: str, origin: GlobalOrigin,
                 rate_hz: float = SIM_STATE_RATE_HZ) -> None:
        self._sink = _Datagrams(udp_address(url))
        self.url = url
        self.view_url = view_url(url)
        """What ``mecanum-mav view --connect`` takes to show this truth."""
        self.mav = mavlink.MAVLink(self._sink, srcSystem=TRUTH_SOURCE[0],
                                   srcComponent=TRUTH_SOURCE[1])
        self._record = record
        self._origin = origin
        self._period_s = 1.0 / rate_hz
        self._count = 0  # frames recorded when last sent
        self._contacts_s = math.nan  # physics time of the contacts last sent
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="twin-truth", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self._period_s):
            self.send_now()

    def send_now(self) -> None:
        """Send the latest truth (if the physics moved on) and contacts (if new)."""
        rows = self._record.latest(_YAW_RATE_FRAMES)
        count = self._record.count
        if len(rows) and count != self._count:
            self._count = count
            _, time_s, north, east, yaw, forward, right = rows[-1].tolist()
            dt = time_s - float(rows[0][1])
            turned = wrap_pi(yaw - float(rows[0][4]))
            send_sim_state(self.mav, self._origin, north, east, yaw, forward, right,
                           turned / dt if dt > 0.0 else 0.0)
        read = self._record.contacts()
        if read is not None and read[0] != self._contacts_s:
            self._contacts_s = read[0]
            send_contacts(self.mav, max(round(read[0] * 1e6), 0), read[1])

    def close(self) -> None:
        """Stop the thread and close the socket; idempotent."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=5)
        self._sink.sock.close()
