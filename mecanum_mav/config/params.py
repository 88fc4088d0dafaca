"""The one parameter schema and the validated parameter store.

One schema
    :data:`SCHEMA` lists every parameter once (name, kind, default, range, units, one
    sentence, enumeration labels), as ArduPilot's ``AP_Param`` tables or ros2_controllers'
    ``generate_parameter_library`` do. Everything else reads it: :class:`Params` validation,
    parameter files (:func:`load`, :func:`save`), the command line's ``--set NAME=VALUE``
    (:func:`parse_assignment`), the reference table (:func:`markdown_table`) and the MAVLink
    parameter protocol (index = position in :data:`SCHEMA`). Names follow ArduPilot: at most
    16 characters (the MAVLink ``param_id`` field), upper case, ``GROUP_NAME``; the schema is
    checked when this module is imported and a bad entry raises. An entry also says whether
    a change waits for a restart (``reboot_required``, which the parameter protocol reports).

Cross-parameter rules
    :data:`RULES` declares them as data (MIN < TRIM < MAX triples, groups of distinct RC
    channels); :func:`consistency_problems` evaluates them and :class:`Params` keeps them.

Files
    Parameter files (the format MAVProxy and Mission Planner load) are read and written by
    :mod:`mecanum_mav.io.paramfile`; this module holds no I/O.

Float encoding
    MAVLink carries every parameter value as a float32 (``PARAM_VALUE.param_value``). A float
    parameter is therefore stored as the float32 it will travel as, written as the shortest
    decimal that reads back to that float32 (``0.15``, not ``0.15000000596046448``; see
    :func:`float32_canonical`). So the value a ground station shows, the value in a saved file
    and the value the control loop reads are the same number, and save -> load and
    float32 -> store -> float32 round trips are exact. The change is below 1e-7 relative. Int
    parameters stay Python ints; their ranges are far inside float32's exact-integer range.

Usage (through the documented facade :mod:`mecanum_mav.params`)::

    params = load("params/example_400x300_97mm_wheels.parm")
    params.set("INP_EXPO", 0.2)
    speed = params["WHL_MAX_SPD"]          # float; a plain dict lookup
    save(params, "robot.parm")
"""

from __future__ import annotations

import contextlib
import difflib
import math
import numbers
import re
import struct
import types
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field

from mecanum_mav.mecanum.wheels import WHEEL_KEYS as WHEELS
from mecanum_mav.mecanum.wheels import WHEEL_NAMES

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


def float32_canonical(x: float) -> float:
    """Return the float that ``x`` becomes as a MAVLink float32, written shortest.

    ``x`` is rounded to float32 and the result is the shortest decimal (at most 9
    significant digits) that reads back to that same float32, e.g. ``0.15`` for any input
    that rounds to float32(0.15). The function is idempotent and monotonic, and
    ``float32_canonical(float32(v)) == v`` for every value it returns.
    Raises ``OverflowError`` outside float32's range.
    """
    single: float = _FLOAT32.unpack(_FLOAT32.pack(x))[0]
    for digits in range(1, 10):
        shortest = float(format(single, f".{digits}g"))
        if _FLOAT32.unpack(_FLOAT32.pack(shortest))[0] == single:
            return shortest
    return single  # pragma: no cover - 9 significant digits always identify a float32


def _show(x: float) -> str:
    """Format a number for a message: integral values without decimals."""
    if math.isfinite(x) and x == int(x) and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def _join(items: Sequence[str], word: str = "or") -> str:
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
        return f"{_show(x)} {self.units}" if self.units else _show(x)

    def range_text(self, *, units: bool = True) -> str:
        """The accepted values: ``0.02 .. 5 m`` or ``0 = normal, 1 = reversed``."""
        if self.values is not None:
            return ", ".join(f"{k} = {label}" for k, label in sorted(self.values.items()))
        high = self.with_units(self.maximum) if units else _show(self.maximum)
        return f"{_show(self.minimum)} .. {high}"

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
            return f"{self.name}: {_show(x)} is not one of {self.range_text()}"
        return f"{self.name}: {self.with_units(x)} is outside the range {self.range_text()}"

    def parse(self, text: str) -> Value:
        """Parse and validate a value written in a file or on the command line."""
        text = text.strip()
        if not text:
            raise ParamError(f"{self.name}: missing value")
        if not (_NUMBER_RE.fullmatch(text) or _NON_FINITE_RE.fullmatch(text)):
            raise ParamError(f"{self.name}: {text!r} is not a number")
        return self.check(float(text))


# WHEELS (exported): the wheel abbreviations in parameter names, FL, FR, RL, RR, defined in
# mecanum_mav.mecanum.wheels as WHEEL_KEYS.
_WHEEL_WORDS = {
    abbreviation: full.replace("_", "-")
    for abbreviation, full in zip(WHEELS, WHEEL_NAMES, strict=True)
}


# fmt: off
# (the schema tables keep each entry's numbers on one line)
def _wheel_specs(wheel: str, channel: int) -> tuple[ParamSpec, ...]:
    """The five motor output parameters of one wheel (``FL`` ... ``RR``)."""
    words = _WHEEL_WORDS[wheel]
    prefix = f"MOT_{wheel}"
    return (
        ParamSpec(
            f"{prefix}_CH", int, default=channel, minimum=1, maximum=16, units="",
            description=f"RC channel (1-16, sent in RC_CHANNELS_OVERRIDE; ArduPilot never "
            f"reads 17-18) whose flight controller output drives the {words} wheel's ESC.",
        ),
        ParamSpec(
            f"{prefix}_MIN", int, default=1000, minimum=800, maximum=2200, units="us",
            description=f"ESC pulse width for full output in the {words} motor's negative "
            f"direction (full backward for the robot unless {prefix}_REV = 1).",
        ),
        ParamSpec(
            f"{prefix}_TRIM", int, default=1500, minimum=800, maximum=2200, units="us",
            description=f"ESC pulse width at which the {words} motor stands still; sent as "
            f"neutral when disarmed or in failsafe.",
        ),
        ParamSpec(
            f"{prefix}_MAX", int, default=2000, minimum=800, maximum=2200, units="us",
            description=f"ESC pulse width for full output in the {words} motor's positive "
            f"direction (full forward for the robot unless {prefix}_REV = 1).",
        ),
        ParamSpec(
            f"{prefix}_REV", int, default=0, minimum=0, maximum=1, units="",
            values={0: "normal", 1: "reversed"},
            description=f"Reverse the {words} motor at the PWM edge (set 1 for a mirrored "
            f"motor) so that a positive wheel command rolls the robot forward.",
        ),
    )


GROUP_TITLES: dict[str, str] = {
    "MIX": "Stick mixing",
    "INP": "Stick input shaping",
    "GEO": "Geometry (metres)",
    "WHL": "Wheel speed",
    **{f"MOT_{w}": f"Motor output, {_WHEEL_WORDS[w]} wheel" for w in WHEELS},
    "SYSID": "MAVLink identity",
    "FC": "Flight-controller link",
    "OUT": "Output to the flight controller",
    "FS": "Failsafes",
    "ARMING": "Arming",
    "RCMAP": "Stick channels (RC receiver and ground-station RC_CHANNELS_OVERRIDE)",
    "RCIN": "RC stick input: the receiver through the flight controller, pulse range",
    "MODE": "Mode switch (RC receiver)",
    "MAN": "Manual driving",
    "CTL": "Control loop",
    "GUID": "GUIDED driving",
    "WP": "AUTO missions",
    "ORIGIN": "Global origin of the local frame",
    "ODOM": "Odometry",
    "TLM": "Telemetry to the ground station",
    "SIM": "Built-in simulator (flight controller and chassis)",
}
"""Title of each parameter group, in file order."""

SCHEMA: tuple[ParamSpec, ...] = (
    ParamSpec(
        "MIX_ALGO", int, default=0, minimum=0, maximum=3, units="",
        values={0: "cartesian", 1: "polar_2011", 2: "max_speed_scaled", 3: "holonomic_2010"},
        description="Stick mixing algorithm that turns the (x forward, y right, r clockwise) "
        "drive command into four wheel commands.",
    ),
    ParamSpec(
        "MIX_DESAT", int, default=0, minimum=0, maximum=2, units="",
        values={0: "proportional", 1: "rotation_priority", 2: "translation_priority"},
        description="How wheel commands beyond [-1, 1] are brought back: proportional scales "
        "all four wheels together (WPILib), rotation_priority keeps the yaw command and "
        "shrinks translation along its direction (PX4), translation_priority keeps "
        "translation and shrinks rotation.",
    ),
    ParamSpec(
        "INP_DEADBAND", float, default=0.05, minimum=0.0, maximum=0.5, units="",
        description="Stick deadband as a fraction of full stick on each axis: inputs inside "
        "it read 0 and the rest is rescaled to reach 1 at full stick (WPILib applyDeadband).",
    ),
    ParamSpec(
        "INP_EXPO", float, default=0.0, minimum=0.0, maximum=1.0, units="",
        description="Cubic expo on each stick axis, out = (1 - e) * in + e * in^3 (PX4 "
        "style): 0 is linear, 1 fully cubic.",
    ),
    ParamSpec(
        "INP_CIRCLE", int, default=1, minimum=0, maximum=1, units="",
        values={0: "off", 1: "on"},
        description="Map the square stick range onto the unit circle by clamping the "
        "(x forward, y right) magnitude to 1, so a diagonal is not faster than a straight line.",
    ),
    ParamSpec(
        "GEO_HALF_LEN", float, default=0.15, minimum=0.02, maximum=5.0, units="m",
        reboot_required=True,
        description="Distance along body x (forward) from the robot centre to each wheel "
        "centre, half the wheelbase.",
    ),
    ParamSpec(
        "GEO_HALF_WID", float, default=0.15, minimum=0.02, maximum=5.0, units="m",
        reboot_required=True,
        description="Distance along body y (right) from the robot centre to each wheel "
        "centre, half the track width.",
    ),
    ParamSpec(
        "WHL_MAX_SPD", float, default=1.0, minimum=0.01, maximum=20.0, units="m/s",
        description="Wheel surface speed at full PWM (MOT_x_MIN or MOT_x_MAX), which maps a "
        "wheel command of 1 to m/s and back.",
    ),
    *(spec for i, w in enumerate(WHEELS) for spec in _wheel_specs(w, channel=i + 1)),
    ParamSpec(
        "SYSID_THISMAV", int, default=1, minimum=1, maximum=255, units="",
        reboot_required=True,
        description="MAVLink system id of the vehicle (this companion) on the ground-station "
        "link; component id is always 1.",
    ),
    ParamSpec(
        "SYSID_MYGCS", int, default=0, minimum=0, maximum=255, units="",
        description="Only the ground station with this system id may drive and command the "
        "rover (0 = any ground station).",
    ),
    ParamSpec(
        "FC_SYSID", int, default=1, minimum=1, maximum=255, units="",
        description="System id of the flight controller that RC_CHANNELS_OVERRIDE is "
        "addressed to.",
    ),
    ParamSpec(
        "FC_COMPID", int, default=1, minimum=0, maximum=255, units="",
        description="Component id of the flight controller that RC_CHANNELS_OVERRIDE is "
        "addressed to.",
    ),
    ParamSpec(
        "FC_GCS_SYSID", int, default=255, minimum=1, maximum=255, units="",
        description="System id the companion sends as on the flight-controller link; it must "
        "equal the flight controller's SYSID_MYGCS (MAV_GCS_SYSID), or ArduPilot silently "
        "drops the overrides.",
    ),
    ParamSpec(
        "OUT_RATE", float, default=20.0, minimum=2.0, maximum=200.0, units="Hz",
        description="Rate at which RC_CHANNELS_OVERRIDE is re-sent between input-driven "
        "updates, keeping the flight controller's override timeout from lapsing.",
    ),
    ParamSpec(
        "FS_INPUT_TMO", float, default=0.5, minimum=0.1, maximum=10.0, units="s",
        description="Stick input (MANUAL_CONTROL or ground-station RC override) older than "
        "this while driving by hand brings the wheels to neutral until new input arrives.",
    ),
    ParamSpec(
        "FS_GCS_TMO", float, default=3.0, minimum=0.5, maximum=60.0, units="s",
        description="No ground-station HEARTBEAT for this long triggers the ground-station "
        "failsafe action.",
    ),
    ParamSpec(
        "FS_GCS_ACTION", int, default=0, minimum=0, maximum=1, units="",
        values={0: "hold", 1: "disarm"},
        description="Ground-station failsafe action: switch to HOLD (neutral, stay armed) or "
        "disarm.",
    ),
    ParamSpec(
        "FS_FC_TMO", float, default=3.0, minimum=0.5, maximum=60.0, units="s",
        description="No flight-controller HEARTBEAT for this long reports the link lost, "
        "disarms and refuses to arm until it is back.",
    ),
    ParamSpec(
        "FS_THR_ENABLE", int, default=1, minimum=0, maximum=1, units="",
        values={0: "off", 1: "on"},
        description="Receiver failsafe (RCIN_ENABLE 1): no RC_CHANNELS for FS_INPUT_TMO, "
        "channel count 0, RSSI 0 or the throttle channel below FS_THR_VALUE takes the "
        "FS_RC_ACTION and refuses arming (ArduPilot's throttle failsafe); the wheels stop on "
        "such input either way.",
    ),
    ParamSpec(
        "FS_THR_VALUE", int, default=910, minimum=800, maximum=1100, units="us",
        description="Receiver failsafe: a throttle channel (RCMAP_THROTTLE) pulse below this "
        "is the receiver's failsafe (program the receiver to send it when the link is lost).",
    ),
    ParamSpec(
        "FS_RC_ACTION", int, default=0, minimum=0, maximum=1, units="",
        values={0: "hold", 1: "disarm"},
        description="Receiver failsafe action: switch to HOLD (neutral, stay armed) or "
        "disarm.",
    ),
    ParamSpec(
        "ARMING_CHECK", int, default=1, minimum=0, maximum=1, units="",
        values={0: "off", 1: "on"},
        description="Pre-arm checks before arming (sticks centred, the flight controller's "
        "setup safe), as ArduPilot's ARMING_CHECK; arming with param2 21196 skips them too "
        "(the flight-controller link is always required).",
    ),
    ParamSpec(
        "RCMAP_STEER", int, default=1, minimum=1, maximum=18, units="",
        description="RC channel read as the rotation (steering) stick, clockwise for pulses "
        "above trim, from the receiver or a ground station's override (ArduPilot Rover: "
        "RCMAP_ROLL, channel 1).",
    ),
    ParamSpec(
        "RCMAP_THROTTLE", int, default=3, minimum=1, maximum=18, units="",
        description="RC channel read as the forward (throttle) stick, forward for pulses "
        "above trim, from the receiver or a ground station's override (ArduPilot Rover: "
        "RCMAP_THROTTLE, channel 3).",
    ),
    ParamSpec(
        "RCMAP_LATERAL", int, default=4, minimum=1, maximum=18, units="",
        description="RC channel read as the lateral stick, right for pulses above trim, from "
        "the receiver or a ground station's override (ArduPilot Rover: RCMAP_YAW, channel 4).",
    ),
    ParamSpec(
        "RCIN_MIN", int, default=1000, minimum=800, maximum=2200, units="us",
        description="Stick pulse width for full negative deflection (receiver and "
        "ground-station overrides).",
    ),
    ParamSpec(
        "RCIN_TRIM", int, default=1500, minimum=800, maximum=2200, units="us",
        description="Stick pulse width at centre (receiver and ground-station overrides).",
    ),
    ParamSpec(
        "RCIN_MAX", int, default=2000, minimum=800, maximum=2200, units="us",
        description="Stick pulse width for full positive deflection (receiver and "
        "ground-station overrides).",
    ),
    ParamSpec(
        "RCIN_ENABLE", int, default=0, minimum=0, maximum=1, units="",
        values={0: "off", 1: "on"},
        description="Read the RC receiver on the flight controller (RC_CHANNELS, asked for "
        "at 25 Hz): its sticks drive unless a ground station's sticks are fresh, its mode and "
        "arm switches act; the wheels need channels the receiver does not use (MOT_x_CH).",
    ),
    ParamSpec(
        "RCIN_ARM_CH", int, default=0, minimum=0, maximum=16, units="",
        description="Receiver channel of an arm/disarm switch, 0 = none: high (above 1800 "
        "us) arms, low (below 1200 us) disarms, on a change held 0.2 s (ArduPilot "
        "RCn_OPTION 153).",
    ),
    ParamSpec(
        "MODE_CH", int, default=8, minimum=0, maximum=16, units="",
        description="Receiver channel of the six-position mode switch, 0 = none; a new "
        "position held 0.2 s selects MODE1..MODE6 (ArduPilot Rover MODE_CH).",
    ),
    *(ParamSpec(
        f"MODE{i}", int, default=0, minimum=0, maximum=15, units="",
        description=f"Mode of switch position {i} ({band} us): 0 MANUAL, 4 HOLD, 10 AUTO or "
        f"15 GUIDED (ArduPilot Rover MODE{i}).",
    ) for i, band in enumerate(("up to 1230", "1231-1360", "1361-1490", "1491-1620",
                                "1621-1749", "1750 and above"), start=1)),
    ParamSpec(
        "MAN_Z_SCALE", int, default=0, minimum=0, maximum=1, units="",
        values={0: "off", 1: "on"},
        description="Use MANUAL_CONTROL z (0..1000) as a speed scale on the translation and "
        "rotation sticks; off ignores z.",
    ),
    ParamSpec(
        "CTL_RATE", float, default=50.0, minimum=10.0, maximum=200.0, units="Hz",
        description="Rate of the GUIDED control loop (position, velocity and heading "
        "controllers and the wheel output).",
    ),
    ParamSpec(
        "GUID_SPD_MAX", float, default=0.7, minimum=0.05, maximum=10.0, units="m/s",
        description="GUIDED: largest translation speed, whatever the setpoint asks.",
    ),
    ParamSpec(
        "GUID_ACC_MAX", float, default=1.0, minimum=0.05, maximum=10.0, units="m/s/s",
        description="GUIDED: largest change of the commanded velocity per second; also sets "
        "the braking distance before a position target.",
    ),
    ParamSpec(
        "GUID_YAW_RATE", float, default=90.0, minimum=1.0, maximum=720.0, units="deg/s",
        description="GUIDED: largest yaw rate, whatever the setpoint asks.",
    ),
    ParamSpec(
        "GUID_POS_P", float, default=1.5, minimum=0.1, maximum=10.0, units="1/s",
        description="GUIDED: position gain, commanded speed per metre of position error.",
    ),
    ParamSpec(
        "GUID_YAW_P", float, default=2.5, minimum=0.1, maximum=20.0, units="1/s",
        description="GUIDED: heading gain, commanded yaw rate per radian of heading error.",
    ),
    ParamSpec(
        "GUID_YAW_LEAD", float, default=0.12, minimum=0.0, maximum=1.0, units="s",
        description="GUIDED: the body-frame velocity is computed for the heading the rover "
        "will have this long from now (motor lag plus pose age), so turning does not bend "
        "the path.",
    ),
    ParamSpec(
        "GUID_TIMEOUT", float, default=3.0, minimum=0.1, maximum=60.0, units="s",
        description="GUIDED: velocity and yaw-rate setpoints older than this lapse and the "
        "rover stops (position and yaw targets persist).",
    ),
    ParamSpec(
        "WP_SPEED", float, default=0.5, minimum=0.05, maximum=10.0, units="m/s",
        description="AUTO: speed along the mission's legs until a DO_CHANGE_SPEED (limited "
        "to GUID_SPD_MAX).",
    ),
    ParamSpec(
        "WP_ACCEL", float, default=0.5, minimum=0.05, maximum=10.0, units="m/s/s",
        description="AUTO: acceleration and braking along a leg (at most GUID_ACC_MAX is "
        "used).",
    ),
    ParamSpec(
        "WP_RADIUS", float, default=0.03, minimum=0.01, maximum=100.0, units="m",
        description="AUTO: a waypoint is reached within this distance unless its item gives "
        "an acceptance radius.",
    ),
    ParamSpec(
        "WP_OVERSHOOT", float, default=0.02, minimum=0.0, maximum=10.0, units="m",
        description="AUTO: how far the rover may swing past the next leg's line when it "
        "passes a waypoint without stopping; sets the speed through shallow corners.",
    ),
    ParamSpec(
        "WP_YAW_BEHAVIOR", int, default=0, minimum=0, maximum=1, units="",
        values={0: "hold heading", 1: "face along each leg"},
        description="AUTO: heading between CONDITION_YAW or waypoint yaw commands; a mecanum "
        "rover follows the same path either way.",
    ),
    ParamSpec(
        "ORIGIN_LAT", float, default=0.0, minimum=-90.0, maximum=90.0, units="deg",
        description="Latitude of the local origin for missions in global frames (0 with "
        "ORIGIN_LON 0 = none; SET_GPS_GLOBAL_ORIGIN overrides it).",
    ),
    ParamSpec(
        "ORIGIN_LON", float, default=0.0, minimum=-180.0, maximum=180.0, units="deg",
        description="Longitude of the local origin (float32 carries it to about 1 m; send "
        "SET_GPS_GLOBAL_ORIGIN for 1 cm).",
    ),
    ParamSpec(
        "ODOM_SRC", int, default=0, minimum=0, maximum=2, units="",
        values={0: "auto", 1: "wheel_distance", 2: "commanded"},
        description="Odometry source: auto uses the flight controller's WHEEL_DISTANCE while "
        "it keeps coming and the commanded wheel speeds otherwise; or only one of them.",
    ),
    ParamSpec(
        "ODOM_YAW_SRC", int, default=0, minimum=0, maximum=1, units="",
        values={0: "auto", 1: "wheels"},
        description="Odometry heading: auto uses the flight controller's ATTITUDE yaw while "
        "fresh (a gyro beats wheel-derived yaw on a slipping mecanum base), wheels uses the "
        "wheels' own turn.",
    ),
    ParamSpec(
        "TLM_POS_RATE", float, default=10.0, minimum=0.0, maximum=50.0, units="Hz",
        description="Rate of ODOMETRY, LOCAL_POSITION_NED, ATTITUDE and, once a global origin "
        "is known, GLOBAL_POSITION_INT to the ground station (0 = off).",
    ),
    ParamSpec(
        "TLM_EXT_RATE", float, default=2.0, minimum=0.0, maximum=50.0, units="Hz",
        description="Rate of SYS_STATUS, SERVO_OUTPUT_RAW and WHEEL_DISTANCE to the ground "
        "station (0 = off).",
    ),
    ParamSpec(
        "SIM_MOTOR_TAU", float, default=0.08, minimum=0.001, maximum=5.0, units="s",
        reboot_required=True,
        description="Simulator: first-order time constant of each motor's speed response.",
    ),
    ParamSpec(
        "SIM_SLIP", float, default=0.0, minimum=0.0, maximum=0.5, units="",
        reboot_required=True,
        description="Simulator: standard deviation of each wheel's traction error as a "
        "fraction of its speed (0 = no slip).",
    ),
    ParamSpec(
        "SIM_RC_TMO", float, default=0.5, minimum=0.1, maximum=60.0, units="s",
        reboot_required=True,
        description="Simulator: override timeout after which an un-refreshed RC override "
        "lapses to neutral (ArduPilot RC_OVERRIDE_TIME, as setup-fc --apply sets it; over "
        "1 s the companion's check calls the board unsafe).",
    ),
    ParamSpec(
        "SIM_GCS_SYSID", int, default=255, minimum=1, maximum=255, units="",
        reboot_required=True,
        description="Simulator: the only sender system id whose RC overrides it obeys "
        "(ArduPilot SYSID_MYGCS).",
    ),
    ParamSpec(
        "SIM_RATE", float, default=100.0, minimum=10.0, maximum=1000.0, units="Hz",
        reboot_required=True,
        description="Simulator: physics update rate.",
    ),
    ParamSpec(
        "SIM_SEED", int, default=0, minimum=0, maximum=1000000, units="",
        reboot_required=True,
        description="Simulator: random seed of the slip noise, for repeatable runs.",
    ),
)
"""Every parameter, in file, table and MAVLink index order."""
# fmt: on


RETIRED: dict[str, str] = {
    "GEO_WHEEL_RAD": "wheel speeds are WHL_MAX_SPD in m/s and odometry reads WHEEL_DISTANCE in "
    "metres, so no wheel radius is needed",
}
"""Parameters earlier versions had and nothing reads any more: name -> why. A parameter file
that still sets one loads, with a warning naming the line (:mod:`mecanum_mav.io.paramfile`)."""


def _index(schema: Sequence[ParamSpec]) -> dict[str, ParamSpec]:
    """Map names to specs, raising on a duplicate name or a group without a title."""
    specs: dict[str, ParamSpec] = {}
    for spec in schema:
        if spec.name in specs:
            raise ValueError(f"parameter schema: {spec.name} is listed twice")
        if spec.group not in GROUP_TITLES:
            raise ValueError(f"parameter schema: {spec.name}: group {spec.group} has no title")
        specs[spec.name] = spec
    return specs


SPECS: dict[str, ParamSpec] = _index(SCHEMA)
"""Name -> spec, in schema order."""


def unknown_name(name: str) -> str:
    """Message for an unknown name, with the closest known names."""
    close = difflib.get_close_matches(name.upper(), SPECS, n=3, cutoff=0.6)
    hint = f"; did you mean {_join(close)}?" if close else ""
    return f"unknown parameter {name!r}{hint}"


def get_spec(name: str) -> ParamSpec:
    """The spec of ``name``; :class:`ParamError` with a did-you-mean when it is unknown."""
    try:
        return SPECS[name]
    except KeyError:
        raise ParamError(unknown_name(name)) from None


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
            (f"{_join(on_channel, 'and')} share RC channel {channel}; {self.purpose}",
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
            (f"{_join(on, 'and')} share RC channel {ch}; one function each", tuple(on))
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


def consistency_problems(values: Mapping[str, Value]) -> list[Problem]:
    """Violations of :data:`RULES` in ``values`` (every schema name present), in rule order."""
    return [problem for rule in RULES for problem in rule.problems(values)]


_DEFAULT_PROBLEMS = consistency_problems({s.name: s.default for s in SCHEMA})
if _DEFAULT_PROBLEMS:
    raise ValueError(f"parameter schema: defaults break a rule: {_DEFAULT_PROBLEMS[0][0]}")


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
            self._commit({**self._values, name: stored}, f"{name} = {_show(stored)} rejected: ")
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


def markdown_table() -> str:
    """The parameter table of docs/reference/parameters.md, generated from :data:`SCHEMA`."""
    rows = [
        "| Name | Default | Range / values | Units | Description |",
        "| --- | --- | --- | --- | --- |",
    ]
    for s in SCHEMA:
        default = s.format(s.default)
        if s.values is not None:
            default += f" ({s.values[int(s.default)]})"
        cells = (f"`{s.name}`", default, s.range_text(units=False), s.units, s.description)
        rows.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(rows) + "\n"
