"""``mecanum-mav setup-fc``: check (and with ``--apply`` fix) an ArduPilot flight controller's
settings for the companion, over MAVLink, as the companion connects to it.

It reads the parameters :mod:`mecanum_mav.protocol.fcsetup` needs (through
:class:`~mecanum_mav.protocol.paramread.ParamReader`, as the companion's run-time check does:
paced to what ArduPilot accepts, asked again until answered or a deadline) and prints one row
per setting: its value, what the companion needs, why, and ``ok``, ``HAZARD`` (any value that
differs from what the companion needs) or ``UNKNOWN`` (no answer).

``--apply`` writes every setting the companion needs (PARAM_SET, each confirmed by the
PARAM_VALUE that echoes it), so that ArduPilot stores it: a value the board already has is
first written as a harmless neighbour (:func:`~mecanum_mav.protocol.fcsetup.store_nudge`),
since ArduPilot does not store a value equal to its default and some defaults change at
boot. It then reads everything back and checks again. A setting ArduPilot reads only at boot
(``RCMAP_THROTTLE``) leaves a reboot pending: setup-fc says so and does not call the board
safe; ``--reboot`` reboots it (MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN), waits until it is back
(its SYSTEM_TIME's time since boot starts again), reads and checks again, and with ``--apply``
writes again whatever the reboot changed.

Exit status: 0 when the board is safe for the companion; 1 when a hazard remains or a setting
was not answered; 2 when the flight controller cannot be reached (or Ctrl-C); 3 when it will
be safe once rebooted (``--reboot``, or power-cycle it).
"""

from __future__ import annotations

import contextlib
import selectors
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any, NamedTuple, TextIO

from mecanum_mav.config.params import Params
from mecanum_mav.config.spec import float32_of
from mecanum_mav.control.core import FC_LINK_COMPID
from mecanum_mav.io.links import Link, follow, open_link
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.fcsetup import (
    OPTIONAL_NAMES,
    REBOOT_NAMES,
    Finding,
    check,
    safe_settings,
    store_nudge,
    wanted_groups,
)
from mecanum_mav.protocol.heartbeat import send_gcs_heartbeat
from mecanum_mav.protocol.paramread import REPEAT_S, WINDOW, ParamReader

__all__ = ["EXIT_REBOOT_PENDING", "FcSession", "Reading", "run_setup"]

HEARTBEAT_TIMEOUT_S = 10.0
WRITE_DEADLINE_S = 10.0
REBOOT_TIMEOUT_S = 60.0
"""How long a rebooting board may take to come back."""
ACK_TIMEOUT_S = 1.0
"""How long a COMMAND_LONG waits for its COMMAND_ACK (or the answer it asks for) before it is
sent again."""
BOOT_TIME_TIMEOUT_S = 3.0
"""How long the board's time since boot is asked for before a reboot (no answer: the first
answer after the reboot counts)."""
EXIT_REBOOT_PENDING = 3


class Reading(NamedTuple):
    """What one read of the board gave: the values answered and the settings not answered."""

    values: dict[str, float]
    missing: list[str]


class FcSession:
    """A MAVLink session with a flight controller for reading and writing parameters."""

    def __init__(self, url: str, params: Params, signing_key: bytes | None = None) -> None:
        self.target = (int(params["FC_SYSID"]), int(params["FC_COMPID"]))
        self.link: Link = open_link(url, source_system=int(params["FC_GCS_SYSID"]),
                                    source_component=FC_LINK_COMPID, name="fc",
                                    signing_key=signing_key)
        self._selector = selectors.DefaultSelector()
        self._fd = follow(self._selector, self.link, None)
        self.types: dict[str, int] = {}
        self._next_beat_s = 0.0

    def close(self) -> None:
        """Close the link."""
        self._selector.close()
        self.link.close(linger_s=0.2)

    def _send(self, send: Callable[..., object], *args: Any) -> None:
        """``send(*args)``, a message to the board; one the link cannot take now (it went
        down, the board rebooting, or its queue is full) is lost: each caller asks again."""
        with contextlib.suppress(OSError):  # (LinkDownError, BlockingIOError, no route)
            send(*args)

    def _receive(self, timeout_s: float) -> list[Any]:
        """What the flight controller sent within ``timeout_s`` (our HEARTBEAT goes out at
        1 Hz meanwhile; a link that went down is reopened)."""
        now = time.monotonic()
        if now >= self._next_beat_s and self.link.up:
            self._send(send_gcs_heartbeat, self.link.mav)
            self._next_beat_s = now + 1.0
        if not self.link.up:
            self.link.reopen(now)
        self._fd = follow(self._selector, self.link, self._fd)  # (and hands over what waits)
        wake_s = min(timeout_s, self.link.next_send_s - now, self._next_beat_s - now)
        if self._fd is None:  # down: wait for the reopen
            time.sleep(max(0.0, min(wake_s, 0.1)))
            return []
        if not self._selector.select(max(0.0, wake_s)):
            return []
        # (read never raises: a link that broke is down, and reopened on the next pass)
        return [m for m in self.link.read() if m.get_srcSystem() == self.target[0]]

    def wait_heartbeat(self, timeout_s: float = HEARTBEAT_TIMEOUT_S) -> bool:
        """Wait for the flight controller's HEARTBEAT (sending ours at 1 Hz meanwhile)."""
        deadline = time.monotonic() + timeout_s
        while (now := time.monotonic()) < deadline:
            if any(m.get_type() == "HEARTBEAT" for m in self._receive(min(0.2, deadline - now))):
                return True
        return False

    def read(self, groups: Iterable[Sequence[str]]) -> Reading:
        """Read the settings ``groups`` (see :class:`ParamReader`)."""
        reader = ParamReader(groups, time.monotonic(), optional=OPTIONAL_NAMES)
        while not reader.over:
            for name in reader.requests(time.monotonic()):
                self._send(self.link.mav.param_request_read_send, *self.target, name.encode(),
                           -1)
            wait_s = reader.next_due_s() - time.monotonic()
            for msg in self._receive(max(0.0, wait_s)):  # (our HEARTBEAT: _receive)
                if msg.get_type() == "PARAM_VALUE":
                    reader.on_value(msg.param_id, float(msg.param_value),
                                    int(msg.param_type))
        self.types.update(reader.types)
        return Reading(dict(reader.values), reader.missing())

    def write(self, settings: dict[str, float]) -> dict[str, float]:
        """PARAM_SET each setting, at most :data:`WINDOW` unconfirmed at once, each sent
        again until the board echoes the value or :data:`WRITE_DEADLINE_S` passes; the values
        the board echoed back."""
        echoed: dict[str, float] = {}
        pending = list(settings)
        sent: dict[str, float] = {}
        deadline = time.monotonic() + WRITE_DEADLINE_S
        while (pending or sent) and (now := time.monotonic()) < deadline:
            for name, at in list(sent.items()):
                if now - at >= REPEAT_S:
                    del sent[name]
                    pending.append(name)
            while pending and len(sent) < WINDOW:
                name = pending.pop(0)
                kind = self.types.get(name, mavlink.MAV_PARAM_TYPE_REAL32)
                self._send(self.link.mav.param_set_send, *self.target, name.encode(),
                           float(settings[name]), kind)
                sent[name] = now
            for msg in self._receive(0.1):
                if msg.get_type() == "PARAM_VALUE" and msg.param_id in sent:
                    name = msg.param_id
                    echoed[name] = float(msg.param_value)
                    if echoed[name] == float32_of(settings[name]):  # (as PARAM_SET carried it)
                        del sent[name]
        return echoed

    def boot_ms(self, timeout_s: float = BOOT_TIME_TIMEOUT_S,
                accept: Callable[[int], bool] = lambda ms: True) -> int | None:
        """The board's time since boot (SYSTEM_TIME.time_boot_ms, asked for with
        MAV_CMD_REQUEST_MESSAGE, again every :data:`ACK_TIMEOUT_S` until answered): the first
        answer ``accept`` takes, or None if none came within ``timeout_s``."""
        now = time.monotonic()
        deadline, next_ask = now + timeout_s, now
        while now < deadline:
            if now >= next_ask:  # (each ask a new request: for the time now)
                self._send(self.link.mav.command_long_send,
                           *self.target, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                           mavlink.MAVLINK_MSG_ID_SYSTEM_TIME, 0, 0, 0, 0, 0, 0)
                next_ask = now + ACK_TIMEOUT_S
            for msg in self._receive(min(next_ask, deadline) - now):
                if msg.get_type() == "SYSTEM_TIME" and accept(int(msg.time_boot_ms)):
                    return int(msg.time_boot_ms)
            now = time.monotonic()
        return None

    def reboot(self, timeout_s: float = REBOOT_TIMEOUT_S) -> str | None:
        """Reboot the board and wait until it is back (its time since boot started again);
        None, or why it failed."""
        before_ms, before_s = self.boot_ms(), time.monotonic()
        # (param1 1: the autopilot reboots; param2 0: the onboard computer, us, does not)
        ack = self._command(mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 1, 0, 0, 0, 0, 0, 0)
        if ack is None:
            return "no answer to MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN"
        if ack != mavlink.MAV_RESULT_ACCEPTED:
            return f"MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN refused (result {ack}); disarm first"

        def restarted(now_ms: int) -> bool:
            """Whether the board's clock is behind where it would be had it run on (by more
            than an answer's way back, 500 ms)."""
            if before_ms is None:
                return True
            return now_ms < before_ms + (time.monotonic() - before_s) * 1000 - 500

        if self.boot_ms(timeout_s, accept=restarted) is None:
            return f"the board was not back within {timeout_s:g} s"
        return None

    def _command(self, command: int, *params: float) -> int | None:
        """COMMAND_LONG ``command`` with its seven ``params``, sent up to three times (its
        confirmation counting the times it was sent before, as MAVLink's command protocol
        asks); the COMMAND_ACK's result."""
        for confirmation in range(3):
            self._send(self.link.mav.command_long_send, *self.target, command, confirmation,
                       *params)
            deadline = time.monotonic() + ACK_TIMEOUT_S
            while (now := time.monotonic()) < deadline:
                for msg in self._receive(deadline - now):
                    if msg.get_type() == "COMMAND_ACK" and msg.command == command:
                        return int(msg.result)
        return None


def _show(value: float | None) -> str:
    if value is None:
        return "(none)"
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


def _status(finding: Finding) -> str:
    if finding.hazard:
        return "HAZARD"
    return "UNKNOWN" if finding.value is None and finding.name not in OPTIONAL_NAMES else "ok"


def print_findings(findings: list[Finding], out: TextIO) -> None:
    """The table: setting, value, what the companion needs, ok / HAZARD / UNKNOWN, and why."""
    width = max(len(f.name) for f in findings)
    out.write(f"{'setting':<{width}}  {'value':>8}  {'needs':<22} {'':7}  why\n")
    for f in findings:
        out.write(f"{f.name:<{width}}  {_show(f.value):>8}  {f.want:<22} {_status(f):<7}  "
                  f"{f.why}\n")
    out.flush()


class _Setup:
    """One setup-fc run: the session, the table printed after each read, the exit status."""

    def __init__(self, session: FcSession, params: Params, out: TextIO) -> None:
        self.session, self.params, self.out = session, params, out
        self.groups = wanted_groups(params)

    def check(self, title: str) -> tuple[Reading, list[Finding]]:
        if title:
            self.out.write(f"\n{title}:\n")
        reading = self.session.read(self.groups)
        findings = check(self.params, reading.values)
        print_findings(findings, self.out)
        return reading, [f for f in findings if f.hazard]

    def apply(self, reading: Reading) -> set[str]:
        """Write every setting the companion needs; the names whose value changed."""
        wanted = safe_settings(self.params, reading.values)
        have = reading.values
        nudges = {n: v for n, value in wanted.items() if have.get(n) == value
                  and (v := store_nudge(n, value)) is not None}
        changed = {n for n, value in wanted.items() if have.get(n) != value}
        if nudges:
            self.session.write(nudges)
        writes = {n: wanted[n] for n in wanted if n in changed or n in nudges}
        echoed = self.session.write(writes)
        refused = sorted(n for n, v in writes.items() if echoed.get(n) != float32_of(v))
        self.out.write(f"\nwrote {len(writes) - len(refused)} of {len(writes)} settings "
                       f"({len(changed)} changed, {len(nudges)} stored by writing a neighbour "
                       "first)" + (f"; not accepted: {', '.join(refused)}" if refused else "")
                       + "\n")
        return changed

    def verdict(self, reading: Reading, hazards: list[Finding], reboot_for: set[str]) -> int:
        out = self.out
        if hazards:
            out.write(f"\n{len(hazards)} hazard(s): the rover may drive on after the companion "
                      "stops, or ignore it; fix with --apply\n")
            return 1
        if reading.missing:
            out.write(f"\nnot confirmed: no answer for {', '.join(reading.missing)} (is this "
                      "ArduPilot Rover, and the link's FC_SYSID right?)\n")
            return 1
        if reboot_for:
            names = ", ".join(sorted(reboot_for))
            out.write(f"\nREBOOT PENDING: the flight controller reads {names} only at boot: "
                      "run again with --reboot (or power-cycle it) before driving\n")
            return EXIT_REBOOT_PENDING
        out.write("\nthe flight controller is set up safely for the companion\n")
        return 0


def run_setup(url: str, params: Params, *, apply: bool, reboot: bool = False,
              signing_key: bytes | None = None, out: TextIO = sys.stdout) -> int:
    """``setup-fc``: check (and with ``apply`` fix, with ``reboot`` reboot) the board at
    ``url`` (signing with ``signing_key``, a board that requires it); the exit status (see
    the module docstring)."""
    try:
        session = FcSession(url, params, signing_key)
    except (OSError, ValueError) as exc:
        print(f"mecanum-mav setup-fc: {exc}", file=sys.stderr)
        return 2
    try:
        out.write(f"mecanum-mav setup-fc: waiting for the flight controller's HEARTBEAT on "
                  f"{url}\n")
        out.flush()
        if not session.wait_heartbeat(HEARTBEAT_TIMEOUT_S):
            print(f"mecanum-mav setup-fc: no HEARTBEAT from system {session.target[0]} on "
                  f"{url}", file=sys.stderr)
            return 2
        setup = _Setup(session, params, out)
        reading, hazards = setup.check("")
        reboot_for: set[str] = set()
        if apply:
            reboot_for = set(REBOOT_NAMES & setup.apply(reading))
            reading, hazards = setup.check("after --apply")
        if reboot:
            out.write("\nrebooting the flight controller ...\n")
            out.flush()
            problem = session.reboot(REBOOT_TIMEOUT_S)
            if problem is not None:
                print(f"mecanum-mav setup-fc: reboot: {problem}", file=sys.stderr)
                return 2
            reboot_for = set()
            reading, hazards = setup.check("after the reboot")
            if apply and hazards:
                reboot_for = set(REBOOT_NAMES & setup.apply(reading))
                reading, hazards = setup.check("after --apply again")
        return setup.verdict(reading, hazards, reboot_for)
    finally:
        session.close()
