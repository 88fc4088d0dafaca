"""Typed, frozen views of the parameters, one per concern, rebuilt when a parameter changes.

The control path reads attributes of these small frozen dataclasses (``config.refresh_period_s``)
instead of looking parameters up by name: no string lookups, no unit conversions, no ``int()``
or ``float()`` per message. The owner builds a view with ``from_params(params)`` at start and
again after every accepted PARAM_SET, so a view is always consistent with one state of the
store. Units are in the attribute names where they are not obvious.
"""

from __future__ import annotations

from dataclasses import dataclass

from mecanum_mav.config.params import Params

__all__ = ["FailsafeConfig", "IdentityConfig", "InputConfig", "OutputConfig"]


@dataclass(frozen=True, slots=True)
class IdentityConfig:
    """Who is who on the two links."""

    sysid: int
    """This vehicle's system id on the ground-station link (``SYSID_THISMAV``)."""
    gcs_sysid: int
    """The only ground station allowed to command and drive, 0 = any (``SYSID_MYGCS``)."""
    fc_sysid: int
    """The flight controller's system id (``FC_SYSID``)."""
    fc_compid: int
    """The flight controller's component id (``FC_COMPID``)."""
    fc_gcs_sysid: int
    """The id the companion sends as on the flight-controller link (``FC_GCS_SYSID``)."""

    @classmethod
    def from_params(cls, params: Params) -> IdentityConfig:
        """Read ``SYSID_THISMAV``, ``SYSID_MYGCS`` and ``FC_SYSID``, ``FC_COMPID``, ``FC_GCS_SYSID``
        (the last three of the flight-controller link)."""
        return cls(int(params["SYSID_THISMAV"]), int(params["SYSID_MYGCS"]),
                   int(params["FC_SYSID"]), int(params["FC_COMPID"]),
                   int(params["FC_GCS_SYSID"]))


@dataclass(frozen=True, slots=True)
class InputConfig:
    """How a pilot's sticks become a drive command (shaping and mixing)."""

    deadband: float
    """Deadband as a fraction of full stick (``INP_DEADBAND``)."""
    expo: float
    """Cubic expo weight, 0 linear .. 1 cubic (``INP_EXPO``)."""
    circle: bool
    """Limit the (x, y) stick to the unit circle (``INP_CIRCLE``)."""
    z_scale: bool
    """MANUAL_CONTROL z scales the stick (``MAN_Z_SCALE``)."""
    algorithm: int
    """Mixing algorithm index into ``mixing.ALGORITHM_NAMES`` (``MIX_ALGO``)."""
    desaturation: int
    """``mixing.Desaturation`` value (``MIX_DESAT``)."""

    @classmethod
    def from_params(cls, params: Params) -> InputConfig:
        """Read ``INP_*``, ``MAN_Z_SCALE`` and ``MIX_*``."""
        return cls(float(params["INP_DEADBAND"]), float(params["INP_EXPO"]),
                   bool(params["INP_CIRCLE"]), bool(params["MAN_Z_SCALE"]),
                   int(params["MIX_ALGO"]), int(params["MIX_DESAT"]))


@dataclass(frozen=True, slots=True)
class OutputConfig:
    """The output to the flight controller."""

    refresh_period_s: float
    """Seconds between RC_CHANNELS_OVERRIDE refreshes (1 / ``OUT_RATE``)."""
    control_period_s: float
    """Seconds between GUIDED/AUTO control ticks (1 / ``CTL_RATE``)."""
    wheel_speed_max_mps: float
    """Wheel surface speed at full command, m/s (``WHL_MAX_SPD``)."""

    @classmethod
    def from_params(cls, params: Params) -> OutputConfig:
        """Read ``OUT_RATE``, ``CTL_RATE`` and ``WHL_MAX_SPD``."""
        return cls(1.0 / float(params["OUT_RATE"]), 1.0 / float(params["CTL_RATE"]),
                   float(params["WHL_MAX_SPD"]))


@dataclass(frozen=True, slots=True)
class FailsafeConfig:
    """The failsafe timeouts and the ground-station failsafe action."""

    input_timeout_s: float
    """Stick input older than this stops MANUAL driving (``FS_INPUT_TMO``)."""
    gcs_timeout_s: float
    """No ground-station HEARTBEAT for this long triggers the action (``FS_GCS_TMO``)."""
    gcs_action_disarm: bool
    """The ground-station failsafe disarms (True) or switches to HOLD (``FS_GCS_ACTION``)."""
    fc_timeout_s: float
    """No flight-controller HEARTBEAT for this long disarms (``FS_FC_TMO``)."""

    @classmethod
    def from_params(cls, params: Params) -> FailsafeConfig:
        """Read ``FS_INPUT_TMO``, ``FS_GCS_TMO``, ``FS_GCS_ACTION`` and ``FS_FC_TMO``."""
        return cls(float(params["FS_INPUT_TMO"]), float(params["FS_GCS_TMO"]),
                   int(params["FS_GCS_ACTION"]) == 1, float(params["FS_FC_TMO"]))
