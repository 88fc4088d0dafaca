"""A flight controller for ``setup-fc``'s tests, in-process on a simulated clock
(mecanum_mav.app.setupfc): the session's waits move the clock, the board answers 10 ms after
each message, so the time each message was sent at is exact."""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import pytest

from mecanum_mav.app import setupfc
from mecanum_mav.protocol.dialect import mavlink

_FC_SESSION = setupfc.FcSession
START_S = 1000.0
LATENCY_S = 0.01
REAL32, INT16 = mavlink.MAV_PARAM_TYPE_REAL32, mavlink.MAV_PARAM_TYPE_INT16


class Clock:
    """The session's clock: it moves only while the session waits (at least 1 us a wait, as a
    real one would), in whole microseconds (so 0.1 s steps add up exactly)."""

    def __init__(self) -> None:
        self.now = START_S

    def monotonic(self) -> float:
        return self.now

    def advance_to(self, t: float) -> None:
        self.now = round(max(t, self.now + 1e-6), 6)

    def sleep(self, s: float) -> None:
        self.advance_to(self.now + s)


@dataclass
class Board:
    """ArduPilot as setup-fc sees it (system 1, component 1): parameters read and set (each
    set echoed with the value it kept), SYSTEM_TIME on request, and a reboot."""

    clock: Clock
    params: dict[str, tuple[float, int]] = field(default_factory=dict)
    drop_sets: dict[str, int] = field(default_factory=dict)
    drop_reads: dict[str, int] = field(default_factory=dict)
    keeps: dict[str, float] = field(default_factory=dict)
    tells_time: bool = True
    silent_until_reboot: bool = False
    """It does not answer REQUEST_MESSAGE before its first reboot."""
    reboot_ack: int | None = mavlink.MAV_RESULT_ACCEPTED
    reboots: bool = True
    down_s: float = 0.0
    booted_s: float = START_S - 600.0
    extra: list[Any] = field(default_factory=list)
    """Messages sent with each answer, before it (another component's HEARTBEAT, ...)."""
    heard: list[tuple[float, Any]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.mav: Any = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self._parser: Any = mavlink.MAVLink(None)
        self._reader: Any = mavlink.MAVLink(None)
        self._queue: list[tuple[float, bytes]] = []
        self._down_until = -1.0
        self.boots = 0

    # the session's side of the wire
    def write(self, data: bytes) -> None:
        for msg in self._parser.parse_buffer(bytes(data)) or []:
            self.heard.append((self.clock.now, msg))
            if self.clock.now >= self._down_until:
                self._answer(msg)

    def receive(self, timeout_s: float) -> list[Any]:
        until = self.clock.now + max(timeout_s, 0.0)
        due = [t for t, _ in self._queue if t <= until]
        self.clock.advance_to(min(due) if due else until)
        now = self.clock.now
        out = [data for t, data in self._queue if t <= now]
        self._queue = [(t, data) for t, data in self._queue if t > now]
        return [m for data in out for m in self._reader.parse_buffer(data) or []]

    # the board
    def _reply(self, *msgs: Any) -> None:
        for msg in [*self.extra, *msgs]:
            self._queue.append((self.clock.now + LATENCY_S, bytes(msg.pack(self.mav))))

    def _value(self, name: str) -> Any:
        value, kind = self.params[name]
        return self.mav.param_value_encode(name.encode(), value, kind, len(self.params), 0)

    def _answer(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "PARAM_REQUEST_READ":  # (MAVLink: by name only with param_index -1)
            names = list(self.params)
            name = msg.param_id if msg.param_index == -1 else \
                names[msg.param_index] if 0 <= msg.param_index < len(names) else ""
            if self.drop_reads.get(name, 0) > 0:
                self.drop_reads[name] -= 1
            elif name in self.params:
                self._reply(self._value(name))
        elif kind == "PARAM_SET":
            name = msg.param_id
            if self.drop_sets.get(name, 0) > 0:
                self.drop_sets[name] -= 1
                return
            _, type_ = self.params.get(name, (0.0, REAL32))
            self.params[name] = (self.keeps.get(name, msg.param_value), type_)
            self._reply(self._value(name))
        elif kind == "COMMAND_LONG" and msg.command == mavlink.MAV_CMD_REQUEST_MESSAGE:
            tells = self.tells_time and not (self.silent_until_reboot and self.boots == 0)
            if tells and int(msg.param1) == mavlink.MAVLINK_MSG_ID_SYSTEM_TIME:
                boot_ms = int((self.clock.now - self.booted_s) * 1000)
                self._reply(self.mav.system_time_encode(0, boot_ms))
        elif kind == "COMMAND_LONG" and msg.command == mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN:
            if self.reboot_ack is None:
                return
            rebooting = self.reboot_ack == mavlink.MAV_RESULT_ACCEPTED and self.reboots \
                and msg.param1 == 1
            if rebooting:
                self._queue.clear()  # (what it was still to send is lost)
            self._reply(self.mav.command_ack_encode(msg.command, self.reboot_ack))
            if rebooting:
                self.boots += 1
                self.booted_s = self.clock.now
                self._down_until = self.clock.now + self.down_s

    # what it heard
    def sent(self, kind: str, **fields: Any) -> list[tuple[float, Any]]:
        return [(t, m) for t, m in self.heard if m.get_type() == kind
                and all(getattr(m, k) == v for k, v in fields.items())]

    def times(self, kind: str, **fields: Any) -> list[float]:
        return [round(t - START_S, 6) for t, _ in self.sent(kind, **fields)]


def use_clock(monkeypatch: pytest.MonkeyPatch) -> Clock:
    """A simulated clock for setupfc (its ``time``)."""
    clock = Clock()
    monkeypatch.setattr(setupfc, "time", SimpleNamespace(monotonic=clock.monotonic,
                                                         sleep=clock.sleep))
    return clock


def session_on(board: Board) -> setupfc.FcSession:
    """An FcSession whose link is ``board`` (system 1, component 1)."""
    session = object.__new__(_FC_SESSION)
    session.target = (1, 1)
    session.link = SimpleNamespace(  # type: ignore[assignment]
        mav=mavlink.MAVLink(board, srcSystem=255, srcComponent=191))
    session.types = {}
    session._receive = board.receive  # type: ignore[method-assign]
    return session


def run_setup_on(board: Board, monkeypatch: pytest.MonkeyPatch, params: Any, *,
                 apply: bool = False, reboot: bool = False) -> tuple[int, str]:
    """``setup-fc`` against ``board`` (its HEARTBEAT taken as heard): (exit status, what it
    printed)."""
    def session(url: str, params: Any, signing_key: bytes | None = None) -> setupfc.FcSession:
        fc = session_on(board)
        fc.wait_heartbeat = lambda timeout_s=0.0: True  # type: ignore[method-assign]
        fc.close = lambda: None  # type: ignore[method-assign]
        return fc

    monkeypatch.setattr(setupfc, "FcSession", session)
    out = io.StringIO()
    status = setupfc.run_setup("udpout:127.0.0.1:9", params, apply=apply, reboot=reboot,
                               out=out)
    return status, out.getvalue()
