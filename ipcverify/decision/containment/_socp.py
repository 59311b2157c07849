"""The SOCP prover for boxes and polytopes: Clarabel's support values, as a cross-check.

The support values ``max_{y in E} a_j^T y`` are computed by Clarabel through cvxpy (a
second-order cone program, compiled once per size). A PROVEN status still needs the exact
closed-form check (:func:`ipcverify.decision.containment.check_faces`); a solver status
other than ``optimal`` (``optimal_inaccurate`` included) is UNKNOWN.

Examples
--------
>>> import numpy as np
>>> from ipcverify.sets import Box, Ellipsoid
>>> prove_socp(Ellipsoid(np.zeros(2), np.eye(2)), Box([-2.0, -2.0], [2.0, 2.0])).status.name
'PROVEN'
"""

from __future__ import annotations

from fractions import Fraction
from functools import partial
from typing import Any

import numpy as np

from ipcverify.decision.containment._certificate import ContainmentCertificate
from ipcverify.decision.containment._geometry import ExactEllipsoid, check_faces, witness_from_direction
from ipcverify.decision.containment._status import Method, Status, solve_with_clarabel
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._exact import exact_vector, matvec
from ipcverify.sets._faces import FacedSet

_SOCP_CACHE: dict[tuple[int, int], Any] = {}


def socp_problem(n: int, m: int) -> Any:
    import cvxpy as cp  # imported on first use: it takes about a second

    key = (n, m)
    if key not in _SOCP_CACHE:
        y = cp.Variable((m, n))
        cpar = cp.Parameter((n, n))
        apar = cp.Parameter((m, n))
        # y_j = c + w_j; maximise sum_j a_j^T w_j  s.t. ||C w_j|| <= 1 (separable in j)
        cons = [cp.norm(y @ cpar.T, 2, axis=1) <= 1]
        prob = cp.Problem(cp.Maximize(cp.sum(cp.multiply(apar, y))), cons)
        _SOCP_CACHE[key] = (prob, y, cpar, apar)
    return _SOCP_CACHE[key]


def prove_socp(
    inner: Ellipsoid, outer: FacedSet, exact: ExactEllipsoid | None = None
) -> ContainmentCertificate:
    """Prove or refute ``inner ⊆ outer`` with Clarabel's support values, re-checked exactly."""
    import cvxpy as cp  # imported on first use: it takes about a second

    answer = partial(ContainmentCertificate, inner, outer, Method.SOCP)
    ex = ExactEllipsoid.of(inner) if exact is None else exact
    a, b = outer.faces()
    n, m = inner.dim, a.shape[0]
    c, cmat = inner.centers[0], inner.shapes[0]
    scale = np.linalg.norm(cmat, 2)
    prob, w, cpar, apar = socp_problem(n, m)
    cpar.value = cmat / scale  # ||C w|| <= 1  <=>  ||(C/s) w|| <= 1/s; solve for v = w s
    anorm = np.maximum(np.linalg.norm(a, axis=1), np.finfo(float).tiny)
    apar.value = a / anorm[:, None]
    status = solve_with_clarabel(prob)
    if status != cp.OPTIMAL or w.value is None:
        return answer(Status.UNKNOWN, detail=f"Clarabel status '{status}' is not 'optimal'")
    with np.errstate(over="ignore"):
        wv = np.asarray(w.value) / scale
    if not np.isfinite(wv).all():
        return answer(
            Status.UNKNOWN,
            detail="the inner set's extent is beyond float's range; decide it with method='closed-form'",
        )
    support = np.einsum("ji,ji->j", a / anorm[:, None], wv) * anorm
    slack = b - a @ c - support
    margin = float(slack.min())
    mult = {"support": tuple(Fraction(float(s)) for s in support)}
    tol = 1e-7 * (1.0 + np.abs(b) + np.abs(a @ c) + np.abs(support))
    ok_exact, why = check_faces(ex, outer)
    if (slack >= -tol).all() and ok_exact:
        return answer(Status.PROVEN, mult, margin, detail=f"Clarabel optimal; exact check: {why}")
    if (slack < -tol).any():
        for j in np.argsort(slack):
            if slack[j] >= -tol[j]:
                break
            wj = exact_vector(wv[j])
            u = matvec(ex.C, wj)  # C (y - c)
            y = witness_from_direction(ex, outer, u)
            if y is not None:
                return answer(
                    Status.REFUTED,
                    mult,
                    margin,
                    tuple(y),
                    detail=f"Clarabel optimal; maximiser on face {j} checked exactly",
                )
    return answer(
        Status.UNKNOWN,
        mult,
        margin,
        detail=f"Clarabel optimal but not decisive or contradicted by the exact check ({why})",
    )
