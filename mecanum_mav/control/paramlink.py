"""The parameter protocol's glue: PARAM_REQUEST_LIST, PARAM_REQUEST_READ and PARAM_SET from the
ground station, answered with PARAM_VALUE through
:class:`~mecanum_mav.protocol.paramservice.ParamService` (names, types, indices, validation).

An accepted PARAM_SET takes effect at once (the core re-reads its views), is kept by the
storage, and a parameter read only at start says so; a refused one changes and keeps nothing,
is answered with the value in force and says why. An unknown name gets no answer, as the
protocol specifies.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

from mecanum_mav.config.params import Params
from mecanum_mav.control.context import Context, Handler
from mecanum_mav.control.refusals import Refusal
from mecanum_mav.protocol.messages import Addressed, ParamReadMsg, ParamSetMsg
from mecanum_mav.protocol.paramservice import RESTART_REQUIRED, ParamService, ParamValue
from mecanum_mav.protocol.statustext import Severity

__all__ = ["ParamLink", "ParamStore"]


class ParamStore(Protocol):
    """Where accepted parameters are kept (the companion's parameter file)."""

    def save_params(self, params: Params) -> None:
        """Keep the parameters; raises ``OSError`` when that fails."""


class ParamLink:
    """The ground station's parameter requests for one rover.

    Args:
        ctx: what the core shares (the parameters, addressing, the voice, the outbox).
        reconfigure: re-reads every view of the parameters (the core's), after a change.
        storage: keeps accepted parameters, or None.
    """

    def __init__(self, ctx: Context, reconfigure: Callable[[], None],
                 storage: ParamStore | None) -> None:
        self.params = ctx.params
        self.service = ParamService(ctx.params)
        self.to_gcs = ctx.to_gcs
        self.reconfigure = reconfigure
        self.storage = storage
        self._for_us = ctx.for_us
        self._from_pilot = ctx.from_pilot
        self.say = ctx.say
        self.refuse = ctx.refuse

    def routes(self) -> dict[str, Handler]:
        """The messages handled here, by type."""
        return {"PARAM_REQUEST_LIST": self.on_request_list,
                "PARAM_REQUEST_READ": self.on_request_read, "PARAM_SET": self.on_param_set}

    def _send_param(self, value: ParamValue) -> None:
        self.to_gcs.param_value_send(value.param_id, value.param_value, value.param_type,
                                     value.param_count, value.param_index)

    def on_request_list(self, msg: Addressed, now_s: float) -> None:
        """PARAM_REQUEST_LIST: every parameter, in index order."""
        if self._for_us(msg.target_system, msg.target_component):
            for value in self.service.all_values():
                self._send_param(value)

    def on_request_read(self, msg: ParamReadMsg, now_s: float) -> None:
        """PARAM_REQUEST_READ: one parameter by name or index (nothing for an unknown one)."""
        if self._for_us(msg.target_system, msg.target_component):
            value = self.service.read(msg.param_id, msg.param_index)
            if value is not None:
                self._send_param(value)

    def on_param_set(self, msg: ParamSetMsg, now_s: float) -> None:
        """PARAM_SET from the pilot: validated, answered, applied and kept (module docstring)."""
        if not (self._for_us(msg.target_system, msg.target_component) and self._from_pilot(msg)):
            return
        answer = self.service.set(msg.param_id, msg.param_value)
        if answer is None:
            return  # unknown name: no answer, as the protocol specifies
        value, problem = answer
        self._send_param(value)
        name = value.param_id.decode()
        if problem:
            self.refuse(Refusal.PARAM, f"Param refused: {problem}")
            return
        self.reconfigure()
        if name in RESTART_REQUIRED:
            self.say(Severity.NOTICE, f"{name} takes effect after a restart")
        if self.storage is not None:
            try:
                self.storage.save_params(self.params)
            except OSError as exc:
                self.say(Severity.ERROR, f"Param save failed: {exc.strerror}")
