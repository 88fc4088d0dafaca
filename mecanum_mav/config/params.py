"""The validated parameter store (:class:`Params`) and the schema's lookups and views.

Where things are
    The schema, every parameter's definition as data, is :mod:`mecanum_mav.config.schema`
    (:data:`SCHEMA`); one entry's type and its value check is
    :mod:`mecanum_mav.config.spec` (:class:`ParamSpec`, :func:`float32_canonical`); the
    cross-parameter rules are :mod:`mecanum_mav.config.rules` (:data:`RULES`,
    :func:`consistency_problems`). This module holds the store, which keeps every value valid
    and every rule kept, the name lookups (:func:`get_spec`, :func:`unknown_name`), the
    command line's ``--set NAME=VALUE`` (:func:`parse_assignment`) and the reference table
    (:func:`markdown_table`), and re-exports the names above, so
    ``from mecanum_mav.config.params import SCHEMA, Params`` keeps working.

Files
    Parameter files (the format MAVProxy and Mission Planner load) are read and written by
    :mod:`mecanum_mav.io.paramfile`; this package holds no I/O.

Usage (through the documented facade :mod:`mecanum_mav.params`)::

    params = load("params/example_400x300_97mm_wheels.parm")
    params.set("INP_EXPO", 0.2)
    speed = params["WHL_MAX_SPD"]          # float; a plain dict lookup
    save(params, "robot.parm")
"""

from __future__ import annotations

import difflib
from collections.abc import Iterator, Mapping, Sequence

from mecanum_mav.config.rules import (
    MODE_NUMBERS,
    RULES,
    DistinctChannels,
    ModeNumbers,
    OrderedTriple,
    ReceiverChannels,
    consistency_problems,
)
from mecanum_mav.config.schema import GROUP_TITLES, RETIRED, SCHEMA, SPECS, WHEELS
from mecanum_mav.config.schema import _index as _index  # the tests check its refusals
from mecanum_mav.config.spec import (
    NAME_MAX_LEN,
    ParamError,
    ParamFileError,
    ParamSpec,
    Value,
    float32_canonical,
    join_words,
    show_number,
)

__all__ = [
    "GROUP_TITLES",
    "MODE_NUMBERS",
    "NAME_MAX_LEN",
    "RETIRED",
    "RULES",
    "SCHEMA",
    "SPECS",
    "WHEELS",
    "DistinctChannels",
    "ModeNumbers",
    "OrderedTriple",
    "ParamError",
    "ParamFileError",
    "ParamSpec",
    "Params",
    "ReceiverChannels",
    "Value",
    "consistency_problems",
    "float32_canonical",
    "get_spec",
    "markdown_table",
    "parse_assignment",
    "unknown_name",
]


def unknown_name(name: str) -> str:
    """Message for an unknown name, with the closest known names."""
    close = difflib.get_close_matches(name.upper(), SPECS, n=3, cutoff=0.6)
    hint = f"; did you mean {join_words(close)}?" if close else ""
    return f"unknown parameter {name!r}{hint}"


def get_spec(name: str) -> ParamSpec:
    """The spec of ``name``; :class:`ParamError` with a did-you-mean when it is unknown."""
    try:
        return SPECS[name]
    except KeyError:
        raise ParamError(unknown_name(name)) from None


class Params(Mapping[str, Value]):
    """A mutable, always valid and consistent store of parameter values.

    ``params["NAME"]`` is a plain dict lookup returning an ``int`` for int parameters and a
    ``float`` for float parameters. Every change goes through :meth:`set` or :meth:`update`,
    which validate against :data:`SCHEMA` and the cross-parameter rules and leave the store
    unchanged when they raise. A change replaces the internal dict in one assignment, so a
    reader never sees half of an :meth:`update`.
    """

    __slots__ = ("_values",)

    def __init__(self, values: Mapping[str, float] | None = None) -> None:
        """Start from the schema defaults, then apply ``values`` (see :meth:`update`)."""
        self._values: dict[str, Value] = {s.name: s.default for s in SCHEMA}
        if values:
            self.update(values)

    def __getitem__(self, name: str) -> Value:
        try:
            return self._values[name]
        except KeyError:
            raise KeyError(unknown_name(name)) from None

    def __contains__(self, name: object) -> bool:
        return name in self._values

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __repr__(self) -> str:
        changed = {name: self._values[name] for name in self.changed()}
        return f"Params({changed!r})"

    def set(self, name: str, value: float) -> Value:
        """Validate and store one value; return it as stored (see :meth:`ParamSpec.check`).

        Raises :class:`ParamError` (store unchanged) for an unknown name (with suggestions),
        an invalid value, or a value that breaks a cross-parameter rule; change such
        parameters in an order that stays consistent, or together with :meth:`update`.
        """
        stored = get_spec(name).check(value)
        if self._values[name] != stored:
            message = f"{name} = {show_number(stored)} rejected: "
            self._commit({**self._values, name: stored}, message)
        return stored

    def update(self, values: Mapping[str, float]) -> None:
        """Validate and store several values at once; all or nothing.

        The cross-parameter rules are checked after all values are applied, so their order
        does not matter (channels can be swapped in one call). Raises :class:`ParamError`.
        """
        candidate = dict(self._values)
        for name, value in values.items():
            candidate[name] = get_spec(name).check(value)
        self._commit(candidate, "")

    def _commit(self, candidate: dict[str, Value], prefix: str) -> None:
        problems = consistency_problems(candidate)
        if problems:
            raise ParamError(prefix + "; ".join(message for message, _ in problems))
        self._values = candidate

    def names(self) -> tuple[str, ...]:
        """All parameter names, in schema order."""
        return tuple(self._values)

    def as_dict(self) -> dict[str, Value]:
        """A copy of all values, in schema order."""
        return dict(self._values)

    def changed(self) -> list[str]:
        """Names whose value differs from the schema default, in schema order."""
        return [s.name for s in SCHEMA if self._values[s.name] != s.default]

    def copy(self) -> Params:
        """An independent store with the same values."""
        clone = Params.__new__(Params)
        clone._values = dict(self._values)
        return clone

    def check_consistency(self) -> list[str]:
        """Messages for broken cross-parameter rules (:data:`RULES`; always empty for a store
        built here)."""
        return [message for message, _ in consistency_problems(self._values)]


def parse_assignment(text: str) -> tuple[str, Value]:
    """Parse a command line ``NAME=VALUE`` into the name and the validated value.

    The value is checked against the parameter's kind and range (not the cross-parameter
    rules, which :meth:`Params.set` applies). Raises :class:`ParamError`.
    """
    name, sep, value = text.partition("=")
    name = name.strip()
    if not sep or not name:
        raise ParamError(f"expected NAME=VALUE, got {text!r}")
    return name, get_spec(name).parse(value)


def markdown_table(schema: Sequence[ParamSpec] = SCHEMA) -> str:
    """The parameter table of docs/reference/parameters.md, generated from ``schema``
    (:data:`SCHEMA`)."""
    rows = [
        "| Name | Default | Range / values | Units | Description |",
        "| --- | --- | --- | --- | --- |",
    ]
    for s in schema:
        default = s.format(s.default)
        if s.values is not None:
            default += f" ({s.values[int(s.default)]})"
        cells = (f"`{s.name}`", default, s.range_text(units=False), s.units, s.description)
        rows.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(rows) + "\n"
