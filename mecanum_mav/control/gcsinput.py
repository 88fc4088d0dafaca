"""The ground station's inputs: its heartbeat, its sticks (MANUAL_CONTROL and its own
RC_CHANNELS_OVERRIDE), GUIDED setpoints, the global origin, and SETUP_SIGNING (refused).

Each handler takes one message and its arrival time (s) and changes the shared
:class:`~mecanum_mav.control.context.Context`: a valid stick becomes the drive input
(:meth:`~mecanum_mav.control.context.Context.take_stick`), a setpoint goes to the GUIDED
controller; the output follows in the core's next tick. Only messages for this vehicle from the
pilot's ground station count; bad input is refused with a reason and moves nothing.
"""

from __future__ import annotations

from collections.abc import Callable

from mecanum_mav.config.params import Params
from mecanum_mav.control.autopilot import Autopilot
from mecanum_mav.control.context import Context, Handler
from mecanum_mav.control.estimator import WheelOdometryEstimator
from mecanum_mav.control.guided import SetpointError, decode_setpoint
from mecanum_mav.control.refusals import Refusal
from mecanum_mav.control.sticks import InputError, RcStickState, stick_from_manual_control
from mecanum_mav.mecanum.geo import GlobalOrigin
from mecanum_mav.protocol.messages import (
    Addressed,
    ManualControlMsg,
    OriginMsg,
    Received,
    SetpointMsg,
)
from mecanum_mav.protocol.modes import Mode
from mecanum_mav.protocol.statustext import Severity

__all__ = ["GcsInput"]


class GcsInput:
    """The ground station's drive inputs for one rover.

    Args:
        ctx: what the core shares (addressing, the voice, the drive input).
        estimator: the pose a setpoint is decoded against.
        autopilot: the GUIDED controller that takes setpoints.
    """

    def __init__(self, ctx: Context, estimator: WheelOdometryEstimator,
                 autopilot: Autopilot) -> None:
        self._ctx = ctx
        self.vehicle = ctx.vehicle
        self.estimator = estimator
        self.autopilot = autopilot
        self.rc_sticks = RcStickState()
        """The ground station's RC_CHANNELS_OVERRIDE channels, as the sticks read them."""
        self.origin_set: GlobalOrigin | None = None
        """The global origin from SET_GPS_GLOBAL_ORIGIN (overrides ORIGIN_LAT/LON)."""
        self._origin_param: GlobalOrigin | None = None
        # bound once: each stick calls them
        self._for_us: Callable[..., bool] = ctx.for_us
        self._from_pilot = ctx.from_pilot
        self._take_stick = ctx.take_stick
        self.refuse = ctx.refuse

    def routes(self) -> dict[str, Handler]:
        """The messages handled here, by type."""
        return {"HEARTBEAT": self.on_heartbeat, "MANUAL_CONTROL": self.on_manual_control,
                "RC_CHANNELS_OVERRIDE": self.on_rc_override,
                "SET_POSITION_TARGET_LOCAL_NED": self.on_position_target,
                "SET_GPS_GLOBAL_ORIGIN": self.on_set_origin,
                "SETUP_SIGNING": self.on_setup_signing}

    def reconfigure(self, params: Params) -> None:
        """Re-read ``ORIGIN_LAT`` and ``ORIGIN_LON`` (both 0: no origin)."""
        lat, lon = float(params["ORIGIN_LAT"]), float(params["ORIGIN_LON"])
        self._origin_param = None if lat == lon == 0.0 else GlobalOrigin.from_degrees(lat, lon)

    def origin(self) -> GlobalOrigin | None:
        """Where local (0, 0) is on the earth: SET_GPS_GLOBAL_ORIGIN, else ORIGIN_LAT/LON."""
        return self._origin_param if self.origin_set is None else self.origin_set

    def on_heartbeat(self, msg: Received, now_s: float) -> None:
        """The pilot's HEARTBEAT keeps the ground-station failsafe from firing."""
        if self._from_pilot(msg):
            self.vehicle.on_gcs_heartbeat(now_s)

    def on_manual_control(self, msg: ManualControlMsg, now_s: float) -> None:
        """MANUAL_CONTROL: the pilot's stick (x forward, y right, r clockwise)."""
        if not (self._for_us(msg.target) and self._from_pilot(msg)):
            return
        try:
            stick = stick_from_manual_control(msg.x, msg.y, msg.r, msg.z,
                                              z_scale=self._ctx.input.z_scale)
        except InputError as exc:
            self.refuse(Refusal.STICK, f"Rejected: {exc}")
            return
        self._take_stick(stick, now_s)

    def on_rc_override(self, msg: Addressed, now_s: float) -> None:
        """RC_CHANNELS_OVERRIDE from the ground station: its stick channels drive."""
        if not (self._for_us(msg.target_system, msg.target_component) and self._from_pilot(msg)):
            return
        channels = [getattr(msg, f"chan{i}_raw") for i in range(1, 19)]
        rc_input = self._ctx.rc_input
        try:
            self.rc_sticks.apply(channels)
        except InputError as exc:
            self.refuse(Refusal.STICK, f"Rejected: {exc}")
            return
        if self.rc_sticks.touches_sticks(channels, rc_input):
            self._take_stick(self.rc_sticks.stick(rc_input), now_s)

    def on_position_target(self, msg: SetpointMsg, now_s: float) -> None:
        """SET_POSITION_TARGET_LOCAL_NED: a GUIDED setpoint (refused in other modes)."""
        if not (self._for_us(msg.target_system, msg.target_component) and self._from_pilot(msg)):
            return
        if self.vehicle.mode is not Mode.GUIDED:
            self.refuse(Refusal.SETPOINT, "Rejected: setpoint: not in GUIDED")
            return
        pose = self.estimator.pose
        try:
            setpoint = decode_setpoint(msg.coordinate_frame, msg.type_mask, msg.x, msg.y,
                                       msg.vx, msg.vy, msg.yaw, msg.yaw_rate, pose, now_s)
        except SetpointError as exc:
            self.refuse(Refusal.SETPOINT, f"Rejected: setpoint: {exc}")
            return
        self.autopilot.guided.accept(setpoint, pose)
        ctx = self._ctx
        ctx.faulted = False
        ctx.new_input = True

    def on_set_origin(self, msg: OriginMsg, now_s: float) -> None:
        """SET_GPS_GLOBAL_ORIGIN: where local (0, 0) is; answered with GPS_GLOBAL_ORIGIN."""
        if not (self._for_us(msg.target_system) and self._from_pilot(msg)):
            return
        try:
            origin = GlobalOrigin(msg.latitude, msg.longitude, msg.altitude)
        except ValueError as exc:
            self.refuse(Refusal.ORIGIN, f"Rejected: origin: {exc}")
            return
        self.origin_set = origin
        ctx = self._ctx
        ctx.to_gcs.gps_global_origin_send(origin.lat_e7, origin.lon_e7, origin.alt_mm,
                                          int((now_s - ctx.boot_s) * 1e6))
        ctx.say(Severity.INFO, f"Origin {origin.lat_e7 / 1e7:.7f} {origin.lon_e7 / 1e7:.7f}")

    def on_setup_signing(self, msg: Addressed, now_s: float) -> None:
        """SETUP_SIGNING: refused (the key is the companion's ``--signing-key`` file)."""
        if self._for_us(msg.target_system, msg.target_component):
            # the key is changed in the file, and takes effect at the next start
            self.refuse(Refusal.COMMAND, "SETUP_SIGNING refused: key is from --signing-key")
