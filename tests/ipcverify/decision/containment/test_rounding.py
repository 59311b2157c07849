"""Rigorous float slacks (containment/rounding.py) against exact rational slacks, face by face.

Every face that the float bound calls decided must be decided the same way by exact arithmetic
(``b - a^T c >= 0`` and ``(b - a^T c)^2 >= ||C^{-T} a||^2``, in Fractions); PROVEN certificates of the
fast closed form must re-verify exactly. Dimensions 2 to 6, condition numbers up to 1e8, faces at
relative margins down to 1e-15 of touching, both signs (proofs/float_landing.md, part II).
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ipcverify.decision.containment import Status, prove, verify
from ipcverify.decision.containment._geometry import ExactEllipsoid, exact_faces
from ipcverify.decision.containment._margin import support_slack
from ipcverify.decision.containment._rounding import support_slack_bounds
from ipcverify.sets._box import Box
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._polytope import Polytope

SEEDS = st.integers(0, 2**32 - 1)


def _orth(rng: np.random.Generator, n: int) -> np.ndarray:
    q, r = np.linalg.qr(rng.standard_normal((n, n)))
    return q * np.sign(np.diag(r))


def _ellipsoid(rng: np.random.Generator, n: int, log_cond: float) -> Ellipsoid:
    s = 10.0 ** rng.uniform(0.0, log_cond, n)
    s[0], s[-1] = 1.0, 10.0**log_cond
    C = _orth(rng, n) @ np.diag(s * 10.0 ** rng.uniform(-2, 2)) @ _orth(rng, n).T
    if rng.random() < 0.3:
        C = np.linalg.qr(C)[1]  # triangular (R^T R = C^T C: the same set), many exact zeros
    return Ellipsoid(rng.normal(scale=3.0, size=n), C)


def _outer(rng: np.random.Generator, e: Ellipsoid, box: bool, margin: float, sign: float) -> Box | Polytope:
    n = e.dim
    c = e.centers[0]
    if box:
        h = e.half_widths()[0]
        rel = np.where(rng.random(2 * n) < 0.5, sign * margin, 0.1) * rng.uniform(0.5, 1.0, 2 * n)
        return Box(c - h * (1 + rel[n:]), c + h * (1 + rel[:n]))
    m = int(rng.integers(1, 9))
    a = rng.standard_normal((m, n)) * 10.0 ** rng.uniform(-3, 3, (m, 1))
    support = np.linalg.norm(np.linalg.solve(e.shapes[0].T, a.T), axis=0)
    rel = np.where(rng.random(m) < 0.6, sign * margin, 0.1)
    return Polytope(a, a @ c + support * (1 + rel))


def _exact_holds(e: Ellipsoid, outer: Box | Polytope) -> list[bool]:
    """Per face, exactly (box faces: the upper ones, then the lower, as support_slack_bounds)."""
    return [f.holds for f in exact_faces(ExactEllipsoid.of(e), outer)]


@settings(derandomize=True, max_examples=1500, deadline=None)
@given(
    seed=SEEDS,
    n=st.sampled_from([2, 3, 3, 4, 6]),
    log_cond=st.sampled_from([0.0, 2.0, 4.0, 6.0, 8.0]),
    margin=st.sampled_from([1e-1, 1e-3, 1e-6, 1e-9, 1e-12, 1e-15]),
    sign=st.sampled_from([-1.0, 1.0]),
    box=st.booleans(),
)
def test_decided_faces_agree_with_exact_arithmetic(seed, n, log_cond, margin, sign, box):
    rng = np.random.default_rng(seed)
    e = _ellipsoid(rng, n, log_cond)
    outer = _outer(rng, e, box, margin, sign)
    sb = support_slack_bounds(e, outer)
    truth = _exact_holds(e, outer)
    slack, bound = sb.slack[0], sb.bound[0]
    for j, holds in enumerate(truth):
        if slack[j] >= bound[j]:
            assert holds, f"face {j}: float says holds by {slack[j]:.3g} > {bound[j]:.3g}"
        if slack[j] < -bound[j]:
            assert not holds, f"face {j}: float says fails by {slack[j]:.3g} < -{bound[j]:.3g}"
    scale = 1.0 + np.abs(e.centers).max() + np.abs(slack).max()
    assert np.allclose(slack, support_slack(e, outer)[0], rtol=0.0, atol=1e-12 * scale)  # the same slacks
    if margin >= 1e-6 and log_cond <= 4.0:  # the band is tiny: every face is decided
        assert (np.abs(slack) >= bound).all()


@settings(derandomize=True, max_examples=150, deadline=None)
@given(seed=SEEDS, n=st.sampled_from([2, 3, 4]), box=st.booleans(), log_cond=st.sampled_from([0.0, 3.0, 6.0]))
def test_fast_proven_certificates_reverify_exactly(seed, n, box, log_cond):
    rng = np.random.default_rng(seed)
    e = _ellipsoid(rng, n, log_cond)
    outer = _outer(rng, e, box, 1e-3, 1.0)  # contained with a comfortable margin
    cert = prove(e, outer)
    assert cert.status is Status.PROVEN and "rounding bound" in cert.detail
    assert verify(cert).status is Status.PROVEN


def test_batches_mix_decided_and_undecided_rows():
    c = np.zeros((3, 2))
    shapes = np.stack([np.eye(2) * 2.0, np.eye(2), np.eye(2) * 0.5])  # radii 0.5, 1, 2
    sb = support_slack_bounds(Ellipsoid(c, shapes), Box([-1.0, -1.0], [1.0, 1.0]))
    assert sb.proven().tolist() == [True, False, False]  # radius 1 touches: in the band
    assert sb.refuted().tolist() == [False, False, True]
    assert sb.slack.shape == sb.bound.shape == (3, 4)
