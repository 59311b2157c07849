"""Proposition 1 as code: landing_decision, the turn-off point and their exact checks."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from ipcverify.decision._landing_float import landing_accept_float
from ipcverify.decision._landing_proof import (
    LandingDecision,
    check_landing,
    landing_decision,
    turnoff_point,
)
from ipcverify.decision.containment import Status, verify
from ipcverify.errors import SetError
from ipcverify.sets._box import Box
from ipcverify.sets._ellipsoid import Ellipsoid

#: The paper's target box G (the library takes it from the caller).
G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])

F = Fraction


def _q(rows):
    return [[F(float(v)) for v in r] for r in rows]


def _det3(m):
    return (
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    )


def _inverse3(m):
    """Exact inverse by the adjugate (independent of ipcverify.sets._exact.inverse)."""
    det = _det3(m)

    def cof(i, j):
        r = [k for k in range(3) if k != i]
        c = [k for k in range(3) if k != j]
        return (-1) ** (i + j) * (m[r[0]][c[0]] * m[r[1]][c[1]] - m[r[0]][c[1]] * m[r[1]][c[0]])

    return [[cof(j, i) / det for j in range(3)] for i in range(3)]


def _in_target_exact(p, y, target: Box = G) -> bool:
    """P - y in G, exactly."""
    lo, up = _q([target.lower])[0], _q([target.upper])[0]
    return all(lo[i] <= F(float(p[i])) - y[i] <= up[i] for i in range(3))


def _random_ellipsoid(rng: np.random.Generator, max_semi: float, log_cond: float) -> Ellipsoid:
    q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    semi = rng.uniform(0.2, 1.0, 3) * max_semi
    semi[rng.integers(3)] /= 10.0**log_cond
    return Ellipsoid(rng.uniform(-10, 10, 3), q @ np.diag(1.0 / semi) @ q.T)


def _sphere_point(s: Fraction, t: Fraction) -> list[Fraction]:
    """A rational point on the unit sphere (inverse stereographic projection), norm exactly 1."""
    d = s * s + t * t + 1
    return [2 * s / d, 2 * t / d, (s * s + t * t - 1) / d]


# ------------------------------------------------------------------- examples
def test_small_ellipsoid_is_accepted_with_exact_certificate():
    e = Ellipsoid([1.0, 2.0, 0.3], np.diag([25.0, 25.0, 50.0]))  # semi-axes .04, .04, .02
    d = landing_decision(e, G)
    assert d.accept and d.certificate.status is Status.PROVEN
    assert d.turnoff[0] == 1.0 and d.turnoff[1] == 2.0
    assert F(float(d.turnoff[2])) >= F(0.3) + F(1, 50)
    assert verify(d.certificate).status is Status.PROVEN
    assert check_landing(d).status is Status.PROVEN
    assert d.certificate.margin > 0


@pytest.mark.parametrize(
    "diag",
    [
        [9.0, 25.0, 50.0],  # x semi-axis 0.111 > 0.05
        [25.0, 9.0, 50.0],  # y
        [25.0, 25.0, 30.0],  # z semi-axis 0.0333: height 0.0667 > 0.05
    ],
)
def test_too_wide_ellipsoid_is_rejected(diag):
    d = landing_decision(Ellipsoid([0.0, 0.0, 1.0], np.diag(diag)), G)
    assert not d.accept
    assert d.certificate.status is Status.REFUTED
    assert verify(d.certificate).status is Status.REFUTED


def test_paper_threshold_is_matched_away_from_the_boundary():
    """The paper accepts iff widths <= (0.1, 0.1, 0.05); exact and float agree off the boundary."""
    rng = np.random.default_rng(11)
    agree = 0
    for _ in range(300):
        e = _random_ellipsoid(rng, 0.06, rng.uniform(0, 2))
        w = 2 * e.half_widths()[0]
        gap = np.min(np.abs(w / np.array([0.1, 0.1, 0.05]) - 1))
        if gap < 1e-9:
            continue
        paper = bool((w <= np.array([0.1, 0.1, 0.05])).all())
        assert landing_decision(e, G).accept == paper
        assert bool(landing_accept_float(e, G)[0]) == paper
        agree += 1
    assert agree > 250


def test_turnoff_point_is_z_max_rounded_up_by_at_most_one_float():
    rng = np.random.default_rng(12)
    for _ in range(50):
        e = _random_ellipsoid(rng, 0.05, rng.uniform(0, 3))
        p = turnoff_point(e)
        c = [F(float(v)) for v in e.centers[0]]
        hz2 = sum(v * v for v in _inverse3(_q(e.shapes[0]))[2])  # (C^T C)^{-1}_zz
        above = F(float(p[2])) - c[2]
        assert above >= 0 and above * above >= hz2  # P_z >= z_max exactly
        below = F(math.nextafter(float(p[2]), -math.inf)) - c[2]
        assert below < 0 or below * below < hz2  # ... and the float below is not
        assert p[0] == e.centers[0, 0] and p[1] == e.centers[0, 1]


def test_check_landing_detects_a_moved_turnoff_point():
    d = landing_decision(Ellipsoid([0.0, 0.0, 0.0], np.diag([25.0, 25.0, 50.0])), G)
    moved = LandingDecision(True, d.turnoff + np.array([0.01, 0.0, 0.0]), d.certificate, d.target)
    v = check_landing(moved)
    assert v.status is Status.UNKNOWN and "coordinate 0" in v.reason


def test_decision_must_match_its_certificate():
    d = landing_decision(Ellipsoid([0.0, 0.0, 0.0], np.diag([5.0, 5.0, 5.0])), G)
    assert not d.accept
    with pytest.raises(SetError, match="PROVEN"):
        LandingDecision(True, d.turnoff, d.certificate, d.target)


def test_custom_target_and_bad_inputs():
    e = Ellipsoid([0.0, 0.0, 0.0], np.diag([25.0, 25.0, 50.0]))
    assert not landing_decision(e, Box([-0.01, -0.01, 0.0], [0.01, 0.01, 0.01])).accept
    assert landing_decision(e, Box([-1.0, -1.0, 0.0], [1.0, 1.0, 1.0])).accept
    with pytest.raises(SetError, match="3-D"):
        landing_decision(Ellipsoid(np.zeros(2), np.eye(2)), G)
    with pytest.raises(SetError, match="batch"):
        landing_decision(Ellipsoid(np.zeros((2, 3)), np.stack([np.eye(3)] * 2)), G)
    with pytest.raises(SetError, match="positive width"):
        landing_decision(e, Box([0.0, 0.0, 0.0], [0.0, 1.0, 1.0]))


def test_batch_float_acceptance_shape():
    rng = np.random.default_rng(13)
    es = Ellipsoid(rng.normal(size=(50, 3)), np.tile(np.diag([25.0, 25.0, 50.0]), (50, 1, 1)))
    assert landing_accept_float(es, G).all()


# ------------------------------------------------------- Proposition 1, property
rationals = st.fractions(min_value=-20, max_value=20, max_denominator=10**6)


@settings(derandomize=True, max_examples=150, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    log_cond=st.sampled_from([0.0, 1.0, 3.0]),
    s=rationals,
    t=rationals,
    radius=st.one_of(st.just(F(1)), st.fractions(min_value=0, max_value=1, max_denominator=10**9)),
)
def test_proposition1_turnoff_minus_y_in_target(seed, log_cond, s, t, radius):
    """For accepted ellipsoids and any y in E (boundary included): P - y in G, exactly."""
    rng = np.random.default_rng(seed)
    e = _random_ellipsoid(rng, 0.055, log_cond)
    d = landing_decision(e, G)
    assume(d.accept)
    assert check_landing(d).status is Status.PROVEN
    # y = c + C^{-1} u with ||u|| = radius <= 1 exactly: y is in E exactly
    u = [radius * v for v in _sphere_point(s, t)]
    cinv = _inverse3(_q(e.shapes[0]))
    c = [F(float(v)) for v in e.centers[0]]
    y = [c[i] + sum(cinv[i][j] * u[j] for j in range(3)) for i in range(3)]
    assert _in_target_exact(d.turnoff, y)
    # float boundary samples, kept only if exactly inside E
    for p in e.sample(rng, surface=True).tolist() + e.sample(rng).tolist():
        yq = [F(v) for v in p]
        g2 = sum(sum(F(float(a)) * (yq[k] - c[k]) for k, a in enumerate(r)) ** 2 for r in e.shapes[0])
        if g2 <= 1:
            assert _in_target_exact(d.turnoff, yq)
