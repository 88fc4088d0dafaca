"""Pilot stick input: MANUAL_CONTROL and ground-station RC_CHANNELS_OVERRIDE -> (x, y, r).

Output is a normalized stick: x forward, y right, r clockwise, each in [-1, 1], before input
shaping (:func:`mecanum_mav.mecanum.shaping.shape_stick`). Decoding is strict: a message
with a value outside its field's range is rejected whole with a reason (:class:`InputError`), never
clamped into motion.

MANUAL_CONTROL (MAVLink "directional control"): x forward, y right, r clockwise, each
-1000..1000; ``0x7FFF`` (INT16_MAX) marks an axis invalid and reads as 0. z (0..1000) is not a
drive axis; with ``MAN_Z_SCALE`` on it scales the whole stick (z/1000).

RC_CHANNELS_OVERRIDE from the ground station (MAVProxy's ``rc`` command drives this way):
channels ``RCMAP_STEER`` (rotation), ``RCMAP_THROTTLE`` (forward) and ``RCMAP_LATERAL``
(right), pulse widths around ``RCIN_TRIM`` within ``RCIN_MIN..RCIN_MAX``. Channel semantics as
ArduPilot (:mod:`mecanum_mav.protocol.rcoverride` holds the rules: on 1-8 65535 leaves the
channel as it was and 0 releases it; on 9-18 0 and 65535 leave it and 65534 releases it). There
is no radio behind the companion, so a released channel reads centre.
"""

from __future__ import annotations

from collections.abc import Sequence

from mecanum_mav.config.views import RcInputConfig
from mecanum_mav.protocol.rcoverride import LEAVE, RELEASE, field_action

__all__ = [
    "INVALID_AXIS",
    "InputError",
    "RcStickState",
    "stick_from_manual_control",
    "stick_from_pulses",
]

INVALID_AXIS = 0x7FFF
"""MANUAL_CONTROL's marker for an axis that is not in use (INT16_MAX)."""

PULSE_RANGE_US = (800, 2200)
"""Pulse widths a ground station may send for a stick; anything else is rejected."""

Stick = tuple[float, float, float]


class InputError(ValueError):
    """A stick message that must not move the robot; the text says why."""


def _axis(value: int, name: str) -> float:
    if value == INVALID_AXIS:
        return 0.0
    if not -1000 <= value <= 1000:
        raise InputError(f"MANUAL_CONTROL {name}={value} not in +-1000")
    return value / 1000.0


def stick_from_manual_control(x: int, y: int, r: int, z: int, *, z_scale: bool) -> Stick:
    """Decode MANUAL_CONTROL axes into a normalized stick (x forward, y right, r clockwise).

    Args:
        x, y, r: the message's axes, -1000..1000, or 0x7FFF for "invalid" (read as 0).
        z: the z axis, 0..1000 (0x7FFF invalid); used only when ``z_scale`` is True.
        z_scale: scale the whole stick by z/1000 (parameter ``MAN_Z_SCALE``).

    Raises:
        InputError: an axis outside its range.
    """
    stick = (_axis(x, "x"), _axis(y, "y"), _axis(r, "r"))
    if not z_scale or z == INVALID_AXIS:
        return stick
    if not 0 <= z <= 1000:
        raise InputError(f"MANUAL_CONTROL z={z} not in 0..1000")
    k = z / 1000.0
    return stick[0] * k, stick[1] * k, stick[2] * k


def stick_from_pulses(x_us: int, y_us: int, r_us: int, config: RcInputConfig) -> Stick:
    """The normalized stick (x forward, y right, r clockwise) from the pulse widths (us) of
    the three stick channels: ``RCIN_TRIM`` is 0, ``RCIN_MIN``/``RCIN_MAX`` are -1/+1,
    clamped beyond them."""
    low, trim, high = config.min_us, config.trim_us, config.max_us
    out = []
    for pulse in (x_us, y_us, r_us):
        span = (high - trim) if pulse >= trim else (trim - low)
        value = (pulse - trim) / span
        out.append(-1.0 if value < -1.0 else (1.0 if value > 1.0 else value))
    return out[0], out[1], out[2]


class RcStickState:
    """The ground station's RC override sticks, remembered across messages.

    A channel set to "leave alone" keeps its previous pulse, as ArduPilot does, so the state
    lives here. Pulses are microseconds; :meth:`stick` returns the normalized stick.
    """


    def __init__(self) -> None:
        self.pulses: dict[int, int] = {}

    def apply(self, channels: Sequence[int]) -> None:
        """Apply one RC_CHANNELS_OVERRIDE's 18 channel fields (chan1_raw..chan18_raw).

        What each field means (leave, release, pulse) is
        :func:`mecanum_mav.protocol.rcoverride.field_action`'s answer.

        Raises:
            InputError: a pulse outside 800..2200 us on any channel (nothing is applied).
        """
        updates: dict[int, int] = {}
        low, high = PULSE_RANGE_US
        for number, value in enumerate(channels, start=1):
            action = field_action(number, value)
            if action == LEAVE:
                continue
            if action != RELEASE and not low <= action <= high:
                raise InputError(f"RC ch{number}={value} not in {low}..{high} us")
            updates[number] = action
        for number, action in updates.items():
            if action == RELEASE:
                self.pulses.pop(number, None)
            else:
                self.pulses[number] = action

    def touches_sticks(self, channels: Sequence[int], config: RcInputConfig) -> bool:
        """Whether a message sets or releases any of the three stick channels."""
        return any(field_action(n, channels[n - 1]) != LEAVE for n in config.axes)

    def stick(self, config: RcInputConfig) -> Stick:
        """The normalized stick (x forward, y right, r clockwise) from the held pulses."""
        x, y, r = (self.pulses.get(number, config.trim_us) for number in config.axes)
        return stick_from_pulses(x, y, r, config)
