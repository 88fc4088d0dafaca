"""One scripted ground station for the demo, the tests and the tools.

:class:`ScriptedGroundStation` speaks to a vehicle through a *port*: the lockstep harness's
virtual link (:class:`~mecanum_mav.sim.lockstep.Lockstep`, virtual time) or a real UDP socket
(:class:`UdpPort`, wall-clock time). The script is the same either way: it records everything
it receives, sends its own HEARTBEAT at 1 Hz while time passes, and waits for messages with a
deadline in the port's time (never a blind sleep). System 255, component 190, as Mission
Planner and MAVProxy.
"""

from __future__ import annotations

import selectors
import time
from collections.abc import Callable, Collection, Sequence
from typing import Any, Protocol

from mecanum_mav.io.links import Link, open_link
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.heartbeat import send_gcs_heartbeat
from mecanum_mav.protocol.mission import MissionItem, float_xy, item_from_fields
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.statustext import StatusChunks

__all__ = ["CLOCK_EPSILON_S", "GCS_COMPID", "GCS_SYSID", "Port", "ScriptedGroundStation",
           "SharedUdpPort", "UdpPort", "VehiclePort", "fleet_ground_station"]

GCS_SYSID = 255
GCS_COMPID: int = mavlink.MAV_COMP_ID_MISSIONPLANNER
HEARTBEAT_PERIOD_S = 1.0
CLOCK_EPSILON_S = 1e-9
"""Times closer than this (s) are one instant: a virtual clock's sums of steps end a hair
short of a deadline (the lockstep harness steps by the same rule)."""
MISSION_TIMEOUT_S = 1.5
"""The mission protocol's default timeout: silence this long restarts an upload."""

Predicate = Callable[[Any], bool]


def _any(msg: Any) -> bool:
    return True


def _seq_is(seq: int) -> Predicate:
    return lambda msg: bool(msg.seq == seq)


class Port(Protocol):
    """How the ground station reaches the vehicle."""

    @property
    def mav(self) -> Any:
        """A pymavlink ``MAVLink`` sending as the ground station: ``port.mav.xxx_send(...)``."""

    def now(self) -> float:
        """The port's time, seconds (virtual or monotonic)."""

    def pump(self, timeout_s: float) -> list[Any]:
        """Let up to ``timeout_s`` pass; the messages received meanwhile (may return early)."""


class ScriptedGroundStation:
    """A ground station that can be scripted: send, wait, command, upload a mission.

    Args:
        port: the link to the vehicle.
        target: (system, component) of the vehicle.
    """

    def __init__(self, port: Port, target: tuple[int, int] = (1, 1)) -> None:
        self.port = port
        self.target = target
        self.messages: list[Any] = []
        """Everything received, oldest first (index it with :meth:`mark`)."""
        self.arrived_s: list[float] = []
        """When each of :attr:`messages` was received, in the port's time (s)."""
        self.beating = True
        """Whether the HEARTBEAT goes out (clear it to test the vehicle's GCS failsafe)."""
        self._next_beat_s = -1.0

    @property
    def mav(self) -> Any:
        """Send anything: ``gcs.mav.manual_control_send(...)``."""
        return self.port.mav

    def on_time(self, now_s: float) -> None:
        """Time passed: the 1 Hz HEARTBEAT (the port calls this)."""
        if self.beating and now_s >= self._next_beat_s:
            send_gcs_heartbeat(self.mav)
            self._next_beat_s = now_s + HEARTBEAT_PERIOD_S

    def pump(self, timeout_s: float) -> list[Any]:
        """Let up to ``timeout_s`` pass (less if something arrives); returns (and records)
        what arrived."""
        before = len(self.messages)
        self.receive(self.port.pump(timeout_s), self.port.now())
        return self.messages[before:]

    def receive(self, messages: Sequence[Any], now_s: float) -> None:
        """Record messages that arrived at ``now_s`` (ports that deliver call this)."""
        if messages:
            self.messages += messages
            self.arrived_s += [now_s] * len(messages)

    def mark(self) -> int:
        """An index into :attr:`messages`: wait only for what arrives after this point."""
        self.pump(0.0)
        return len(self.messages)

    def received(self, kind: str, since: int = 0) -> list[Any]:
        """The messages of ``kind`` received from index ``since`` on."""
        return [m for m in self.messages[since:] if m.get_type() == kind]

    def texts(self, since: int = 0) -> list[str]:
        """The STATUSTEXTs received from index ``since`` on, a long text's chunks joined
        (:class:`~mecanum_mav.protocol.statustext.StatusChunks`), as each completed; texts
        whose last chunk has not come yet last."""
        chunks = StatusChunks()
        done = [text for msg in self.received("STATUSTEXT", since)
                for _, _, text in chunks.add(0.0, msg)]
        return done + [text for _, _, text in chunks.flush()]

    def wait(self, kind: str, predicate: Predicate = _any, timeout_s: float = 3.0,
             since: int | None = None) -> Any | None:
        """The first message of ``kind`` matching ``predicate`` from index ``since`` (default:
        from now on), waiting up to ``timeout_s`` of the port's time; None if none came."""
        index = self.mark() if since is None else since
        deadline = self.port.now() + timeout_s
        while True:
            while index < len(self.messages):
                msg = self.messages[index]
                index += 1
                if msg.get_type() == kind and predicate(msg):
                    return msg
            remaining = deadline - self.port.now()
            if remaining <= CLOCK_EPSILON_S:  # (a hair short of it is the deadline)
                if index < len(self.messages) or self.pump(0.0):
                    continue  # arrived by the deadline: look at it first
                return None
            self.pump(min(remaining, 0.05))

    # ------------------------------------------------------------------ commands

    def command(self, command: int, *params: float, timeout_s: float = 1.0) -> Any | None:
        """COMMAND_LONG to the vehicle; its COMMAND_ACK, or None within ``timeout_s``."""
        p = [*params, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0][:7]
        since = self.mark()
        self.mav.command_long_send(*self.target, command, 0, *p)
        return self.wait("COMMAND_ACK", lambda m: m.command == command, timeout_s, since)

    def arm(self, timeout_s: float = 5.0) -> None:
        """Arm, retrying until the vehicle accepts (it waits for its flight controller).

        Raises:
            RuntimeError: not accepted within ``timeout_s``.
        """
        deadline = self.port.now() + timeout_s
        while self.port.now() < deadline:
            ack = self.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, timeout_s=0.5)
            if ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED:
                return
            retry_s = self.port.now() + 0.2
            # wait out the interval, not the first message (to within a virtual clock's rounding)
            while self.port.now() < retry_s - CLOCK_EPSILON_S:
                self.pump(retry_s - self.port.now())
        raise RuntimeError("the vehicle never accepted arming")

    def set_mode(self, mode: Mode, timeout_s: float = 1.0) -> int | None:
        """MAV_CMD_DO_SET_MODE with a Rover mode; the COMMAND_ACK result, or None."""
        ack = self.command(mavlink.MAV_CMD_DO_SET_MODE,
                           mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, int(mode),
                           timeout_s=timeout_s)
        return None if ack is None else int(ack.result)

    def sticks(self, x: int = 0, y: int = 0, r: int = 0, z: int = 500,
               target: int | None = None) -> int:
        """MANUAL_CONTROL (x forward, y right, r clockwise, -1000..1000); returns the index of
        :attr:`messages` from just before it."""
        since = self.mark()
        self.mav.manual_control_send(self.target[0] if target is None else target, x, y, z,
                                     r, 0)
        return since

    def upload(self, items: Sequence[MissionItem], *, legacy: bool = False,
               lose_first: Collection[int] = (), duplicate: bool = False,
               timeout_s: float = 10.0) -> Any:
        """Upload a mission over the mission protocol; returns the vehicle's MISSION_ACK (its
        ``type`` is MAV_MISSION_ACCEPTED = 0 on success).

        Answers every request (re-requests too) with MISSION_ITEM_INT, or the legacy
        MISSION_ITEM (float x/y) with ``legacy``; when the vehicle falls silent for the
        protocol's 1.5 s it starts again with MISSION_COUNT, as ground stations do. For tests
        of a lossy link: the first request for each seq in ``lose_first`` goes unanswered, and
        ``duplicate`` sends every item twice.

        Raises:
            TimeoutError: no MISSION_ACK within ``timeout_s``.
        """
        since = self.mark()
        self.mav.mission_count_send(*self.target, len(items), 0)
        deadline = self.port.now() + timeout_s
        quiet_since = self.port.now()
        lost: set[int] = set()
        index = since
        while self.port.now() < deadline:
            while index < len(self.messages):
                msg = self.messages[index]
                index += 1
                kind = msg.get_type()
                if kind == "MISSION_ACK":
                    return msg
                if kind not in ("MISSION_REQUEST_INT", "MISSION_REQUEST") or not (
                        0 <= msg.seq < len(items)):
                    continue
                quiet_since = self.port.now()
                if msg.seq in lose_first and msg.seq not in lost:
                    lost.add(msg.seq)
                    continue
                for _ in range(2 if duplicate else 1):
                    self._send_item(items[msg.seq], legacy=legacy)
            if self.port.now() - quiet_since > MISSION_TIMEOUT_S:
                self.mav.mission_count_send(*self.target, len(items), 0)
                quiet_since = self.port.now()
            self.pump(0.05)
        raise TimeoutError("mission upload: no MISSION_ACK")

    def download(self, *, legacy: bool = False,
                 timeout_s: float = 3.0) -> list[MissionItem] | None:
        """Download the mission item by item (MISSION_REQUEST_INT, or the legacy
        MISSION_REQUEST with ``legacy``), waiting up to ``timeout_s`` of the port's time for
        each answer; None if the vehicle stops answering."""
        since = self.mark()
        self.mav.mission_request_list_send(*self.target, 0)
        count = self.wait("MISSION_COUNT", timeout_s=timeout_s, since=since)
        if count is None:
            return None
        items = []
        reply = "MISSION_ITEM" if legacy else "MISSION_ITEM_INT"
        for seq in range(count.count):
            since = self.mark()
            if legacy:
                self.mav.mission_request_send(*self.target, seq, 0)
            else:
                self.mav.mission_request_int_send(*self.target, seq, 0)
            msg = self.wait(reply, _seq_is(seq), timeout_s, since)
            if msg is None:
                return None
            items.append(item_from_fields(msg.seq, msg.frame, msg.command, msg.current,
                                          msg.autocontinue,
                                          (msg.param1, msg.param2, msg.param3, msg.param4),
                                          msg.x, msg.y, msg.z, encoded=not legacy))
        self.mav.mission_ack_send(*self.target, mavlink.MAV_MISSION_ACCEPTED, 0)
        return items

    def _send_item(self, it: MissionItem, *, legacy: bool) -> None:
        fields = (it.seq, it.frame, it.command, it.current, it.autocontinue, it.param1,
                  it.param2, it.param3, it.param4)
        if legacy:
            x, y = float_xy(it)
            self.mav.mission_item_send(*self.target, *fields, x, y, it.z, 0)
        else:
            self.mav.mission_item_int_send(*self.target, *fields, it.x, it.y, it.z, 0)


class UdpPort:
    """A real UDP socket on 127.0.0.1 (port 0 by default), in wall-clock time.

    The vehicle reaches it at :attr:`url` (``udpout:127.0.0.1:PORT``).
    """

    def __init__(self, url: str = "udpin:127.0.0.1:0", *, sysid: int = GCS_SYSID,
                 compid: int = GCS_COMPID) -> None:
        self.link: Link = open_link(url, source_system=sysid, source_component=compid,
                                    name="gcs")
        self._selector = selectors.DefaultSelector()
        self._selector.register(self.link.fileno(), selectors.EVENT_READ)
        self.on_time: Callable[[float], None] = lambda now_s: None
        """Called with the time whenever the port waits (the ground station's heartbeat)."""

    @property
    def url(self) -> str:
        """The URL a vehicle uses to reach this ground station."""
        return f"udpout:127.0.0.1:{self.link.local_port}"

    @property
    def mav(self) -> Any:
        """The link's pymavlink ``MAVLink`` (sends as the ground station)."""
        return self.link.mav

    def now(self) -> float:
        """Monotonic seconds."""
        return time.monotonic()

    def pump(self, timeout_s: float) -> list[Any]:
        """Wait up to ``timeout_s`` for a datagram; what arrived."""
        self.on_time(time.monotonic())
        return self.link.read() if self._selector.select(max(0.0, timeout_s)) else []

    def close(self) -> None:
        """Close the socket."""
        self._selector.close()
        self.link.close()


def udp_ground_station(url: str = "udpin:127.0.0.1:0") -> tuple[ScriptedGroundStation, UdpPort]:
    """A scripted ground station on a real UDP socket, and its port (for ``port.url`` and
    ``port.close()``)."""
    port = UdpPort(url)
    gcs = ScriptedGroundStation(port)
    port.on_time = gcs.on_time
    return gcs, port


class SharedUdpPort:
    """One UDP socket for several vehicles, as a ground station behind a router has: each
    vehicle gets a :class:`VehiclePort` (:meth:`view`) that sees only what that vehicle (its
    system id) sent, so one :class:`ScriptedGroundStation` per vehicle can wait, command and
    upload without taking another vehicle's answers for its own."""

    def __init__(self, url: str = "udpin:127.0.0.1:0") -> None:
        self.udp = UdpPort(url)
        self._inbox: dict[int, list[Any]] = {}
        self.unclaimed = 0
        """Messages received from system ids that have no view (dropped)."""

    @property
    def url(self) -> str:
        """The URL a router (or a vehicle) uses to reach this ground station."""
        return self.udp.url

    def view(self, sysid: int) -> VehiclePort:
        """The port of vehicle ``sysid``: it sends on the shared socket (address messages
        with ``target_system = sysid``) and receives only what ``sysid`` sent."""
        self._inbox.setdefault(sysid, [])
        return VehiclePort(self, sysid)

    def take(self, sysid: int, timeout_s: float) -> list[Any]:
        """What ``sysid`` sent, waiting up to ``timeout_s`` for something (returns early);
        what other vehicles sent meanwhile waits in their inboxes."""
        deadline = time.monotonic() + timeout_s
        box = self._inbox[sysid]
        while not box:
            remaining = deadline - time.monotonic()
            for msg in self.udp.pump(max(0.0, remaining)):
                other = self._inbox.get(msg.get_srcSystem())
                if other is None:
                    self.unclaimed += 1
                else:
                    other.append(msg)
            if remaining <= CLOCK_EPSILON_S:  # (a hair short of it is the deadline)
                break
        taken = box[:]
        box.clear()
        return taken

    def close(self) -> None:
        """Close the socket."""
        self.udp.close()


class VehiclePort:
    """One vehicle's share of a :class:`SharedUdpPort` (a :class:`Port`), wall-clock time."""

    def __init__(self, shared: SharedUdpPort, sysid: int) -> None:
        self.shared = shared
        self.sysid = sysid

    @property
    def mav(self) -> Any:
        """The shared socket's pymavlink ``MAVLink`` (sends as the ground station)."""
        return self.shared.udp.mav

    def now(self) -> float:
        """Monotonic seconds."""
        return time.monotonic()

    def pump(self, timeout_s: float) -> list[Any]:
        """Wait up to ``timeout_s`` for a message from this vehicle; what it sent."""
        return self.shared.take(self.sysid, timeout_s)


def fleet_ground_station(sysids: Sequence[int], url: str = "udpin:127.0.0.1:0"
                         ) -> tuple[dict[int, ScriptedGroundStation], SharedUdpPort]:
    """One ground station on one UDP socket for the vehicles ``sysids`` (behind a router):
    a :class:`ScriptedGroundStation` per system id, each addressing its vehicle (component 1),
    and the shared port (``port.url``, ``port.close()``). One HEARTBEAT a second goes out for
    them all, as from one ground station."""
    port = SharedUdpPort(url)
    stations = {sysid: ScriptedGroundStation(port.view(sysid), target=(sysid, 1))
                for sysid in sysids}
    beating = stations[sysids[0]]
    port.udp.on_time = beating.on_time
    return stations, port
