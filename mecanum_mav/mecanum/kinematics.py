"""Mecanum drive kinematics in the body FRD frame.

Frames and signs (see CONVENTIONS.md): x forward, y right, yaw rate positive clockwise seen
from above; wheel order FL, FR, RL, RR on the last axis of every wheel array; a positive
wheel speed rolls the robot forward. Rollers are in the usual "X": a wheel rolls at
``v_x + s_i * v_y`` of the velocity at its contact point, with ``s = (+1, -1, -1, +1)``
(:data:`ROLLER_SIGNS`, defined in :mod:`mecanum_mav.mecanum.wheels` as ``LATERAL_SIGNS``).

For a rigid body turning at ``w`` about a centre of rotation ``c`` (which moves at
``(vx, vy)``), the velocity at a point ``p`` relative to ``c`` is ``(vx - w*p_y, vy + w*p_x)``,
so wheel ``i`` at ``r_i`` (from the robot centre) rolls at::

    wheel_i = vx + s_i*vy + w*(s_i*(r_ix - c_x) - (r_iy - c_y))

Forward kinematics inverts the 4x3 matrix of that map for ``c = (0, 0)`` by least squares
(Moore-Penrose pseudo-inverse), as WPILib's ``MecanumDriveKinematics`` does. WPILib works
in NWU (y left, counter-clockwise positive); here y and yaw rate have the opposite sign.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from mecanum_mav.mecanum.geometry import Twist2d
from mecanum_mav.mecanum.wheels import CORNER_SIGNS
from mecanum_mav.mecanum.wheels import LATERAL_SIGNS as ROLLER_SIGNS

__all__ = ["ROLLER_SIGNS", "MecanumKinematics"]

FloatArray = npt.NDArray[np.float64]
Position = tuple[float, float]

_PY_SCALARS = (float, int)


def _finite_wheels(values: npt.ArrayLike, what: str) -> FloatArray:
    """``values`` as a float64 array with a last axis of 4; ValueError if non-finite."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.shape[-1:] != (4,):
        raise ValueError(f"wheel {what} need a last axis of length 4 (FL, FR, RL, RR)")
    if not np.isfinite(arr).all():
        raise ValueError(f"non-finite wheel {what}: {arr!r}")
    return arr


class MecanumKinematics:
    """Inverse and forward kinematics of a four-wheel mecanum drive ("X" rollers).

    Wheel positions are (x, y) in metres in the body FRD frame (x forward, y right),
    measured from the robot centre, the point whose velocity forward kinematics reports;
    :attr:`positions` keeps them as float pairs in the order FL, FR, RL, RR.
    Chassis quantities are (vx m/s forward, vy m/s right, yaw rate rad/s clockwise);
    wheel quantities are surface speeds in m/s (positive rolls the robot forward),
    ordered FL, FR, RL, RR.

    ``strafe_efficiency`` (``WHL_STRAFE_EFF``) is the fraction of the roller-kinematic lateral
    speed the chassis achieves (rollers slip sideways; 1.0 = ideal): the inverse kinematics ask
    the wheels for ``vy / strafe_efficiency`` and the forward kinematics report the wheels'
    lateral part times it, both ways the same matrix.
    """

    __slots__ = ("_k", "_lateral_gain", "_matrix", "_pinv_rows", "_pinv_t", "positions",
                 "strafe_efficiency")

    def __init__(
        self,
        front_left: Sequence[float],
        front_right: Sequence[float],
        rear_left: Sequence[float],
        rear_right: Sequence[float],
        *,
        strafe_efficiency: float = 1.0,
    ) -> None:
        """Build the kinematics from the four wheel positions (x, y), metres, FRD, and the
        strafe efficiency (class docstring; a finite number in (0, 2]).

        Raises ValueError if the strafe efficiency is out of range, a position is not a
        finite (x, y) pair or the wheels are
        placed so that the 4x3 inverse-kinematics matrix does not have rank 3 (the
        chassis motion could not be recovered from the wheel speeds).
        """
        if not (math.isfinite(strafe_efficiency) and 0.0 < strafe_efficiency <= 2.0):
            raise ValueError(f"strafe efficiency {strafe_efficiency!r} is not in (0, 2]")
        self.strafe_efficiency = float(strafe_efficiency)
        self._lateral_gain = 1.0 / self.strafe_efficiency
        pos = np.asarray((front_left, front_right, rear_left, rear_right), dtype=np.float64)
        if pos.shape != (4, 2):
            raise ValueError("each wheel position must be an (x, y) pair in metres")
        if not np.isfinite(pos).all():
            raise ValueError(f"non-finite wheel position: {pos.tolist()}")
        signs = np.asarray(ROLLER_SIGNS)
        # Yaw-rate column for a centre of rotation at the robot centre.
        k = signs * pos[:, 0] - pos[:, 1]
        matrix = np.column_stack((np.ones(4), signs * self._lateral_gain, k))
        if np.linalg.matrix_rank(matrix) < 3:
            raise ValueError(
                f"wheel positions {pos.tolist()} give a rank-deficient kinematics matrix"
            )
        fl, fr, rl, rr = ((float(x), float(y)) for x, y in pos)
        self.positions: tuple[Position, Position, Position, Position] = (fl, fr, rl, rr)
        self._matrix: FloatArray = matrix
        pinv = np.linalg.pinv(matrix)
        self._pinv_t: FloatArray = np.ascontiguousarray(pinv.T)
        # Python-float copies for the scalar fast paths (numpy scalars are slow there).
        k_fl, k_fr, k_rl, k_rr = k.tolist()
        self._k: tuple[float, float, float, float] = (k_fl, k_fr, k_rl, k_rr)
        vx_row, vy_row, w_row = (tuple(row) for row in pinv.tolist())
        self._pinv_rows: tuple[tuple[float, ...], ...] = (vx_row, vy_row, w_row)

    @classmethod
    def from_half_extents(cls, half_length_m: float, half_width_m: float, *,
                          strafe_efficiency: float = 1.0) -> MecanumKinematics:
        """Wheels on a rectangle centred on the robot, half-sizes in metres.

        FL = (L, -W), FR = (L, W), RL = (-L, -W), RR = (-L, W) in FRD (x forward, y right),
        with L = ``half_length_m`` (centre to axle) and W = ``half_width_m`` (centre to
        wheel contact, sideways); ``strafe_efficiency`` as in the class docstring.
        """
        fl, fr, rl, rr = ((sx * half_length_m, sy * half_width_m) for sx, sy in CORNER_SIGNS)
        return cls(fl, fr, rl, rr, strafe_efficiency=strafe_efficiency)

    @property
    def matrix(self) -> FloatArray:
        """Copy of the 4x3 inverse-kinematics matrix (rows FL, FR, RL, RR; columns vx,
        vy, yaw rate) for a centre of rotation at the robot centre: wheels = M @ chassis."""
        matrix: FloatArray = self._matrix.copy()
        return matrix

    @property
    def pseudo_inverse(self) -> FloatArray:
        """Copy of the 3x4 Moore-Penrose pseudo-inverse of :attr:`matrix`."""
        pinv: FloatArray = self._pinv_t.T.copy()
        return pinv

    def __repr__(self) -> str:
        """Constructor-style representation with the wheel positions in metres."""
        fl, fr, rl, rr = self.positions
        eff = self.strafe_efficiency
        extra = "" if eff == 1.0 else f", strafe_efficiency={eff!r}"
        return f"{type(self).__name__}({fl}, {fr}, {rl}, {rr}{extra})"

    def to_wheel_speeds(
        self,
        vx: npt.ArrayLike,
        vy: npt.ArrayLike,
        yaw_rate: npt.ArrayLike,
        center_of_rotation: npt.ArrayLike = (0.0, 0.0),
    ) -> FloatArray:
        """Inverse kinematics: chassis velocity -> wheel speeds [..., 4] in m/s.

        ``vx`` (m/s forward), ``vy`` (m/s right) and ``yaw_rate`` (rad/s clockwise) are in
        the body FRD frame and are the velocity of ``center_of_rotation`` (x, y metres,
        FRD, from the robot centre; default the robot centre), about which the robot
        turns at ``yaw_rate``. Floats or array-likes that broadcast together (the centre's
        last axis is its (x, y)); the result has the broadcast shape plus a last axis of
        4 (FL, FR, RL, RR). With scalar numbers only (and the centre a tuple), a fast
        plain-arithmetic path is used (about 1 us).

        Warning: the result is NOT normalized or desaturated. A command may ask a wheel
        for more than it can attain; pass the result through ``mixing.desaturate``.

        A non-finite value (NaN or inf) in any component of a command, or in its centre
        of rotation, gives that command all four wheel speeds 0.0 (stop): the output is
        never NaN or inf. A finite command so large that a wheel speed overflows to inf
        is treated the same way.
        """
        if (
            isinstance(vx, _PY_SCALARS)
            and isinstance(vy, _PY_SCALARS)
            and isinstance(yaw_rate, _PY_SCALARS)
            and isinstance(center_of_rotation, tuple)
            and len(center_of_rotation) == 2
        ):
            cx, cy = center_of_rotation
            if isinstance(cx, _PY_SCALARS) and isinstance(cy, _PY_SCALARS):
                return np.array(self.wheel_speeds(vx, vy, yaw_rate, (cx, cy)))
        return self._to_wheels_array(vx, vy, yaw_rate, center_of_rotation)

    def wheel_speeds(self, vx: float, vy: float, yaw_rate: float,
                     center_of_rotation: tuple[float, float] = (0.0, 0.0)
                     ) -> tuple[float, float, float, float]:
        """:meth:`to_wheel_speeds` for one command of plain numbers, as a tuple of floats
        (m/s, FL, FR, RL, RR): the control loop's path, no numpy (a small array costs more
        than the arithmetic, several times more when the caches are cold).

        ``vx`` (m/s forward), ``vy`` (m/s right), ``yaw_rate`` (rad/s clockwise), body FRD,
        of ``center_of_rotation`` (x, y metres from the robot centre). Non-finite input, or a
        wheel speed that overflows, gives four 0.0 (stop).

        Warning: NOT normalized or desaturated (see :meth:`to_wheel_speeds`).
        """
        # float() also turns numpy scalars into python floats, whose arithmetic gives
        # inf/NaN quietly instead of raising numpy RuntimeWarnings.
        w = float(yaw_rate)
        cx, cy = center_of_rotation
        # Velocity of the robot centre, then the fixed centre-based matrix rows.
        vxc = float(vx) + w * float(cy)
        vyc = (float(vy) - w * float(cx)) * self._lateral_gain
        k_fl, k_fr, k_rl, k_rr = self._k
        fl = vxc + vyc + w * k_fl
        fr = vxc - vyc + w * k_fr
        rl = vxc - vyc + w * k_rl
        rr = vxc + vyc + w * k_rr
        # x - x is 0.0 for finite x and NaN for NaN or inf.
        if (fl - fl) + (fr - fr) + (rl - rl) + (rr - rr) == 0.0:
            return fl, fr, rl, rr
        return 0.0, 0.0, 0.0, 0.0

    def _to_wheels_array(
        self,
        vx: npt.ArrayLike,
        vy: npt.ArrayLike,
        yaw_rate: npt.ArrayLike,
        center_of_rotation: npt.ArrayLike,
    ) -> FloatArray:
        """Numpy path of :meth:`to_wheel_speeds` (same units, frames and rules)."""
        c = np.asarray(center_of_rotation, dtype=np.float64)
        if c.shape[-1:] != (2,):
            raise ValueError("center_of_rotation needs a last axis of length 2: (x, y) metres")
        w = np.asarray(yaw_rate, dtype=np.float64)
        with np.errstate(invalid="ignore", over="ignore"):
            chassis = np.stack(
                np.broadcast_arrays(
                    np.asarray(vx, dtype=np.float64) + w * c[..., 1],
                    np.asarray(vy, dtype=np.float64) - w * c[..., 0],
                    w,
                ),
                axis=-1,
            )
            wheels: FloatArray = chassis @ self._matrix.T
        bad = ~np.isfinite(wheels).all(axis=-1)
        if bad.any():
            wheels[bad] = 0.0
        return wheels

    def to_wheel_accelerations(
        self,
        ax: npt.ArrayLike,
        ay: npt.ArrayLike,
        yaw_accel: npt.ArrayLike,
        center_of_rotation: npt.ArrayLike = (0.0, 0.0),
    ) -> FloatArray:
        """Inverse kinematics for accelerations: chassis -> wheel accelerations [..., 4].

        ``ax`` (m/s^2 forward), ``ay`` (m/s^2 right), ``yaw_accel`` (rad/s^2 clockwise),
        body FRD, of ``center_of_rotation`` (x, y metres, FRD, from the robot centre).
        Returns wheel surface accelerations in m/s^2, order FL, FR, RL, RR. This is the
        same linear map as :meth:`to_wheel_speeds` (as in WPILib; no centripetal terms),
        with the same broadcasting, fast path, no-desaturation warning and non-finite
        rule (a non-finite command gives all-zero wheel accelerations).
        """
        return self.to_wheel_speeds(ax, ay, yaw_accel, center_of_rotation)

    def to_chassis_speeds(self, wheel_speeds: npt.ArrayLike) -> FloatArray:
        """Forward kinematics: wheel speeds [..., 4] (m/s, FL, FR, RL, RR) -> [..., 3].

        Returns (vx m/s forward, vy m/s right, yaw rate rad/s clockwise) of the robot
        centre in the body FRD frame, the least-squares (pseudo-inverse) fit to the four
        wheels, as WPILib. A python tuple or list of 4 numbers takes a fast
        plain-arithmetic path. Raises ValueError("non-finite wheel speeds ...") if any
        wheel speed is NaN or inf, and ValueError if the last axis is not 4 long.
        """
        return self._forward(wheel_speeds, "speeds")

    def to_chassis_accelerations(self, wheel_accels: npt.ArrayLike) -> FloatArray:
        """Forward kinematics for accelerations: wheel [..., 4] (m/s^2) -> chassis [..., 3].

        Returns (ax m/s^2 forward, ay m/s^2 right, yaw acceleration rad/s^2 clockwise),
        body FRD, robot centre, by least squares. Raises ValueError if any wheel
        acceleration is non-finite or the last axis is not 4 long.
        """
        return self._forward(wheel_accels, "accelerations")

    def to_twist(self, wheel_deltas: npt.ArrayLike) -> Twist2d | FloatArray:
        """Forward kinematics for small displacements: metres rolled -> body twist.

        ``wheel_deltas`` are the distances (m, FL, FR, RL, RR) each wheel rolled over one
        step. One set (a sequence of 4 or an array of shape (4,)) returns a
        :class:`Twist2d` (dx m forward, dy m right, dyaw rad clockwise; body FRD frame at
        the start of the step, robot centre), the least-squares fit as in WPILib; a batch
        of shape [..., 4] with two or more dimensions returns a float64 ndarray [..., 3]
        of the same quantities. Feed it to ``geometry.pose_exp`` to move a pose. Raises
        ValueError if any delta is non-finite or the last axis is not 4 long.
        """
        plain = self._forward_plain(wheel_deltas)
        if plain is not None:  # (the odometry's path: no numpy)
            return Twist2d(*plain)
        if np.ndim(wheel_deltas) == 1:
            dx, dy, dyaw = self._forward(wheel_deltas, "deltas").tolist()
            return Twist2d(dx, dy, dyaw)
        return self._forward(wheel_deltas, "deltas")

    def _forward_plain(self, wheels: object) -> tuple[float, float, float] | None:
        """The least-squares fit for a tuple or list of 4 finite plain numbers; else None."""
        if isinstance(wheels, (tuple, list)) and len(wheels) == 4:
            fl, fr, rl, rr = wheels
            scalars = _PY_SCALARS  # (no generator: each is a frame on the control path)
            if not (isinstance(fl, scalars) and isinstance(fr, scalars)
                    and isinstance(rl, scalars) and isinstance(rr, scalars)):
                return None
            fl, fr, rl, rr = float(fl), float(fr), float(rl), float(rr)
            # x - x is 0.0 for finite x and NaN for NaN or inf.
            if (fl - fl) + (fr - fr) + (rl - rl) + (rr - rr) == 0.0:
                (a, b, c, d), (e, f, g, h), (i, j, k, m) = self._pinv_rows
                return (a * fl + b * fr + c * rl + d * rr, e * fl + f * fr + g * rl + h * rr,
                        i * fl + j * fr + k * rl + m * rr)
        return None

    def _forward(self, wheels: npt.ArrayLike, what: str) -> FloatArray:
        """Least-squares chassis quantities [..., 3] from wheel quantities [..., 4]."""
        plain = self._forward_plain(wheels)
        if plain is not None:
            return np.array(plain)
        return _finite_wheels(wheels, what) @ self._pinv_t
