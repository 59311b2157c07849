"""Quadrotor model: hover equilibrium, integrator, mixer signs, linearisation, parameters."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from case_studies.quad_landing.sim.config import load_config
from case_studies.quad_landing.sim.dynamics import (
    QuadParams,
    continuous_dynamics,
    hover_state,
    hover_thrust,
    linearize_hover,
    mixer_matrix,
    rk4_step,
)
from ipcverify.errors import InvalidInputError

QUAD = load_config().quad


def _f(x: np.ndarray, u: np.ndarray) -> np.ndarray:
    return np.asarray(continuous_dynamics(QUAD)(x, u), dtype=float).ravel()


@settings(max_examples=30, deadline=None, derandomize=True)
@given(px=st.floats(-3, 3), py=st.floats(-3, 3), pz=st.floats(0.2, 3), yaw=st.floats(-np.pi, np.pi))
def test_hover_is_an_equilibrium_anywhere(px, py, pz, yaw):
    x = hover_state((px, py, pz), yaw)
    u = np.full(4, hover_thrust(QUAD))
    assert np.max(np.abs(_f(x, u))) < 1e-12
    step = rk4_step(QUAD, 1 / 240)
    x1 = np.asarray(step(x, u)).ravel()
    assert np.max(np.abs(x1 - x)) < 1e-12


def test_rk4_function_is_named():
    step = rk4_step(QUAD, 1 / 240)
    assert step.name() == "quad_rk4"
    assert step.name_in() == ["x", "u"] and step.name_out() == ["x_next"]
    f = continuous_dynamics(QUAD)
    assert f.name() == "quad_ode" and f.name_out() == ["xdot"]


def test_free_fall_matches_closed_form_with_linear_drag():
    # motors off: v(t) = -(m g / c) (1 - exp(-c t / m)); z(t) by integrating that.
    m, g, c = QUAD.mass, QUAD.gravity, QUAD.linear_drag
    dt, n = 1 / 240, 120
    step = rk4_step(QUAD, dt)
    x = hover_state((0, 0, 3.0))
    for _ in range(n):
        x = np.asarray(step(x, np.zeros(4))).ravel()
    t = n * dt
    vz = -(m * g / c) * (1 - np.exp(-c * t / m))
    z = 3.0 - (m * g / c) * (t - (m / c) * (1 - np.exp(-c * t / m)))
    assert x[5] == pytest.approx(vz, abs=1e-9)
    assert x[2] == pytest.approx(z, abs=1e-9)


def test_rk4_saturates_thrust():
    step = rk4_step(QUAD, 1 / 240)
    x = hover_state((0, 0, 1))
    over = np.asarray(step(x, np.full(4, 1e3))).ravel()
    at_max = np.asarray(step(x, np.full(4, QUAD.max_rotor_thrust))).ravel()
    np.testing.assert_array_equal(over, at_max)
    under = np.asarray(step(x, np.full(4, -5.0))).ravel()
    off = np.asarray(step(x, np.zeros(4))).ravel()
    np.testing.assert_array_equal(under, off)


def test_mixer_signs_follow_the_frame_conventions():
    x = hover_state((0, 0, 1))
    u0 = np.full(4, hover_thrust(QUAD))
    front = u0 + np.array([0.1, 0.1, -0.1, -0.1])  # more thrust at the front
    left = u0 + np.array([0.1, -0.1, -0.1, 0.1])  # more thrust on the left
    spin = u0 + np.array([0.1, -0.1, 0.1, -0.1])  # rotors 0 and 2 faster
    assert _f(x, front)[10] < 0  # nose up: negative pitch acceleration
    assert _f(x, left)[9] > 0  # left side up: positive roll acceleration
    assert _f(x, spin)[11] > 0  # reaction torque of rotors 0 and 2 is +z
    M = mixer_matrix(QUAD)
    assert np.linalg.matrix_rank(M) == 4
    np.testing.assert_allclose(M @ u0, [QUAD.mass * QUAD.gravity, 0, 0, 0], atol=1e-12)


def test_linearisation_matches_finite_differences():
    A, B = linearize_hover(QUAD)
    x0, u0 = hover_state((0, 0, 0)), np.full(4, hover_thrust(QUAD))
    h = 1e-6
    A_fd = np.column_stack([(_f(x0 + h * e, u0) - _f(x0 - h * e, u0)) / (2 * h) for e in np.eye(12)])
    B_fd = np.column_stack([(_f(x0, u0 + h * e) - _f(x0, u0 - h * e)) / (2 * h) for e in np.eye(4)])
    np.testing.assert_allclose(A, A_fd, atol=1e-6)
    np.testing.assert_allclose(B, B_fd, atol=1e-6)
    assert A[3, 7] == pytest.approx(QUAD.gravity) and A[4, 6] == pytest.approx(-QUAD.gravity)


def test_f450_parameters_are_the_defaults():
    assert QUAD.mass == 1.5 and QUAD.arm_length == 0.25
    assert QUAD.inertia == pytest.approx((0.029, 0.029, 0.055))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"mass": -1.0}, "quad.mass must be a number > 0, got -1.0"),
        ({"inertia": (0.029, 0.0, 0.055)}, "three positive moments"),
        ({"max_rotor_thrust": 3.0}, "too small to hover"),
        ({"linear_drag": -0.1}, "linear_drag must be >= 0"),
    ],
)
def test_bad_quad_parameters_are_refused(kwargs, match):
    with pytest.raises(InvalidInputError, match=match):
        QuadParams.defaults(**kwargs)


def test_bad_step_length_is_refused():
    with pytest.raises(InvalidInputError, match="dt must be in"):
        rk4_step(QUAD, 0.5)


def test_casadi_function_is_symbolic():
    # the step can be differentiated by CasADi (a real CasADi model, not a numpy callback)
    step = rk4_step(QUAD, 1 / 240)
    x = ca.MX.sym("x", 12)
    jac = ca.Function("j", [x], [ca.jacobian(step(x, np.full(4, 3.0)), x)])
    J = np.asarray(jac(hover_state((0, 0, 1))))
    assert J.shape == (12, 12) and np.all(np.isfinite(J))
