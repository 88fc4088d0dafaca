"""Real pymavlink peers on 127.0.0.1 for tests: a ground station and a flight controller.

Each peer listens on its own port 0 socket (``udpin:127.0.0.1:0``); the companion under test
connects ``udpout`` to it. Waiting is always on a condition with a deadline, never a blind sleep.
"""

from __future__ import annotations

import selectors
import threading
import time
from collections.abc import Callable
from typing import Any

from mecanum_mav.io.links import Link, mavlink, open_link


class Peer:
    """A MAVLink endpoint that records what it receives and sends HEARTBEAT at 2 Hz.

    Clear :attr:`beating` to fall silent (link-loss tests), set it to resume.
    """

    def __init__(self, name: str, sysid: int, compid: int, mav_type: int) -> None:
        self.link: Link = open_link("udpin:127.0.0.1:0", source_system=sysid,
                                    source_component=compid, name=name)
        self.messages: list[Any] = []
        self._selector = selectors.DefaultSelector()
        self._selector.register(self.link.fileno(), selectors.EVENT_READ)
        self.mav_type = mav_type
        self.beating = threading.Event()
        self.beating.set()
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._beat, daemon=True)
        self._thread.start()

    def _beat(self) -> None:
        while not self._closed.wait(0.5):
            if self.beating.is_set():
                self.mav.heartbeat_send(self.mav_type, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 4)

    @property
    def url(self) -> str:
        """The URL the companion uses to reach this peer."""
        return f"udpout:127.0.0.1:{self.link.local_port}"

    @property
    def mav(self) -> Any:
        return self.link.mav

    def pump(self, timeout_s: float) -> None:
        """Receive whatever arrives within ``timeout_s``."""
        if self._selector.select(timeout_s):
            self.messages.extend(self.link.read())

    def wait(self, mtype: str, predicate: Callable[[Any], bool] = lambda m: True,
             timeout_s: float = 3.0, since: int = 0) -> Any | None:
        """The first message of ``mtype`` (from index ``since``) matching ``predicate``."""
        deadline = time.monotonic() + timeout_s
        index = since
        while True:
            while index < len(self.messages):
                msg = self.messages[index]
                index += 1
                if msg.get_type() == mtype and predicate(msg):
                    return msg
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            self.pump(min(remaining, 0.05))

    def mark(self) -> int:
        """An index to wait from: only messages after this point."""
        self.pump(0.0)
        return len(self.messages)

    def overrides(self, since: int = 0) -> list[Any]:
        """RC_CHANNELS_OVERRIDE messages received from index ``since``."""
        self.pump(0.0)
        return [m for m in self.messages[since:] if m.get_type() == "RC_CHANNELS_OVERRIDE"]

    def close(self) -> None:
        self._closed.set()
        self._thread.join(2.0)
        self._selector.close()
        self.link.close()


def ground_station() -> Peer:
    """A ground station peer: system 255, component 190 (as Mission Planner / MAVProxy)."""
    return Peer("gcs", 255, 190, mavlink.MAV_TYPE_GCS)


def flight_controller(sysid: int = 1) -> Peer:
    """A flight-controller peer: system 1, component 1."""
    return Peer("fc", sysid, 1, mavlink.MAV_TYPE_GROUND_ROVER)


def channels(msg: Any) -> list[int]:
    """The 18 chanN_raw fields of an RC_CHANNELS_OVERRIDE."""
    return [getattr(msg, f"chan{i}_raw") for i in range(1, 19)]
