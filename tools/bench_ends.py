"""The ends of each path that ``tools/bench_latency.py`` times, and the cores it pins them to.

A *path* is the transport pair the companion is started with:

- ``udpout``: ``--gcs udpout:`` and ``--fc udpout:`` (the companion sends first; the
  harness listens on both), the run ``bench_latency`` always made;
- ``udpin``: ``--gcs udpin:`` (the companion listens; the harness's ground station sends to
  the companion's port from its own, as a ground station connects to a rover), ``--fc
  udpout:``;
- ``serial``: ``--gcs udpout:``, ``--fc PTY,BAUD``: the flight controller is the master end
  of a pseudo-terminal (:class:`PtyBoard`, played by the harness), the companion opens its
  slave end as a serial device.

Each path's floor relay (``bench_latency.run_floor``) opens the same transports as the
companion does (:func:`open_floor_gcs`, :func:`open_floor_fc`), so the ratio to it measures
what the companion adds on that path, not the transport.

Pinning (:func:`core_split`): on a machine with two or more cores the harness runs on one and
every system under test on another (the floor relay and the companion alike), so the two do not
compete for a core and runs on the same machine compare.
"""

from __future__ import annotations

import contextlib
import functools
import os
import socket
import termios
import tty
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mecanum_mav.protocol.dialect import mavlink

PATHS = ("udpout", "udpin", "serial")
SERIAL_BAUD = 921_600
"""The serial path's baud rate: ArduPilot's usual rate for a companion computer (SERIALn_BAUD
921). 8N1 carries 92,160 bytes/s: a 30-byte override is 0.33 ms on the wire, so 1 kHz sticks
fit (a third of the wire) and the companion's pacing (it hands the kernel the next packet when
what it holds would be on the wire within 2 ms) never holds an override back. At 115,200 baud an
override is 2.6 ms on the wire: 1 kHz input would be mostly superseded (newest wins) and the
delays would be the wire's, not the companion's."""
LOOPBACK = "127.0.0.1"


# ---------------------------------------------------------------------------- cores

@dataclass(frozen=True)
class CoreSplit:
    """Which cores the harness and the systems under test run on (None: not pinned)."""

    harness: frozenset[int] | None
    sut: frozenset[int] | None

    def describe(self) -> str:
        if self.harness is None or self.sut is None:
            return "not pinned"
        return (f"harness on core {','.join(map(str, sorted(self.harness)))}, systems under "
                f"test on core {','.join(map(str, sorted(self.sut)))}")


NOT_PINNED = CoreSplit(None, None)


def core_split(pin: bool) -> CoreSplit:
    """The harness on the first core this process may use, the systems under test on the
    second (none pinned when ``pin`` is false or only one core is available)."""
    cores = sorted(os.sched_getaffinity(0))
    if not pin or len(cores) < 2:
        return NOT_PINNED
    return CoreSplit(frozenset(cores[:1]), frozenset(cores[1:2]))


def pin_self(cores: frozenset[int] | None) -> None:
    """Pin this process to ``cores``: every thread it has (numpy's BLAS starts some at
    import) and, inheriting it, every thread and process it starts afterwards; None: leave
    it."""
    if cores is None:
        return
    for task in Path("/proc/self/task").iterdir():
        with contextlib.suppress(OSError):  # (a thread that ended meanwhile)
            os.sched_setaffinity(int(task.name), cores)
    os.sched_setaffinity(0, cores)


# ---------------------------------------------------------------------------- the harness's board

class PtyBoard:
    """The flight controller's end of a serial line: the master end of a pty (raw: no echo,
    no CR/LF translation), non-blocking. The slave end stays open here too, so the master
    never reads EIO while the system under test opens and closes it. :attr:`url` is what the
    system under test is given (``/dev/pts/N,BAUD``); :attr:`mav` packs and parses as the
    board (``source_system``, ``source_component``)."""

    def __init__(self, baud: int = SERIAL_BAUD, source_system: int = 1,
                 source_component: int = 1) -> None:
        self.mav = mavlink.MAVLink(None, srcSystem=source_system, srcComponent=source_component)
        self.mav.robust_parsing = True
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self.url = f"{self.path},{baud}"

    def fileno(self) -> int:
        return self.master

    def read(self, size: int) -> bytes:
        """What waits (at most ``size`` bytes); b"" when nothing does or no one is there."""
        try:
            return os.read(self.master, size)
        except OSError:  # BlockingIOError: nothing waits; EIO: no slave open
            return b""

    def write(self, data: bytes) -> None:
        with contextlib.suppress(OSError):
            os.write(self.master, data)

    def close(self) -> None:
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)


# ---------------------------------------------------------------------------- the floor's ends

def open_floor_gcs(url: str) -> tuple[socket.socket, bool]:
    """The floor relay's ground-station socket, non-blocking, and whether it listens:
    ``udpout:HOST:PORT`` connected there, ``udpin:HOST:PORT`` bound there (port 0: the OS
    picks one, see ``getsockname``)."""
    scheme, host, port = url.split(":")
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    if scheme == "udpin":
        sock.bind((host, int(port)))
    else:
        sock.connect((host, int(port)))
    sock.setblocking(False)
    return sock, scheme == "udpin"


def open_floor_fc(url: str) -> tuple[Callable[[bytes], object], Callable[[], None]]:
    """The floor relay's flight-controller end: (send one packet, close). ``udpout:HOST:PORT``
    is a connected UDP socket; anything else is a serial device ``PATH,BAUD``, opened raw and
    non-blocking at that baud rate, written with ``os.write`` (a full device drops the
    packet: the send raises, the floor carries on)."""
    if url.startswith("udpout:"):
        _, host, port = url.split(":")
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.connect((host, int(port)))
        sock.setblocking(False)
        return sock.send, sock.close
    path, _, baud = url.partition(",")
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(fd)
    speed = getattr(termios, f"B{int(baud or SERIAL_BAUD)}")
    attrs = termios.tcgetattr(fd)
    attrs[4] = attrs[5] = speed
    termios.tcsetattr(fd, termios.TCSANOW, attrs)
    return functools.partial(os.write, fd), functools.partial(os.close, fd)
