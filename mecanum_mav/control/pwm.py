"""The PWM edge: normalized wheel commands -> RC channel pulse widths (microseconds).

This is the one place where mirrored motors are handled (per-wheel reverse) and where the
per-wheel PWM range lives (``MOT_<W>_MIN/TRIM/MAX``). Neutral is each wheel's trim: a stopped
wheel, and what every failsafe sends.

It is also where the ESCs' dead band is compensated (``MOT_DZ``, ``MOT_DZ_TYPE``,
:meth:`PwmMap.pulses_us`):
every wheel command becomes a pulse here, whether from the sticks (the general path and the
compiled stick lane) or from the GUIDED/AUTO controllers. What a pulse stands for
(:meth:`WheelOutput.command_from_pulse`, the simulated ESC's view) does not undo it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mecanum_mav.mecanum.wheels import WHEEL_KEYS

if TYPE_CHECKING:
    from mecanum_mav.config.params import Params

__all__ = ["DEAD_BAND_LIVE", "WHEEL_KEYS", "PwmMap", "WheelOutput"]

DEAD_BAND_LIVE = 0.002
"""Wheel commands (normalized) whose size is at most this are not compensated for the dead
band: they stay inside it, so a wheel told to (all but) stop brakes. One microsecond of the
usual 500 us half-range: a position controller holding its target (``GUID_POS_P`` 1.5,
``WHL_MAX_SPD`` 3 m/s) lets the wheels rest within 4 mm of it instead of jumping to the
band's edge and back."""


@dataclass(frozen=True)
class WheelOutput:
    """One wheel's output channel.

    Attributes:
        channel: RC channel number, 1..18.
        minimum, trim, maximum: pulse widths in microseconds; trim is neutral (stopped).
        reversed: True when the motor is mounted mirrored: +1 then maps to ``minimum``.
    """

    channel: int
    minimum: int
    trim: int
    maximum: int
    reversed: bool = False

    def pulse_us(self, command: float) -> int:
        """Pulse width in microseconds for a normalized command in [-1, 1] (limited to it).

        Positive commands go from trim towards maximum, negative towards minimum, each side
        linear on its own (so an off-centre trim still gives full range both ways). A
        non-finite command gives trim.
        """
        if not math.isfinite(command):
            return self.trim
        c = -command if self.reversed else command
        c = -1.0 if c < -1.0 else (1.0 if c > 1.0 else c)
        span = (self.maximum - self.trim) if c >= 0.0 else (self.trim - self.minimum)
        return round(self.trim + c * span)

    def command_from_pulse(self, pulse_us: float) -> float:
        """Normalized command in [-1, 1] that a pulse width (microseconds) stands for.

        The inverse of :meth:`pulse_us` (exact up to its rounding to whole microseconds):
        each side of trim is linear on its own, reverse flips the sign, and pulses outside
        [minimum, maximum] are limited to them. A non-finite pulse gives 0 (stopped).
        """
        if not math.isfinite(pulse_us):
            return 0.0
        p = min(max(float(pulse_us), self.minimum), self.maximum)
        span = (self.maximum - self.trim) if p >= self.trim else (self.trim - self.minimum)
        c = (p - self.trim) / span
        return -c if self.reversed else c


@dataclass(frozen=True)
class PwmMap:
    """The four wheels' output channels, in wheel order FL, FR, RL, RR, and the ESCs' dead
    band (``MOT_DZ``, a fraction of full command, 0 = no compensation) and how the ESCs drive
    past it (``MOT_DZ_TYPE``: False offset, True jump; :meth:`pulses_us`)."""

    wheels: tuple[WheelOutput, WheelOutput, WheelOutput, WheelOutput]
    dead_band: float = 0.0
    dead_band_jump: bool = False

    @classmethod
    def from_params(cls, params: Params) -> PwmMap:
        """Build from the ``MOT_<W>_CH/MIN/TRIM/MAX/REV`` and ``MOT_DZ`` parameters."""
        outs = [
            WheelOutput(
                channel=int(params[f"MOT_{w}_CH"]),
                minimum=int(params[f"MOT_{w}_MIN"]),
                trim=int(params[f"MOT_{w}_TRIM"]),
                maximum=int(params[f"MOT_{w}_MAX"]),
                reversed=bool(params[f"MOT_{w}_REV"]),
            )
            for w in WHEEL_KEYS
        ]
        return cls((outs[0], outs[1], outs[2], outs[3]), float(params["MOT_DZ"]),
                   bool(params["MOT_DZ_TYPE"]))

    def __post_init__(self) -> None:
        # Precomputed once: the control loop asks for these on every output.
        w = self.wheels
        object.__setattr__(self, "channels", tuple(x.channel for x in w))
        object.__setattr__(self, "_neutral", (w[0].trim, w[1].trim, w[2].trim, w[3].trim))
        object.__setattr__(self, "spans", tuple((x.trim, x.maximum - x.trim, x.trim - x.minimum,
                                                 -1.0 if x.reversed else 1.0) for x in w))
        band = self.dead_band
        object.__setattr__(self, "_lift_keep",
                           (0.0, 1.0) if self.dead_band_jump else (band, 1.0 - band))

    channels: tuple[int, ...] = field(init=False)
    """RC channel numbers (1..18) of FL, FR, RL, RR."""
    spans: tuple[tuple[int, int, int, float], ...] = field(init=False, repr=False,
                                                          compare=False)
    """Per wheel, FL, FR, RL, RR: trim, maximum - trim, trim - minimum (us), and the sign a
    command is multiplied by (-1.0 reversed, else 1.0)."""
    _neutral: tuple[int, int, int, int] = field(init=False, repr=False, compare=False)
    _lift_keep: tuple[float, float] = field(init=False, repr=False, compare=False)
    """The dead band's map past its edge, ``|c| -> lift + keep * |c|`` (:meth:`pulses_us`)."""

    def neutral(self) -> tuple[int, int, int, int]:
        """Trim on every wheel, microseconds: the safe output."""
        return self._neutral

    def pulses_us(self, wheels: Sequence[float] | NDArray[np.float64]) -> tuple[int, int, int, int]:
        """Pulse widths (us) for one set of four normalized wheel commands FL, FR, RL, RR:
        :meth:`WheelOutput.pulse_us` of each, in one call (it runs at the output rate, with
        cold caches), with the ESCs' dead band compensated.

        Dead band ``dz`` (:attr:`dead_band`): a command ``c`` (limited to [-1, 1]) larger in
        size than :data:`DEAD_BAND_LIVE` is sent so that an ESC that does not drive under
        ``dz`` drives it: for an ESC whose output starts from zero at the band's edge (offset,
        as ArduPilot's MOT_THR_MIN assumes) as ``sign(c) * (dz + (1 - dz) * |c|)``; for one
        that jumps to the command there (:attr:`dead_band_jump`) as ``sign(c) * max(|c|,
        dz)``. 1 stays 1; 0 and commands at most :data:`DEAD_BAND_LIVE` in size stay as they
        are (inside the band: the wheel brakes).
        """
        band = self.dead_band
        lift, keep = self._lift_keep
        live = DEAD_BAND_LIVE
        pulses = []
        for command, (trim, up, down, sign) in zip(wheels, self.spans, strict=True):
            c = sign * command
            if not -1.0 <= c <= 1.0:  # (one test on the way every output takes)
                if not math.isfinite(c):
                    pulses.append(trim)
                    continue
                c = 1.0 if c > 0.0 else -1.0
            if band:
                if c > live:
                    c = lift + keep * c
                    if c < band:
                        c = band
                elif c < -live:
                    c = keep * c - lift
                    if c > -band:
                        c = -band
            pulses.append(round(trim + c * (up if c >= 0.0 else down)))
        return pulses[0], pulses[1], pulses[2], pulses[3]

    def pulses_us_array(self, wheels: ArrayLike) -> NDArray[np.int64]:
        """Vectorized :meth:`pulses_us` for ``[..., 4]`` commands; returns ``[..., 4]`` ints."""
        c = np.asarray(wheels, dtype=np.float64)
        sign = np.array([-1.0 if w.reversed else 1.0 for w in self.wheels])
        trim = np.array([w.trim for w in self.wheels], dtype=np.float64)
        up = np.array([w.maximum - w.trim for w in self.wheels], dtype=np.float64)
        down = np.array([w.trim - w.minimum for w in self.wheels], dtype=np.float64)
        finite = np.isfinite(c)
        c = np.clip(np.where(finite, c, 0.0) * sign, -1.0, 1.0)
        if self.dead_band:
            band = self.dead_band
            lift, keep = self._lift_keep
            size = np.abs(c)
            c = np.where(size > DEAD_BAND_LIVE,
                         np.sign(c) * np.maximum(lift + keep * size, band), c)
        pulses: NDArray[np.int64] = np.rint(trim + c * np.where(c >= 0.0, up, down)).astype(
            np.int64)
        return pulses
