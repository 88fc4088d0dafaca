"""The compiled stick lane equals the general path bit for bit, answers nothing else, and the
companion's loop answers the pilot's sticks in it."""

from __future__ import annotations

from dataclasses import replace

import pytest
from conftest import lockstep
from hypothesis import given, settings
from hypothesis import strategies as st

from mecanum_mav.config.params import Params
from mecanum_mav.config.views import IdentityConfig, InputConfig
from mecanum_mav.control.chain import manual_output
from mecanum_mav.control.core import FC_LINK_COMPID, RoverCore
from mecanum_mav.control.lane import compile_stick_lane
from mecanum_mav.control.pwm import PwmMap, WheelOutput
from mecanum_mav.control.sticks import INVALID_AXIS, InputError, stick_from_manual_control
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
    # an ESC dead band (MOT_DZ) half the time: the lane compensates it as the general path
    # (kills lane-dead-band)
    band = draw(st.one_of(st.just(0.0), st.floats(0.0, 0.3)))
    return PwmMap((wheels[0], wheels[1], wheels[2], wheels[3]), band, draw(st.booleans()))


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



int16 = st.integers(-32768, 32767)
stick_axes = st.one_of(st.integers(-1000, 1000), st.just(INVALID_AXIS), int16)
"""Every int16 a MANUAL_CONTROL axis can carry: in range mostly, "invalid", and beyond."""
extension = st.one_of(st.just(0), int16)


@st.composite
def manual_controls(draw: st.DrawFn) -> dict[str, int]:
    """MANUAL_CONTROL's every field: the target (this vehicle, all, any other), the axes
    (full int16 ranges), the buttons and the MAVLink 2 extensions (zero: truncated away)."""
    fields = {"target": draw(st.one_of(st.sampled_from([0, IDENTITY.sysid]),
                                       st.integers(0, 255))),
              "x": draw(stick_axes), "y": draw(stick_axes),
              "z": draw(st.one_of(st.integers(0, 1000), st.just(INVALID_AXIS), int16)),
              "r": draw(stick_axes), "buttons": draw(st.integers(0, 65535)),
              "buttons2": draw(st.one_of(st.just(0), st.integers(0, 65535))),
              "enabled_extensions": draw(st.one_of(st.just(0), st.integers(0, 255)))}
    for name in ("s", "t", "aux1", "aux2", "aux3", "aux4", "aux5", "aux6"):
        fields[name] = draw(extension)
    return fields


def _other_message(mav: mavlink.MAVLink, fields: dict[str, int]) -> bytes:
    """Another message from the same sender, as like a stick as its fields let it be."""
    kind = fields["buttons"] % 4
    msg = (mav.heartbeat_encode(6, 8, 0, 0, 4) if kind == 0 else
           mav.rc_channels_override_encode(fields["target"], 1,
                                           *[1000 + abs(fields["x"]) % 1000] * 8) if kind == 1
           else mav.manual_setpoint_encode(0, fields["x"] / 1000, fields["y"] / 1000,
                                           fields["r"] / 1000, fields["z"] / 1000, 0, 0)
           if kind == 2 else mav.command_long_encode(fields["target"], 1, 400, 0, 1, 0, 0, 0,
                                                     0, 0, 0))
    return bytes(msg.pack(mav))


def _restamped(packet: bytes, at: int, value: int) -> bytes:
    """A MAVLink 2 MANUAL_CONTROL ``packet`` with its header byte ``at`` set to ``value`` and
    its CRC made good again: only that field tells it from a stick."""
    changed = bytearray(packet)
    changed[at] = value
    end = 10 + changed[1]
    crc = mavlink.x25crc(bytes(changed[1:end]))
    crc.accumulate(bytes([mavlink.MAVLink_manual_control_message.crc_extra]))
    changed[end:end + 2] = crc.crc.to_bytes(2, "little")
    return bytes(changed)


@st.composite
def well_formed_datagrams(draw: st.DrawFn) -> bytes:
    """Whole, good-CRC MAVLink: a stick from the pilot or another sender, signed or not,
    MAVLink 2 or 1; another message; two packets; a stick one header field away."""
    fields = draw(manual_controls())
    source = draw(st.one_of(st.just(PILOT[0]), st.integers(1, 255)))
    form = draw(st.sampled_from(["stick", "stick", "stick", "signed", "MAVLink 1", "other",
                                 "two", "restamped"]))
    if form == "MAVLink 1":
        from pymavlink.dialects.v10 import ardupilotmega as v1

        mav1 = v1.MAVLink(None, srcSystem=source, srcComponent=PILOT[1])
        return bytes(mav1.manual_control_encode(*[fields[k] for k in (
            "target", "x", "y", "z", "r", "buttons")]).pack(mav1))
    mav = mavlink.MAVLink(None, srcSystem=source, srcComponent=PILOT[1])
    mav.seq = draw(st.integers(0, 255))
    if form == "signed":
        mav.signing.secret_key, mav.signing.sign_outgoing = bytes(32), True
        mav.signing.link_id, mav.signing.timestamp = 0, 1
    if form == "other":
        return _other_message(mav, fields)
    packet = bytes(mav.manual_control_encode(**fields).pack(mav))
    if form == "two":
        return packet + packet
    if form == "restamped":  # flags, or a message id whose low byte is MANUAL_CONTROL's
        at = draw(st.sampled_from([2, 8, 9]))
        return _restamped(packet, at, draw(st.integers(1, 255)))
    return packet


def general_path_answer(datagram: bytes, config: InputConfig, pwm: PwmMap,
                        identity: IdentityConfig, seq: int) -> tuple[object, ...] | None:
    """What the general path answers with the override alone, read with pymavlink's own
    parser: exactly one whole, unsigned MAVLink 2 MANUAL_CONTROL, for this vehicle (or all),
    from the pilot, with valid axes; None for anything else (refused, or more to do)."""
    parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    try:
        messages = parser.parse_buffer(datagram) or []
    except Exception:  # (a refusal all the same)
        return None
    if len(messages) != 1 or len(parser.buf) > parser.buf_index:
        return None
    msg = messages[0]
    if (msg.get_type() != "MANUAL_CONTROL" or msg.get_msgbuf()[0] != mavlink.PROTOCOL_MARKER_V2
            or msg.get_header().incompat_flags):
        return None
    if msg.target not in (0, identity.sysid) or (
            identity.gcs_sysid and msg.get_srcSystem() != identity.gcs_sysid):
        return None
    try:
        stick_from_manual_control(msg.x, msg.y, msg.r, msg.z, z_scale=config.z_scale)
    except InputError:
        return None
    return general_path((msg.x, msg.y, msg.z, msg.r), config, pwm, identity, seq)


@settings(max_examples=1000, deadline=None)
@given(st.one_of(
    st.binary(max_size=64),
    st.tuples(axes, axes, axes, st.integers(0, 42), st.integers(0, 255)).map(
        lambda t: _flip(stick_packet(t[0], t[1], 500, t[2]), t[3], t[4])),
    well_formed_datagrams()), st.booleans(), st.sampled_from([0, PILOT[0]]))
def test_any_datagram_is_refused_or_answered_as_its_decoded_stick(datagram, z_scale, pilot):
    config = replace(InputConfig.from_params(Params()), z_scale=z_scale)
    pwm = PwmMap.from_params(Params())
    identity = replace(IDENTITY, gcs_sysid=pilot)  # (0: any ground station drives)
    answer = compile_stick_lane(config, pwm, identity, FC_LINK_COMPID)(datagram, 9)
    if answer is None:
        return
    # pymavlink reads one stick the general path acts on, and it answers the same
    assert answer == general_path_answer(datagram, config, pwm, identity, 9)


def _flip(packet: bytes, at: int, value: int) -> bytes:
    """``packet`` with the byte at ``at`` (if there is one) replaced by ``value``."""
    if at >= len(packet):
        return packet
    return packet[:at] + bytes((value,)) + packet[at + 1:]


def test_the_companions_loop_answers_each_stick_of_the_pilot_in_its_lane_in_the_step_it_arrived():
    """Through the shipped loop (:class:`~mecanum_mav.runtime.loop.ControlLoop`, which the
    lockstep harness steps): while the rover drives in MANUAL every stick after the first (which
    makes the stale input fresh: the general path's) is answered in the lane, unparsed
    (``Lockstep.lane_answers``), its override on the wire to the board in the step the stick
    arrived, the general path's channels exactly."""
    h = lockstep()
    h.gcs.arm()
    h.run_for(0.1)
    arrived: list[float] = []

    def send(now_s: float) -> None:
        h.gcs.mav.manual_control_send(1, 600, -200, 500, 100, 0)
        arrived.append(now_s if arrived else now_s + h.dt_s)  # (the first: between steps)

    stop = h.every(0.02, send)
    h.run_for(1.0)
    stop()
    h.run_for(0.1)
    expected = general_path((600, -200, 500, 100), h.core.input, h.core.pwm, h.core.identity,
                            0)[4]
    assert len(arrived) >= 50
    assert h.lane_answers == len(arrived) - 1
    for t in arrived:
        assert [o.channels for o in h.overrides if abs(o.time_s - t) < 1e-9] == [expected]


@pytest.mark.parametrize(("deadband", "expo"), [(1.0, 0.0), (-0.1, 0.0), (0.0, 1.5),
                                                 (0.0, -0.2)])
def test_a_lane_is_not_built_for_a_deadband_or_expo_the_shaping_cannot_use(deadband, expo):
    config = replace(InputConfig.from_params(Params()), deadband=deadband, expo=expo)
    with pytest.raises(ValueError, match="out of range"):
        compile_stick_lane(config, PwmMap.from_params(Params()), IDENTITY, FC_LINK_COMPID)


def test_stick_sent_without_a_packet_from_the_lane_is_a_caller_error():
    """RoverCore.stick_sent records the packet stick_lane returned: called with none, it
    raises instead of recording a stick nobody sent."""
    core = RoverCore(Params(), now_s=0.0)
    with pytest.raises(RuntimeError, match="stick_sent without a packet from stick_lane"):
        core.stick_sent()
