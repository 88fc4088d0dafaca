"""The RC receiver read through the flight controller: RC_CHANNELS -> stick, mode, arming.

With ``RCIN_ENABLE`` the companion asks the flight controller for RC_CHANNELS (its receiver's
pulse widths, us) and reads them as ArduPilot Rover reads its receiver:

- Sticks: channels ``RCMAP_THROTTLE`` (forward), ``RCMAP_LATERAL`` (right) and ``RCMAP_STEER``
  (clockwise), pulses about ``RCIN_TRIM`` within ``RCIN_MIN..RCIN_MAX``
  (:func:`~mecanum_mav.control.sticks.stick_from_pulses`, as a ground station's override);
  the core shapes and mixes them as MANUAL_CONTROL.
- Mode switch: channel ``MODE_CH``, six positions (ArduPilot's ``read_6pos_switch``: below
  1231, 1361, 1491, 1621, 1750 us and above; at or below 900 or at or above 2200 is no
  reading), a new position held :data:`DEBOUNCE_S` selects ``MODE1..MODE6``. The first
  position read counts as new, so the switch sets the mode when the receiver appears; after
  that only a move does (a ground station's mode change stands until the switch moves).
- Arm switch: channel ``RCIN_ARM_CH`` (ArduPilot ``RCn_OPTION`` 153), three positions (below
  1200 low, above 1800 high; outside 800..2200 no reading), a change held :data:`DEBOUNCE_S`:
  high arms, low disarms. The first position read is where the switch stands, not a change
  (a switch left high does not arm at boot).
- Failsafe (:attr:`ReceiverFrame.problem`): no channels (``chancount`` 0), RSSI 0 (255 is
  "unknown" and fine), a throttle pulse below ``FS_THR_VALUE``, or a stick channel without a
  pulse (beyond ``chancount``, 0 or UINT16_MAX, outside 800..2200 us). Such a frame gives no
  stick and moves no switch.

Pure logic, time passed in; :class:`~mecanum_mav.control.core.RoverCore` acts on the frames.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

from mecanum_mav.config.views import RcInputConfig, ReceiverConfig
from mecanum_mav.control.sticks import PULSE_RANGE_US, Stick, stick_from_pulses

__all__ = ["DEBOUNCE_S", "RC_CHANNELS_INTERVAL_US", "ReceiverFrame", "ReceiverInput",
           "arm_switch_position", "mode_switch_position"]

RC_CHANNELS_INTERVAL_US = 40_000
"""The flight controller is asked for RC_CHANNELS every 40 ms (25 Hz)."""
DEBOUNCE_S = 0.2
"""A switch's new position counts once held this long (ArduPilot SWITCH_DEBOUNCE_TIME_MS)."""
_MODE_BANDS_US = (1231, 1361, 1491, 1621, 1750)
ARM_LOW_US, ARM_HIGH_US = 1200, 1800
"""Arm switch: low below 1200 us (disarm), high above 1800 us (arm)."""


def mode_switch_position(pulse_us: int) -> int | None:
    """Position 0..5 of a six-position switch at ``pulse_us``, None when no reading."""
    if pulse_us <= 900 or pulse_us >= 2200:
        return None
    return sum(pulse_us >= band for band in _MODE_BANDS_US)


def arm_switch_position(pulse_us: int) -> int | None:
    """0 low, 1 middle, 2 high for a three-position switch at ``pulse_us``, None when no
    reading."""
    if pulse_us <= 800 or pulse_us >= 2200:
        return None
    return 0 if pulse_us < ARM_LOW_US else (2 if pulse_us > ARM_HIGH_US else 1)


class _Switch:
    """A debounced switch (ArduPilot's ``RC_Channel::debounce_completed``)."""

    def __init__(self, *, first_is_change: bool) -> None:
        self.position: int | None = None
        self._first_is_change = first_is_change
        self._candidate: int | None = None
        self._since_s = 0.0

    def update(self, position: int | None, now_s: float) -> int | None:
        """The new position once it has held :data:`DEBOUNCE_S`, else None."""
        if position is None or position == self.position:
            self._candidate = None
            return None
        if position != self._candidate:
            self._candidate, self._since_s = position, now_s
            if self.position is not None or self._first_is_change:
                return None
        elif now_s - self._since_s < DEBOUNCE_S - 1e-9:
            return None
        first = self.position is None
        self.position, self._candidate = position, None
        return None if first and not self._first_is_change else position


class ReceiverFrame(NamedTuple):
    """What one RC_CHANNELS says."""

    problem: str | None
    """Why this is the receiver's failsafe, or None."""
    stick: Stick | None = None
    """The sticks (x forward, y right, r clockwise), None in failsafe."""
    mode: int | None = None
    """The Rover mode number the mode switch selects now, None if it did not move."""
    arm: bool | None = None
    """True: the arm switch went high; False: low; None: no change."""


class ReceiverInput:
    """The receiver's switches and what each RC_CHANNELS says (see the module docstring)."""

    def __init__(self) -> None:
        self._mode = _Switch(first_is_change=True)
        self._arm = _Switch(first_is_change=False)

    def frame(self, chancount: int, pulses: Sequence[int], rssi: int, config: ReceiverConfig,
              sticks: RcInputConfig, now_s: float) -> ReceiverFrame:
        """Read one RC_CHANNELS (``chancount``, ``pulses`` = chan1_raw..chan18_raw, ``rssi``)
        received at ``now_s``."""
        if chancount == 0:
            return ReceiverFrame("no channels")
        if rssi == 0:
            return ReceiverFrame("RSSI 0")
        low, high = PULSE_RANGE_US
        axes = []
        for channel in sticks.axes:
            pulse = pulses[channel - 1] if channel <= chancount else 0
            if channel == sticks.throttle_ch and pulse < config.throttle_fs_us:
                return ReceiverFrame(f"throttle {pulse} us < FS_THR_VALUE")
            if not low <= pulse <= high:
                return ReceiverFrame(f"no pulse on ch{channel}")
            axes.append(pulse)
        mode = arm = None
        if config.mode_ch and config.mode_ch <= chancount:
            position = self._mode.update(mode_switch_position(pulses[config.mode_ch - 1]), now_s)
            if position is not None:
                mode = config.modes[position]
        if config.arm_ch and config.arm_ch <= chancount:
            position = self._arm.update(arm_switch_position(pulses[config.arm_ch - 1]), now_s)
            if position is not None and position != 1:
                arm = position == 2
        return ReceiverFrame(None, stick_from_pulses(axes[0], axes[1], axes[2], sticks),
                             mode, arm)
