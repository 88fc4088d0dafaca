"""RC_CHANNELS_OVERRIDE channel fields for the four wheel channels (to the flight controller).

The message has 18 channel fields with two conventions (MAVLink common / ArduPilot):

- channels 1-8: ``65535`` = leave the channel alone, ``0`` = release it to the radio;
- channels 9-18: ``0`` or ``65535`` = leave it alone, ``65534`` = release it.

Channels the companion does not own are always "leave alone" (65535 on 1-8, 0 on 9-18), never
zeroed: a zero on 1-8 would release a channel someone else may be overriding.
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["CHANNELS", "override_fields", "release_fields"]

CHANNELS = 18
LEAVE_LOW, LEAVE_HIGH = 65535, 0
RELEASE_LOW, RELEASE_HIGH = 0, 65534


_UNTOUCHED = [LEAVE_LOW] * 8 + [LEAVE_HIGH] * (CHANNELS - 8)


def _untouched() -> list[int]:
    return _UNTOUCHED.copy()


def override_fields(channels: Sequence[int], pulses_us: Sequence[int]) -> list[int]:
    """The 18 ``chanN_raw`` fields that set ``channels`` (1..18) to ``pulses_us``.

    Args:
        channels: RC channel numbers of FL, FR, RL, RR.
        pulses_us: pulse widths in microseconds, same order.
    """
    fields = _untouched()
    for channel, pulse in zip(channels, pulses_us, strict=True):
        fields[channel - 1] = int(pulse)
    return fields


def release_fields(channels: Sequence[int]) -> list[int]:
    """The 18 fields that hand ``channels`` back to the flight controller's radio input."""
    fields = _untouched()
    for channel in channels:
        fields[channel - 1] = RELEASE_LOW if channel <= 8 else RELEASE_HIGH
    return fields
