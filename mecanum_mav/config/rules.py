"""The rules between parameters, as data: :data:`RULES`, and the check of a whole store.

A single value is checked by its :class:`~mecanum_mav.config.spec.ParamSpec`; some values
are only valid together (a wheel's MIN < TRIM < MAX, four wheels on four RC channels, the
receiver's functions on channels of their own). Each rule is a small frozen record naming
the parameters it reads (``names``) with a ``problems(values)`` check;
:func:`consistency_problems` evaluates them all and the store
(:class:`~mecanum_mav.config.params.Params`) refuses a change that breaks one. The rules are
checked against the schema when this module is imported: a rule reading an unknown
parameter, or defaults that break a rule, raise.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from mecanum_mav.config.schema import SCHEMA, SPECS, WHEELS
from mecanum_mav.config.spec import Value, join_words

__all__ = [
    "MODE_NUMBERS",
    "RECEIVER_CHANNELS",
    "RULES",
    "DistinctChannels",
    "ModeNumbers",
    "OrderedTriple",
    "Problem",
    "ReceiverChannels",
    "Rule",
    "consistency_problems",
]

Problem = tuple[str, tuple[str, ...]]
"""A broken cross-parameter rule: (message, names of the parameters involved)."""


@dataclass(frozen=True)
class OrderedTriple:
    """Rule: ``{prefix}_MIN < {prefix}_TRIM < {prefix}_MAX`` (pulse widths, microseconds)."""

    prefix: str

    @property
    def names(self) -> tuple[str, str, str]:
        """The three parameters, MIN, TRIM, MAX."""
        return (f"{self.prefix}_MIN", f"{self.prefix}_TRIM", f"{self.prefix}_MAX")

    def problems(self, values: Mapping[str, Value]) -> list[Problem]:
        """The rule's violation in ``values`` (at most one)."""
        names = self.names
        low, trim, high = (values[n] for n in names)
        if low < trim < high:
            return []
        got = ", ".join(f"{n} {values[n]}" for n in names)
        return [(f"{self.prefix}: need MIN < TRIM < MAX, got {got} us", names)]


@dataclass(frozen=True)
class DistinctChannels:
    """Rule: the RC channel parameters in ``names`` hold different channels; ``purpose``
    ends the message (``"one motor each"``)."""

    names: tuple[str, ...]
    purpose: str

    def problems(self, values: Mapping[str, Value]) -> list[Problem]:
        """One violation per channel that two or more of the parameters share."""
        users: dict[Value, list[str]] = {}
        for name in self.names:
            users.setdefault(values[name], []).append(name)
        return [
            (f"{join_words(on_channel, 'and')} share RC channel {channel}; {self.purpose}",
             tuple(on_channel))
            for channel, on_channel in users.items()
            if len(on_channel) > 1
        ]


MODE_NUMBERS: dict[int, str] = {0: "MANUAL", 4: "HOLD", 10: "AUTO", 15: "GUIDED"}
"""The Rover mode numbers this companion has (a mode switch position may name one)."""
RECEIVER_CHANNELS = ("RCMAP_STEER", "RCMAP_THROTTLE", "RCMAP_LATERAL", "MODE_CH", "RCIN_ARM_CH")
"""The receiver channels the companion reads (a switch channel 0 is none)."""


@dataclass(frozen=True)
class ModeNumbers:
    """Rule: each of ``names`` holds one of the Rover mode numbers of :data:`MODE_NUMBERS`."""

    names: tuple[str, ...]

    def problems(self, values: Mapping[str, Value]) -> list[Problem]:
        """One violation per parameter naming a mode this companion does not have."""
        known = ", ".join(f"{k} {label}" for k, label in MODE_NUMBERS.items())
        return [(f"{name} {values[name]} is not a mode: one of {known}", (name,))
                for name in self.names if values[name] not in MODE_NUMBERS]


@dataclass(frozen=True)
class ReceiverChannels:
    """Rule: the receiver's channels (sticks, mode and arm switch; 0 = none) are distinct, and
    with ``RCIN_ENABLE`` 1 no wheel (``MOT_x_CH``) is on one of them: the flight controller
    reports the companion's overrides in RC_CHANNELS, so a wheel there would read back as a
    stick."""

    names: tuple[str, ...] = ("RCIN_ENABLE", *RECEIVER_CHANNELS,
                              *(f"MOT_{w}_CH" for w in WHEELS))

    def problems(self, values: Mapping[str, Value]) -> list[Problem]:
        """The channels two receiver functions share; with the receiver on, each wheel on a
        receiver channel."""
        users: dict[Value, list[str]] = {}
        for name in RECEIVER_CHANNELS:
            if values[name] != 0:
                users.setdefault(values[name], []).append(name)
        out: list[Problem] = [
            (f"{join_words(on, 'and')} share RC channel {ch}; one function each", tuple(on))
            for ch, on in users.items() if len(on) > 1 and not set(on) <= {
                "RCMAP_STEER", "RCMAP_THROTTLE", "RCMAP_LATERAL"}]  # (DistinctChannels says)
        if values["RCIN_ENABLE"] == 1:
            for w in WHEELS:
                wheel = f"MOT_{w}_CH"
                on = users.get(values[wheel])
                if on:
                    out.append((f"{wheel} {values[wheel]} is the receiver's {on[0]} channel; "
                                f"with RCIN_ENABLE 1 the wheels need channels the receiver "
                                f"does not use (e.g. 9-12)", (wheel, on[0], "RCIN_ENABLE")))
        return out


Rule = OrderedTriple | DistinctChannels | ModeNumbers | ReceiverChannels
"""A cross-parameter rule: ``names`` (the parameters it reads) and ``problems(values)``."""

RULES: tuple[Rule, ...] = (
    *(OrderedTriple(f"MOT_{w}") for w in WHEELS),
    OrderedTriple("RCIN"),
    DistinctChannels(tuple(f"MOT_{w}_CH" for w in WHEELS), "one motor each"),
    DistinctChannels(("RCMAP_STEER", "RCMAP_THROTTLE", "RCMAP_LATERAL"), "one stick axis each"),
    ReceiverChannels(),
    ModeNumbers(tuple(f"MODE{i}" for i in range(1, 7))),
)
"""The cross-parameter rules every :class:`Params` store keeps, in the order their
problems are reported: each wheel's MOT_x_MIN < MOT_x_TRIM < MOT_x_MAX, the same for RCIN,
four distinct MOT_x_CH and three distinct RCMAP channels, the mode and arm switches on channels
of their own (and, with the receiver on, no wheel on a receiver channel), MODE1..MODE6 modes
this companion has."""


def _check_rules(rules: Sequence[Rule]) -> None:
    """Raise when a rule reads a parameter the schema does not have."""
    for rule in rules:
        for name in rule.names:
            if name not in SPECS:
                raise ValueError(f"parameter schema: a rule reads unknown parameter {name}")


_check_rules(RULES)


def consistency_problems(values: Mapping[str, Value],
                         rules: Sequence[Rule] = RULES) -> list[Problem]:
    """Violations of ``rules`` (:data:`RULES`) in ``values`` (every schema name present), in
    rule order."""
    return [problem for rule in rules for problem in rule.problems(values)]


def _check_defaults(rules: Sequence[Rule]) -> None:
    """Raise when the schema's defaults break one of ``rules`` (naming the first problem)."""
    problems = consistency_problems({s.name: s.default for s in SCHEMA}, rules)
    if problems:
        raise ValueError(f"parameter schema: defaults break a rule: {problems[0][0]}")


_check_defaults(RULES)
