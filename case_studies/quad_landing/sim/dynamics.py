"""Rigid-body quadrotor model in CasADi: 12 states, four rotor thrusts in an X layout.

State ``x = [p (3), v (3), (roll, pitch, yaw), omega (3)]``: position and velocity of
the centre of mass in W, ZYX Euler angles of Q in W, and body rates in Q (see
:mod:`.frames`). Input ``u = [T_0, T_1, T_2, T_3]``: rotor thrusts in newtons, rotors
front-left, front-right, rear-right, rear-left.

.. math::

    \\dot p = v, \\quad m \\dot v = R_{WQ} e_3 \\textstyle\\sum_i T_i - m g e_3 - c_d v,
    \\quad \\dot\\eta = W(\\eta)\\,\\omega, \\quad J \\dot\\omega = \\tau - \\omega \\times J\\omega

with ``[F, tau] = M u`` (:func:`mixer_matrix`). :func:`rk4_step` saturates the thrusts to
``[0, max_rotor_thrust]`` and integrates one step with classical Runge-Kutta 4.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.settings import DEFAULTS_PATH, TomlSection, check_positive
from ipcverify.errors import InvalidInputError

__all__ = [
    "QuadParams",
    "STATE_NAMES",
    "continuous_dynamics",
    "rk4_step",
    "mixer_matrix",
    "hover_thrust",
    "hover_state",
    "linearize_hover",
]


#: Names of the 12 state components, in order.
STATE_NAMES: tuple[str, ...] = (
    "px", "py", "pz", "vx", "vy", "vz", "roll", "pitch", "yaw", "wx", "wy", "wz",
)  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class QuadParams(TomlSection, file=DEFAULTS_PATH, section="quad"):
    """Physical parameters of an F450-class quadrotor.

    Parameters
    ----------
    mass : float
        Total mass (kg).
    inertia : tuple of 3 floats
        Principal moments of inertia ``(Ixx, Iyy, Izz)`` (kg m^2).
    arm_length : float
        Distance from the centre to each rotor (m); rotors sit at +-45 degrees (X layout).
    yaw_moment_coefficient : float
        Rotor reaction torque per newton of thrust (m).
    max_rotor_thrust : float
        Upper thrust limit of one rotor (N); the lower limit is 0.
    linear_drag : float
        Translational drag coefficient ``c_d`` (N s / m).
    gravity : float
        Gravitational acceleration (m / s^2).

    Examples
    --------
    >>> p = QuadParams.defaults()  # [quad] of defaults.toml
    >>> round(hover_thrust(p), 3)  # 1.5 kg * 9.81 m/s^2 / 4
    3.679
    """

    mass: float
    inertia: tuple[float, float, float]
    arm_length: float
    yaw_moment_coefficient: float
    max_rotor_thrust: float
    linear_drag: float
    gravity: float

    def __post_init__(self) -> None:
        inertia = tuple(float(v) for v in self.inertia)
        object.__setattr__(self, "inertia", inertia)
        for name in ("mass", "arm_length", "yaw_moment_coefficient", "max_rotor_thrust", "gravity"):
            check_positive(f"quad.{name}", getattr(self, name))
        if len(inertia) != 3 or not all(np.isfinite(v) and v > 0 for v in inertia):
            raise InvalidInputError(
                f"quad.inertia must be three positive moments (Ixx, Iyy, Izz), got {self.inertia}"
            )
        if not (np.isfinite(self.linear_drag) and self.linear_drag >= 0):
            raise InvalidInputError(f"quad.linear_drag must be >= 0, got {self.linear_drag}")
        if 4 * self.max_rotor_thrust <= self.mass * self.gravity * 1.2:
            raise InvalidInputError(
                "quad.max_rotor_thrust is too small to hover with 20 % margin: need "
                f"4 * max_rotor_thrust > 1.2 * mass * gravity = {1.2 * self.mass * self.gravity:.2f} N"
            )


def mixer_matrix(params: QuadParams) -> FloatArray:
    """The matrix ``M`` with ``[F, tau_x, tau_y, tau_z] = M @ [T_0, T_1, T_2, T_3]``.

    Rotors: 0 front-left, 1 front-right, 2 rear-right, 3 rear-left, at
    ``(+-a, +-a)`` with ``a = arm_length / sqrt(2)``. Rotors 0 and 2 turn so that their
    reaction torque is ``+kappa T`` about ``z_Q``, rotors 1 and 3 ``-kappa T``.

    Examples
    --------
    >>> p = QuadParams.defaults()
    >>> M = mixer_matrix(p)
    >>> M[0].tolist()
    [1.0, 1.0, 1.0, 1.0]
    >>> bool(np.linalg.matrix_rank(M) == 4)
    True
    """
    a = params.arm_length / np.sqrt(2.0)
    x = np.array([a, a, -a, -a])
    y = np.array([a, -a, -a, a])
    spin = np.array([1.0, -1.0, 1.0, -1.0])
    return np.vstack([np.ones(4), y, -x, spin * params.yaw_moment_coefficient])


def hover_thrust(params: QuadParams) -> float:
    """Per-rotor thrust (N) that balances gravity."""
    return params.mass * params.gravity / 4.0


def hover_state(position: tuple[float, float, float] | FloatArray, yaw: float = 0.0) -> FloatArray:
    """The 12-state of a quadrotor hovering still at ``position`` with heading ``yaw``.

    Examples
    --------
    >>> hover_state((0.0, 0.0, 1.0))[:3]
    array([0., 0., 1.])
    """
    x = np.zeros(12)
    x[:3] = np.asarray(position, dtype=np.float64)
    x[8] = yaw
    return x


def _ode_expr(params: QuadParams, x: ca.SX, u: ca.SX) -> ca.SX:
    v = x[3:6]
    phi, theta, psi = x[6], x[7], x[8]
    w = x[9:12]
    cphi, sphi = ca.cos(phi), ca.sin(phi)
    cth, sth = ca.cos(theta), ca.sin(theta)
    cpsi, spsi = ca.cos(psi), ca.sin(psi)
    # third column of R_WQ = Rz Ry Rx: the body z axis in W
    zb = ca.vertcat(cpsi * sth * cphi + spsi * sphi, spsi * sth * cphi - cpsi * sphi, cth * cphi)
    wrench = ca.mtimes(ca.DM(mixer_matrix(params)), u)
    thrust, tau = wrench[0], wrench[1:4]
    acc = zb * thrust / params.mass - ca.vertcat(0, 0, params.gravity)
    acc = acc - params.linear_drag / params.mass * v
    # Euler-angle rates from body rates (ZYX)
    euler_dot = ca.vertcat(
        w[0] + sphi * sth / cth * w[1] + cphi * sth / cth * w[2],
        cphi * w[1] - sphi * w[2],
        sphi / cth * w[1] + cphi / cth * w[2],
    )
    J = ca.DM(np.diag(params.inertia))
    w_dot = ca.solve(J, tau - ca.cross(w, ca.mtimes(J, w)))
    return ca.vertcat(v, acc, euler_dot, w_dot)


def continuous_dynamics(params: QuadParams) -> ca.Function:
    """The ODE ``xdot = f(x, u)`` as ``casadi.Function('quad_ode', [x, u], [xdot])``.

    Inputs are named ``x`` (12) and ``u`` (4); the output is named ``xdot`` (12).
    Thrusts are *not* saturated here, so Jacobians are those of the smooth model.

    Examples
    --------
    >>> p = QuadParams.defaults()
    >>> f = continuous_dynamics(p)
    >>> xdot = f(x=hover_state((0, 0, 1)), u=np.full(4, hover_thrust(p)))["xdot"]
    >>> float(ca.norm_inf(xdot)) < 1e-12
    True
    """
    x = ca.SX.sym("x", 12)
    u = ca.SX.sym("u", 4)
    return ca.Function("quad_ode", [x, u], [_ode_expr(params, x, u)], ["x", "u"], ["xdot"])


def rk4_step(params: QuadParams, dt: float) -> ca.Function:
    """One saturated RK4 step as ``casadi.Function('quad_rk4', [x, u], [x_next])``.

    The thrusts are clipped to ``[0, max_rotor_thrust]`` and held for ``dt`` seconds.

    Parameters
    ----------
    params : QuadParams
        The vehicle.
    dt : float
        Step length (s); use ``<= 1/200`` (the simulator default is ``1/240``).

    Examples
    --------
    >>> p = QuadParams.defaults()
    >>> step = rk4_step(p, 1 / 240)
    >>> step.name_in(), step.name_out()
    (['x', 'u'], ['x_next'])
    >>> x1 = np.asarray(step(hover_state((0, 0, 1)), np.zeros(4))).ravel()  # motors off
    >>> bool(x1[5] < 0)  # falling
    True
    """
    if not (np.isfinite(dt) and 0 < dt <= 0.05):
        raise InvalidInputError(f"integration step dt must be in (0, 0.05] s, got {dt}")
    x = ca.SX.sym("x", 12)
    u = ca.SX.sym("u", 4)
    us = ca.fmin(ca.fmax(u, 0.0), params.max_rotor_thrust)
    k1 = _ode_expr(params, x, us)
    k2 = _ode_expr(params, x + dt / 2 * k1, us)
    k3 = _ode_expr(params, x + dt / 2 * k2, us)
    k4 = _ode_expr(params, x + dt * k3, us)
    x_next = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("quad_rk4", [x, u], [x_next], ["x", "u"], ["x_next"])


def linearize_hover(params: QuadParams) -> tuple[FloatArray, FloatArray]:
    """Jacobians ``(A, B)`` of :func:`continuous_dynamics` at hover (origin, yaw 0).

    Examples
    --------
    >>> p = QuadParams.defaults()
    >>> A, B = linearize_hover(p)
    >>> A.shape, B.shape
    ((12, 12), (12, 4))
    >>> round(float(A[3, 7]), 2)  # pitching nose-down accelerates forward at g
    9.81
    """
    x = ca.SX.sym("x", 12)
    u = ca.SX.sym("u", 4)
    xdot = _ode_expr(params, x, u)
    jac = ca.Function("quad_jac", [x, u], [ca.jacobian(xdot, x), ca.jacobian(xdot, u)],
                      ["x", "u"], ["A", "B"])  # fmt: skip
    out = jac(x=np.zeros(12), u=np.full(4, hover_thrust(params)))
    return np.asarray(out["A"], dtype=np.float64), np.asarray(out["B"], dtype=np.float64)
