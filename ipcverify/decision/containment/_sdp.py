"""The SDP prover for ellipsoid-in-ellipsoid: the S-lemma LMI, certified exactly.

``E1 ⊆ E2`` iff ``tau* = max_{y in E1} ||C2 (y - c2)||^2 <= 1``; minimising ``tau`` subject
to ``lam Q1 - Q2 + tau e e^T >= 0``, ``lam >= 0`` gives ``tau*`` (``proofs/containment.md``).
Clarabel proposes ``(lam, tau)``; the certificate holds multipliers that pass an exact PSD
test (:func:`ipcverify.decision.containment.check_lmi`). Refutations come from the
trust-region maximiser of the normalised problem, checked exactly.

Examples
--------
>>> import numpy as np
>>> from ipcverify.sets import Ellipsoid
>>> ball = Ellipsoid(np.zeros(2), np.eye(2))
>>> prove_sdp(ball, ball.scaled(2.0)).status.name, prove_sdp(ball.scaled(2.0), ball).status.name
('PROVEN', 'REFUTED')
"""

from __future__ import annotations

import math
from fractions import Fraction
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ipcverify.decision.containment._certificate import ContainmentCertificate
from ipcverify.decision.containment._geometry import ExactEllipsoid, check_lmi, witness_from_direction
from ipcverify.decision.containment._status import Method, Status, solve_with_clarabel
from ipcverify.errors import SetError
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._exact import exact_vector, matvec

FloatArray = NDArray[np.float64]


_SDP_CACHE: dict[int, Any] = {}


def sdp_problem(n: int) -> Any:
    """``min tau  s.t.  lam Q1n - Q2n + tau e e^T >= 0, lam >= 0`` (compiled once per n).

    Parameters
    ----------
    n : int
        The ellipsoids' dimension; returns ``(problem, lam, tau, q2)`` with ``q2`` the
        ``(n + 1, n + 1)`` symmetric parameter to set before solving.
    """
    import cvxpy as cp  # imported on first use: it takes about a second

    if n not in _SDP_CACHE:
        lam = cp.Variable(nonneg=True)
        tau = cp.Variable()
        q2 = cp.Parameter((n + 1, n + 1), symmetric=True)
        q1 = np.diag([1.0] * n + [-1.0])  # normalised inner set: ||u||^2 - 1
        e = np.zeros((n + 1, n + 1))
        e[n, n] = 1.0
        lmi = lam * q1 - q2 + tau * e
        prob = cp.Problem(cp.Minimize(tau), [lmi >> 0])
        if not prob.is_dpp():  # pragma: no cover - guards a cvxpy behaviour change
            raise SetError("internal error: the S-lemma program is not DPP; please report this")
        _SDP_CACHE[n] = (prob, lam, tau, q2)
    return _SDP_CACHE[n]


def normalised(inner: Ellipsoid, outer: Ellipsoid) -> tuple[FloatArray, FloatArray]:
    """Float ``D = C2 C1^{-1}``, ``d = C1 (c2 - c1)``: the outer set in unit-ball coordinates.

    Parameters
    ----------
    inner, outer : Ellipsoid
        Single ellipsoids ``E(c1, C1)`` and ``E(c2, C2)`` of one dimension (a ``C1`` singular in
        float64 raises :class:`numpy.linalg.LinAlgError`).
    """
    c1, s1 = inner.centers[0], inner.shapes[0]
    c2, s2 = outer.centers[0], outer.shapes[0]
    d_mat = np.linalg.solve(s1.T, s2.T).T
    d = s1 @ (c2 - c1)
    return d_mat, d


def _q2n(d_mat: FloatArray, d: FloatArray) -> FloatArray:
    n = d.shape[0]
    f = np.hstack([d_mat, -(d_mat @ d)[:, None]])  # ||D u - D d||^2 = ||F (u, 1)||^2
    q = f.T @ f
    return 0.5 * (q + q.T) if n else q


def trust_region_maximiser(d_mat: FloatArray, d: FloatArray) -> tuple[FloatArray, float]:
    """Float ``argmax_{||u|| <= 1} ||D (u - d)||^2`` and its multiplier ``mu``.

    The trust-region subproblem: with ``H = D^T D = V diag(h) V^T`` and ``a = h * V^T d``,
    the maximiser is ``u = V w`` with ``w_i = -a_i / (mu - h_i)`` where ``mu >= max h``
    solves ``sum_i a_i^2 / (mu - h_i)^2 = 1`` (bisection); ``mu`` is also the S-lemma
    multiplier ``lambda*``. If the top component of ``a`` vanishes (the "hard case"),
    ``mu = max h`` and the top eigenvector fills ``w`` up to unit length.

    Parameters
    ----------
    d_mat : ndarray, shape (n, n)
        ``D`` (from :func:`normalised`).
    d : ndarray, shape (n,)
        ``d``. The result is a float estimate; the caller checks any witness made from it exactly.
    """
    h_mat = d_mat.T @ d_mat
    h, v = np.linalg.eigh(0.5 * (h_mat + h_mat.T))
    e = v.T @ d
    a = h * e  # stationarity: (mu - h_i) w_i = -a_i
    hmax = float(h[-1])
    top = h >= hmax - 1e-14 * max(hmax, 1e-300)
    with np.errstate(all="ignore"):
        if np.linalg.norm(a[top]) <= 1e-15 * (np.linalg.norm(a) + 1e-300):
            rest = ~top
            gaps = hmax - h[rest]
            w = np.zeros_like(h)
            w[rest] = np.where(gaps > 0, -a[rest] / np.where(gaps > 0, gaps, 1.0), 0.0)
            r2 = float(w @ w)
            if r2 <= 1.0:  # hard case: fill the top eigenspace
                w[np.flatnonzero(top)[0]] = math.sqrt(1.0 - r2)
                return v @ w, hmax
        lo, hi = hmax, hmax + float(np.linalg.norm(a)) + 1e-300
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                break
            ww = a / (mid - h)
            if float(ww @ ww) > 1.0:
                lo = mid
            else:
                hi = mid
        w = -a / (hi - h)
    nrm = float(np.linalg.norm(w))
    if not (nrm > 0) or not np.isfinite(w).all():
        w = np.zeros_like(h)
        w[-1] = 1.0
        nrm = 1.0
    return v @ (w / nrm), hi


def _normalised_exact(ex: ExactEllipsoid, outer: Ellipsoid) -> tuple[FloatArray, FloatArray]:
    """``D = C2 C1^{-1}`` and ``d = C1 (c2 - c1)`` computed exactly, then rounded once.

    Slower than :func:`_normalised` but accurate to one rounding even when ``C1``
    is ill-conditioned; used when the fast path neither proves nor refutes.
    """
    o = ExactEllipsoid.of(outer)
    ci_cols = list(zip(*ex.cinv, strict=True))
    d_mat = [
        [float(sum((x * y for x, y in zip(row, col, strict=True)), Fraction(0))) for col in ci_cols]
        for row in o.C
    ]
    d = matvec(ex.C, [a - b for a, b in zip(o.c, ex.c, strict=True)])
    return np.array(d_mat, dtype=np.float64), np.array([float(v) for v in d])


def _sdp_candidates(lam: float, tau: float, lift: float) -> list[tuple[Fraction, Fraction, str]]:
    """Multipliers to try exactly: lifted solver values, then tau = 1, then snapped rationals.

    Adding ``delta`` to ``lam`` and ``2 delta`` to ``tau`` adds ``diag(delta I, delta)`` in
    unit-ball coordinates, lifting every eigenvalue of the LMI by ``delta``.
    """
    out: list[tuple[Fraction, Fraction, str]] = []
    lam_q, tau_q = Fraction(max(lam, 0.0)), Fraction(tau)
    for delta in (lift, 100.0 * lift):
        dq = Fraction(delta)
        if tau_q + 2 * dq <= 1:
            out.append((lam_q + dq, tau_q + 2 * dq, f"solver multipliers lifted by {delta:.3g}"))
    out.append((lam_q, Fraction(1), "solver lambda, tau = 1"))
    if tau_q < 1:
        dq = (1 - tau_q) / 2
        out.append((lam_q + dq, Fraction(1), "solver lambda lifted, tau = 1"))
    for den in (10**3, 10**6, 10**9):
        lam_s = lam_q.limit_denominator(den)
        for tau_s in (tau_q.limit_denominator(den), Fraction(1)):
            if tau_s <= 1:
                out.append((lam_s, tau_s, f"multipliers snapped to denominators <= {den}"))
    seen: set[tuple[Fraction, Fraction]] = set()
    uniq = []
    for lq, tq, why in out:
        if (lq, tq) not in seen and lq >= 0:
            seen.add((lq, tq))
            uniq.append((lq, tq, why))
    return uniq


def prove_sdp(
    inner: Ellipsoid, outer: Ellipsoid, exact: ExactEllipsoid | None = None
) -> ContainmentCertificate:
    """Prove or refute ``inner ⊆ outer`` for two single ellipsoids (S-lemma, checked exactly).

    Parameters
    ----------
    inner, outer : Ellipsoid
        Single ellipsoids of one dimension.
    exact : ExactEllipsoid, optional
        ``inner`` in exact rationals, if the caller has it already (computed otherwise).
    """
    import cvxpy as cp  # imported on first use: it takes about a second

    answer = partial(ContainmentCertificate, inner, outer, Method.SDP)
    ex = ExactEllipsoid.of(inner) if exact is None else exact
    n = inner.dim
    d_mat, d = normalised(inner, outer)
    q2n = _q2n(d_mat, d)
    scale = max(1.0, float(np.abs(q2n).max()))
    prob, lam_v, tau_v, q2p = sdp_problem(n)
    q2p.value = q2n / scale
    status = solve_with_clarabel(prob)
    notes = [f"Clarabel status '{status}'"]
    lam = tau = math.nan
    q1 = ex.quadratic_form(1)
    q2 = ExactEllipsoid.of(outer).quadratic_form(0)
    if status == cp.OPTIMAL and lam_v.value is not None and tau_v.value is not None:
        lam, tau = float(lam_v.value) * scale, float(tau_v.value) * scale
        q1n = np.diag([1.0] * n + [-1.0])
        e = np.zeros((n + 1, n + 1))
        e[n, n] = 1.0
        eig = float(np.linalg.eigvalsh(lam * q1n - q2n + tau * e).min())
        cond = float(np.linalg.cond(inner.shapes[0]))
        lift = 2.0 * max(0.0, -eig) + 8.0 * cond * np.finfo(float).eps * max(1.0, scale, lam, abs(tau))
        if tau <= 1.0 + 1e-6:
            for lq, tq, why in _sdp_candidates(lam, tau, lift):
                ok, how = check_lmi(q1, q2, lq, tq)
                if ok:
                    return answer(
                        Status.PROVEN,
                        {"lambda": (lq,), "tau": (tq,)},
                        1.0 - tau,
                        detail=f"{notes[0]}; {why}; {how}",
                    )
            notes.append("no multiplier candidate passed the exact PSD test")
    else:
        notes.append("not 'optimal', so no proof is attempted")
    margin = None if math.isnan(tau) else 1.0 - tau
    mult = {} if math.isnan(tau) else {"lambda": (Fraction(max(lam, 0.0)),), "tau": (Fraction(tau),)}
    solver_ok = not math.isnan(tau)

    def refuted(u: FloatArray, how: str) -> ContainmentCertificate | None:
        for cand in (u, -u):
            y = witness_from_direction(ex, outer, exact_vector(cand))
            if y is not None:
                return answer(Status.REFUTED, mult, margin, tuple(y), detail="; ".join([*notes, how]))
        return None

    u, _ = trust_region_maximiser(d_mat, d)
    cert = refuted(u, "witness: trust-region maximiser, checked exactly")
    if cert is not None:
        return cert
    # slow path: normalise exactly (one rounding), re-solve the trust-region problem
    d_mat, d = _normalised_exact(ex, outer)
    u, mu = trust_region_maximiser(d_mat, d)
    if solver_ok:
        for lq in (Fraction(mu), Fraction(mu) * (1 + Fraction(1, 2**40))):
            ok, how = check_lmi(q1, q2, lq, Fraction(1))
            if ok:
                return answer(
                    Status.PROVEN,
                    {"lambda": (lq,), "tau": (Fraction(1),)},
                    margin,
                    detail=f"{notes[0]}; lambda refined by the trust-region secular equation, tau = 1; {how}",
                )
    cert = refuted(u, "witness: trust-region maximiser of the exactly normalised problem")
    if cert is not None:
        return cert
    notes.append("no exact witness found")
    return answer(Status.UNKNOWN, mult, margin, detail="; ".join(notes))
