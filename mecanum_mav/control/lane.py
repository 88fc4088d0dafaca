"""The stick lane: a pilot's MANUAL_CONTROL datagram -> its RC_CHANNELS_OVERRIDE packet, one call.

The control path's latency is what a Python process does between the wake and the send, and
at 50 Hz every message arrives to cold caches, where each Python function entered costs
microseconds. :func:`compile_stick_lane` builds, once per configuration, a single function
that does the whole of :func:`~mecanum_mav.control.sticks.stick_from_manual_control`,
:func:`~mecanum_mav.control.chain.manual_output` (shaping, Cartesian mixing with its
desaturation, PWM) and :func:`~mecanum_mav.protocol.codec.encode_rc_override` inline, with the
configuration's constants bound. It enters two Python functions, the library's own: the
mixing (:func:`~mecanum_mav.mecanum.mixing.mix_pairs` for Cartesian, the closed-form
desaturation; :func:`~mecanum_mav.mecanum.mixing.wheels_from_stick` for the polar
algorithms) and :meth:`~mecanum_mav.control.pwm.PwmMap.pulses_us`. Measured with
``tools/bench_latency.py``: with the rest of its session's work it took the companion's median
stick-to-PWM delay at 50 Hz from 1.5-1.6x to 0.9-1.3x the floor relay's (docs/benchmarks.md).

Everything it computes is bit for bit what those functions compute (tests/test_lane.py holds
it to them for every configuration, with hypothesis), and it answers only what needs no
decision beyond them: a datagram holding exactly one unsigned MAVLink 2 MANUAL_CONTROL with a
good CRC, addressed to this vehicle (or to all) from the pilot (``SYSID_MYGCS``), with valid
axes. Anything else gives None and takes the general path, which refuses bad input with its
reason. Whether the rover may drive at all is the core's decision
(:meth:`~mecanum_mav.control.core.RoverCore.stick_lane`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

from mecanum_mav.config.views import IdentityConfig, InputConfig
from mecanum_mav.control.pwm import PwmMap
from mecanum_mav.control.sticks import INVALID_AXIS, Stick
from mecanum_mav.mecanum.mixing import WheelTuple, mix_pairs, wheels_from_stick
from mecanum_mav.protocol.codec import STICK_WIRE
from mecanum_mav.protocol.rcoverride import override_fields

__all__ = ["LaneAnswer", "StickLane", "compile_stick_lane"]

LaneAnswer = tuple[bytes, Stick, WheelTuple, tuple[int, ...], list[int]]
"""The RC_CHANNELS_OVERRIDE packet; the stick (normalized x forward, y right, r clockwise, as
:func:`~mecanum_mav.control.sticks.stick_from_manual_control` gives it); the wheel commands
(normalized FL, FR, RL, RR); the pulse widths (us, same order); the packet's 18
``chanN_raw`` fields (as :func:`~mecanum_mav.protocol.rcoverride.override_fields`)."""

StickLane = Callable[[bytes, int], LaneAnswer | None]
"""``lane(datagram, seq)``: the answer to one datagram, its packet numbered ``seq``, or None."""


def compile_stick_lane(config: InputConfig, pwm: PwmMap, identity: IdentityConfig,
                       source_component: int) -> StickLane:
    """The stick lane for one configuration (build it again when a parameter changes).

    Args:
        config: shaping and mixing (``INP_*``, ``MAN_Z_SCALE``, ``MIX_*``).
        pwm: the wheels' channels and pulse ranges (``MOT_*``).
        identity: this vehicle's id, the pilot's (``SYSID_MYGCS``), the flight controller's
            (the override's target) and the id the override is sent as (``FC_GCS_SYSID``).
        source_component: the component id the override is sent as.

    Returns:
        ``lane(datagram, seq)``: for a datagram the lane answers (module description), the
        unsigned MAVLink 2 RC_CHANNELS_OVERRIDE packet with sequence number ``seq`` and what it
        was computed from (:data:`LaneAnswer`); else None.

    Raises:
        ValueError: a deadband outside [0, 1) or an expo outside [0, 1] (the parameter
            schema keeps both inside).
    """
    wire = STICK_WIRE
    crc16, header, crc_field = wire.crc16, wire.header.pack, wire.crc.pack
    magic, manual_low, manual_extra = wire.magic, wire.manual_id & 0xFF, wire.manual_crc_extra
    manual_size = wire.manual_size
    axes_from, axes_size = wire.manual_axes.unpack_from, wire.manual_axes.size
    override_low, override_high = wire.override_id & 0xFFFF, wire.override_id >> 16
    override_extra, override_pack = wire.override_crc_extra, wire.override_pack
    assert wire.manual_id < 256, "MANUAL_CONTROL's id fits one byte"
    sysid, pilot = identity.sysid, identity.gcs_sysid
    target_system, target_component = identity.fc_sysid, identity.fc_compid
    source_system = identity.fc_gcs_sysid
    invalid, z_scale = INVALID_AXIS, config.z_scale
    band, weight, circle = config.deadband, config.expo, config.circle
    if not (0.0 <= band < 1.0 and 0.0 <= weight <= 1.0):
        raise ValueError(f"deadband {band!r} or expo {weight!r} out of range")
    gain, keep = 1.0 / (1.0 - band), 1.0 - weight
    algorithm, priority = config.algorithm, int(config.desaturation)
    cartesian = algorithm == "cartesian"
    if not cartesian:
        wheels_from_stick(0.0, 0.0, 0.0, algorithm, priority=priority)  # KeyError: unknown
    pulses_us = pwm.pulses_us
    # Without a dead band the PWM step is inline (as pulses_us: sign, limit, each side of
    # trim to its own end; the mix is finite, so no trim for a non-finite command).
    inline_pwm = not pwm.dead_band
    (trim_fl, up_fl, down_fl, sign_fl), (trim_fr, up_fr, down_fr, sign_fr), (
        trim_rl, up_rl, down_rl, sign_rl), (trim_rr, up_rr, down_rr, sign_rr) = pwm.spans
    template = override_fields(pwm.channels, pwm.neutral())
    slot_fl, slot_fr, slot_rl, slot_rr = (channel - 1 for channel in pwm.channels)
    sqrt = math.sqrt

    def lane(datagram: bytes, seq: int) -> LaneAnswer | None:
        # One unsigned MAVLink 2 MANUAL_CONTROL, whole, good CRC (as decode_manual_control).
        size = len(datagram)
        if (size < 13 or datagram[0] != magic or datagram[2] or datagram[7] != manual_low
                or datagram[8] or datagram[9]):
            return None
        length = datagram[1]
        end = 10 + length
        if size != end + 2 or length > manual_size or (
                datagram[end] | datagram[end + 1] << 8) != crc16(
                manual_extra, crc16(datagram[1:end], 0xFFFF)):
            return None
        if length >= axes_size:  # the axes and target whole: read them in place
            x, y, z, r, _buttons, to = axes_from(datagram, 10)
        else:  # MAVLink 2 dropped trailing zero bytes: put them back
            x, y, z, r, _buttons, to = axes_from(datagram[10:end] + bytes(axes_size - length))
        # For us, from the pilot, valid axes (as Context.for_us, from_pilot and
        # stick_from_manual_control; else the general path refuses it, saying why).
        if (to and to != sysid) or (pilot and datagram[5] != pilot):
            return None
        if x == invalid:
            x = 0
        if y == invalid:
            y = 0
        if r == invalid:
            r = 0
        if not (-1000 <= x <= 1000 and -1000 <= y <= 1000 and -1000 <= r <= 1000):
            return None
        sx, sy, sr = x / 1000.0, y / 1000.0, r / 1000.0
        if z_scale and z != invalid:
            if not 0 <= z <= 1000:
                return None
            k = z / 1000.0
            sx, sy, sr = sx * k, sy * k, sr * k
        stick = (sx, sy, sr)
        # Shaping (as shape_stick): per axis the rescaled deadband (|axis| <= 1: no limit
        # needed) and the cubic expo, then the circle. shape_stick works on the magnitude and
        # restores the sign; both steps are odd functions and IEEE rounding is symmetric, so
        # on the signed value they give the same bits.
        sx = 0.0 if -band <= sx <= band else (sx - band if sx > 0.0 else sx + band) * gain
        sy = 0.0 if -band <= sy <= band else (sy - band if sy > 0.0 else sy + band) * gain
        sr = 0.0 if -band <= sr <= band else (sr - band if sr > 0.0 else sr + band) * gain
        if weight:  # (with none, shape_stick's expo step returns its input)
            sx = keep * sx + weight * sx * sx * sx
            sy = keep * sy + weight * sy * sy * sy
            sr = keep * sr + weight * sr * sr * sr
        if circle:
            length_sq = sx * sx + sy * sy
            if length_sq > 1.0:
                norm = sqrt(length_sq)
                sx, sy = sx / norm, sy / norm
        # Mixing (as wheels_from_stick: Cartesian is the pair mix, with its desaturation),
        # PWM, then the override's fields and packet (as encode_rc_override: MAVLink 2
        # payload truncation, the native CRC).
        if cartesian:
            a, b = sx + sy, sx - sy
            if (a if a >= 0.0 else -a) + (sr if sr >= 0.0 else -sr) <= 1.0 and (
                    b if b >= 0.0 else -b) + (sr if sr >= 0.0 else -sr) <= 1.0:
                wheels = (a + sr, b - sr, b + sr, a - sr)  # (mix_pairs unsaturated)
            else:
                wheels = mix_pairs(a, b, sr, priority)
        else:
            wheels = wheels_from_stick(sx, sy, sr, algorithm, priority=priority)
        if inline_pwm:
            fl, fr, rl, rr = wheels
            fl, fr, rl, rr = sign_fl * fl, sign_fr * fr, sign_rl * rl, sign_rr * rr
            if not (-1.0 <= fl <= 1.0 and -1.0 <= fr <= 1.0 and -1.0 <= rl <= 1.0
                    and -1.0 <= rr <= 1.0):  # (the mix's rounding, at most an ulp)
                fl, fr, rl, rr = (1.0 if c > 1.0 else (-1.0 if c < -1.0 else c)
                                  for c in (fl, fr, rl, rr))
            pulses = (round(trim_fl + fl * (up_fl if fl >= 0.0 else down_fl)),
                      round(trim_fr + fr * (up_fr if fr >= 0.0 else down_fr)),
                      round(trim_rl + rl * (up_rl if rl >= 0.0 else down_rl)),
                      round(trim_rr + rr * (up_rr if rr >= 0.0 else down_rr)))
        else:
            pulses = pulses_us(wheels)
        fields = template.copy()
        fields[slot_fl], fields[slot_fr], fields[slot_rl], fields[slot_rr] = pulses
        payload = override_pack(*fields[:8], target_system, target_component, *fields[8:])
        size = len(payload.rstrip(b"\x00")) or 1
        body = header(magic, size, 0, 0, seq, source_system, source_component,
                      override_low, override_high) + payload[:size]
        packet = body + crc_field(crc16(override_extra, crc16(body[1:], 0xFFFF)))
        return packet, stick, wheels, pulses, fields

    return lane
