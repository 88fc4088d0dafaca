"""The vehicle state machine and the stick decoders, with time passed in (no sockets)."""

from __future__ import annotations

import pytest

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import RcInputConfig
from mecanum_mav.control.sticks import InputError, RcStickState, stick_from_manual_control
from mecanum_mav.control.vehicle import Mode, Vehicle


def vehicle(**values: float) -> Vehicle:
    params = Params()
    params.update(values)
    v = Vehicle(params)
    v.on_fc_heartbeat(0.0)
    v.on_gcs_heartbeat(0.0)
    v.take_events()
    return v


def texts(v: Vehicle) -> list[str]:
    return [event.text for event in v.take_events()]


# --------------------------------------------------------------------------- vehicle


def test_a_new_vehicle_is_disarmed_in_manual_and_does_not_drive():
    v = vehicle()
    assert not v.armed and v.mode is Mode.MANUAL and not v.driving()


def test_arming_waits_for_fresh_sticks_before_driving():
    v = vehicle()
    assert v.request_arm(0.1).accepted
    assert not v.driving()
    v.on_stick_input(0.2)
    assert v.driving()


def test_arming_is_refused_until_the_flight_controller_has_been_heard():
    v = Vehicle(Params())
    decision = v.request_arm(0.0)
    assert not decision.accepted and "flight controller" in decision.reason


def test_input_goes_stale_exactly_after_the_timeout():
    v = vehicle(FS_INPUT_TMO=0.5)
    v.request_arm(0.0)
    v.on_stick_input(1.0)
    v.update(1.5)
    assert v.driving()
    v.update(1.5001)
    assert not v.driving() and "Manual input lost: wheels neutral" in texts(v)
    v.on_stick_input(1.6)
    assert v.driving() and "Manual input resumed" in texts(v)


def test_gcs_loss_switches_to_hold_after_the_timeout_and_stays_there():
    v = vehicle(FS_GCS_TMO=3.0)
    v.request_arm(0.0)
    v.on_stick_input(2.9)
    v.on_fc_heartbeat(2.9)
    v.update(3.0)
    assert v.mode is Mode.MANUAL
    v.update(3.01)
    assert v.mode is Mode.HOLD and v.armed and v.failsafe and not v.driving()
    v.on_gcs_heartbeat(4.0)
    assert not v.failsafe and v.mode is Mode.HOLD  # the pilot chooses when to drive again


def test_gcs_loss_with_disarm_action_disarms():
    v = vehicle(FS_GCS_TMO=1.0, FS_GCS_ACTION=1)
    v.request_arm(0.0)
    v.update(1.5)
    assert not v.armed and any("GCS failsafe" in t for t in texts(v))


def test_no_gcs_failsafe_before_a_ground_station_was_ever_seen():
    v = Vehicle(Params())
    v.on_fc_heartbeat(0.0)
    v.request_arm(1.0)
    v.on_fc_heartbeat(50.0)
    v.update(50.0)
    assert not v.gcs_failsafe and v.armed


def test_next_due_is_the_earliest_failsafe_deadline_and_inf_when_none_can_fire():
    v = vehicle(FS_FC_TMO=3.0, FS_GCS_TMO=2.0, FS_INPUT_TMO=0.5)  # both heard at 0.0
    assert v.next_due_s() == 2.0
    v.request_arm(0.0)
    v.on_stick_input(1.8)
    assert v.next_due_s() == 2.0  # the GCS's (the stick's is 2.3)
    v.on_gcs_heartbeat(1.9)
    assert v.next_due_s() == pytest.approx(2.3)  # the stick's, then
    v.update(2.31)
    assert v.next_due_s() == 3.0  # stale input has nothing left to fire: the FC's
    v.update(3.01)
    assert v.fc_lost and v.next_due_s() == pytest.approx(3.9)  # the GCS's
    v.update(3.91)
    assert v.next_due_s() == float("inf")


def test_fc_loss_disarms_and_reports_once():
    v = vehicle(FS_FC_TMO=3.0)
    v.request_arm(0.0)
    v.update(3.0)
    assert v.armed
    v.update(3.1)
    v.update(3.2)
    events = texts(v)
    assert not v.armed and events.count("Flight controller link lost") == 1
    v.on_fc_heartbeat(4.0)
    assert "Flight controller link up" in texts(v)


def test_auto_drives_only_when_armed_and_without_failsafe():
    v = vehicle()
    assert v.request_mode(int(Mode.AUTO), 0.0).accepted
    assert not v.auto()  # disarmed
    v.on_fc_heartbeat(0.0)
    v.request_arm(0.0)
    assert v.auto() and not v.guided() and not v.driving()
    v.update(10.0)  # flight controller silent: failsafe disarms
    assert not v.auto()


def test_unknown_mode_numbers_are_refused():
    assert not vehicle().request_mode(99, 0.0).accepted


# --------------------------------------------------------------------------- MANUAL_CONTROL


def test_manual_control_axes_scale_to_plus_minus_one():
    assert stick_from_manual_control(1000, -500, 250, 0, z_scale=False) == (1.0, -0.5, 0.25)


def test_invalid_axis_marker_reads_as_zero():
    assert stick_from_manual_control(0x7FFF, 1000, 0x7FFF, 0x7FFF, z_scale=True) == (0, 1, 0)


def test_z_scales_the_stick_when_enabled():
    assert stick_from_manual_control(1000, 0, 1000, 500, z_scale=True) == (0.5, 0.0, 0.5)
    assert stick_from_manual_control(1000, 0, 0, 0, z_scale=False) == (1.0, 0.0, 0.0)


@pytest.mark.parametrize(("x", "z"), [(1001, 0), (-32768, 0), (0, 1001), (0, -1)])
def test_out_of_range_axes_reject_the_whole_message(x, z):
    with pytest.raises(InputError):
        stick_from_manual_control(x, 0, 0, z, z_scale=True)


# --------------------------------------------------------------------------- GCS RC override


def rc(**set_: int) -> list[int]:
    fields = [65535] * 8 + [0] * 10
    for key, value in set_.items():
        fields[int(key[2:]) - 1] = value
    return fields


def test_rc_override_maps_throttle_lateral_and_steering_like_ardupilot_rover():
    state, params = RcStickState(), Params()
    state.apply(rc(ch1=2000, ch3=1750, ch4=1000))
    assert state.stick(RcInputConfig.from_params(params)) == (0.5, -1.0, 1.0)


def test_rc_override_65535_keeps_a_channel_and_0_releases_it_to_centre():
    state, params = RcStickState(), Params()
    state.apply(rc(ch3=2000))
    state.apply(rc(ch1=1250))
    assert state.stick(RcInputConfig.from_params(params)) == (1.0, 0.0, -0.5)
    state.apply(rc(ch3=0))
    assert state.stick(RcInputConfig.from_params(params)) == (0.0, 0.0, -0.5)


def test_rc_override_high_channels_release_with_65534_and_ignore_0():
    params = Params()
    params.update({"RCMAP_LATERAL": 10})
    state = RcStickState()
    state.apply(rc(ch10=2000))
    state.apply(rc(ch10=0))  # 0 on 9-18: leave alone
    assert state.stick(RcInputConfig.from_params(params))[1] == 1.0
    state.apply(rc(ch10=65534))
    assert state.stick(RcInputConfig.from_params(params))[1] == 0.0


def test_rc_override_with_an_absurd_pulse_applies_nothing():
    state = RcStickState()
    with pytest.raises(InputError, match="ch2=40000"):
        state.apply(rc(ch3=2000, ch2=40000))
    assert state.pulses == {}


def test_only_messages_touching_the_stick_channels_count_as_stick_input():
    state, params = RcStickState(), Params()
    assert not state.touches_sticks(rc(ch7=1900), RcInputConfig.from_params(params))
    assert state.touches_sticks(rc(ch4=1500), RcInputConfig.from_params(params))
    assert state.touches_sticks(rc(ch1=0), RcInputConfig.from_params(params))


class RecordingHooks:
    """:class:`~mecanum_mav.control.vehicle.ModeHooks` that allow every mode and keep what they
    were told."""

    def __init__(self) -> None:
        self.asked: list[tuple[Mode, float]] = []
        self.changes: list[tuple[Mode, Mode, float]] = []

    def refuse_entry(self, mode: Mode, now_s: float) -> str | None:
        self.asked.append((mode, now_s))
        return None

    def on_mode_change(self, before: Mode, after: Mode, now_s: float) -> None:
        self.changes.append((before, after, now_s))


def test_the_receiver_failsafes_switch_to_hold_is_told_to_the_hooks_at_its_time():
    # Vehicle.request_mode: "The hooks see every change, failsafe switches included";
    # ModeHooks.on_mode_change: the change at now_s (the controllers start from it).
    params = Params()
    params.update({"RCIN_ENABLE": 1, "MOT_FL_CH": 9, "MOT_FR_CH": 10, "MOT_RL_CH": 11,
                   "MOT_RR_CH": 12})
    hooks = RecordingHooks()
    v = Vehicle(params, hooks)
    v.on_fc_heartbeat(0.0)
    v.on_receiver(None, 0.5)
    assert v.request_arm(1.0).accepted and not v.config.receiver_action_disarm
    v.on_receiver("RSSI 0", 2.5)
    assert v.mode is Mode.HOLD and v.rc_failsafe
    assert hooks.asked == [(Mode.HOLD, 2.5)]
    assert hooks.changes == [(Mode.MANUAL, Mode.HOLD, 2.5)]
