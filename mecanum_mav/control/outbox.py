"""What the core returns: the messages to send on each link and the RC override when one is due.

:class:`Outbox` is what :meth:`~mecanum_mav.control.core.RoverCore.handle`,
:meth:`~mecanum_mav.control.core.RoverCore.tick` and
:meth:`~mecanum_mav.control.core.RoverCore.housekeeping` return; :data:`NOTHING` the empty one
(compare with ``is``). Re-exported by :mod:`mecanum_mav.control.core`, where the loop, the
simulator and the app import them from.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial
from typing import Any, NamedTuple

__all__ = ["NOTHING", "Outbox", "RcOverride", "new_outbox", "new_override"]


class RcOverride(NamedTuple):
    """One RC_CHANNELS_OVERRIDE to the flight controller."""

    target_system: int
    target_component: int
    channels: list[int]
    """The 18 ``chanN_raw`` fields, channel 1 first."""


class Outbox(NamedTuple):
    """What the core wants sent: message objects per link, and the override if one is due."""

    gcs: Sequence[Any]
    fc: Sequence[Any]
    override: RcOverride | None = None


# The hot path builds these two tuples up to 1000 times a second: tuple.__new__ skips the
# generated keyword-handling __new__ (120 ns instead of 240 ns each), same values.
new_override: Callable[[tuple[int, int, list[int]]], RcOverride] = partial(
    tuple.__new__, RcOverride)
new_outbox: Callable[[tuple[Sequence[Any], Sequence[Any], RcOverride | None]], Outbox] = (
    partial(tuple.__new__, Outbox))

NOTHING = Outbox((), (), None)
"""The outbox with nothing in it (the common answer to a message: compare with ``is``)."""
