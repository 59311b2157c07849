"""Property tests (hypothesis) for the containment provers against independent oracles.

Ground truth never comes from the code under test:

* boxes / polytopes: ``max_E a^T y = a^T c + sqrt(a^T Q^{-1} a)`` with ``Q = C^T C``,
  evaluated exactly through the adjugate (``Q^{-1} = adj Q / det Q``, Laplace
  expansion), not through the Gauss-Jordan inverse the prover uses;
* homothetic ellipsoids (``C2 = C1 / 2^j``, exact in floats): ``E1 ⊆ E2`` iff
  ``||C1 (c1 - c2)|| <= 2^j - 1``, an exact rational comparison;
* concentric ellipsoids: ``E1 ⊆ E2`` iff ``C1^T C1 - C2^T C2`` is PSD, decided by the
  signs of all principal minors;
* general ellipsoid pairs: the trust-region value ``max_{E1} ||C2 (y - c2)||^2`` in
  60-digit arithmetic (mpmath); pairs within 1e-30 of touching are skipped.

Sets are ill-conditioned (condition numbers up to 1e6) and near-tight (relative
margins down to 1e-15, i.e. a few ulps, both signs). All tests are derandomized.
"""

from __future__ import annotations

import functools
import itertools
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from ipcverify.decision.containment import Status, prove, verify
from ipcverify.decision.containment._certificate import ContainmentCertificate
from ipcverify.sets._box import Box
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._polytope import Polytope

F = Fraction
PROPS = settings(derandomize=True, max_examples=60, deadline=None)

seeds = st.integers(0, 2**32 - 1)
log_conds = st.sampled_from([0.0, 1.0, 3.0, 4.5, 6.0])
margins = st.sampled_from([1e-1, 1e-3, 1e-6, 1e-9, 1e-12, 1e-15])
signs = st.sampled_from([-1.0, 1.0])
dims = st.sampled_from([2, 3, 3, 4])


# ------------------------------------------------------------------ generators
def _orth(rng: np.random.Generator, n: int) -> np.ndarray:
    q, r = np.linalg.qr(rng.standard_normal((n, n)))
    return q * np.sign(np.diag(r))


def _shape(rng: np.random.Generator, n: int, log_cond: float) -> np.ndarray:
    s = 10.0 ** np.sort(rng.uniform(0.0, log_cond, n))
    s[0], s[-1] = 1.0, 10.0**log_cond
    return _orth(rng, n) @ np.diag(s * 10.0 ** rng.uniform(-2, 2)) @ _orth(rng, n).T


def _ellipsoid(rng: np.random.Generator, n: int, log_cond: float) -> Ellipsoid:
    return Ellipsoid(rng.normal(scale=3.0, size=n), _shape(rng, n, log_cond))


# --------------------------------------------------------------- exact oracles
def _q(rows):
    return [[F(float(v)) for v in r] for r in rows]


def _det(m):
    if len(m) == 1:
        return m[0][0]
    return sum((-1) ** j * m[0][j] * _det([r[:j] + r[j + 1 :] for r in m[1:]]) for j in range(len(m)))


def _adjugate(m):
    n = len(m)
    minor = lambda i, j: [r[:j] + r[j + 1 :] for k, r in enumerate(m) if k != i]  # noqa: E731
    return [[(-1) ** (i + j) * _det(minor(j, i)) for j in range(n)] for i in range(n)]


def _gram(c):
    n = len(c)
    return [[sum(c[k][i] * c[k][j] for k in range(n)) for j in range(n)] for i in range(n)]


def _faces_hold_oracle(e: Ellipsoid, a_rows, b) -> bool:
    """Exact: for every face, b - a^T c >= 0 and (b - a^T c)^2 det Q >= a^T adj(Q) a."""
    cq = [F(float(v)) for v in e.centers[0]]
    qm = _gram(_q(e.shapes[0]))
    adj, det = _adjugate(qm), _det(qm)
    for a, bj in zip(_q(a_rows), [F(float(v)) for v in b], strict=True):
        s = bj - sum(x * y for x, y in zip(a, cq, strict=True))
        quad = sum(a[i] * adj[i][j] * a[j] for i in range(len(a)) for j in range(len(a)))
        if s < 0 or s * s * det < quad:
            return False
    return True


def _g2(e: Ellipsoid, y) -> Fraction:
    cq = [F(float(v)) for v in e.centers[0]]
    d = [F(v) - c for v, c in zip(y, cq, strict=True)]
    return sum(sum(x * z for x, z in zip(r, d, strict=True)) ** 2 for r in _q(e.shapes[0]))


def _outside_oracle(outer, y) -> bool:
    if isinstance(outer, Ellipsoid):
        return _g2(outer, y) > 1
    a_rows, b = outer.faces()
    return any(
        sum(x * F(v) for x, v in zip(a, y, strict=True)) > bj
        for a, bj in zip(_q(a_rows), [F(float(v)) for v in b], strict=True)
    )


def _check_against_truth(cert: ContainmentCertificate, truth: bool) -> None:
    """The soundness properties every certificate must have."""
    if cert.status is Status.PROVEN:
        assert truth, f"PROVEN but not contained: {cert.detail}"
    if cert.status is Status.REFUTED:
        assert not truth, f"REFUTED but contained: {cert.detail}"
        assert _g2(cert.inner, cert.witness) <= 1, "witness not inside the inner set"
        assert _outside_oracle(cert.outer, cert.witness), "witness not outside the outer set"
    v = verify(cert)
    assert v.ok, v.reason
    assert v.status is cert.status


# ------------------------------------------------------- boxes and polytopes
def _near_tight_box(seed, n, log_cond, margin, sign):
    rng = np.random.default_rng(seed)
    e = _ellipsoid(rng, n, log_cond)
    c, h = e.centers[0], e.half_widths()[0]
    rel = np.full(2 * n, 0.1)
    tight = rng.choice(2 * n, size=rng.integers(1, 2 * n + 1), replace=False)
    rel[tight] = sign * margin * rng.uniform(0.5, 1.0, tight.size)
    return e, Box(c - h * (1 + rel[n:]), c + h * (1 + rel[:n]))


def _near_tight_polytope(seed, n, log_cond, margin, sign):
    rng = np.random.default_rng(seed)
    e = _ellipsoid(rng, n, log_cond)
    m = int(rng.integers(1, 8))
    a = rng.standard_normal((m, n)) * 10.0 ** rng.uniform(-3, 3, (m, 1))
    support = np.linalg.norm(np.linalg.solve(e.shapes[0].T, a.T), axis=0)
    rel = np.where(rng.random(m) < 0.6, sign * margin, 0.1)
    return e, Polytope(a, a @ e.centers[0] + support * (1 + rel))


@PROPS
@given(seed=seeds, n=dims, log_cond=log_conds, margin=margins, sign=signs)
def test_closed_form_box_is_exact(seed, n, log_cond, margin, sign):
    e, box = _near_tight_box(seed, n, log_cond, margin, sign)
    truth = _faces_hold_oracle(e, *box.faces())
    cert = prove(e, box)
    assert cert.status is not Status.UNKNOWN  # the closed form always decides
    assert (cert.status is Status.PROVEN) == truth
    _check_against_truth(cert, truth)


@PROPS
@given(seed=seeds, n=dims, log_cond=log_conds, margin=margins, sign=signs)
def test_closed_form_polytope_is_exact(seed, n, log_cond, margin, sign):
    e, poly = _near_tight_polytope(seed, n, log_cond, margin, sign)
    truth = _faces_hold_oracle(e, poly.A, poly.b)
    cert = prove(e, poly)
    assert cert.status is not Status.UNKNOWN
    assert (cert.status is Status.PROVEN) == truth
    _check_against_truth(cert, truth)


def _near_tight_faces(seed, n, log_cond, margin, sign, box):
    """A near-tight box or polytope, with the oracle's answer."""
    make = _near_tight_box if box else _near_tight_polytope
    e, outer = make(seed, n, log_cond, margin, sign)
    return e, outer, _faces_hold_oracle(e, *outer.faces())


@settings(derandomize=True, max_examples=40, deadline=None)
@given(seed=seeds, n=dims, log_cond=log_conds, margin=margins, sign=signs, box=st.booleans())
def test_socp_agrees_with_closed_form_when_decisive(seed, n, log_cond, margin, sign, box):
    e, outer, truth = _near_tight_faces(seed, n, log_cond, margin, sign, box)
    socp = prove(e, outer, method="socp")
    closed = prove(e, outer)
    _check_against_truth(socp, truth)
    if socp.status is not Status.UNKNOWN:
        assert socp.status is closed.status
        # and the solver's support values match the closed form's
        h_socp = np.array([float(v) for v in socp.multipliers["support"]])
        h_closed = np.array([float(v) for v in closed.multipliers["support"]])
        np.testing.assert_allclose(h_socp, h_closed, rtol=1e-5, atol=1e-9 * h_closed.max())
    if margin >= 1e-3:  # comfortably away from touching: the cross-check must decide
        assert socp.status is closed.status, socp.detail


@settings(derandomize=True, max_examples=200, deadline=None)
@given(seed=seeds, n=dims, log_cond=log_conds, margin=margins, sign=signs, box=st.booleans())
def test_sdp_faces_agree_with_the_closed_form_and_the_oracle(seed, n, log_cond, margin, sign, box):
    e, outer, truth = _near_tight_faces(seed, n, log_cond, margin, sign, box)
    sdp = prove(e, outer, method="sdp")
    _check_against_truth(sdp, truth)
    # conditioning to 1e6 and margins down to a few ulps: the S-lemma route still decides
    assert sdp.status is not Status.UNKNOWN, sdp.detail
    assert sdp.status is prove(e, outer).status


# ------------------------------------------------------------------ ellipsoids
def _homothetic_contains(e1: Ellipsoid, c2: np.ndarray, f: float) -> bool:
    """Exact: E(c1, C1) ⊆ E(c2, C1 / f) iff ||C1 (c1 - c2)|| <= f - 1 (f a power of two)."""
    c1q = [F(float(x)) for x in e1.centers[0]]
    d = [a - F(float(b)) for a, b in zip(c1q, c2, strict=True)]
    dist2 = sum(sum(x * y for x, y in zip(r, d, strict=True)) ** 2 for r in _q(e1.shapes[0]))
    return f >= 1 and dist2 <= F(f - 1.0) ** 2


def _homothetic(seed, n, log_cond, margin, sign):
    """E2 = E(c2, C1 / F) with F = 2^j (exact in floats), centre offset near the limit F - 1."""
    rng = np.random.default_rng(seed)
    e1 = _ellipsoid(rng, n, log_cond)
    f = 2.0 ** int(rng.integers(0, 4))
    v = rng.standard_normal(n)
    v *= (f - 1.0) * (1.0 - sign * margin) / np.linalg.norm(v)
    c2 = e1.centers[0] - np.linalg.solve(e1.shapes[0], v)
    return e1, Ellipsoid(c2, e1.shapes[0] / f), _homothetic_contains(e1, c2, f)


def _concentric(seed, n, log_cond, margin, sign, psd):
    """C2 = K C1 with ||K|| = 1 / (1 - sign margin): contained iff C1^T C1 - C2^T C2 is PSD."""
    rng = np.random.default_rng(seed)
    e1 = _ellipsoid(rng, n, log_cond)
    k = rng.uniform(0.2, 1.0, n)
    k[0] = 1.0 - sign * margin
    e2 = Ellipsoid(e1.centers[0], _orth(rng, n) @ np.diag(k) @ _orth(rng, n).T @ e1.shapes[0])
    g1, g2 = _gram(_q(e1.shapes[0])), _gram(_q(e2.shapes[0]))
    return (
        e1,
        e2,
        psd([[a - b for a, b in zip(r1, r2, strict=True)] for r1, r2 in zip(g1, g2, strict=True)]),
    )


@PROPS
@given(seed=seeds, n=dims, log_cond=log_conds, margin=margins, sign=signs)
def test_sdp_homothetic_pairs_are_sound(seed, n, log_cond, margin, sign):
    e1, e2, truth = _homothetic(seed, n, log_cond, margin, sign)
    _check_against_truth(prove(e1, e2), truth)


@PROPS
@given(seed=seeds, n=dims, log_cond=log_conds, margin=margins, sign=signs)
def test_sdp_concentric_pairs_are_sound(seed, n, log_cond, margin, sign, minors):
    e1, e2, truth = _concentric(seed, n, log_cond, margin, sign, minors.psd)
    _check_against_truth(prove(e1, e2), truth)


def _tau_star_mp(e1: Ellipsoid, e2: Ellipsoid) -> float:
    """``max_{y in E1} ||C2 (y - c2)||^2`` in 60-digit arithmetic (trust-region secular equation)."""
    mp = pytest.importorskip("mpmath").mp
    with mp.workdps(60):
        c1 = mp.matrix([float(v) for v in e1.centers[0]])
        c2 = mp.matrix([float(v) for v in e2.centers[0]])
        s1 = mp.matrix(e1.shapes[0].tolist())
        s2 = mp.matrix(e2.shapes[0].tolist())
        d_mat = s2 * mp.inverse(s1)  # outer set in unit-ball coordinates of E1
        d = s1 * (c2 - c1)
        h_mat = d_mat.T * d_mat
        h, v = mp.eigsy(h_mat)
        n = len(h)
        e = v.T * d
        a = [h[i] * e[i] for i in range(n)]
        hmax = max(h[i] for i in range(n))
        top = max(range(n), key=lambda i: h[i])
        assume(abs(a[top]) > mp.mpf(10) ** -25 * (1 + hmax))  # skip the (measure-zero) hard case
        lo, hi = hmax, hmax + mp.sqrt(sum(x * x for x in a)) + 1
        for _ in range(400):
            mid = (lo + hi) / 2
            if sum((a[i] / (mid - h[i])) ** 2 for i in range(n)) > 1:
                lo = mid
            else:
                hi = mid
        w = [-a[i] / (hi - h[i]) for i in range(n)]
        return sum(h[i] * (w[i] - e[i]) ** 2 for i in range(n))


@settings(derandomize=True, max_examples=40, deadline=None)
@given(seed=seeds, n=st.sampled_from([2, 3]), log_cond=log_conds, margin=margins, sign=signs)
def test_sdp_general_pairs_are_sound(seed, n, log_cond, margin, sign):
    rng = np.random.default_rng(seed)
    e1 = _ellipsoid(rng, n, log_cond)
    e2 = Ellipsoid(
        e1.centers[0] + rng.normal(size=n) / np.linalg.norm(e1.shapes[0], 2),
        _shape(rng, n, min(log_cond, 3.0)),
    )
    tau = float(_tau_star_mp(e1, e2))
    e2 = Ellipsoid(e2.centers[0], e2.shapes[0] * np.sqrt((1.0 - sign * margin) / tau))
    tau = _tau_star_mp(e1, e2)
    assume(abs(tau - 1) > 1e-30)
    cert = prove(e1, e2)
    _check_against_truth(cert, bool(tau < 1))
    # the SDP value agrees with the trust-region closed form (margin = 1 - tau_solver)
    assert cert.margin is not None
    assert abs(cert.margin - (1 - float(tau))) <= 1e-6


@PROPS
@given(seed=seeds, n=dims, log_cond=log_conds, margin=margins, push=st.sampled_from([1e-9, 1e-3, 1.0]))
def test_verify_rejects_multipliers_reused_for_a_non_contained_pair(seed, n, log_cond, margin, push):
    e1, e2, truth = _homothetic(seed, n, log_cond, margin, 1.0)
    cert = prove(e1, e2)
    assume(cert.status is Status.PROVEN)
    # push the outer centre along the offset so the inner set sticks out; keep the multipliers
    f = float(e1.shapes[0][0, 0] / e2.shapes[0][0, 0])
    offset = e2.centers[0] - e1.centers[0]
    c2 = e1.centers[0] + offset * (1.0 + margin + push) / (1.0 - margin)
    if not np.any(offset):  # identical sets (f = 1): any shift sticks out
        c2 = e1.centers[0] + push
    assume(not _homothetic_contains(e1, c2, f))
    forged = ContainmentCertificate(
        e1, Ellipsoid(c2, e2.shapes[0]), cert.method, Status.PROVEN, cert.multipliers, 0.0
    )
    assert verify(forged).status is Status.UNKNOWN


# ------------------------------------------------------------- how rare is UNKNOWN
def test_unknown_is_rare_for_sdp_and_absent_for_closed_forms(minors):
    """A fixed, seeded sweep over conditioning and margins (numbers reported by the benchmark)."""
    unknown_sdp = total_sdp = unknown_closed = 0
    for i, (log_cond, margin, sign) in enumerate(
        itertools.product([0.0, 3.0, 6.0], [1e-1, 1e-6, 1e-12], [-1.0, 1.0])
    ):
        for j in range(3):
            seed = 1000 * i + j
            for make in (_homothetic, functools.partial(_concentric, psd=minors.psd)):
                e1, e2, truth = make(seed, 3, log_cond, margin, sign)
                cert = prove(e1, e2)
                _check_against_truth(cert, truth)
                total_sdp += 1
                unknown_sdp += cert.status is Status.UNKNOWN
            e, box = _near_tight_box(seed, 3, log_cond, margin, sign)
            unknown_closed += prove(e, box).status is Status.UNKNOWN
    assert unknown_closed == 0
    assert unknown_sdp <= 0.1 * total_sdp, f"{unknown_sdp} of {total_sdp} SDP problems UNKNOWN"
