"""Each typed view of the parameters (config/views.py) reads the parameters its docstrings
name, in the units they name: every value below differs from its default and from the
others, so a view that reads the wrong parameter, drops one or converts it wrongly shows."""

from __future__ import annotations

import math

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import (
    FailsafeConfig,
    GuidedConfig,
    IdentityConfig,
    InputConfig,
    MissionConfig,
    OdometryConfig,
    OutputConfig,
    RcInputConfig,
    ReceiverConfig,
)

WHEELS_OFF_THE_RECEIVER = {"MOT_FL_CH": 9, "MOT_FR_CH": 10, "MOT_RL_CH": 11, "MOT_RR_CH": 12}
"""Where the wheels go when the receiver is read (its channels are its own)."""


def params(**values: float) -> Params:
    store = Params()
    store.update({**WHEELS_OFF_THE_RECEIVER, **values} if values.get("RCIN_ENABLE") else values)
    return store


def test_the_identity_view_reads_the_five_system_and_component_ids() -> None:
    view = IdentityConfig.from_params(params(SYSID_THISMAV=7, SYSID_MYGCS=200, FC_SYSID=3,
                                             FC_COMPID=4, FC_GCS_SYSID=250))
    assert view == IdentityConfig(sysid=7, gcs_sysid=200, fc_sysid=3, fc_compid=4,
                                  fc_gcs_sysid=250)


def test_the_input_view_names_the_mixing_algorithm_by_its_index() -> None:
    view = InputConfig.from_params(params(INP_DEADBAND=0.125, INP_EXPO=0.5, INP_CIRCLE=0,
                                          MAN_Z_SCALE=1, MIX_ALGO=3, MIX_DESAT=2))
    assert view == InputConfig(deadband=0.125, expo=0.5, circle=False, z_scale=True,
                               algorithm="holonomic_2010", desaturation=2)
    again = InputConfig.from_params(params(INP_CIRCLE=1, MAN_Z_SCALE=0, MIX_ALGO=1))
    assert (again.circle, again.z_scale, again.algorithm) == (True, False, "polar_2011")


def test_the_output_view_turns_rates_in_hz_into_periods_in_seconds() -> None:
    view = OutputConfig.from_params(params(OUT_RATE=25, CTL_RATE=40, WHL_MAX_SPD=2.5))
    assert view == OutputConfig(refresh_period_s=0.04, control_period_s=0.025,
                                wheel_speed_max_mps=2.5)


def test_the_failsafe_view_reads_timeouts_and_actions() -> None:
    view = FailsafeConfig.from_params(params(FS_INPUT_TMO=0.75, FS_GCS_TMO=5, FS_GCS_ACTION=1,
                                             FS_FC_TMO=7, ARMING_CHECK=0, RCIN_ENABLE=1,
                                             FS_THR_ENABLE=1, FS_RC_ACTION=1))
    assert view == FailsafeConfig(input_timeout_s=0.75, gcs_timeout_s=5.0,
                                  gcs_action_disarm=True, fc_timeout_s=7.0, arming_check=False,
                                  receiver_failsafe=True, receiver_action_disarm=True)
    hold = FailsafeConfig.from_params(params(FS_GCS_ACTION=0, FS_RC_ACTION=0, ARMING_CHECK=1))
    assert (hold.gcs_action_disarm, hold.receiver_action_disarm, hold.arming_check) == (
        False, False, True)


@pytest.mark.parametrize(("rcin_enable", "fs_thr_enable", "on"), [
    (1, 1, True), (1, 0, False), (0, 1, False), (0, 0, False)])
def test_the_receiver_failsafe_is_on_only_when_the_receiver_is_read_and_its_failsafe_enabled(
        rcin_enable: int, fs_thr_enable: int, on: bool) -> None:
    view = FailsafeConfig.from_params(params(RCIN_ENABLE=rcin_enable,
                                             FS_THR_ENABLE=fs_thr_enable))
    assert view.receiver_failsafe is on


def test_the_rc_input_view_gives_the_forward_right_and_clockwise_channels_in_that_order() -> None:
    view = RcInputConfig.from_params(params(RCMAP_THROTTLE=2, RCMAP_LATERAL=5, RCMAP_STEER=6,
                                            RCIN_MIN=1100, RCIN_TRIM=1520, RCIN_MAX=1900))
    assert view == RcInputConfig(throttle_ch=2, lateral_ch=5, steer_ch=6, min_us=1100,
                                 trim_us=1520, max_us=1900)
    assert view.axes == (2, 5, 6)


def test_the_receiver_view_reads_the_six_switch_positions_in_order() -> None:
    view = ReceiverConfig.from_params(params(RCIN_ENABLE=1, MODE_CH=7, MODE1=15, MODE2=10,
                                             MODE3=4, MODE4=0, MODE5=4, MODE6=10,
                                             RCIN_ARM_CH=13, FS_THR_VALUE=950))
    assert view == ReceiverConfig(enabled=True, mode_ch=7, modes=(15, 10, 4, 0, 4, 10), arm_ch=13,
                                  throttle_fs_us=950)
    assert ReceiverConfig.from_params(params(RCIN_ENABLE=0)).enabled is False


def test_the_guided_view_turns_the_yaw_rate_from_degrees_into_radians() -> None:
    view = GuidedConfig.from_params(params(GUID_SPD_MAX=1.25, GUID_ACC_MAX=2, GUID_YAW_RATE=45,
                                           GUID_POS_P=2, GUID_YAW_P=4, GUID_YAW_LEAD=0.25,
                                           GUID_TIMEOUT=6))
    assert view == GuidedConfig(speed_max_mps=1.25, accel_max_mps2=2.0,
                                yaw_rate_max=math.radians(45.0), position_gain=2.0,
                                yaw_gain=4.0, yaw_lead_s=0.25, timeout_s=6.0)


@pytest.mark.parametrize(("wp_accel", "guid_acc_max", "accel"), [(0.25, 2, 0.25), (3, 2, 2.0)])
def test_the_mission_view_brakes_and_accelerates_at_the_lower_of_wp_accel_and_guid_acc_max(
        wp_accel: float, guid_acc_max: float, accel: float) -> None:
    view = MissionConfig.from_params(params(WP_SPEED=1.5, WP_ACCEL=wp_accel,
                                            GUID_ACC_MAX=guid_acc_max, WP_RADIUS=0.5,
                                            WP_OVERSHOOT=0.125, WP_YAW_BEHAVIOR=1, WP_POS_P=4,
                                            GUID_SPD_MAX=2.5))
    assert view == MissionConfig(speed_mps=1.5, accel_mps2=accel, radius_m=0.5,
                                 overshoot_m=0.125, face_along_legs=True, position_gain=4.0,
                                 speed_limit_mps=2.5)
    assert MissionConfig.from_params(params(WP_YAW_BEHAVIOR=0)).face_along_legs is False


def test_the_odometry_view_reads_its_sources_geometry_and_lags() -> None:
    view = OdometryConfig.from_params(params(ODOM_SRC=2, ODOM_YAW_SRC=1, WHL_MAX_SPD=1.5,
                                             GEO_HALF_LEN=0.25, GEO_HALF_WID=0.125,
                                             ODOM_CMD_TAU=0.5, ODOM_YAW_BIAS=1,
                                             ODOM_POS_TAU=4, ODOM_CMD_GAIN=0.875))
    assert view == OdometryConfig(source=2, yaw_from_gyro=False, wheel_speed_max_mps=1.5,
                                  half_length_m=0.25, half_width_m=0.125, commanded_tau_s=0.5,
                                  yaw_bias=1, position_tau_s=4.0, commanded_gain=0.875)
    assert OdometryConfig.from_params(params(ODOM_YAW_SRC=0)).yaw_from_gyro is True
