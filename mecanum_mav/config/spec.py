"""One parameter's definition (:class:`ParamSpec`) and the check of a single value.

A :class:`ParamSpec` is one entry of the schema (:mod:`mecanum_mav.config.schema`): name,
kind, default, inclusive range, units, one sentence, enumeration labels and whether a change
waits for a restart. It checks itself when it is built (a bad entry raises ``ValueError``
at import) and checks one value against itself (:meth:`ParamSpec.check`,
:meth:`ParamSpec.parse`); the rules between parameters are :mod:`mecanum_mav.config.rules`.

Float encoding
    MAVLink carries every parameter value as a float32 (``PARAM_VALUE.param_value``). A float
    parameter is therefore stored as the float32 it will travel as, written as the shortest
    decimal that reads back to that float32 (``0.15``, not ``0.15000000596046448``; see
    :func:`float32_canonical`). So the value a ground station shows, the value in a saved file
    and the value the control loop reads are the same number, and save -> load and
    float32 -> store -> float32 round trips are exact. The change is below 1e-7 relative. Int
    parameters stay Python ints; their ranges are far inside float32's exact-integer range.
"""

from __future__ import annotations

import contextlib
import math
import numbers
import re
import struct
import types
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

__all__ = [
    "NAME_MAX_LEN",
    "ParamError",
    "ParamFileError",
    "ParamSpec",
    "Value",
    "float32_canonical",
    "join_words",
    "show_number",
]

Value = int | float
"""A parameter value: ``int`` for int parameters, ``float`` for float parameters."""

NAME_MAX_LEN = 16
"""MAVLink ``param_id`` is 16 characters."""

_NAME_RE = re.compile(r"[A-Z][A-Z0-9]*(?:_[A-Z0-9]+)+|MODE[1-6]")
"""``GROUP_NAME``; and ArduPilot Rover's mode-switch names MODE1..MODE6 (group ``MODE``)."""
_NUMBER_RE = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_NON_FINITE_RE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)
_FLOAT32 = struct.Struct("<f")
_FLOAT32_EXACT_INT = 2**24


class ParamError(ValueError):
    """One parameter name or value was rejected; the message says which and why."""


class ParamFileError(ValueError):
    """A parameter file was rejected; nothing from it was applied.

    ``errors`` holds every problem found, each formatted ``"{path}:{line}: {message}"``.
    """

    def __init__(self, errors: Sequence[str]) -> None:
        self.errors: list[str] = list(errors)
        super().__init__(self.errors)

    def __str__(self) -> str:
        count = len(self.errors)
        heading = f"parameter file rejected, nothing applied ({count} error{'s' * (count != 1)}):"
        return "\n".join([heading, *(f"  {e}" for e in self.errors)])


def float32_of(x: float) -> float:
    """``x`` rounded to the nearest float32 (what a MAVLink float field carries), as a float.
    Raises ``OverflowError`` outside float32's range."""
    single: float = _FLOAT32.unpack(_FLOAT32.pack(x))[0]
    return single


def float32_canonical(x: float) -> float:
    """Return the float that ``x`` becomes as a MAVLink float32, written shortest.

    ``x`` is rounded to float32 and the result is the shortest decimal (at most 9
    significant digits) that reads back to that same float32, e.g. ``0.15`` for any input
    that rounds to float32(0.15). The function is idempotent and monotonic, and
    ``float32_canonical(float32(v)) == v`` for every value it returns.
    Raises ``OverflowError`` outside float32's range.
    """
    single = float32_of(x)
    for digits in range(1, 10):
        shortest = float(format(single, f".{digits}g"))
        if _FLOAT32.unpack(_FLOAT32.pack(shortest))[0] == single:
            return shortest
    return single  # pragma: no cover - 9 significant digits always identify a float32


def show_number(x: float) -> str:
    """Format a number for a message: integral values without decimals (``-0.0`` as ``0``),
    others as Python writes them (``0.25``, ``1e+16``, ``inf``)."""
    text = repr(float(x) + 0.0)  # + 0.0: -0.0 becomes 0.0
    return text.removesuffix(".0")


def join_words(items: Sequence[str], word: str = "or") -> str:
    """``A``, ``A or B``, ``A, B or C``."""
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} {word} {items[-1]}"


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: name, kind, default, inclusive range, units, meaning, labels, and
    whether a change waits for a restart.

    Construction checks the entry and raises ``ValueError`` when it is inconsistent (bad
    name, default out of range, int parameter with a non-int bound, float bound that does
    not survive float32, enumeration labels that do not cover the range).
    """

    name: str
    kind: type[int] | type[float]
    default: Value
    minimum: Value
    maximum: Value
    units: str
    description: str
    values: Mapping[int, str] | None = field(default=None, hash=False)
    """Enumeration labels (value -> label); ``None`` for a plain number."""
    reboot_required: bool = False
    """True when a new value is stored at once but used only after a restart (ArduPilot's
    ``RebootRequired``): the MAVLink parameter service says so when it is set."""

    def __post_init__(self) -> None:
        if self.values is not None:
            object.__setattr__(self, "values", types.MappingProxyType(dict(self.values)))
        problem = self._problem()
        if problem:
            raise ValueError(f"parameter schema: {self.name}: {problem}")

    def _problem(self) -> str | None:
        """Say what is wrong with this entry, or ``None``."""
        bounds = (self.default, self.minimum, self.maximum)
        if len(self.name) > NAME_MAX_LEN or not _NAME_RE.fullmatch(self.name):
            return f"name must be GROUP_NAME in upper case, at most {NAME_MAX_LEN} characters"
        if self.kind not in (int, float):
            return "kind must be int or float"
        if any(isinstance(b, bool) or not isinstance(b, self.kind) for b in bounds):
            return f"default, minimum and maximum must be of kind {self.kind.__name__}"
        if not self.minimum <= self.default <= self.maximum:
            return "default must lie within minimum .. maximum"
        if self.kind is float and any(float32_canonical(b) != b for b in bounds):
            return "default, minimum and maximum must be exact as float32 (float32_canonical)"
        if self.kind is int and max(abs(self.minimum), abs(self.maximum)) > _FLOAT32_EXACT_INT:
            return "int range must be exact as float32 (within +-2**24)"
        if not self.description.strip().endswith("."):
            return "description must be one sentence ending with a full stop"
        if self.values is not None:
            if self.kind is not int:
                return "an enumeration must be of kind int"
            if set(self.values) != set(range(int(self.minimum), int(self.maximum) + 1)):
                return "enumeration labels must cover minimum .. maximum exactly"
        return None

    @property
    def group(self) -> str:
        """The group a file and the table list this parameter under (``MOT_FL``, ``GEO``)."""
        parts = self.name.split("_")
        if len(parts) == 1:  # MODE1 .. MODE6
            return self.name.rstrip("0123456789")
        return "_".join(parts[:2]) if parts[0] == "MOT" else parts[0]

    def with_units(self, x: float) -> str:
        """Format ``x`` followed by this parameter's units, if any."""
        return f"{show_number(x)} {self.units}" if self.units else show_number(x)

    def range_text(self, *, units: bool = True) -> str:
        """The accepted values: ``0.02 .. 5 m`` or ``0 = normal, 1 = reversed``."""
        if self.values is not None:
            return ", ".join(f"{k} = {label}" for k, label in sorted(self.values.items()))
        high = self.with_units(self.maximum) if units else show_number(self.maximum)
        return f"{show_number(self.minimum)} .. {high}"

    def format(self, value: Value) -> str:
        """Write ``value`` as a parameter file does: ints without decimals, floats shortest."""
        return str(int(value)) if self.kind is int else repr(float(value))

    def check(self, value: object) -> Value:
        """Validate ``value`` and return it as stored (``int``, or float32-canonical ``float``).

        A float is rounded to float32 before the range check, so a value that float32 carries
        as a bound (``0.02`` arrives as ``0.019999999552965164``) is accepted as that bound.
        Raises :class:`ParamError` for a non-number, a non-finite value, a non-integral
        value for an int parameter, or a value outside the range.
        """
        if isinstance(value, (bool, str, bytes)) or not isinstance(value, numbers.Real):
            raise ParamError(f"{self.name}: expected a number, got {value!r}")
        try:
            x = float(value)
        except OverflowError:  # an int beyond float's range
            raise ParamError(f"{self.name}: {value} is outside {self.range_text()}") from None
        if not math.isfinite(x):
            raise ParamError(f"{self.name}: value must be finite, got {x!r}")
        if self.kind is int and not x.is_integer():
            raise ParamError(f"{self.name}: {x!r} is not an integer; this parameter is an int")
        if self.kind is float:  # the range applies to the value as stored and sent
            with contextlib.suppress(OverflowError):  # beyond float32: out of range anyway
                x = float32_canonical(x)
        if not self.minimum <= x <= self.maximum:
            raise ParamError(self._range_message(x))
        return int(x) if self.kind is int else x

    def _range_message(self, x: float) -> str:
        if self.values is not None:
            return f"{self.name}: {show_number(x)} is not one of {self.range_text()}"
        return f"{self.name}: {self.with_units(x)} is outside the range {self.range_text()}"

    def parse(self, text: str) -> Value:
        """Parse and validate a value written in a file or on the command line."""
        text = text.strip()
        if not text:
            raise ParamError(f"{self.name}: missing value")
        if not (_NUMBER_RE.fullmatch(text) or _NON_FINITE_RE.fullmatch(text)):
            raise ParamError(f"{self.name}: {text!r} is not a number")
        return self.check(float(text))
