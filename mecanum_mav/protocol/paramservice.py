"""The MAVLink parameter protocol, served from the one parameter schema.

- ``PARAM_REQUEST_LIST``: every parameter as ``PARAM_VALUE``; the index is the parameter's
  position in :data:`mecanum_mav.config.params.SCHEMA`, the count the schema's length.
- ``PARAM_REQUEST_READ``: by index, or by name when ``param_index`` is -1. An unknown name or
  index gets no answer (the protocol's way: the ground station times out).
- ``PARAM_SET``: validated by the schema (range, integer, finite, cross-parameter rules). If
  accepted the new value is stored and announced with ``PARAM_VALUE``; if refused the
  unchanged value is sent back and the reason goes out as STATUSTEXT. Unknown names: silence.

Values travel as floats cast from the stored value, ArduPilot's encoding (which MAVProxy,
MAVSDK and QGroundControl all expect from an ArduPilot autopilot), with ``param_type``
``MAV_PARAM_TYPE_INT32`` for int parameters and ``MAV_PARAM_TYPE_REAL32`` for float ones.
"""

from __future__ import annotations

from dataclasses import dataclass

from mecanum_mav.config.params import SCHEMA, SPECS, ParamError, Params
from mecanum_mav.protocol.dialect import mavlink

__all__ = ["RESTART_REQUIRED", "ParamService", "ParamValue"]

RESTART_REQUIRED: frozenset[str] = frozenset(spec.name for spec in SCHEMA if spec.reboot_required)
"""Parameters stored at once but used only after a restart (``ParamSpec.reboot_required`` in
the schema): identity, the wheel geometry (the odometry's kinematics is built once, so a live
change cannot bend its history) and the simulator."""

_INDEX = {spec.name: index for index, spec in enumerate(SCHEMA)}


@dataclass(frozen=True)
class ParamValue:
    """The fields of one PARAM_VALUE message."""

    param_id: bytes
    param_value: float
    param_type: int
    param_count: int
    param_index: int


class ParamService:
    """Answers the parameter protocol for a :class:`~mecanum_mav.config.params.Params` store."""

    def __init__(self, params: Params) -> None:
        self.params = params

    def value(self, name: str) -> ParamValue:
        """PARAM_VALUE fields for the parameter ``name`` (which must exist)."""
        spec = SPECS[name]
        kind = mavlink.MAV_PARAM_TYPE_INT32 if spec.kind is int else mavlink.MAV_PARAM_TYPE_REAL32
        return ParamValue(name.encode("ascii"), float(self.params[name]), kind, len(SCHEMA),
                          _INDEX[name])

    def all_values(self) -> list[ParamValue]:
        """PARAM_VALUE fields for every parameter, in index order (PARAM_REQUEST_LIST)."""
        return [self.value(spec.name) for spec in SCHEMA]

    def read(self, param_id: str, param_index: int) -> ParamValue | None:
        """PARAM_REQUEST_READ: by index, or by name (as pymavlink gives it) when
        ``param_index`` is -1; else None (an index past the last, an unknown name)."""
        if param_index >= 0:
            return self.value(SCHEMA[param_index].name) if param_index < len(SCHEMA) else None
        return self.value(param_id) if param_id in SPECS else None

    def set(self, param_id: str, param_value: float) -> tuple[ParamValue, str] | None:
        """PARAM_SET: None for an unknown name (no answer is sent), else ``(reply, problem)``:
        ``problem`` is "" when the value was stored, else the reason it was refused (the reply
        then holds the old value).

        Names as pymavlink gives them (``param_id`` ends at its NUL)."""
        if param_id not in SPECS:
            return None
        try:
            self.params.set(param_id, param_value)
        except ParamError as exc:
            return self.value(param_id), str(exc)
        return self.value(param_id), ""
