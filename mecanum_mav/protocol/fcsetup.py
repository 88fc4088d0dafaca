"""What an ArduPilot flight controller must be set to for the companion to drive it safely.

Pure rules, no I/O: :func:`wanted_names` lists the flight-controller parameters to read for a
companion configuration, :func:`check` turns the values read into findings (each setting, its
value, what the companion needs and why), :func:`safe_settings` gives the values that make the
board safe. ``mecanum-mav setup-fc`` (:mod:`mecanum_mav.app.setupfc`) reads, prints and writes
them over MAVLink.

What "safe" means, measured with ArduPilot Rover SITL (see the project's SITL notes):

- Overrides are obeyed only from the ground-station id (``MAV_GCS_SYSID``, older firmware
  ``SYSID_MYGCS``): it must be the companion's ``FC_GCS_SYSID``.
- Each wheel channel's servo output must pass its RC input through, scaled:
  ``SERVOn_FUNCTION`` 140..155 (RCIN1Scaled..RCIN16Scaled), not the plain 51..66 (RCINn).
- With the plain pass-through and no receiver, a board whose companion dies (kill -9, power
  loss) HOLDS THE LAST OVERRIDE FOREVER: the wheels keep turning. The scaled pass-through with
  the channel's bit in ``SERVO_RC_FS_MSK`` goes to the servo's trim when the radio failsafe
  fires (``FS_THR_ENABLE``), which happens about 0.5 s after the overrides stop provided the
  throttle input channel (``RCMAP_THROTTLE``) is one of the channels the companion refreshes.
- ``RC_OVERRIDE_TIME`` longer than 1 s keeps a dead companion's override alive that long where
  a receiver is fitted.
- The scaled pass-through maps the pulse through ``RCn_MIN/TRIM/MAX/DZ`` and
  ``SERVOn_MIN/TRIM/MAX``: only ranges equal to the companion's ``MOT_x_MIN/TRIM/MAX`` and a
  dead zone of 0 pass a pulse unchanged.
- ``ARMING_RUDDER`` (channel 1 held near full with channel 3 at trim arms or disarms the board)
  turns a diagonal drive into an arming gesture.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import NamedTuple

from mecanum_mav.config.params import Params

__all__ = [
    "GCS_SYSID_NAMES",
    "OPTIONAL_NAMES",
    "OVERRIDE_TIME_MAX_S",
    "REBOOT_NAMES",
    "SAFE_OVERRIDE_TIME_S",
    "Finding",
    "check",
    "safe_settings",
    "store_nudge",
    "wanted_groups",
    "wanted_names",
    "wheel_channels",
]

GCS_SYSID_NAMES = ("MAV_GCS_SYSID", "SYSID_MYGCS")
"""The ground-station id's name in current and older ArduPilot."""
OPTIONAL_NAMES = ("RC_PROTOCOLS",)
"""Read for the table only: no value of theirs is a hazard, and no answer is no problem."""
RCIN_SCALED_FIRST = 140
"""SERVOn_FUNCTION of RCIN1Scaled (RCINkScaled is 139 + k; the plain RCINk, 50 + k, is a
hazard)."""
OVERRIDE_TIME_MAX_S = 1.0
"""A longer RC_OVERRIDE_TIME keeps a dead companion's command alive too long."""
SAFE_OVERRIDE_TIME_S = 0.5
"""What ``--apply`` sets RC_OVERRIDE_TIME to."""

Values = Mapping[str, float]


class Finding(NamedTuple):
    """One flight-controller setting: its value (None: unknown, the board did not answer),
    what the companion needs, why, and whether it is a hazard as it stands."""

    name: str
    value: float | None
    want: str
    why: str
    hazard: bool


def wheel_channels(params: Params) -> list[tuple[str, int]]:
    """(wheel key, RC channel) of the four wheels, FL, FR, RL, RR."""
    return [(w, int(params[f"MOT_{w}_CH"])) for w in ("FL", "FR", "RL", "RR")]


def wanted_groups(params: Params) -> list[tuple[str, ...]]:
    """Every flight-controller setting :func:`check` reads, for this configuration, each as
    the names it may have (see :class:`~mecanum_mav.protocol.paramread.ParamReader`)."""
    groups: list[tuple[str, ...]] = [GCS_SYSID_NAMES]
    groups += [(n,) for n in ("SERVO_RC_FS_MSK", "RC_OVERRIDE_TIME", "ARMING_RUDDER",
                              "RCMAP_THROTTLE", "FS_THR_ENABLE", *OPTIONAL_NAMES)]
    for _, ch in wheel_channels(params):
        groups += [(f"SERVO{ch}_FUNCTION",), (f"SERVO{ch}_MIN",), (f"SERVO{ch}_TRIM",),
                   (f"SERVO{ch}_MAX",), (f"RC{ch}_MIN",), (f"RC{ch}_TRIM",), (f"RC{ch}_MAX",),
                   (f"RC{ch}_DZ",)]
    return groups


def wanted_names(params: Params) -> list[str]:
    """Every flight-controller parameter name :func:`check` may read, for this
    configuration."""
    return [name for group in wanted_groups(params) for name in group]


def _gcs_name(values: Values) -> str:
    return next((n for n in GCS_SYSID_NAMES if n in values), GCS_SYSID_NAMES[0])


def _int(value: float | None) -> int | None:
    return None if value is None else int(value)


def check(params: Params, values: Values) -> list[Finding]:
    """Findings for a board whose parameters are ``values`` (name -> value), for the
    companion configured by ``params``.

    A name missing from ``values`` is unknown (not answered, or not on this firmware): its
    finding has ``value`` None and is not a hazard; :func:`wanted_groups` and the reader say
    which settings were not answered. Every known value that differs from what the companion
    needs is a hazard, whatever the other settings are (a board half set up is not safe).
    """
    out: list[Finding] = []
    gcs_name = _gcs_name(values)
    gcs = _int(values.get(gcs_name))
    own = int(params["FC_GCS_SYSID"])
    out.append(Finding(gcs_name, values.get(gcs_name), str(own),
                       "overrides are obeyed only from this system id (FC_GCS_SYSID)",
                       gcs is not None and gcs != own))
    wheels = wheel_channels(params)
    fs_mask = _int(values.get("SERVO_RC_FS_MSK"))
    refreshed = {ch for _, ch in wheels}
    for w, ch in wheels:
        fn_name = f"SERVO{ch}_FUNCTION"
        fn = _int(values.get(fn_name))
        scaled = RCIN_SCALED_FIRST + ch - 1
        out.append(Finding(fn_name, values.get(fn_name), f"{scaled} (RCIN{ch}Scaled)",
                           f"the {w} wheel's output must pass RC channel {ch} through, and go "
                           "to trim when the companion dies", fn is not None and fn != scaled))
        masked = None if fs_mask is None else float(bool(fs_mask & (1 << (ch - 1))))
        out.append(Finding(f"SERVO_RC_FS_MSK bit {ch - 1}", masked, "set",
                           f"channel {ch} goes to trim when the companion dies (with "
                           f"RCIN{ch}Scaled): else the last command is held", masked == 0.0))
        for part in ("MIN", "TRIM", "MAX"):
            want = int(params[f"MOT_{w}_{part}"])
            for name in (f"RC{ch}_{part}", f"SERVO{ch}_{part}"):
                value = _int(values.get(name))
                out.append(Finding(name, values.get(name), str(want),
                                   f"MOT_{w}_{part}: the pulse passes unchanged",
                                   value is not None and value != want))
        dz = _int(values.get(f"RC{ch}_DZ"))
        out.append(Finding(f"RC{ch}_DZ", values.get(f"RC{ch}_DZ"), "0",
                           "no dead zone: small commands pass", dz is not None and dz != 0))
    timeout = values.get("RC_OVERRIDE_TIME")
    out.append(Finding("RC_OVERRIDE_TIME", timeout, f"{SAFE_OVERRIDE_TIME_S:g}",
                       f"a dead companion's override lapses within {OVERRIDE_TIME_MAX_S:g} s "
                       "(0 would ignore every override, -1 keeps it for ever)",
                       timeout is not None and not 0 < timeout <= OVERRIDE_TIME_MAX_S))
    throttle = _int(values.get("RCMAP_THROTTLE"))
    out.append(Finding("RCMAP_THROTTLE", values.get("RCMAP_THROTTLE"),
                       f"one of {sorted(refreshed)}",
                       "the radio failsafe watches this channel; the companion must refresh "
                       "it", throttle is not None and throttle not in refreshed))
    fs_thr = _int(values.get("FS_THR_ENABLE"))
    out.append(Finding("FS_THR_ENABLE", values.get("FS_THR_ENABLE"), "1",
                       "the radio failsafe takes the scaled outputs to trim", fs_thr == 0))
    out.append(Finding("RC_PROTOCOLS", values.get("RC_PROTOCOLS"), "any",
                       "the receiver's protocols (0: no receiver is read; then only the "
                       "scaled pass-through's fall-back stops a dead companion's wheels)",
                       False))
    rudder = _int(values.get("ARMING_RUDDER"))
    out.append(Finding("ARMING_RUDDER", values.get("ARMING_RUDDER"), "0",
                       "a diagonal drive (ch 1 full, ch 3 trim) must not arm or disarm",
                       rudder is not None and rudder != 0))
    return out


def safe_settings(params: Params, values: Values) -> dict[str, float]:
    """The parameter values that make the board safe for this companion (what ``--apply``
    writes): the ground-station id, scaled pass-through with the failsafe mask, matched
    ranges, no dead zone, a short override timeout, the radio failsafe on, no rudder arming.
    ``values`` (what the board has) chooses the ground-station id's name."""
    wheels = wheel_channels(params)
    out: dict[str, float] = {_gcs_name(values): int(params["FC_GCS_SYSID"])}
    mask = int(values.get("SERVO_RC_FS_MSK", 0))
    for w, ch in wheels:
        out[f"SERVO{ch}_FUNCTION"] = RCIN_SCALED_FIRST + ch - 1
        mask |= 1 << (ch - 1)
        for part in ("MIN", "TRIM", "MAX"):
            want = int(params[f"MOT_{w}_{part}"])
            out[f"RC{ch}_{part}"] = want
            out[f"SERVO{ch}_{part}"] = want
        out[f"RC{ch}_DZ"] = 0
    out["SERVO_RC_FS_MSK"] = mask
    out["RC_OVERRIDE_TIME"] = SAFE_OVERRIDE_TIME_S
    throttle = values.get("RCMAP_THROTTLE")
    if throttle is None or int(throttle) not in {ch for _, ch in wheels}:
        out["RCMAP_THROTTLE"] = wheels[0][1]
    fs_thr = values.get("FS_THR_ENABLE")
    out["FS_THR_ENABLE"] = 1 if fs_thr is None or int(fs_thr) == 0 else fs_thr
    out["ARMING_RUDDER"] = 0
    return out


def store_nudge(name: str, value: float) -> float | None:
    """A harmless neighbour of ``value`` to write to ``name`` first, so that ArduPilot stores
    ``value`` when it is written next; None where no neighbour is harmless.

    ArduPilot stores a parameter set over MAVLink only if it is already stored or differs
    from its default (``AP_Param::save_sync``), and some defaults are set at every boot from
    other settings: Rover gives the dead zone of its steering, throttle and lateral input
    channels a default of 30 (``set_default_dead_zone``). Measured with the SITL: RC9_DZ
    written as 0 while 0 was its default, then RCMAP_THROTTLE 9 and a reboot: RC9_DZ read 30;
    written 1 then 0 first, it read 0. A pulse width or dead zone 1 us off for a moment while
    setting up moves nothing; a function, id, mask or switch is never nudged."""
    if _NUDGED.match(name):
        return value + 1
    if name == "RC_OVERRIDE_TIME":
        return value + 0.1
    return None


_NUDGED = re.compile(r"(RC|SERVO)\d+_(MIN|TRIM|MAX)$|RC\d+_DZ$")
REBOOT_NAMES = frozenset({"RCMAP_THROTTLE"})
"""Settings ArduPilot reads at boot only (a change needs a reboot of the flight controller)."""
