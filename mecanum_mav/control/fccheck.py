"""The companion's own read-only check of the flight controller's setup, while it runs.

The same rules as ``mecanum-mav setup-fc`` (:mod:`mecanum_mav.protocol.fcsetup`), read the
same way (:class:`~mecanum_mav.protocol.paramread.ParamReader`: requests paced to what
ArduPilot accepts, asked again until answered or a deadline), run by the core without
blocking anything. Time is passed in.

- When the flight-controller link comes up the board is read (:meth:`FcSetupCheck.start`).
- The verdict, said once per change (STATUSTEXT and the log):
  ``FC setup checked: safe for the companion``; ``FC setup unsafe (N): ...`` (a value the
  companion cannot drive safely with: a pre-arm failure until the board is fixed);
  ``FC setup not confirmed: no answer for ...`` (the board answered some parameters but not
  these by the deadline: never called a hazard, but arming waits for them, and each arm
  attempt reads the board again); ``FC setup not checked: no parameters from the flight
  controller`` (a board that answers no parameter at all within 3 s: a firmware without
  them, a signing board the link cannot talk to; nothing to check, nothing blocked).
- ArduPilot announces every parameter a ground station changes (a PARAM_VALUE on all its
  links). A checked setting that changes starts a new read at once, and arming waits for it.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence

from mecanum_mav.config.params import Params
from mecanum_mav.protocol.fcsetup import OPTIONAL_NAMES, Finding, check, wanted_groups
from mecanum_mav.protocol.paramread import ParamReader

__all__ = ["FcCheckState", "FcSetupCheck"]


class FcCheckState(enum.Enum):
    """Where the check stands."""

    IDLE = "not started"
    READING = "reading"
    SAFE = "safe"
    UNSAFE = "unsafe"
    UNCONFIRMED = "not confirmed"
    NOT_CHECKED = "not checked"


class FcSetupCheck:
    """The check of one flight controller (see the module docstring)."""

    def __init__(self) -> None:
        self.state = FcCheckState.IDLE
        self.hazards: list[Finding] = []
        """The hazards the last decided read found (empty if none)."""
        self.missing: list[str] = []
        """The settings the last decided read got no answer for."""
        self.values: dict[str, float] = {}
        """The board's values as last read or announced."""
        self._reader: ParamReader | None = None
        self._groups: list[tuple[str, ...]] = []
        self._names: frozenset[str] = frozenset()
        self._said: str | None = None

    @property
    def checked(self) -> bool:
        """The last read decided with answers from the board (safe or unsafe)."""
        return self.state in (FcCheckState.SAFE, FcCheckState.UNSAFE)

    @property
    def next_due_s(self) -> float:
        """When :meth:`tick` has something to do (inf when idle), monotonic seconds."""
        reader = self._reader
        if reader is None:
            return math.inf
        return reader.started_s if reader.over else reader.next_due_s()  # (over: decide now)

    def start(self, params: Params, now_s: float) -> list[str]:
        """Read the board (the link came up, or a reason to read again); the parameter names
        to ask for now."""
        self._groups = wanted_groups(params)
        self._names = frozenset(n for g in self._groups for n in g)
        self._said = None  # each verdict is said once per link-up
        return self._read(now_s)

    def _read(self, now_s: float) -> list[str]:
        self.state = FcCheckState.READING
        self._reader = ParamReader(self._groups, now_s, optional=OPTIONAL_NAMES)
        return self._reader.requests(now_s)

    def on_value(self, name: str, value: float, now_s: float) -> list[str]:
        """A PARAM_VALUE from the flight controller; the names to ask for now."""
        if name not in self._names:
            return []
        changed = name in self.values and self.values[name] != value
        self.values[name] = value
        if self._reader is not None:
            self._reader.on_value(name, value)
            return self._reader.requests(now_s)
        return self._read(now_s) if changed else []

    def tick(self, params: Params, now_s: float) -> tuple[Sequence[str], str | None]:
        """(names to ask for now, a verdict to report or None); call when due."""
        reader = self._reader
        if reader is None:
            return (), None
        names = reader.requests(now_s)
        if not reader.over:
            return names, None
        self._reader = None
        return names, self._decide(params, reader)

    def _decide(self, params: Params, reader: ParamReader) -> str | None:
        self.missing = reader.missing()
        self.hazards = [f for f in check(params, reader.values) if f.hazard]
        if reader.answered == 0:
            self.state = FcCheckState.NOT_CHECKED
            verdict = "FC setup not checked: no parameters from the flight controller"
        elif self.hazards:
            self.state = FcCheckState.UNSAFE
            names = ", ".join(f.name for f in self.hazards)
            verdict = (f"FC setup unsafe ({len(self.hazards)}): {names}; run mecanum-mav "
                       f"setup-fc --apply")
        elif self.missing:
            self.state = FcCheckState.UNCONFIRMED
            verdict = (f"FC setup not confirmed: no answer for {', '.join(self.missing)}; "
                       f"asked again when arming")
        else:
            self.state = FcCheckState.SAFE
            verdict = "FC setup checked: safe for the companion"
        if verdict == self._said:
            return None
        self._said = verdict
        return verdict

    def arm_problem(self, now_s: float) -> tuple[str | None, list[str]]:
        """(the pre-arm problem, or None; the names to ask for now) for an arm attempt at
        ``now_s``. A board not confirmed is read again (the attempt is refused meanwhile)."""
        state = self.state
        if state is FcCheckState.READING and self._reader is not None:
            return (f"FC setup not confirmed: reading the flight controller "
                    f"({self._reader.answered} of {len(self._groups)})"), []
        if state is FcCheckState.UNSAFE:
            return f"FC setup unsafe: {self.hazards[0].name} (mecanum-mav setup-fc)", []
        if state is FcCheckState.UNCONFIRMED:
            names = self._read(now_s)
            return (f"FC setup not confirmed: no answer for {', '.join(self.missing)}; "
                    f"reading again"), names
        return None, []
