"""MAVLink links: pymavlink connections driven by a selector loop, MAVLink 2, never raising.

MAVLink 2 and the ArduPilot dialect throughout (:mod:`mecanum_mav.protocol.dialect`). URLs
are pymavlink connection strings; :func:`open_link` opens one and picks its class, one per
transport family under a common base, as python-can has one module per interface under a
common bus class:

=====================================  ====================================================
``udpin:HOST:PORT``                    :class:`~.udpin.UdpinLink` (listens; replies go to
                                       every peer it earned), :class:`~.udpin.
                                       SignedUdpinLink` with a key and ``tell_refused``
``udpout:HOST:PORT``                   :class:`~.datagram.UdpoutLink` (its socket connected
                                       there: it reads only what comes from there)
``tcp:HOST:PORT``                      :class:`~.tcp.TcpLink`
``tcpin:HOST:PORT``                    :class:`~.tcp.TcpServerLink`
``/dev/ttyUSB0,57600``                 :class:`~.serialport.SerialLink` (pyserial)
``udpbcast:HOST:PORT``                 :class:`~.datagram.UdpBroadcastLink`
anything else                          :class:`~.datagram.PymavlinkDatagramLink`
=====================================  ====================================================

:class:`~.base.Link` (:mod:`~mecanum_mav.io.links.base`) is what every link has and what the
loop uses (:class:`~mecanum_mav.runtime.loop.LoopLink`); datagram links
(:mod:`~mecanum_mav.io.links.datagram`, :mod:`~mecanum_mav.io.links.udpin`) send at once and
never go down; stream links (:mod:`~mecanum_mav.io.links.stream` and its transports) queue
in the link, paced to the wire, and come back by themselves after a break. Signing and tlog
recording are parts any link takes (:mod:`~mecanum_mav.io.links.parts`). Every timer runs on
the link's ``clock`` (monotonic seconds).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from mecanum_mav.io.links.base import (
    REOPEN_PERIOD_S,
    SEND_WARNING_PERIOD_S,
    Link,
    LinkDownError,
    follow,
)
from mecanum_mav.io.links.datagram import (
    DATAGRAM_BYTES,
    DatagramLink,
    PymavlinkDatagramLink,
    UdpBroadcastLink,
    UdpoutLink,
    fixed_destination,
)
from mecanum_mav.io.links.datagram import _dissolve as _dissolve
from mecanum_mav.io.links.serialport import QUEUE_MIN_BYTES, QUEUE_S, SerialLink
from mecanum_mav.io.links.stream import PACING_LEAD_S, StreamLink
from mecanum_mav.io.links.tcp import (
    TCP_CONNECT_TIMEOUT_S,
    TCP_POLL_S,
    TCP_QUEUE_BYTES,
    TCP_UNSENT_LIMIT,
    TcpLink,
    TcpServerLink,
)
from mecanum_mav.io.links.udpin import MAX_PEERS, PEER_TIMEOUT_S, SignedUdpinLink, UdpinLink
from mecanum_mav.protocol.dialect import mavlink, mavutil

__all__ = ["DATAGRAM_BYTES", "MAX_PEERS", "PACING_LEAD_S", "PEER_TIMEOUT_S", "QUEUE_MIN_BYTES",
           "QUEUE_S", "REOPEN_PERIOD_S", "SEND_WARNING_PERIOD_S", "TCP_CONNECT_TIMEOUT_S",
           "TCP_POLL_S", "TCP_QUEUE_BYTES", "TCP_UNSENT_LIMIT", "DatagramLink", "Link",
           "LinkDownError",
           "PymavlinkDatagramLink", "SerialLink", "SignedUdpinLink", "StreamLink", "TcpLink",
           "TcpServerLink", "UdpBroadcastLink", "UdpinLink", "UdpoutLink", "follow", "mavlink",
           "mavutil", "open_link"]


def open_link(url: str, *, source_system: int, source_component: int, name: str,
              signing_key: bytes | None = None, tell_refused: bool = False,
              clock: Callable[[], float] = time.monotonic) -> Link:
    """Open the :class:`~.base.Link` for ``url`` (the table above).

    Args:
        url: pymavlink connection string.
        source_system: system id this side sends as (1..255).
        source_component: component id this side sends as.
        name: short name for logs (``"gcs"``, ``"fc"``).
        signing_key: the 32-byte MAVLink 2 signing key, or None (:class:`~.parts.Signing`).
        tell_refused: with a signing key on a ``udpin:`` link (the ground station's), tell an
            address whose packets were all refused why, with each heartbeat
            (:class:`~.udpin.SignedUdpinLink`); off for the flight controller's link.
        clock: the monotonic time source (seconds) of every timer of the link (see
            :class:`~.base.Link`).

    Raises:
        OSError, ValueError: it cannot be opened (the message names the URL).
    """
    try:
        conn = mavutil.mavlink_connection(url, source_system=source_system,
                                          source_component=source_component)
        return _link_for(conn, url=url, name=name, signing_key=signing_key,
                         tell_refused=tell_refused, clock=clock)
    except (OSError, ValueError) as exc:
        raise type(exc)(f"cannot open {name} link {url!r}: {exc}") from exc


def _link_for(conn: object, *, url: str, name: str, signing_key: bytes | None,
              tell_refused: bool, clock: Callable[[], float]) -> Link:
    """The link class for pymavlink's connection ``conn``: how it moves its bytes, breaks
    and comes back."""
    if isinstance(conn, mavutil.mavserial):
        return SerialLink(conn, url=url, name=name, signing_key=signing_key, clock=clock)
    if type(conn) is mavutil.mavtcp:  # not its Unix-socket subclass
        return TcpLink(conn, url=url, name=name, signing_key=signing_key, clock=clock)
    if isinstance(conn, mavutil.mavtcpin):
        return TcpServerLink(conn, url=url, name=name, signing_key=signing_key, clock=clock)
    if isinstance(conn, mavutil.mavudp) and conn.udp_server:
        if signing_key is not None and tell_refused:
            return SignedUdpinLink(conn, url=url, name=name, signing_key=signing_key,
                                   clock=clock)
        return UdpinLink(conn, url=url, name=name, signing_key=signing_key, clock=clock)
    if isinstance(conn, mavutil.mavudp) and conn.broadcast:
        return UdpBroadcastLink(conn, url=url, name=name, signing_key=signing_key, clock=clock)
    destination = fixed_destination(conn)
    if destination is not None:
        return UdpoutLink(conn, destination, url=url, name=name, signing_key=signing_key,
                          clock=clock)
    return PymavlinkDatagramLink(conn, url=url, name=name, signing_key=signing_key,
                                 clock=clock)
