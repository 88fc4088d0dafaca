"""What the tests share: peers played by the test, files and bytes they feed the product, and
waiting on a condition with a deadline.

- Waiting: :func:`wait_until` (wall-clock time, for real processes, threads and sockets;
  virtual time has :meth:`mecanum_mav.sim.lockstep.Lockstep.run_until`), and
  :func:`at_most_every` for what a wait sends meanwhile. Its home is here, not in
  conftest.py: the rigs (sitl.py, clients.py) import it as plain code, which conftest.py (a
  file pytest loads by itself, for fixtures) is not meant to be; conftest.py only re-exports
  it for older imports.
- The flight controller played by the test: :func:`fc_heartbeat` (ArduPilot Rover's
  HEARTBEAT), :class:`FlightControllerEnd` (one connection's end: a socket or a pty master),
  :class:`PtyFlightController` (a board on a serial pty, which can be unplugged),
  :class:`FakeFlightController` (a board on UDP or TCP in a thread of its own) and
  :class:`RawPty` (a pseudo-terminal a device path leads to).
- :class:`PeerPump`: a ground station and a flight controller around a companion on UDP
  loopback, pumped together.
- :class:`ClosedOnExit`: a helper with a ``close()`` is a context manager that closes it.
- :func:`status_texts`, :func:`override_channels`, :func:`mavlink_sender`,
  :class:`Sender` (messages as one sender packs them, decoded as received),
  :func:`write_key_file`, :func:`junk_packets`, and on sockets :func:`deliver` and
  :func:`read_for`; :func:`child_processes` (this process's children).

Sockets bind port 0 on 127.0.0.1; every wait has a deadline (no blind sleeps).
"""

from __future__ import annotations

import contextlib
import math
import os
import select
import selectors
import socket
import struct
import sys
import threading
import time
import tty
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple, Self, TypeVar

from mecanum_mav.io.links import Link, mavlink, open_link
from mecanum_mav.protocol.dialect import mavutil
from mecanum_mav.protocol.heartbeat import send_gcs_heartbeat
from mecanum_mav.protocol.signing import ticks_from_unix
from mecanum_mav.sim.lockstep import Lockstep

if TYPE_CHECKING:
    from mecanum_mav.sim.groundstation import ScriptedGroundStation

T = TypeVar("T")

FC_BEAT_PERIOD_S = 0.1
"""How often the test's flight controllers send HEARTBEAT (s) unless told otherwise."""

# --------------------------------------------------------------------------- waiting


def wait_until(condition: Callable[[], T], timeout_s: float, *,
               pump: Callable[[float], object] | None = None,
               pump_s: float = 0.05) -> T | None:
    """``condition()`` once it returns something true (returned), or None when ``timeout_s``
    of wall-clock time has passed without it.

    Between checks, ``pump(wait_s)`` runs with ``wait_s`` at most ``pump_s`` and never past
    the deadline: it does the test's side of the I/O (read a peer, send a stick) and may wait
    up to ``wait_s`` for something to arrive. Without ``pump``, 10 ms pass (another thread or
    process makes the condition true).
    """
    deadline = time.monotonic() + timeout_s
    while True:
        result = condition()
        if result:
            return result
        left = deadline - time.monotonic()
        if left <= 0.0:
            return None
        if pump is None:
            threading.Event().wait(min(0.01, left))
        else:
            pump(min(pump_s, left))


def at_most_every(period_s: float, action: Callable[[], object]) -> Callable[[], None]:
    """A function that runs ``action`` when called, at most once per ``period_s`` of
    wall-clock time (the first call runs it): a stick stream or a heartbeat in a
    :func:`wait_until` pump. Late calls do not catch up with a burst."""
    next_s = -math.inf

    def call() -> None:
        nonlocal next_s
        now = time.monotonic()
        if now >= next_s:
            next_s = now + period_s
            action()

    return call


def read_for(fileno: int, read: Callable[[], Sequence[T]], timeout_s: float, *,
             enough: int = 1, settle_s: float = math.inf) -> list[T]:
    """Everything ``read()`` gives each time ``fileno`` has input, for up to ``timeout_s`` of
    wall-clock time, or until ``settle_s`` after the ``enough``-th item (the rest of a
    burst)."""
    out: list[T] = []
    deadline = time.monotonic() + timeout_s
    while (left := deadline - time.monotonic()) > 0 and select.select([fileno], [], [], left)[0]:
        out += read()
        if len(out) >= enough:
            deadline = min(deadline, time.monotonic() + settle_s)
    return out


def deliver(link: Link, sock: socket.socket, data: bytes) -> list[Any]:
    """Send ``data`` from ``sock`` to ``link`` (on 127.0.0.1) and read it there once it has
    arrived: what the link kept."""
    sock.sendto(data, ("127.0.0.1", link.local_port))
    assert select.select([link.fileno()], [], [], 2.0)[0], "the datagram never arrived"
    return link.read()


# --------------------------------------------------------------------------- messages


def status_texts(h: Lockstep | ScriptedGroundStation, since: int = 0) -> list[str]:
    """The STATUSTEXTs the ground station (a harness's, or ``h`` itself) received from index
    ``since`` (of its messages) on, what has arrived until now included."""
    gcs = h.gcs if isinstance(h, Lockstep) else h
    gcs.mark()  # collect what has arrived (a real port; the harness delivers by itself)
    return [m.text for m in gcs.received("STATUSTEXT", since)]


def mavlink_sender(key: bytes | None = None, *, sysid: int = 255, compid: int = 190,
                   link_id: int = 0, timestamp: int | None = None) -> Any:
    """A pymavlink ``MAVLink`` that packs as ``sysid``/``compid`` (a ground station's by
    default): unsigned, or signing with ``key`` on link ``link_id`` from ``timestamp`` (10 us
    ticks since 2015; default now), as MAVProxy's ``signing key`` sets one up."""
    mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    if key is not None:
        mav.signing.secret_key, mav.signing.sign_outgoing = key, True
        mav.signing.link_id = link_id
        mav.signing.timestamp = ticks_from_unix(time.time()) if timestamp is None else timestamp
    return mav


class Sender:
    """Messages as one MAVLink sender (system, component) packs them, decoded as received:
    ``Sender(1, 1)("heartbeat", ...)`` is the HEARTBEAT a ground station reads."""

    def __init__(self, sysid: int, compid: int) -> None:
        self.mav = mavlink_sender(sysid=sysid, compid=compid)

    def __call__(self, build: str, *args: Any, **fields: Any) -> Any:
        data = getattr(self.mav, f"{build}_encode")(*args, **fields).pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) % 256
        return mavlink.MAVLink(None).decode(bytearray(data))


def child_processes() -> set[int]:
    """The process ids whose parent is this process (Linux /proc)."""
    mine = os.getpid()
    found = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue  # (ended meanwhile)
        if int(stat.rsplit(")", 1)[1].split()[1]) == mine:
            found.add(int(entry.name))
    return found


def lane_answers(link: Link) -> list[bytes]:
    """Every datagram ``link``'s loop answers in the stick lane from now on (it calls
    ``link.answered``, which still counts it): a list that fills as they come."""
    answered: list[bytes] = []
    real_answered = link.answered

    def spy(data: bytes, address: object) -> None:
        answered.append(data)
        real_answered(data, address)

    link.answered = spy  # type: ignore[method-assign]
    return answered


def override_channels(msg: Any) -> list[int]:
    """The 18 ``chanN_raw`` fields of an RC_CHANNELS_OVERRIDE (us; 0 and 65535 as sent)."""
    return [getattr(msg, f"chan{i}_raw") for i in range(1, 19)]


def junk_packets(packet: bytes) -> list[bytes]:
    """What a broken radio delivers, one datagram each: random bytes, a run of start bytes,
    and cut or padded copies of ``packet`` (a valid MAVLink 2 packet)."""
    return [bytes(range(256)), b"\xfd" * 300, packet[:7], packet[:-3], b"\xfd\x09\x00\x00",
            packet[:10] + b"\x00" * 50]


def write_key_file(path: Path, key: str | bytes, mode: int = 0o600) -> Path:
    """Write a signing-key file (``key`` as it stands in the file: a passphrase or 64 hex
    digits, with its newline if it has one; bytes as they are) with permissions ``mode``;
    returns ``path``."""
    path.write_bytes(key.encode() if isinstance(key, str) else key)
    path.chmod(mode)
    return path


class ClosedOnExit:
    """A base for the test's peers and relays: ``with Peer(...) as peer:`` calls
    :meth:`close` at the end, however the block ends."""

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# --------------------------------------------------------------------------- the board


def fc_heartbeat(mav: Any) -> Any:
    """ArduPilot Rover's HEARTBEAT (ground rover, ArduPilot, standby), for ``mav`` to send:
    ``mav.send(fc_heartbeat(mav))`` or ``fc_heartbeat(mav).pack(mav)``."""
    return mav.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,
                                mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0,
                                mavlink.MAV_STATE_STANDBY)


@contextlib.contextmanager
def tcp_link_to_a_board(sysid: int = 255, compid: int = 190) -> Iterator[tuple[Link,
                                                                             socket.socket]]:
    """A ``tcp:`` link (named "fc", sending as ``sysid``/``compid``) connected to a listening
    socket of the test's: the link and the board's end of the connection; both closed after."""
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        link = open_link(f"tcp:127.0.0.1:{server.getsockname()[1]}", source_system=sysid,
                         source_component=compid, name="fc")
        board, _ = server.accept()
        try:
            yield link, board
        finally:
            board.close()
            link.close()


class RawPty:
    """A pseudo-terminal in raw mode (no echo, no line editing, no CR/LF translation): the
    far end opens :attr:`path` (the slave), the test reads and writes :attr:`master`
    (non-blocking). The slave stays open here too, so the master never reads EIO because the
    far end closed it. With ``link``, :attr:`path` is that symlink to the device (as udev's
    /dev/serial/by-id names are)."""

    def __init__(self, link: Path | None = None) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.device = os.ttyname(self.slave)
        self.link = link
        if link is not None:
            link.symlink_to(self.device)
        self.path = str(link) if link is not None else self.device
        self.closed = False

    def close(self) -> None:
        """Remove the symlink and close both ends (the far end then reads EIO); idempotent."""
        if self.link is not None:
            self.link.unlink(missing_ok=True)
        if not self.closed:
            self.closed = True
            for fd in (self.master, self.slave):
                with contextlib.suppress(OSError):
                    os.close(fd)


class FlightControllerEnd:
    """The flight controller's end of one connection (a socket, or a pty's master): each
    :meth:`pump` sends HEARTBEAT when ``beat_period_s`` has passed since the last, then
    parses everything the companion sent into :attr:`messages`.

    Args:
        fileno: what to wait on for input.
        read: reads what is there (raises BlockingIOError or returns b"" when nothing is).
        write: writes bytes.
        close: closes the connection.
        beat_period_s: HEARTBEAT period (s); 0 sends one every pump, ``math.inf`` none.
    """

    def __init__(self, fileno: int, read: Callable[[], bytes], write: Callable[[bytes], Any],
                 close: Callable[[], None], beat_period_s: float = FC_BEAT_PERIOD_S) -> None:
        self._fileno, self._read, self._write, self._close = fileno, read, write, close
        self.beat_period_s = beat_period_s
        self.mav: Any = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self.mav.robust_parsing = True
        self.messages: list[Any] = []
        """Everything the companion sent, oldest first (no BAD_DATA)."""
        self.first_byte_s: float | None = None
        """When the first byte arrived (monotonic s)."""
        self._beat_s = -math.inf

    @classmethod
    def on_socket(cls, sock: socket.socket,
                  beat_period_s: float = FC_BEAT_PERIOD_S) -> FlightControllerEnd:
        """The end of a connected stream socket (made non-blocking)."""
        sock.setblocking(False)
        return cls(sock.fileno(), lambda: sock.recv(4096), sock.send, sock.close,
                   beat_period_s)

    def beat(self) -> None:
        """Send HEARTBEAT now."""
        self._beat_s = time.monotonic()
        self._write(fc_heartbeat(self.mav).pack(self.mav))

    def pump(self, wait_s: float = 0.0) -> None:
        """HEARTBEAT if due, then everything that arrived, waiting up to ``wait_s`` for the
        first byte."""
        if time.monotonic() - self._beat_s >= self.beat_period_s:
            self.beat()
        if wait_s > 0.0:
            select.select([self._fileno], [], [], wait_s)
        while True:
            try:
                data = self._read()
            except (BlockingIOError, InterruptedError):
                return
            if not data:
                return
            if self.first_byte_s is None:
                self.first_byte_s = time.monotonic()
            self.messages += [m for m in self.mav.parse_buffer(data) or []
                              if m.get_type() != "BAD_DATA"]

    def overrides(self) -> list[list[int]]:
        """The 18 channels of every RC_CHANNELS_OVERRIDE received, oldest first."""
        return [override_channels(m) for m in self.messages
                if m.get_type() == "RC_CHANNELS_OVERRIDE"]

    def close(self) -> None:
        self._close()


class PtyFlightController(FlightControllerEnd):
    """A flight controller on a serial cable: a :class:`FlightControllerEnd` on a
    :class:`RawPty`'s master. The companion opens :attr:`path` (``link``, a symlink, when
    given); :meth:`unplug` is the USB cable pulled."""

    def __init__(self, link: Path | None = None,
                 beat_period_s: float = FC_BEAT_PERIOD_S) -> None:
        self.pty = pty = RawPty(link)
        self.path = pty.path
        super().__init__(pty.master, lambda: os.read(pty.master, 4096),
                         lambda data: os.write(pty.master, data), pty.close, beat_period_s)

    def unplug(self) -> None:
        """The device node vanishes and the pty closes: the companion's end reads EIO."""
        self.pty.close()


class Override(NamedTuple):
    """One RC_CHANNELS_OVERRIDE as the board received it: monotonic s, channels 1-4 (us)."""

    time_s: float
    wheels: tuple[int, int, int, int]


class FakeFlightController(ClosedOnExit):
    """A flight controller on a real socket (127.0.0.1, port 0), in a thread of its own, that
    the companion reaches at :attr:`url`: UDP (``udpout:``) or TCP (it listens, the companion
    connects with ``tcp:``, a stream link as a serial board is). It sends a 5 Hz HEARTBEAT to
    whoever reached it and records every RC_CHANNELS_OVERRIDE with its arrival time."""

    HEARTBEAT_PERIOD_S = 0.2

    def __init__(self, kind: str = "udp", sysid: int = 1, compid: int = 1) -> None:
        self.tcp = kind == "tcp"
        self.sock = socket.socket(socket.AF_INET,
                                  socket.SOCK_STREAM if self.tcp else socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        if self.tcp:
            self.sock.listen(1)
        self.url = f"{'tcp' if self.tcp else 'udpout'}:127.0.0.1:{self.sock.getsockname()[1]}"
        self._conn: socket.socket | None = None
        self.mav: Any = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.overrides: list[Override] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        parser: Any = mavlink.MAVLink(None)
        peer = None
        next_beat = 0.0
        while not self._stop.is_set():
            now = time.monotonic()
            if peer is not None and now >= next_beat:
                beat = fc_heartbeat(self.mav).pack(self.mav)
                with contextlib.suppress(OSError):
                    if self._conn is not None:
                        self._conn.sendall(beat)
                    else:
                        self.sock.sendto(beat, peer)
                next_beat = now + self.HEARTBEAT_PERIOD_S
            try:
                if self.tcp and self._conn is None:
                    self._conn, peer = self.sock.accept()
                    self._conn.settimeout(0.05)
                    continue
                if self._conn is not None:
                    data = self._conn.recv(65536)
                    if not data:  # the companion closed the connection
                        self._conn.close()
                        self._conn = None
                        continue
                else:
                    data, peer = self.sock.recvfrom(65536)
            except (TimeoutError, OSError):
                continue
            arrived = time.monotonic()
            for msg in parser.parse_buffer(data) or []:
                if msg.get_type() == "RC_CHANNELS_OVERRIDE":
                    wheels = (msg.chan1_raw, msg.chan2_raw, msg.chan3_raw, msg.chan4_raw)
                    with self._lock:
                        self.overrides.append(Override(arrived, wheels))

    def received(self) -> list[Override]:
        """The overrides received so far, oldest first."""
        with self._lock:
            return list(self.overrides)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        if self._conn is not None:
            self._conn.close()
        self.sock.close()


# --------------------------------------------------------------------------- both peers


class PeerPump:
    """A ground station and a flight controller around a companion on UDP loopback, each on a
    port of its own that the companion sends to (:attr:`gcs_url`, :attr:`fc_url`).

    The ground station is pymavlink as a script sets it up (``gcs_key``: signing with it);
    the flight controller a :class:`~mecanum_mav.io.links.Link`. :meth:`pump` reads both and
    sends each one's HEARTBEAT every ``*_beat_period_s`` while it is beating
    (:attr:`gcs_beating`, :attr:`fc_beating`; the flight controller only once it has heard the
    companion, as a ``udpin`` link answers the address it last heard); :attr:`gcs_beat_s`
    and :attr:`fc_beat_s` are when each last went out (monotonic s). Everything the ground
    station receives is kept in :attr:`received` with its arrival time in :attr:`arrived_s`;
    the flight controller keeps channels 1-4 of each override in :attr:`overrides`.
    """

    def __init__(self, gcs_url: str = "udpin:127.0.0.1:0", *, gcs_key: bytes | None = None,
                 gcs_beat_period_s: float = 1.0,
                 fc_beat_period_s: float = FC_BEAT_PERIOD_S) -> None:
        self.gcs: Any = mavutil.mavlink_connection(
            gcs_url, source_system=255, source_component=mavlink.MAV_COMP_ID_MISSIONPLANNER)
        if gcs_key is not None:
            self.gcs.setup_signing(gcs_key, sign_outgoing=True)
        self.fc: Link = open_link("udpin:127.0.0.1:0", source_system=1, source_component=1,
                                  name="test-fc")
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.gcs.fd, selectors.EVENT_READ, "gcs")
        self.selector.register(self.fc.fileno(), selectors.EVENT_READ, "fc")
        self.gcs_beat_period_s, self.fc_beat_period_s = gcs_beat_period_s, fc_beat_period_s
        self.gcs_beating = self.fc_beating = True
        self.gcs_beat_s = self.fc_beat_s = -math.inf
        self.received: list[Any] = []
        self.arrived_s: list[float] = []
        """When each of :attr:`received` arrived (monotonic s)."""
        self.overrides: list[list[int]] = []
        self._fc_heard = False

    @property
    def gcs_url(self) -> str:
        """The companion's ``--gcs`` for this ground station."""
        return f"udpout:127.0.0.1:{self.gcs.port.getsockname()[1]}"

    @property
    def fc_url(self) -> str:
        """The companion's ``--fc`` for this flight controller."""
        return f"udpout:127.0.0.1:{self.fc.local_port}"

    def pump(self, wait_s: float = 0.02) -> None:
        """Beat what is due, then wait up to ``wait_s`` for either peer and read it."""
        now = time.monotonic()
        if self.gcs_beating and now - self.gcs_beat_s >= self.gcs_beat_period_s:
            self.gcs_beat_s = now
            send_gcs_heartbeat(self.gcs.mav)
        if (self.fc_beating and self._fc_heard
                and now - self.fc_beat_s >= self.fc_beat_period_s):
            self.fc_beat_s = now
            self.fc.mav.send(fc_heartbeat(self.fc.mav))
        for key, _ in self.selector.select(max(0.0, wait_s)):
            if key.data == "fc":
                self._fc_heard = True
                self.overrides += [override_channels(m)[:4] for m in self.fc.read()
                                   if m.get_type() == "RC_CHANNELS_OVERRIDE"]
            else:
                while (msg := self.gcs.recv_msg()) is not None:
                    self.received.append(msg)
                    self.arrived_s.append(time.monotonic())

    def run_until(self, done: Callable[[], object], timeout_s: float) -> bool:
        """Pump until ``done()`` is true (True) or ``timeout_s`` has passed (False)."""
        return bool(wait_until(done, timeout_s, pump=self.pump, pump_s=0.02))

    def seen(self, kind: str, since: int = 0,
             predicate: Callable[[Any], bool] = lambda m: True) -> list[Any]:
        """The ``kind`` messages the ground station received from index ``since`` on that
        ``predicate`` takes."""
        return [m for m in self.received[since:] if m.get_type() == kind and predicate(m)]

    def said_since(self, text: str, since_s: float) -> float | None:
        """When a STATUSTEXT containing ``text`` first arrived at or after ``since_s``."""
        return next((t for t, m in zip(self.arrived_s, self.received, strict=True)
                     if t >= since_s and m.get_type() == "STATUSTEXT" and text in m.text),
                    None)

    def close(self) -> None:
        self.selector.close()
        self.gcs.close()
        self.fc.close()


def not_installed(monkeypatch: Any, package: str, *also_gone: str) -> None:
    """Make ``import package`` raise ImportError for the rest of the test, as on a machine
    without it (its submodules and ``also_gone``, modules already imported that hold it,
    forgotten too)."""
    for name in [m for m in sys.modules if m == package or m.startswith(package + ".")]:
        monkeypatch.delitem(sys.modules, name)
    for name in also_gone:
        monkeypatch.delitem(sys.modules, name, raising=False)
    monkeypatch.setitem(sys.modules, package, None)


def png_size_and_dpi(path: Path) -> tuple[int, int, float]:
    """(width px, height px, dots per inch) of the PNG at ``path``, from its header and its
    pHYs chunk (what matplotlib writes for ``dpi``)."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", data[16:24])
    phys = data.index(b"pHYs")
    per_metre, _, unit = struct.unpack(">IIB", data[phys + 4:phys + 13])
    assert unit == 1  # metres
    return width, height, per_metre * 0.0254
