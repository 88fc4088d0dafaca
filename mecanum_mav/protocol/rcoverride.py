"""RC_CHANNELS_OVERRIDE channel rules: the one definition, for writing and for reading.

The message has 18 channel fields with two conventions (MAVLink common / ArduPilot):

- channels 1-8: ``65535`` = leave the channel alone, ``0`` = release it to the radio;
- channels 9-18: ``0`` or ``65535`` = leave it alone, ``65534`` = release it.

Any other value is a pulse width in microseconds that overrides the channel.

Writing (the companion to the flight controller): :func:`override_fields` and
:func:`release_fields` build the 18 fields for the four wheel channels. Channels the companion
does not own are always "leave alone" (65535 on 1-8, 0 on 9-18), never zeroed: a zero on 1-8
would release a channel someone else may be overriding.

Reading (a ground station's sticks, the simulated flight controller): :func:`field_action`
says what one field asks for.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

__all__ = [
    "CHANNELS",
    "LEAVE",
    "LEAVE_HIGH",
    "LEAVE_LOW",
    "LOW_CHANNELS",
    "RELEASE",
    "RELEASE_HIGH",
    "RELEASE_LOW",
    "field_action",
    "override_fields",
    "release_fields",
]

CHANNELS: Final = 18
"""Channel fields RC_CHANNELS_OVERRIDE carries (``chan1_raw`` .. ``chan18_raw``)."""
LOW_CHANNELS: Final = 8
"""Channels 1..LOW_CHANNELS follow the first convention, the rest the second."""

LEAVE_LOW: Final = 65535
"""Channels 1-8: leave the channel alone (UINT16_MAX). Also "leave alone" on 9-18."""
LEAVE_HIGH: Final = 0
"""Channels 9-18: leave the channel alone (what the companion writes there)."""
RELEASE_LOW: Final = 0
"""Channels 1-8: release the channel to the radio."""
RELEASE_HIGH: Final = 65534
"""Channels 9-18: release the channel to the radio (UINT16_MAX - 1)."""

LEAVE: Final = -1
""":func:`field_action`'s answer: leave the channel as it is (keep any override in force)."""
RELEASE: Final = -2
""":func:`field_action`'s answer: end the override, give the channel back to the radio."""


def field_action(channel: int, raw: int) -> int:
    """What one ``chanN_raw`` field asks for: :data:`LEAVE`, :data:`RELEASE` or a pulse.

    Args:
        channel: the channel number, 1..18 (the field is ``chan{channel}_raw``).
        raw: the field's value, 0..65535.

    Returns:
        :data:`LEAVE` (-1), :data:`RELEASE` (-2), or else ``raw`` itself: the pulse width in
        microseconds to override the channel with (any other value, not range-checked here;
        never 0, and never 65534 on channels 9-18). Plain ints, a few comparisons: cheap
        enough for 18 fields per message at 1 kHz.
    """
    if raw == LEAVE_LOW:
        return LEAVE
    if channel <= LOW_CHANNELS:
        return RELEASE if raw == RELEASE_LOW else raw
    if raw == LEAVE_HIGH:
        return LEAVE
    return RELEASE if raw == RELEASE_HIGH else raw


_UNTOUCHED: Final = [LEAVE_LOW] * LOW_CHANNELS + [LEAVE_HIGH] * (CHANNELS - LOW_CHANNELS)


def _untouched() -> list[int]:
    return _UNTOUCHED.copy()


def override_fields(channels: Sequence[int], pulses_us: Sequence[int]) -> list[int]:
    """The 18 ``chanN_raw`` fields that set ``channels`` (1..18) to ``pulses_us``.

    Args:
        channels: RC channel numbers of FL, FR, RL, RR.
        pulses_us: pulse widths in microseconds, same order.
    """
    fields = _UNTOUCHED.copy()
    for channel, pulse in zip(channels, pulses_us, strict=True):
        fields[channel - 1] = int(pulse)
    return fields


def release_fields(channels: Sequence[int]) -> list[int]:
    """The 18 fields that hand ``channels`` back to the flight controller's radio input."""
    fields = _untouched()
    for channel in channels:
        fields[channel - 1] = RELEASE_LOW if channel <= LOW_CHANNELS else RELEASE_HIGH
    return fields
