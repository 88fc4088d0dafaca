"""A stand-in flight controller on a real socket (127.0.0.1, port 0) for process tests: UDP
(the companion sends to it, ``udpout:``) or TCP (it listens, the companion connects with
``tcp:``, a stream link as a serial board is). It sends a 5 Hz HEARTBEAT (an ArduPilot Rover)
to whoever reached it and records every RC_CHANNELS_OVERRIDE it receives, with its arrival
time."""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from typing import Any, NamedTuple

from mecanum_mav.io.links import mavlink

HEARTBEAT_PERIOD_S = 0.2


class Override(NamedTuple):
    """One RC_CHANNELS_OVERRIDE as the board received it: monotonic s, channels 1-4 (us)."""

    time_s: float
    wheels: tuple[int, int, int, int]


class FakeFlightController:
    """A flight controller the companion reaches at :attr:`url` (``udpout:`` or ``tcp:``)."""

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
                beat = self.mav.heartbeat_encode(mavlink.MAV_TYPE_GROUND_ROVER,
                                                 mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0,
                                                 mavlink.MAV_STATE_STANDBY)
                with contextlib.suppress(OSError):
                    if self._conn is not None:
                        self._conn.sendall(beat.pack(self.mav))
                    else:
                        self.sock.sendto(beat.pack(self.mav), peer)
                next_beat = now + HEARTBEAT_PERIOD_S
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

    def __enter__(self) -> FakeFlightController:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
