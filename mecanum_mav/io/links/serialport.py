"""Serial links: :class:`SerialLink`, a device such as ``/dev/ttyUSB0,57600`` (pyserial),
paced to its baud rate; reopened by its path when it vanished.

Pacing (times in seconds on the link's clock): the wire carries ``baud / 10`` bytes/s (8N1,
:attr:`SerialLink.bytes_per_s`); a packet goes to the kernel only when what was handed over
would be on the wire within :data:`~mecanum_mav.io.links.stream.PACING_LEAD_S`, judged from
the baud rate (the time the bytes handed over need on the wire) and from the tty's own
output queue (``TIOCOUTQ``), whichever is longer; a pty, a USB-CDC board or any device faster
than its nominal rate is thus paced to the nominal rate too. At most :data:`QUEUE_S` of the
wire (at least :data:`QUEUE_MIN_BYTES`) waits in the link besides the newest override.
The stick lane's packet (``takes_packet``, ``send_packet``) is judged by the baud rate alone,
and the kernel's queue read after it, at most every :data:`KERNEL_LOOK_S`.

A device that vanishes (USB unplugged, board rebooting: reads and writes fail with
EIO/ENXIO) puts the link down ("device gone"); its port is closed, and the same path is
opened again, as pymavlink opens it, once it exists.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import select
import termios
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar

import serial

from mecanum_mav.io.links.base import READ_CHUNK
from mecanum_mav.io.links.stream import PACING_LEAD_S, StreamLink, queued_bytes, ready_within

log = logging.getLogger("mecanum_mav.io.links")

__all__ = ["KERNEL_LOOK_S", "QUEUE_MIN_BYTES", "QUEUE_S", "SerialLink"]

QUEUE_S = 1.0
"""A serial link queues at most this much wire time (seconds; at least
:data:`QUEUE_MIN_BYTES`) of packets other than the newest override; more is dropped."""
QUEUE_MIN_BYTES = 4096
KERNEL_LOOK_S = 0.01
"""The stick lane's packets go to the kernel judged by the baud rate alone; after them the
link asks the kernel what it still holds (``TIOCOUTQ``) at most this often (seconds): a
device slower than its baud rate can run ahead of it by at most this much of the lane's
packets before the link follows the device."""


class SerialLink(StreamLink):
    """A serial device (module description)."""

    gone_reason: ClassVar[str] = "device gone"

    def __init__(self, conn: Any, *, url: str, name: str, signing_key: bytes | None,
                 clock: Callable[[], float]) -> None:
        baud = int(conn.baud)  # (pymavlink's: the URL's, 115200 where it gives none)
        if baud <= 0:
            raise ValueError(f"baud rate {baud}: a serial link needs a positive one")
        self.bytes_per_s = baud / 10.0
        """The wire's capacity: 8N1 at the URL's baud rate (bytes/s)."""
        self._wire_free_s = 0.0  # when what was handed over is on the wire (clock s)
        self._next_look_s = -math.inf  # when the lane's path next asks the kernel (clock s)
        limit = max(QUEUE_MIN_BYTES, int(QUEUE_S * self.bytes_per_s))
        super().__init__(conn, url=url, name=name, signing_key=signing_key, clock=clock,
                         queue_limit=limit)

    def _current_port_fd(self) -> int:
        fd = super()._current_port_fd()
        if fd >= 0:
            # pyserial (3.5) opens it non-blocking already and its write() waits in select;
            # ours must never wait, whatever opened the port
            os.set_blocking(fd, False)
        return fd

    def _read_port(self) -> bytes:
        """What the device holds, read from its non-blocking descriptor (pyserial's read()
        waits in ``select()``, which refuses a descriptor past 1023: a process with many files
        open). Nothing from a device said readable is the device gone, as pyserial says."""
        if not ready_within(self._port_fd, select.POLLIN, 0.0):  # (the tty, VMIN 0, reads
            return b""  # b"" when it holds nothing)
        data = os.read(self._port_fd, READ_CHUNK)
        if not data:
            raise OSError("device reports readiness to read but returned no data "
                          "(device disconnected?)")
        return data

    def _write_port(self, data: bytes) -> int:
        return os.write(self._port_fd, data)

    def _backlog_s(self, now: float) -> float:
        rate = self.bytes_per_s
        in_kernel = queued_bytes(self._port_fd, termios.TIOCOUTQ)
        if in_kernel:  # the device is slower than its baud rate says: follow the device
            self._wire_free_s = max(self._wire_free_s, now + in_kernel / rate)
        return self._wire_free_s - now - PACING_LEAD_S

    def _free_in_s(self, now: float) -> float:
        """From the baud rate alone; :meth:`_sent_now` follows the device after the write."""
        return self._wire_free_s - now - PACING_LEAD_S

    def _sent_now(self, now: float) -> None:
        """After the lane's write: what the kernel holds, at most every
        :data:`KERNEL_LOOK_S` (a syscall costs about as much as the write)."""
        if now >= self._next_look_s:
            self._next_look_s = now + KERNEL_LOOK_S
            self._backlog_s(now)  # a device slower than its baud rate: follow the device

    def _handed(self, n: int, now: float) -> None:
        self._wire_free_s = max(self._wire_free_s, now) + n / self.bytes_per_s

    def _drop_pending(self) -> None:
        super()._drop_pending()
        self._wire_free_s = 0.0

    def _reopen(self, now_s: float) -> bool:
        conn = self.conn
        if not Path(conn.device).exists():
            return False
        try:  # as pymavlink opens it: at 1200 baud first (a Linux driver bug), then the rate;
            # pyserial's defaults: no RTS/CTS, DSR/DTR or XON/XOFF flow control
            port = serial.Serial(conn.device, 1200, timeout=0)
        except (OSError, ValueError) as exc:  # not ready yet (permissions, enumeration)
            log.debug("%s: reopening %s failed: %s", self.name, conn.device, exc)
            return False
        with contextlib.suppress(OSError):
            conn.port.close()
        conn.port = port
        conn.set_baudrate(conn.baud)
        conn.fd = port.fileno()  # (not inherited by child processes: Python's default)
        return True

    def _flush_out(self, linger_s: float) -> None:
        """pyserial waits until what was handed over is sent (at most
        :data:`~mecanum_mav.io.links.stream.PACING_LEAD_S` and a packet after the pacing).
        A device gone meanwhile raises ``OSError`` (its ``tcdrain`` raises ``termios.error``,
        which is none)."""
        try:
            self.conn.port.flush()
        except termios.error as exc:
            raise OSError(*exc.args) from exc
