"""The compiled stick lane equals the general path bit for bit, and answers nothing else."""

from __future__ import annotations

from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import IdentityConfig, InputConfig
from mecanum_mav.control.chain import manual_output
from mecanum_mav.control.core import FC_LINK_COMPID, RoverCore
from mecanum_mav.control.lane import compile_stick_lane
from mecanum_mav.control.pwm import PwmMap, WheelOutput
from mecanum_mav.control.sticks import INVALID_AXIS, stick_from_manual_control
from mecanum_mav.mecanum.mixing import ALGORITHM_NAMES
from mecanum_mav.protocol.codec import encode_rc_override
from mecanum_mav.protocol.dialect import mavlink
from mecanum_mav.protocol.rcoverride import override_fields

PILOT = (255, 190)
IDENTITY = IdentityConfig.from_params(Params())

axes = st.one_of(st.integers(-1000, 1000), st.just(INVALID_AXIS))
configs = st.builds(InputConfig, deadband=st.floats(0.0, 0.5), expo=st.floats(0.0, 1.0),
                    circle=st.booleans(), z_scale=st.booleans(),
                    algorithm=st.sampled_from(ALGORITHM_NAMES),
                    desaturation=st.integers(0, 2))


@st.composite
def pwm_maps(draw: st.DrawFn) -> PwmMap:
    channels = draw(st.permutations(range(1, 19)))[:4]
    wheels = []
    for channel in channels:
        trim = draw(st.integers(1100, 1900))
        wheels.append(WheelOutput(channel, draw(st.integers(800, trim)), trim,
                                  draw(st.integers(trim, 2200)), draw(st.booleans())))
    return PwmMap((wheels[0], wheels[1], wheels[2], wheels[3]))


def stick_packet(x: int, y: int, z: int, r: int, *, target: int = 1, source: int = PILOT[0],
                 seq: int = 0) -> bytes:
    mav = mavlink.MAVLink(None, srcSystem=source, srcComponent=PILOT[1])
    mav.seq = seq
    return bytes(mav.manual_control_encode(target, x, y, z, r, 0).pack(mav))


def general_path(datagram_axes: tuple[int, int, int, int], config: InputConfig, pwm: PwmMap,
                 identity: IdentityConfig, seq: int) -> tuple[object, ...]:
    """What RoverCore.handle then tick compute for the same stick, and the companion sends."""
    x, y, z, r = datagram_axes
    stick = stick_from_manual_control(x, y, r, z, z_scale=config.z_scale)
    wheels, pulses = manual_output(*stick, config, pwm)
    mav = mavlink.MAVLink(None, srcSystem=identity.fc_gcs_sysid, srcComponent=FC_LINK_COMPID)
    mav.seq = seq
    fields = override_fields(pwm.channels, pulses)
    packet = encode_rc_override(mav, identity.fc_sysid, identity.fc_compid, fields)
    return packet, stick, wheels, pulses, fields


@settings(max_examples=400, deadline=None)
@given(config=configs, pwm=pwm_maps(), x=axes, y=axes, r=axes,
       z=st.one_of(st.integers(0, 1000), st.just(INVALID_AXIS)), seq=st.integers(0, 255),
       fc=st.tuples(st.integers(1, 255), st.integers(0, 255), st.integers(1, 255)),
       target=st.sampled_from([0, 1]))  # (0, all: the packet's payload is truncated more)
def test_the_lane_answers_a_stick_exactly_as_the_general_path(config, pwm, x, y, r, z, seq, fc,
                                                              target):
    identity = replace(IDENTITY, fc_sysid=fc[0], fc_compid=fc[1], fc_gcs_sysid=fc[2])
    lane = compile_stick_lane(config, pwm, identity, FC_LINK_COMPID)
    answer = lane(stick_packet(x, y, z, r, target=target), seq)
    assert answer is not None
    packet, stick, wheels, pulses, fields = answer
    expected = general_path((x, y, z, r), config, pwm, identity, seq)
    assert packet == expected[0]  # byte for byte
    assert (stick, tuple(wheels), pulses, fields) == (expected[1], tuple(expected[2]),
                                                      *expected[3:])


@pytest.mark.parametrize("algorithm", ALGORITHM_NAMES)
@pytest.mark.parametrize("desaturation", [0, 1, 2])
@pytest.mark.parametrize("x, y, r", [(1000, 0, 1000), (700, -800, -600), (-1000, 1000, 300)])
def test_the_lane_desaturates_a_full_stick_exactly_as_the_general_path(algorithm, desaturation,
                                                                       x, y, r):
    config = replace(InputConfig.from_params(Params()), algorithm=algorithm,
                     desaturation=desaturation, circle=False)
    pwm = PwmMap.from_params(Params())
    answer = compile_stick_lane(config, pwm, IDENTITY, FC_LINK_COMPID)(
        stick_packet(x, y, 500, r), 3)
    assert answer == general_path((x, y, 500, r), config, pwm, IDENTITY, 3)


def test_the_lanes_packet_is_what_pymavlink_reads_as_the_override():
    lane = compile_stick_lane(InputConfig.from_params(Params()), PwmMap.from_params(Params()),
                              IDENTITY, FC_LINK_COMPID)
    answer = lane(stick_packet(500, -250, 500, 100), 7)
    assert answer is not None
    msg = mavlink.MAVLink(None).parse_char(answer[0])
    assert msg.get_type() == "RC_CHANNELS_OVERRIDE" and msg.get_seq() == 7
    assert [msg.chan1_raw, msg.chan2_raw, msg.chan3_raw, msg.chan4_raw] == list(answer[3])
    assert (msg.get_srcSystem(), msg.get_srcComponent()) == (IDENTITY.fc_gcs_sysid,
                                                             FC_LINK_COMPID)


def _signed(packet: bytes) -> bytes:
    mav = mavlink.MAVLink(None, srcSystem=PILOT[0], srcComponent=PILOT[1])
    mav.signing.secret_key, mav.signing.sign_outgoing = bytes(32), True
    mav.signing.link_id, mav.signing.timestamp = 0, 1
    return bytes(mav.manual_control_encode(1, 500, 0, 500, 0, 0).pack(mav))


def _v1(packet: bytes) -> bytes:
    from pymavlink.dialects.v10 import ardupilotmega as v1

    mav = v1.MAVLink(None, srcSystem=PILOT[0], srcComponent=PILOT[1])
    return bytes(mav.manual_control_encode(1, 500, 0, 500, 0, 0).pack(mav))


def _heartbeat(packet: bytes) -> bytes:
    mav = mavlink.MAVLink(None, srcSystem=PILOT[0], srcComponent=PILOT[1])
    return bytes(mav.heartbeat_encode(6, 8, 0, 0, 4).pack(mav))


@pytest.mark.parametrize("datagram", [
    pytest.param(lambda p: p[:-1], id="truncated"),
    pytest.param(lambda p: p + b"\x00", id="a stray byte"),
    pytest.param(lambda p: p[:-2] + bytes((p[-2] ^ 1, p[-1])), id="bad CRC"),
    pytest.param(lambda p: p + p, id="two packets"),
    pytest.param(lambda p: b"", id="empty"),
    pytest.param(_signed, id="signed"),
    pytest.param(_v1, id="MAVLink 1"),
    pytest.param(_heartbeat, id="another message"),
    pytest.param(lambda p: stick_packet(500, 0, 500, 0, target=2), id="for another vehicle"),
    pytest.param(lambda p: stick_packet(1001, 0, 500, 0), id="x out of range"),
    pytest.param(lambda p: stick_packet(0, -1001, 500, 0), id="y out of range"),
    pytest.param(lambda p: stick_packet(0, 0, 500, 32000), id="r out of range"),
])
def test_the_lane_leaves_anything_but_one_valid_stick_to_the_general_path(datagram):
    lane = compile_stick_lane(InputConfig.from_params(Params()), PwmMap.from_params(Params()),
                              IDENTITY, FC_LINK_COMPID)
    assert lane(datagram(stick_packet(500, 0, 500, 0)), 0) is None


def test_the_lane_leaves_a_stick_from_another_ground_station_to_the_general_path():
    identity = replace(IDENTITY, gcs_sysid=200)
    lane = compile_stick_lane(InputConfig.from_params(Params()), PwmMap.from_params(Params()),
                              identity, FC_LINK_COMPID)
    assert lane(stick_packet(500, 0, 500, 0, source=201), 0) is None
    assert lane(stick_packet(500, 0, 500, 0, source=200), 0) is not None


def test_the_lane_leaves_a_bad_z_to_the_general_path_only_when_z_scales():
    config = InputConfig.from_params(Params())
    pwm = PwmMap.from_params(Params())
    scaled = compile_stick_lane(replace(config, z_scale=True), pwm, IDENTITY, FC_LINK_COMPID)
    unscaled = compile_stick_lane(replace(config, z_scale=False), pwm, IDENTITY, FC_LINK_COMPID)
    assert scaled(stick_packet(500, 0, 1001, 0), 0) is None
    assert unscaled(stick_packet(500, 0, 1001, 0), 0) is not None


def test_the_core_lane_is_closed_while_disarmed_and_follows_a_parameter_change():
    params = Params()
    core = RoverCore(params, now_s=0.0)
    assert core.stick_lane(stick_packet(500, 0, 500, 0), 0.1, 0) is None  # not driving
    core.params.set("INP_DEADBAND", 0.2)
    core.reconfigure()
    expected = general_path((500, 0, 500, 0), core.input, core.pwm, core.identity, 0)
    assert core._lane(stick_packet(500, 0, 500, 0), 0) == expected



@settings(max_examples=1000, deadline=None)
@given(st.one_of(
    st.binary(max_size=64),
    st.tuples(axes, axes, axes, st.integers(0, 42), st.integers(0, 255)).map(
        lambda t: _flip(stick_packet(t[0], t[1], 500, t[2]), t[3], t[4]))))
def test_any_datagram_is_refused_or_answered_as_its_decoded_stick(datagram):
    from mecanum_mav.protocol.codec import decode_manual_control

    config, pwm = InputConfig.from_params(Params()), PwmMap.from_params(Params())
    answer = compile_stick_lane(config, pwm, IDENTITY, FC_LINK_COMPID)(datagram, 9)
    if answer is None:
        return
    msg = decode_manual_control(datagram)  # the general path's own decoder agrees...
    assert msg is not None and msg.target in (0, IDENTITY.sysid)
    assert answer == general_path((msg.x, msg.y, msg.z, msg.r), config, pwm, IDENTITY, 9)


def _flip(packet: bytes, at: int, value: int) -> bytes:
    """``packet`` with the byte at ``at`` (if there is one) replaced by ``value``."""
    if at >= len(packet):
        return packet
    return packet[:at] + bytes((value,)) + packet[at + 1:]
