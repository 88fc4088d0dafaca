"""``mecanum-mav setup-fc``: check (and with ``--apply`` fix) an ArduPilot flight controller's
settings for the companion, over MAVLink, as the companion connects to it.

It reads the parameters :mod:`mecanum_mav.protocol.fcsetup` needs (PARAM_REQUEST_READ by
name, re-asked for up to three rounds; a parameter the firmware does not have stays unknown),
prints one row per setting (value, what the companion needs, why, OK or HAZARD), and with
``--apply`` writes the safe values (PARAM_SET, each confirmed by the PARAM_VALUE that echoes
it), reads everything back and checks again. Exit status 0 only when the board is safe;
1 when a hazard remains; 2 when the flight controller cannot be reached.
"""

from __future__ import annotations

import selectors
import sys
import time
from collections.abc import Iterable
from typing import Any, TextIO

from mecanum_mav.config.params import Params
from mecanum_mav.control.core import FC_LINK_COMPID
from mecanum_mav.io.links import Link, follow, open_link
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.fcsetup import Finding, check, safe_settings, wanted_names
from mecanum_mav.protocol.heartbeat import send_gcs_heartbeat

__all__ = ["REBOOT_NAMES", "FcSession", "run_setup"]

HEARTBEAT_TIMEOUT_S = 10.0
ROUND_S = 1.0
ROUNDS = 3
REBOOT_NAMES = frozenset({"RCMAP_THROTTLE"})
"""Settings ArduPilot reads at boot only (a change needs a reboot of the flight controller)."""


class FcSession:
    """A MAVLink session with a flight controller for reading and writing parameters."""

    def __init__(self, url: str, params: Params) -> None:
        self.target = (int(params["FC_SYSID"]), int(params["FC_COMPID"]))
        self.link: Link = open_link(url, source_system=int(params["FC_GCS_SYSID"]),
                                    source_component=FC_LINK_COMPID, name="fc")
        self._selector = selectors.DefaultSelector()
        self._fd = follow(self._selector, self.link, None)
        self.types: dict[str, int] = {}

    def close(self) -> None:
        """Close the link."""
        self._selector.close()
        self.link.close(linger_s=0.2)

    def _receive(self, timeout_s: float) -> list[Any]:
        self._fd = follow(self._selector, self.link, self._fd)  # (and hands over what waits)
        wake_s = min(timeout_s, self.link.next_send_s - time.monotonic())  # paced writes
        if not self._selector.select(max(0.0, wake_s)):
            return []
        return [m for m in self.link.read() if m.get_srcSystem() == self.target[0]]

    def wait_heartbeat(self, timeout_s: float = HEARTBEAT_TIMEOUT_S) -> bool:
        """Wait for the flight controller's HEARTBEAT (sending ours at 1 Hz meanwhile)."""
        deadline = time.monotonic() + timeout_s
        next_beat = 0.0
        while (now := time.monotonic()) < deadline:
            if now >= next_beat:
                send_gcs_heartbeat(self.link.mav)
                next_beat = now + 1.0
            if any(m.get_type() == "HEARTBEAT" for m in self._receive(min(0.2, deadline - now))):
                return True
        return False

    def read(self, names: Iterable[str]) -> dict[str, float]:
        """The values of ``names`` the board has (PARAM_REQUEST_READ, up to three rounds)."""
        missing, values = list(dict.fromkeys(names)), {}
        for _ in range(ROUNDS):
            for name in missing:
                self.link.mav.param_request_read_send(*self.target, name.encode(), -1)
            values.update(self._collect(set(missing), ROUND_S))
            missing = [n for n in missing if n not in values]
            if not missing:
                break
        return values

    def _collect(self, names: set[str], window_s: float) -> dict[str, float]:
        got: dict[str, float] = {}
        deadline = time.monotonic() + window_s
        while names - set(got) and (now := time.monotonic()) < deadline:
            for msg in self._receive(deadline - now):
                if msg.get_type() == "PARAM_VALUE":
                    name = msg.param_id.rstrip("\x00")
                    if name in names:
                        got[name] = float(msg.param_value)
                        self.types[name] = int(msg.param_type)
        return got

    def write(self, settings: dict[str, float]) -> dict[str, float]:
        """PARAM_SET each setting; the values the board echoed back."""
        echoed: dict[str, float] = {}
        pending = dict(settings)
        for _ in range(ROUNDS):
            for name, value in pending.items():
                kind = self.types.get(name, mavlink.MAV_PARAM_TYPE_REAL32)
                self.link.mav.param_set_send(*self.target, name.encode(), float(value), kind)
            got = self._collect(set(pending), ROUND_S)
            echoed.update(got)
            pending = {n: v for n, v in pending.items() if abs(got.get(n, 1e30) - v) > 1e-3}
            if not pending:
                break
        return echoed


def _show(value: float | None) -> str:
    if value is None:
        return "(none)"
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


def print_findings(findings: list[Finding], out: TextIO) -> None:
    """The table: setting, value, what the companion needs, OK or HAZARD, and why."""
    width = max(len(f.name) for f in findings)
    out.write(f"{'setting':<{width}}  {'value':>8}  {'needs':<22} {'':6}  why\n")
    for f in findings:
        status = "HAZARD" if f.hazard else "ok"
        out.write(f"{f.name:<{width}}  {_show(f.value):>8}  {f.want:<22} {status:<6}  {f.why}\n")


def run_setup(url: str, params: Params, *, apply: bool, out: TextIO = sys.stdout) -> int:
    """``setup-fc``: check (and with ``apply`` fix) the board at ``url``; the exit status."""
    try:
        session = FcSession(url, params)
    except (OSError, ValueError) as exc:
        print(f"mecanum-mav setup-fc: {exc}", file=sys.stderr)
        return 2
    try:
        if not session.wait_heartbeat():
            print(f"mecanum-mav setup-fc: no HEARTBEAT from system {session.target[0]} on "
                  f"{url}", file=sys.stderr)
            return 2
        values = session.read(wanted_names(params))
        findings = check(params, values)
        print_findings(findings, out)
        hazards = [f for f in findings if f.hazard]
        if apply and hazards:
            wanted = safe_settings(params, values)
            changes = {n: v for n, v in wanted.items() if values.get(n) != v}
            echoed = session.write(changes)
            refused = sorted(n for n, v in changes.items() if n not in echoed
                             or abs(echoed[n] - v) > 1e-3)
            out.write(f"\napplied {len(changes) - len(refused)} of {len(changes)} settings"
                      + (f"; not accepted: {', '.join(refused)}" if refused else "") + "\n")
            reboot = sorted(REBOOT_NAMES & set(changes))
            out.write("reboot the flight controller for: " + ", ".join(reboot) + "\n"
                      if reboot else "no reboot needed\n")
            values = session.read(wanted_names(params))
            findings = check(params, values)
            out.write("\nafter --apply:\n")
            print_findings(findings, out)
            hazards = [f for f in findings if f.hazard]
        if hazards:
            out.write(f"\n{len(hazards)} hazard(s): the rover may drive on after the companion "
                      "stops, or ignore it" + ("" if apply else "; fix with --apply") + "\n")
            return 1
        out.write("\nthe flight controller is set up safely for the companion\n")
        return 0
    finally:
        session.close()
