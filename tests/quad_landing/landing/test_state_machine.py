"""The landing state machine: exact accept and cut tests (proofs/landing_safety.md),
waypoints and runs."""

from __future__ import annotations

import dataclasses
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from case_studies.quad_landing import Flight
from case_studies.quad_landing.landing.runs import Outcome
from case_studies.quad_landing.landing.scenario import draw_scenario
from case_studies.quad_landing.landing.state_machine import (
    LandingParams,
    cut_allowed,
    cut_box,
    decision_target,
    in_target,
    into_pad,
    new_waypoint,
    run_landing,
)
from case_studies.quad_landing.reproduction.config import load_reproduce_config
from case_studies.quad_landing.sim.config import load_config
from ipcverify.decision._landing import LandingRule
from ipcverify.decision._landing_proof import landing_decision
from ipcverify.decision.containment import Status
from ipcverify.errors import InvalidInputError
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._exact import exact_vector

CFG = load_config()
TAUS = [0.001, 0.005, 0.01, 0.02]

#: The paper's target region, as the reproduction configures it.
G = LandingParams.defaults().target


@pytest.mark.parametrize("tau", TAUS)
def test_box_sum_is_exactly_G(tau):
    lo, hi = cut_box(tau, G)
    g_tau = decision_target(tau, G)
    gl, gu = exact_vector(G.lower), exact_vector(G.upper)
    tl, tu = exact_vector(g_tau.lower), exact_vector(g_tau.upper)
    assert [a + b for a, b in zip(lo, tl, strict=True)] == gl
    assert [a + b for a, b in zip(hi, tu, strict=True)] == gu
    # K is about [-tau, tau]^2 x [0, 2 tau]
    assert np.allclose([float(v) for v in lo], [-tau, -tau, 0.0], atol=1e-15)
    assert np.allclose([float(v) for v in hi], [tau, tau, 2 * tau], atol=1e-15)


def _rational_point_in(e: Ellipsoid, u: np.ndarray, r: Fraction) -> list[Fraction]:
    """An exact point c + r C^{-1} u / ||u|| (approx.) that is certainly inside E, checked exactly."""
    d = np.linalg.solve(e.shapes[0], u / np.linalg.norm(u))
    y = [Fraction(float(c)) + r * Fraction(float(v)) for c, v in zip(e.centers[0], d, strict=True)]
    C = [[Fraction(float(v)) for v in row] for row in e.shapes[0]]
    diff = [a - Fraction(float(c)) for a, c in zip(y, e.centers[0], strict=True)]
    g2 = sum((sum(C[i][j] * diff[j] for j in range(3))) ** 2 for i in range(3))
    return y if g2 <= 1 else []


@settings(max_examples=60, deadline=None, derandomize=True)
@given(
    center=st.lists(st.floats(-2.5, 2.5), min_size=3, max_size=3),
    axes=st.lists(st.floats(0.002, 0.03), min_size=3, max_size=3),
    angle=st.floats(-np.pi, np.pi),
    tau_index=st.integers(0, len(TAUS) - 1),
    u=st.lists(st.floats(-1, 1), min_size=3, max_size=3),
    r=st.fractions(0, 1),
    cut=st.lists(st.fractions(0, 1), min_size=3, max_size=3),
)
def test_theorem1_accept_and_cut_give_p_minus_y_in_G(center, axes, angle, tau_index, u, r, cut):
    tau = TAUS[tau_index]
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    e = Ellipsoid(np.array(center), np.diag(1.0 / np.array(axes)) @ R.T)
    d = landing_decision(e, decision_target(tau, G))
    if not d.accept or np.linalg.norm(u) < 1e-6:
        return
    y = _rational_point_in(e, np.array(u), r)
    if not y:
        return
    lo, hi = cut_box(tau, G)
    P = exact_vector(d.turnoff)
    p = [Pi + lo_i + w * (hi_i - lo_i) for Pi, lo_i, hi_i, w in zip(P, lo, hi, cut, strict=True)]
    diff = [a - b for a, b in zip(p, y, strict=True)]
    gl, gu = exact_vector(G.lower), exact_vector(G.upper)
    assert all(a <= v <= b for a, v, b in zip(gl, diff, gu, strict=True))


def test_cut_allowed_is_exact_at_the_faces():
    P = np.array([0.3, -1.2, 0.021])
    tau = 0.005
    lo, hi = cut_box(tau, G)
    corner_hi = np.array([float(Fraction(float(a)) + b) for a, b in zip(P, hi, strict=True)])
    # the float nearest the exact face may lie just outside: the test must decide exactly
    exact_inside = all(
        Fraction(float(v)) - Fraction(float(a)) <= b for v, a, b in zip(corner_hi, P, hi, strict=True)
    )
    assert cut_allowed(corner_hi, P, tau, G) == exact_inside
    assert cut_allowed(P + np.array([0.0, 0.0, tau]), P, tau, G)
    assert not cut_allowed(P + np.array([0.0, 0.0, -1e-12]), P, tau, G)
    assert not cut_allowed(P + np.array([tau * 1.001, 0.0, tau]), P, tau, G)


@pytest.mark.parametrize("tau", [0.0, 0.025, 0.03, float("nan")])
def test_decision_target_refuses_a_bad_tau(tau):
    with pytest.raises(InvalidInputError, match="tau must be > 0"):
        decision_target(tau, G)


def test_in_target_is_the_closed_box():
    assert in_target(np.array([0.05, -0.05, 0.05]), G)
    assert not in_target(np.array([0.0501, 0.0, 0.01]), G)
    assert not in_target(np.array([0.0, 0.0, -1e-9]), G)


def test_new_waypoint_is_the_surface_point_when_high_enough():
    params = LandingParams.defaults(measure_height=0.3)
    e = Ellipsoid(np.array([0.0, 0.0, 0.0]), np.eye(3) * 2.0)  # radius 0.5
    p = np.array([0.0, 0.0, 2.0])
    w = new_waypoint(p, e, flight=Flight(buffer_size=1), params=params)
    # the segment from p to c leaves the ball at height 0.5, above 0.3 + 0.05
    np.testing.assert_allclose(w, [0.0, 0.0, 0.5], atol=1e-12)
    assert float(np.linalg.norm(e.shapes[0] @ (w - e.centers[0]))) == pytest.approx(1.0)


def test_new_waypoint_is_raised_to_the_measuring_height_and_clamped():
    params = LandingParams.defaults()
    e = Ellipsoid(np.array([2.9, 0.4, 0.0]), np.eye(3) * 20.0)  # radius 0.05
    p = np.array([2.0, 0.4, 1.8])
    w = new_waypoint(p, e, flight=Flight(buffer_size=1), params=params)
    assert w[2] == pytest.approx(params.measure_height + 0.05)
    assert 2.8 < w[0] < 2.9
    far = new_waypoint(
        np.array([0.0, 0.0, 2.9]),
        Ellipsoid(np.array([3.5, 0.0, 0.0]), np.eye(3) * 20.0),
        flight=Flight(buffer_size=1),
        params=params,
    )
    assert far[0] == 3.0  # clamped into the workspace


def test_new_waypoint_inside_the_ellipsoid_keeps_the_position():
    e = Ellipsoid(np.array([0.0, 0.0, 1.0]), np.eye(3) * 0.5)  # radius 2: p is inside
    p = np.array([0.1, 0.0, 1.2])
    w = new_waypoint(p, e, flight=Flight(buffer_size=1), params=LandingParams.defaults())
    np.testing.assert_allclose(w[:2], p[:2])


def test_unsafe_runs_have_a_violated_accepted_query(baseline_runs):
    """Corollary 1 on the baseline with five camera buffers (it lands unsafely often)."""
    assert any(r.outcome is Outcome.UNSAFE for r in baseline_runs)
    for r in baseline_runs:
        assert r.n_queries == 1 and r.queries[0].accepted  # the baseline trusts its first measurement
        if r.outcome is Outcome.UNSAFE:
            assert r.queries[-1].truth_inside is False
        if r.outcome is Outcome.ABORTED:
            continue
        assert r.certificate_verified
        if into_pad(r.turnoff, 0.005, r.scenario.pad.position):
            assert r.outcome is Outcome.UNSAFE and "into the pad" in r.reason
        else:
            assert cut_allowed(r.cut_position, r.turnoff, 0.005, G)
            assert (r.outcome is Outcome.SAFE) == in_target(r.offset, G)


def test_a_target_below_the_pad_is_a_collision():
    """A pad perceived 3 cm too low: the vehicle is driven into the pad, an UNSAFE run that
    accepted a set missing y (Corollary 1), not an abort."""

    class Low:
        name = "low"

        def decide(self, m, target):
            return LandingRule(target).decide(m.yhat_w - np.array([0.0, 0.0, 0.03]), np.eye(3) * 1e4)

    p = load_reproduce_config()
    sc = draw_scenario(0, seed=21, params=p.scenario, config=CFG)
    run = run_landing(sc, Low(), sim_config=CFG, params=p.landing)
    assert into_pad(run.turnoff, p.landing.tracking_tolerance, sc.pad.position)
    assert run.outcome is Outcome.UNSAFE and "into the pad" in run.reason
    assert run.queries[-1].accepted and run.queries[-1].truth_inside is False
    assert run.cut_position is not None and run.cut_position[2] < sc.pad.position[2] + 0.01


def test_a_run_records_what_the_figures_need(baseline_runs):
    r = baseline_runs[0]
    d = r.to_dict(trajectory=True)
    assert d["outcome"] in {"safe", "unsafe", "aborted"} and len(d["trajectory"]) == len(r.trajectory) > 10
    assert r.queries[0].time > 0 and r.queries[0].half_widths is not None


def test_a_run_that_reaches_the_cap_aborts_and_never_cuts():
    class Huge:
        name = "huge"

        def decide(self, m, target):
            return LandingRule(target).decide(m.yhat_w, np.eye(3) * 2.0)  # 0.5 m radius: never fits in G

    p = load_reproduce_config()
    sc = draw_scenario(0, seed=21, params=p.scenario, config=CFG)
    run = run_landing(sc, Huge(), sim_config=CFG, params=dataclasses.replace(p.landing, max_measurements=2))
    assert run.outcome is Outcome.ABORTED and run.cut_position is None and "cap of 2" in run.reason
    assert run.n_queries == 2 and not any(q.accepted for q in run.queries)


def test_landing_decision_status_matches_acceptance():
    d = landing_decision(Ellipsoid(np.array([0.0, 0.0, 0.01]), np.eye(3) * 100.0), decision_target(0.005, G))
    assert d.accept and d.certificate.status is Status.PROVEN
