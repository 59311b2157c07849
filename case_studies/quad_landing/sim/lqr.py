"""LQR hover controller (designed with python-control on the CasADi Jacobians).

The gain ``K`` comes from ``control.lqr(A, B, Q, R)`` with ``(A, B)`` the Jacobians of
the quadrotor at hover with yaw 0 (:func:`.dynamics.linearize_hover`). Because the
hover linearisation at any yaw is the yaw-0 one seen in a yawed frame, position and
velocity errors are rotated into the yaw frame before ``K`` is applied. The position
error is clamped (horizontal norm and vertical separately) so that far waypoints do
not command large tilts: the tilt stays small and a downward camera keeps the pad in
view.

The control law, for a reference ``(p_r, v_r, a_r, j_r, psi_r, psidot_r)``::

    a' = Rz(psi)^T a_r,  L = g + a_r,z,  N = |a' + g e3|   (feedforward, yaw frame)
    roll_r = -asin(a'_y / N),  pitch_r = atan2(a'_x, L)     (thrust along a_r + g e3)
    omega_r = body rates of d/dt (roll_r, pitch_r, psi_r)    (from the jerk j_r)
    e = [Rz(psi)^T clamp(p - p_r), Rz(psi)^T (v - v_r),
         roll - roll_r, pitch - pitch_r, wrap(psi - psi_r), omega - omega_r]
    u = clip(u_hover N / g - K e, 0, max_rotor_thrust)

The feedforward tilts the vehicle ahead of time on curved paths so that exploration
paths are tracked to a few centimetres; for waypoints it is zero.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import control
import numpy as np
from numpy.typing import ArrayLike

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.settings import DEFAULTS_PATH, TomlSection, check_positive
from case_studies.quad_landing.sim.dynamics import QuadParams, hover_thrust, linearize_hover
from case_studies.quad_landing.sim.frames import wrap_angle
from ipcverify.errors import InvalidInputError

__all__ = ["LqrParams", "SettleParams", "is_settled", "Reference", "HoverLqr", "MOTORS_OFF"]


#: The motors-off command (all rotor thrusts zero).
MOTORS_OFF: FloatArray = np.zeros(4)
MOTORS_OFF.setflags(write=False)


def _positive_tuple(name: str, values: ArrayLike, n: int) -> tuple[float, ...]:
    out = tuple(float(v) for v in np.asarray(values, dtype=np.float64).reshape(-1))
    if len(out) != n or not all(np.isfinite(v) and v > 0 for v in out):
        raise InvalidInputError(f"{name} must be {n} positive numbers, got {values!r}")
    return out


@dataclass(frozen=True, kw_only=True)
class LqrParams(TomlSection, file=DEFAULTS_PATH, section="lqr"):
    """LQR weights and error clamps.

    Parameters
    ----------
    q_position, q_velocity, q_attitude, q_rate : tuple of 3 floats
        Diagonal state weights (x, y, z / roll, pitch, yaw) in the yaw frame.
    r_thrust : float
        Weight on each rotor thrust deviation (1/N^2).
    max_position_error_xy : float
        Clamp on the horizontal norm of the position error (m).
    max_position_error_z : float
        Clamp on the vertical position error (m).

    Examples
    --------
    >>> LqrParams.defaults().max_position_error_xy  # [lqr] of defaults.toml
    0.5
    """

    q_position: tuple[float, float, float]
    q_velocity: tuple[float, float, float]
    q_attitude: tuple[float, float, float]
    q_rate: tuple[float, float, float]
    r_thrust: float
    max_position_error_xy: float
    max_position_error_z: float

    def __post_init__(self) -> None:
        for name in ("q_position", "q_velocity", "q_attitude", "q_rate"):
            object.__setattr__(self, name, _positive_tuple(f"lqr.{name}", getattr(self, name), 3))
        for name in ("r_thrust", "max_position_error_xy", "max_position_error_z"):
            check_positive(f"lqr.{name}", getattr(self, name))


@dataclass(frozen=True, kw_only=True)
class SettleParams(TomlSection, file=DEFAULTS_PATH, section="settle"):
    """When a waypoint counts as reached: within tolerances for ``hold_time`` seconds.

    Parameters
    ----------
    position_tolerance : float
        Largest distance from the waypoint (m, Euclidean norm in W).
    velocity_tolerance : float
        Largest speed (m/s, norm of the velocity in W).
    yaw_tolerance : float
        Largest yaw error, wrapped to ``[-pi, pi)`` (rad).
    hold_time : float
        How long all three must hold without a break (s).

    Examples
    --------
    >>> SettleParams.defaults().position_tolerance
    0.02
    """

    position_tolerance: float
    velocity_tolerance: float
    yaw_tolerance: float
    hold_time: float

    def __post_init__(self) -> None:
        for name in ("position_tolerance", "velocity_tolerance", "yaw_tolerance", "hold_time"):
            check_positive(f"settle.{name}", getattr(self, name))


def is_settled(state: FloatArray, target: FloatArray, yaw: float, settle: SettleParams) -> bool:
    """Within ``settle``'s position (Euclidean), speed and heading tolerances of ``target``.

    Examples
    --------
    >>> state = np.zeros(12)
    >>> state[:3] = (0.01, 0.0, 1.2)
    >>> is_settled(state, np.array([0.0, 0.0, 1.2]), 0.0, SettleParams.defaults())
    True
    """
    return bool(
        np.linalg.norm(state[:3] - target) <= settle.position_tolerance
        and np.linalg.norm(state[3:6]) <= settle.velocity_tolerance
        and abs(float(wrap_angle(state[8] - yaw))) <= settle.yaw_tolerance
    )


@dataclass(frozen=True)
class Reference:
    """A controller reference in W: position, velocity, yaw and feedforward terms.

    ``acceleration`` (m/s^2), ``jerk`` (m/s^3) and ``yaw_rate`` (rad/s) are feedforward
    terms for following a path; all are zero for a waypoint.

    Examples
    --------
    >>> Reference((1.0, 0.0, 1.5)).velocity
    array([0., 0., 0.])
    """

    position: FloatArray
    velocity: FloatArray = field(default_factory=lambda: np.zeros(3))
    yaw: float = 0.0
    acceleration: FloatArray = field(default_factory=lambda: np.zeros(3))
    jerk: FloatArray = field(default_factory=lambda: np.zeros(3))
    yaw_rate: float = 0.0

    def __post_init__(self) -> None:
        for name in ("position", "velocity", "acceleration", "jerk"):
            a = np.array(getattr(self, name), dtype=np.float64).reshape(-1)
            if a.shape != (3,) or not np.all(np.isfinite(a)):
                raise InvalidInputError(
                    f"reference {name} must be 3 finite numbers, got {getattr(self, name)!r}"
                )
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        for name in ("yaw", "yaw_rate"):
            value = getattr(self, name)
            if not np.isfinite(value):
                raise InvalidInputError(f"reference {name} must be finite, got {value}")
            object.__setattr__(self, name, float(value))


@dataclass(frozen=True, eq=False)
class HoverLqr:
    """The hover LQR state-feedback law; build it with :meth:`design`.

    Attributes
    ----------
    gain : ndarray, shape (4, 12)
        The LQR gain ``K``.
    u_hover : ndarray, shape (4,)
        Hover thrusts.
    params : LqrParams
        Weights and clamps used.
    max_rotor_thrust : float
        Saturation limit (N).
    gravity : float
        For the acceleration feedforward (m/s^2).

    Examples
    --------
    >>> from case_studies.quad_landing.sim.dynamics import hover_state
    >>> ctrl = HoverLqr.design(QuadParams.defaults(), LqrParams.defaults())
    >>> u = ctrl(hover_state((0, 0, 1)), Reference((0, 0, 1)))
    >>> np.allclose(u, ctrl.u_hover)  # hover is an equilibrium of the closed loop
    True
    """

    gain: FloatArray
    u_hover: FloatArray
    params: LqrParams
    max_rotor_thrust: float
    gravity: float = 9.81

    @classmethod
    def design(cls, quad: QuadParams, params: LqrParams) -> HoverLqr:
        """Solve the LQR problem at hover with ``control.lqr``."""
        A, B = linearize_hover(quad)
        Q = np.diag(params.q_position + params.q_velocity + params.q_attitude + params.q_rate)
        R = params.r_thrust * np.eye(4)
        K, _, _ = control.lqr(A, B, Q, R)
        gain = np.asarray(K, dtype=np.float64)
        gain.setflags(write=False)
        u_hover = np.full(4, hover_thrust(quad))
        u_hover.setflags(write=False)
        return cls(gain, u_hover, params, quad.max_rotor_thrust, quad.gravity)

    def error(self, x: FloatArray, ref: Reference) -> FloatArray:
        """The clamped, yaw-frame error vector ``e`` (12,) fed to the gain."""
        x = np.asarray(x, dtype=np.float64)
        ff = np.concatenate([ref.acceleration, ref.jerk, [ref.yaw_rate]])
        return self._error(x, ref.position, ref.velocity, ff, ref.yaw)[0]

    def _error(
        self, x: FloatArray, p_ref: FloatArray, v_ref: FloatArray, ff: FloatArray,
        yaw_ref: float,
    ) -> tuple[FloatArray, float]:  # fmt: skip
        """``ff = [acceleration (3), jerk (3), yaw_rate]``; returns ``e`` and ``N / g``."""
        psi = x[8]
        c, s = np.cos(psi), np.sin(psi)
        dp = x[0:3] - p_ref
        horiz = np.hypot(dp[0], dp[1])
        lim = self.params.max_position_error_xy
        if horiz > lim:
            dp[0:2] *= lim / horiz
        dp[2] = min(max(dp[2], -self.params.max_position_error_z), self.params.max_position_error_z)
        dv = x[3:6] - v_ref
        # feedforward attitude (thrust along a_r + g e3) and its body rates, yaw frame
        lift = self.gravity + ff[2]
        ax, ay = c * ff[0] + s * ff[1], -s * ff[0] + c * ff[1]
        yaw_rate = ff[6]
        dax = c * ff[3] + s * ff[4] + yaw_rate * ay  # d/dt of the yaw-frame acceleration
        day = -s * ff[3] + c * ff[4] - yaw_rate * ax
        dlift = ff[5]
        hxz2 = ax * ax + lift * lift
        norm = np.sqrt(hxz2 + ay * ay)
        roll_r = -np.arcsin(ay / norm)
        pitch_r = np.arctan2(ax, lift)
        dnorm = (ax * dax + ay * day + lift * dlift) / norm
        droll = -(day * norm - ay * dnorm) / (norm * np.sqrt(hxz2))
        dpitch = (lift * dax - ax * dlift) / hxz2
        sr, cr = np.sin(roll_r), np.cos(roll_r)
        sp, cp = np.sin(pitch_r), np.cos(pitch_r)
        e = np.empty(12)
        e[0] = c * dp[0] + s * dp[1]
        e[1] = -s * dp[0] + c * dp[1]
        e[2] = dp[2]
        e[3] = c * dv[0] + s * dv[1]
        e[4] = -s * dv[0] + c * dv[1]
        e[5] = dv[2]
        e[6] = x[6] - roll_r
        e[7] = x[7] - pitch_r
        e[8] = (psi - yaw_ref + np.pi) % (2.0 * np.pi) - np.pi
        # ZYX Euler rates -> body rates
        e[9] = x[9] - (droll - sp * yaw_rate)
        e[10] = x[10] - (cr * dpitch + sr * cp * yaw_rate)
        e[11] = x[11] - (-sr * dpitch + cr * cp * yaw_rate)
        return e, norm / self.gravity

    def thrusts(
        self, x: FloatArray, p_ref: FloatArray, v_ref: FloatArray, ff: FloatArray,
        yaw_ref: float,
    ) -> FloatArray:  # fmt: skip
        """Rotor thrusts (4,) for state ``x`` and a reference given as plain arrays.

        ``ff`` is ``[acceleration (3), jerk (3), yaw_rate]``. The same law as calling
        the controller with a :class:`Reference`, without building one (the
        simulator's inner loop).
        """
        e, scale = self._error(x, p_ref, v_ref, ff, yaw_ref)
        u = self.u_hover * scale - self.gain @ e
        return np.minimum(np.maximum(u, 0.0), self.max_rotor_thrust)

    def __call__(self, x: FloatArray, ref: Reference) -> FloatArray:
        """Rotor thrusts (4,) for state ``x`` (12,) and reference ``ref``."""
        x = np.asarray(x, dtype=np.float64)
        ff = np.concatenate([ref.acceleration, ref.jerk, [ref.yaw_rate]])
        return self.thrusts(x, ref.position, ref.velocity, ff, ref.yaw)

    @staticmethod
    def motors_off() -> FloatArray:
        """The motors-off command: all thrusts zero."""
        return MOTORS_OFF.copy()
