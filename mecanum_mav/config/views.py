"""Typed, frozen views of the parameters, one per concern, rebuilt when a parameter changes.

The control path reads attributes of these small frozen dataclasses (``config.refresh_period_s``)
instead of looking parameters up by name: no string lookups, no unit conversions, no ``int()``
or ``float()`` per message. The owner builds a view with ``from_params(params)`` at start and
again after every accepted PARAM_SET, so a view is always consistent with one state of the
store. Units are in the attribute names where they are not obvious.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mecanum_mav.config.params import Params
from mecanum_mav.mecanum.mixing import ALGORITHM_NAMES

__all__ = [
    "FailsafeConfig",
    "GuidedConfig",
    "IdentityConfig",
    "InputConfig",
    "MissionConfig",
    "OdometryConfig",
    "OutputConfig",
    "RcInputConfig",
    "ReceiverConfig",
]


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
    algorithm: str
    """Mixing algorithm name, one of ``mixing.ALGORITHM_NAMES`` (``MIX_ALGO`` is its index)."""
    desaturation: int
    """``mixing.Desaturation`` value (``MIX_DESAT``)."""

    @classmethod
    def from_params(cls, params: Params) -> InputConfig:
        """Read ``INP_*``, ``MAN_Z_SCALE`` and ``MIX_*``."""
        return cls(float(params["INP_DEADBAND"]), float(params["INP_EXPO"]),
                   bool(params["INP_CIRCLE"]), bool(params["MAN_Z_SCALE"]),
                   ALGORITHM_NAMES[int(params["MIX_ALGO"])], int(params["MIX_DESAT"]))


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
    """The failsafe timeouts, the ground-station failsafe action and the pre-arm checks."""

    input_timeout_s: float
    """Stick input older than this stops MANUAL driving (``FS_INPUT_TMO``)."""
    gcs_timeout_s: float
    """No ground-station HEARTBEAT for this long triggers the action (``FS_GCS_TMO``)."""
    gcs_action_disarm: bool
    """The ground-station failsafe disarms (True) or switches to HOLD (``FS_GCS_ACTION``)."""
    fc_timeout_s: float
    """No flight-controller HEARTBEAT for this long disarms (``FS_FC_TMO``)."""
    arming_check: bool
    """Run the pre-arm checks before arming (``ARMING_CHECK``)."""
    receiver_failsafe: bool
    """The receiver is read (``RCIN_ENABLE``) and its failsafe is on (``FS_THR_ENABLE``)."""
    receiver_action_disarm: bool
    """The receiver failsafe disarms (True) or switches to HOLD (``FS_RC_ACTION``)."""

    @classmethod
    def from_params(cls, params: Params) -> FailsafeConfig:
        """Read ``FS_INPUT_TMO``, ``FS_GCS_TMO``, ``FS_GCS_ACTION``, ``FS_FC_TMO``,
        ``ARMING_CHECK``, ``RCIN_ENABLE``, ``FS_THR_ENABLE`` and ``FS_RC_ACTION``."""
        return cls(float(params["FS_INPUT_TMO"]), float(params["FS_GCS_TMO"]),
                   int(params["FS_GCS_ACTION"]) == 1, float(params["FS_FC_TMO"]),
                   bool(params["ARMING_CHECK"]),
                   bool(params["RCIN_ENABLE"]) and bool(params["FS_THR_ENABLE"]),
                   int(params["FS_RC_ACTION"]) == 1)


@dataclass(frozen=True, slots=True)
class RcInputConfig:
    """A ground station's RC override sticks: which channel is which axis, and the pulses."""

    throttle_ch: int
    """Channel read as the forward stick (``RCMAP_THROTTLE``)."""
    lateral_ch: int
    """Channel read as the right stick (``RCMAP_LATERAL``)."""
    steer_ch: int
    """Channel read as the clockwise rotation stick (``RCMAP_STEER``)."""
    min_us: int
    """Pulse width of full negative deflection, us (``RCIN_MIN``)."""
    trim_us: int
    """Pulse width of the centre, us (``RCIN_TRIM``)."""
    max_us: int
    """Pulse width of full positive deflection, us (``RCIN_MAX``)."""

    @property
    def axes(self) -> tuple[int, int, int]:
        """The channels of x (forward), y (right) and r (clockwise), in that order."""
        return self.throttle_ch, self.lateral_ch, self.steer_ch

    @classmethod
    def from_params(cls, params: Params) -> RcInputConfig:
        """Read ``RCMAP_THROTTLE``, ``RCMAP_LATERAL``, ``RCMAP_STEER`` and ``RCIN_*``."""
        return cls(int(params["RCMAP_THROTTLE"]), int(params["RCMAP_LATERAL"]),
                   int(params["RCMAP_STEER"]), int(params["RCIN_MIN"]),
                   int(params["RCIN_TRIM"]), int(params["RCIN_MAX"]))


@dataclass(frozen=True, slots=True)
class ReceiverConfig:
    """The RC receiver read through the flight controller (RC_CHANNELS)."""

    enabled: bool
    """Read it (``RCIN_ENABLE``)."""
    mode_ch: int
    """The six-position mode switch's channel, 0 = none (``MODE_CH``)."""
    modes: tuple[int, int, int, int, int, int]
    """Rover mode number of each switch position (``MODE1..MODE6``)."""
    arm_ch: int
    """The arm/disarm switch's channel, 0 = none (``RCIN_ARM_CH``)."""
    throttle_fs_us: int
    """A throttle pulse below this is the receiver's failsafe, us (``FS_THR_VALUE``); what
    the failsafe does is :class:`FailsafeConfig`'s."""

    @classmethod
    def from_params(cls, params: Params) -> ReceiverConfig:
        """Read ``RCIN_ENABLE``, ``MODE_CH``, ``MODE1..6``, ``RCIN_ARM_CH`` and
        ``FS_THR_VALUE``."""
        m1, m2, m3, m4, m5, m6 = (int(params[f"MODE{i}"]) for i in range(1, 7))
        return cls(bool(params["RCIN_ENABLE"]), int(params["MODE_CH"]),
                   (m1, m2, m3, m4, m5, m6), int(params["RCIN_ARM_CH"]),
                   int(params["FS_THR_VALUE"]))


@dataclass(frozen=True, slots=True)
class GuidedConfig:
    """The GUIDED velocity and heading controller's gains and limits."""

    speed_max_mps: float
    """Largest translation speed, m/s (``GUID_SPD_MAX``)."""
    accel_max_mps2: float
    """Largest change of the commanded velocity, m/s/s (``GUID_ACC_MAX``)."""
    yaw_rate_max: float
    """Largest yaw rate, rad/s (``GUID_YAW_RATE`` is in deg/s)."""
    position_gain: float
    """Commanded speed per metre of position error, 1/s (``GUID_POS_P``)."""
    yaw_gain: float
    """Commanded yaw rate per radian of heading error, 1/s (``GUID_YAW_P``)."""
    yaw_lead_s: float
    """How far ahead the heading is taken for the body velocity, s (``GUID_YAW_LEAD``)."""
    timeout_s: float
    """Velocity and yaw-rate setpoints older than this lapse, s (``GUID_TIMEOUT``)."""

    @classmethod
    def from_params(cls, params: Params) -> GuidedConfig:
        """Read the ``GUID_*`` parameters."""
        return cls(float(params["GUID_SPD_MAX"]), float(params["GUID_ACC_MAX"]),
                   math.radians(float(params["GUID_YAW_RATE"])), float(params["GUID_POS_P"]),
                   float(params["GUID_YAW_P"]), float(params["GUID_YAW_LEAD"]),
                   float(params["GUID_TIMEOUT"]))


@dataclass(frozen=True, slots=True)
class MissionConfig:
    """How AUTO drives a mission's legs."""

    speed_mps: float
    """Cruise speed until a DO_CHANGE_SPEED, m/s (``WP_SPEED``)."""
    accel_mps2: float
    """Acceleration and braking along a leg, m/s/s: ``min(WP_ACCEL, GUID_ACC_MAX)``."""
    radius_m: float
    """Default acceptance radius, m (``WP_RADIUS``)."""
    overshoot_m: float
    """How far past the next leg's line a corner may swing, m (``WP_OVERSHOOT``)."""
    face_along_legs: bool
    """Heading follows each leg (``WP_YAW_BEHAVIOR`` 1) or is held (0)."""
    position_gain: float
    """Cross-track and final-approach gain, 1/s (``WP_POS_P``)."""
    speed_limit_mps: float
    """The fastest a DO_CHANGE_SPEED may ask, m/s (``GUID_SPD_MAX``)."""

    @classmethod
    def from_params(cls, params: Params) -> MissionConfig:
        """Read the ``WP_*`` parameters and the GUIDED limits they share."""
        return cls(float(params["WP_SPEED"]),
                   min(float(params["WP_ACCEL"]), float(params["GUID_ACC_MAX"])),
                   float(params["WP_RADIUS"]), float(params["WP_OVERSHOOT"]),
                   int(params["WP_YAW_BEHAVIOR"]) == 1, float(params["WP_POS_P"]),
                   float(params["GUID_SPD_MAX"]))


@dataclass(frozen=True, slots=True)
class OdometryConfig:
    """Where dead reckoning takes its wheels and its heading from."""

    source: int
    """0 auto (WHEEL_DISTANCE while fresh, else commanded), 1 wheel distances, 2 commanded
    speeds (``ODOM_SRC``)."""
    yaw_from_gyro: bool
    """Use the flight controller's ATTITUDE yaw while fresh (``ODOM_YAW_SRC`` 0)."""
    wheel_speed_max_mps: float
    """Wheel surface speed at full command, m/s (``WHL_MAX_SPD``)."""
    half_length_m: float
    """Half the wheelbase, m (``GEO_HALF_LEN``; used from the next start)."""
    half_width_m: float
    """Half the track width, m (``GEO_HALF_WID``; used from the next start)."""
    commanded_tau_s: float = 0.0
    """The lag of commanded wheel speeds before they count as rolled, s (``ODOM_CMD_TAU``)."""
    yaw_bias: int = 2
    """Where the flight controller's yaw bias is estimated from: 0 nowhere (off), 1 its
    LOCAL_POSITION_NED, 2 its GPS_RAW_INT (``ODOM_YAW_BIAS``)."""
    position_tau_s: float = 0.0
    """Time constant of the pull toward the flight controller's position, s (``ODOM_POS_TAU``;
    0 = none)."""
    commanded_gain: float = 1.0
    """The fraction of a commanded wheel speed the wheel really rolls (``ODOM_CMD_GAIN``)."""

    @classmethod
    def from_params(cls, params: Params) -> OdometryConfig:
        """Read ``ODOM_SRC``, ``ODOM_YAW_SRC``, ``WHL_MAX_SPD``, ``GEO_HALF_*`` and
        ``ODOM_CMD_TAU``, ``ODOM_YAW_BIAS``, ``ODOM_POS_TAU``, ``ODOM_CMD_GAIN``."""
        return cls(int(params["ODOM_SRC"]), int(params["ODOM_YAW_SRC"]) == 0,
                   float(params["WHL_MAX_SPD"]), float(params["GEO_HALF_LEN"]),
                   float(params["GEO_HALF_WID"]), float(params["ODOM_CMD_TAU"]),
                   int(params["ODOM_YAW_BIAS"]), float(params["ODOM_POS_TAU"]),
                   float(params["ODOM_CMD_GAIN"]))
