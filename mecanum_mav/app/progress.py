"""What a running companion tells the person who started it, on stdout.

- At start: ``waiting for the flight controller's HEARTBEAT (system S) on URL``; when it
  comes: ``flight controller found (system S) on URL``; when it goes: ``flight controller
  lost on URL: waiting for its HEARTBEAT``. If none came :data:`FC_HINT_S` after the start,
  once: what to check.
- On a terminal, every :data:`STATUS_PERIOD_S` from the start: one status line
  (:func:`status_line`), e.g.
  ``MANUAL disarmed | fc up gcs up | FC setup safe | N 0.00 E 0.00 m | 0.00 m/s``.

:class:`Progress` reads the core's state on a timer of its own (:data:`CHECK_PERIOD_S`), run
by the companion's loop between passes
(:meth:`~mecanum_mav.app.companion.Companion.set_timer`): no work per message.
"""

from __future__ import annotations

import math
from typing import TextIO

from mecanum_mav.control.core import RoverCore
from mecanum_mav.control.fccheck import FcCheckState, FcSetupCheck

__all__ = ["CHECK_PERIOD_S", "FC_HINT_S", "STATUS_PERIOD_S", "Progress", "fc_check_state",
           "status_line"]

CHECK_PERIOD_S = 1.0
"""How often (s) :class:`Progress` looks at the core (the flight controller found or lost)."""
STATUS_PERIOD_S = 5.0
"""How often (s) the status line is printed."""
FC_HINT_S = 10.0
"""A flight controller not found this long (s) after the start gets a hint of what to check."""
GCS_HEARD_S = 3.0
"""A ground station whose HEARTBEAT came within this long (s) is "up"."""


def fc_check_state(check: FcSetupCheck) -> str:
    """The companion's check of the flight controller's setup, in words: ``checking``,
    ``safe``, ``UNSAFE: NAME, ...``, ``NOT CONFIRMED: NAME, ...`` (no answer) or ``not
    checked`` (no answers from the board, or no board yet)."""
    state = check.state
    if state is FcCheckState.READING:
        return "checking"
    if state is FcCheckState.SAFE:
        return "safe"
    if state is FcCheckState.UNSAFE:
        return "UNSAFE: " + ", ".join(f.name for f in check.hazards)
    if state is FcCheckState.UNCONFIRMED:
        return "NOT CONFIRMED: " + ", ".join(check.missing)
    return "not checked"


def _gcs_state(core: RoverCore, now_s: float) -> str:
    seen = core.vehicle.gcs_seen_s
    if seen is None:
        return "not heard"
    return "up" if now_s - seen <= GCS_HEARD_S else "silent"


def status_line(core: RoverCore, now_s: float) -> str:
    """One line of the rover's state for people: mode, armed, the links (flight controller up
    or down; ground station up, silent or not heard yet, from its HEARTBEAT), the setup check
    (:func:`fc_check_state`), the odometry's position (north, east, m) and speed (m/s)."""
    vehicle, estimator = core.vehicle, core.estimator
    pose = estimator.pose
    speed = math.hypot(*estimator.velocity_body)
    return (f"{vehicle.mode.name} {'armed' if vehicle.armed else 'disarmed'} | "
            f"fc {'down' if vehicle.fc_lost else 'up'} gcs {_gcs_state(core, now_s)} | "
            f"FC setup {fc_check_state(core.fc_check)} | "
            f"N {pose.x_m:.2f} E {pose.y_m:.2f} m | {speed:.2f} m/s")


class Progress:
    """Says what the companion is doing (see the module docstring).

    Args:
        core: the running rover core (read only).
        fc_url: the flight-controller link, as the person gave it.
        out: where to write (stdout).
        periodic: print the status line every :data:`STATUS_PERIOD_S` (on a terminal,
            without ``--quiet``).
    """

    def __init__(self, core: RoverCore, fc_url: str, out: TextIO, *, periodic: bool) -> None:
        self.core = core
        self.fc_url = fc_url
        self.out = out
        self.periodic = periodic
        self._fc_up = False
        self._hint_s = -math.inf  # when the hint is due (inf: said, or not needed)
        self._next_status_s = -math.inf

    def _say(self, text: str) -> None:
        print(f"mecanum-mav: {text}", file=self.out, flush=True)

    def started(self) -> None:
        """Print the waiting line (call once the links are open)."""
        self._say(f"waiting for the flight controller's HEARTBEAT (system "
                  f"{self.core.identity.fc_sysid}) on {self.fc_url}")

    def tick(self, now_s: float) -> float:
        """Look at the core at ``now_s``: print what changed and, when due, the status line;
        returns when to look again (monotonic s)."""
        up = not self.core.vehicle.fc_lost
        if self._hint_s == -math.inf:  # the first look
            self._hint_s = now_s + FC_HINT_S
        if up:
            self._hint_s = math.inf
        elif now_s >= self._hint_s:
            self._hint_s = math.inf
            sysid = self.core.identity.fc_sysid
            self._say(f"no HEARTBEAT from the flight controller (system {sysid}) on "
                      f"{self.fc_url} after {FC_HINT_S:g} s: is it powered and connected "
                      f"(device, baud rate, port), and is its system id FC_SYSID ({sysid})?")
        if up != self._fc_up:
            self._fc_up = up
            if up:
                self._say(f"flight controller found (system {self.core.identity.fc_sysid}) "
                          f"on {self.fc_url}")
            else:
                self._say(f"flight controller lost on {self.fc_url}: waiting for its "
                          f"HEARTBEAT")
        if self._next_status_s == -math.inf:  # the first one a period after the start
            self._next_status_s = now_s + STATUS_PERIOD_S
        if self.periodic and now_s >= self._next_status_s:
            self._next_status_s = now_s + STATUS_PERIOD_S
            self._say(status_line(self.core, now_s))
        return now_s + CHECK_PERIOD_S
