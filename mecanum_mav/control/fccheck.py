"""The companion's own read-only check of the flight controller's setup, when it appears.

The same rules as ``mecanum-mav setup-fc`` (:mod:`mecanum_mav.protocol.fcsetup`), run by the
core without blocking anything: when the flight-controller link comes up the core asks for
each parameter (PARAM_REQUEST_READ by name), asks again for the missing ones after
:data:`RETRY_S`, and at :data:`DECIDE_S` decides. A board that answered none (the built-in
simulator, a firmware without those parameters) is "not checked"; otherwise every hazard is
reported once (STATUSTEXT WARNING and the log) and blocks arming as a pre-arm check until the
board is fixed and the link comes up again. Time is passed in.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from mecanum_mav.config.params import Params
from mecanum_mav.protocol.fcsetup import Finding, check, wanted_names

__all__ = ["DECIDE_S", "RETRY_S", "FcSetupCheck"]

RETRY_S = 1.5
"""The parameters not answered by then are asked for again."""
DECIDE_S = 3.0
"""When the check decides, after it started."""


class FcSetupCheck:
    """One check per flight-controller link-up (see the module docstring)."""

    def __init__(self) -> None:
        self.values: dict[str, float] = {}
        self.names: list[str] = []
        self.hazards: list[Finding] = []
        """The hazards found by the last check (empty before it decided, or if none)."""
        self.checked = False
        """The last check decided with answers from the board."""
        self.next_due_s = math.inf
        """When :meth:`tick` has something to do (inf when idle), monotonic seconds."""
        self._started_s = math.inf
        self._retried = False

    def start(self, params: Params, now_s: float) -> list[str]:
        """The link came up: a new check; the parameter names to ask for."""
        self.names = wanted_names(params)
        self.values, self.hazards, self.checked = {}, [], False
        self._started_s, self._retried = now_s, False
        self.next_due_s = now_s + RETRY_S
        return list(self.names)

    def on_value(self, name: str, value: float) -> None:
        """A PARAM_VALUE from the flight controller."""
        if self.next_due_s < math.inf and name in self.names:
            self.values[name] = value

    def tick(self, params: Params, now_s: float) -> tuple[Sequence[str], str | None]:
        """(names to ask for again, the verdict to report) at ``now_s``; call when due."""
        if now_s < self.next_due_s:
            return (), None
        if not self._retried:
            self._retried = True
            self.next_due_s = self._started_s + DECIDE_S
            return [n for n in self.names if n not in self.values], None
        self.next_due_s = math.inf
        if not self.values:
            return (), "FC setup not checked: no parameters from the flight controller"
        self.checked = True
        self.hazards = [f for f in check(params, self.values) if f.hazard]
        if not self.hazards:
            return (), "FC setup checked: safe for the companion"
        names = ", ".join(f.name for f in self.hazards)
        return (), (f"FC setup unsafe ({len(self.hazards)}): {names}; run mecanum-mav "
                    f"setup-fc --apply")
