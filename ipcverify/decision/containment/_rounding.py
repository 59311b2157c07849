"""Float containment margins with a rigorous bound on their rounding error, for whole batches.

:func:`support_slack` evaluates the slack ``b_j - a_j^T c - ||C^{-T} a_j||`` of every face in
float: its sign decides containment only up to rounding. :func:`support_slack_bounds` returns
the same slacks together with a bound on their error that holds for every input (error
analysis: ``proofs/float_landing.md, part II``), so that

* a face whose slack is ``>= bound`` provably holds (``E`` lies on its side exactly),
* a face whose slack is ``< -bound`` provably fails,
* anything else lies in the rounding band (decide it exactly: :func:`~ipcverify.decision.containment._prove`).

The support ``||C^{-T} a||`` is enclosed by a verified inverse: with ``X ~ C^{-1}`` (LAPACK) and
``R = I - C X``, ``C^{-T} a = (I - R^T)^{-1} X^T a``, so ``| ||C^{-T} a|| - ||X^T a|| | <=
rho / (1 - rho) ||X^T a||`` whenever ``||R||_2 <= rho < 1``; ``rho`` comes from the float
residual plus the standard bound ``gamma_n |C| |X|`` on the rounding of ``C X``.

Examples
--------
>>> import numpy as np
>>> from ipcverify.sets import Box, Ellipsoid
>>> e = Ellipsoid(np.zeros((1, 2)), np.full((1, 2, 2), 2.0) * np.eye(2))  # radius 0.5
>>> sb = support_slack_bounds(e, Box([-1.0, -0.5], [1.0, 1.0]))
>>> sb.slack.round(3).tolist(), bool((sb.bound < 1e-14).all())
([[0.5, 0.5, 0.5, 0.0]], True)
>>> sb.proven().tolist(), sb.refuted().tolist()    # the face at -0.5 touches: inside the band
([False], [False])
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ipcverify.decision.containment._margin import check_faced_pair
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._faces import UNDERFLOW_ALLOWANCE, UNIT_ROUNDOFF, FacedSet, gamma

FloatArray = NDArray[np.float64]
_U = UNIT_ROUNDOFF
_ABS = UNDERFLOW_ALLOWANCE  # absolute allowance for every underflow of the analysis (far above its size)
_gamma = gamma


@dataclass(frozen=True, eq=False)
class SlackBounds:
    """Face slacks of a batch and rigorous bounds on their rounding error.

    Attributes
    ----------
    slack : ndarray, shape (B, m)
        Float slacks ``b_j - a_j^T c - ||C^{-T} a_j||`` (box faces: the upper faces, then the lower).
    bound : ndarray, shape (B, m)
        ``|exact slack - slack| <= bound`` (``inf`` where the analysis does not apply).
    """

    slack: FloatArray
    bound: FloatArray

    def proven(self) -> NDArray[np.bool_]:
        """(B,) every face provably holds: the ellipsoid is inside the outer set."""
        return np.asarray((self.slack >= self.bound).all(axis=1), dtype=np.bool_)

    def refuted(self) -> NDArray[np.bool_]:
        """(B,) some face provably fails: the ellipsoid is not inside."""
        return np.asarray((self.slack < -self.bound).any(axis=1), dtype=np.bool_)


def _inverse_residual(C: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``X ~ C^{-1}`` and ``rho >= ||I - C X||_2`` per matrix (``rho = inf`` if ``inv`` fails)."""
    n = C.shape[-1]
    try:
        X = np.linalg.inv(C)
    except np.linalg.LinAlgError:
        X = np.stack([_safe_inv(m) for m in C]) if len(C) else np.zeros_like(C)
    with np.errstate(all="ignore"):
        R = np.eye(n) - C @ X
        # |R| <= |R~| (1 + 1.01 u) + gamma_n |C| |X| + n eta0, elementwise (proofs/float_landing.md, part II)
        M = np.abs(R) * (1.0 + 4.0 * _U) + _gamma(n + 2) * (np.abs(C) @ np.abs(X)) + _ABS
        rho = np.sqrt(np.einsum("bij,bij->b", M, M)) * (1.0 + _gamma(n * n + 4))
    rho = np.where(np.isfinite(rho) & np.isfinite(X).all(axis=(1, 2)), rho, np.inf)
    return np.asarray(X, dtype=np.float64), np.asarray(rho, dtype=np.float64)


def _safe_inv(m: FloatArray) -> FloatArray:
    try:
        return np.asarray(np.linalg.inv(m))
    except np.linalg.LinAlgError:
        return np.full_like(m, np.nan)


def support_slack_bounds(inner: Ellipsoid, outer: FacedSet) -> SlackBounds:
    """Face slacks of ``inner`` against ``outer`` with rigorous rounding-error bounds.

    Parameters
    ----------
    inner : Ellipsoid
        A batch of ``B`` ellipsoids.
    outer : FacedSet
        The outer set, a Box or Polytope (``m = 2n`` faces for a box) or any set given by faces;
        its :meth:`~ipcverify.sets.FacedSet.slack_terms` give ``b - A c`` and ``||X^T a_j||`` with
        their rounding bounds.

    Returns
    -------
    SlackBounds
        ``slack`` and ``bound`` of shape (B, m); see the module docstring.
    """
    check_faced_pair(inner, outer, "support_slack_bounds")
    n = inner.dim
    c, C = inner.centers, inner.shapes
    X, rho = _inverse_residual(C)
    with np.errstate(all="ignore"):
        kappa = np.where(rho < 0.5, rho / (1.0 - rho) * (1.0 + 4.0 * _U), np.inf)[:, None]
        sigma, e_sigma, s_hat, e_v = outer.slack_terms(c, X)  # the shape's face arithmetic
        # ||X^T a|| from its float value, then ||C^{-T} a|| from ||X^T a|| (verified inverse)
        e_norm = _gamma(n + 3) * s_hat + _ABS
        norm_hi = s_hat + e_norm + e_v
        e_s = kappa * norm_hi + e_norm + e_v
        slack = sigma - s_hat
        bound = (e_sigma + e_s + 1.01 * _U * np.abs(slack)) * (1.0 + 16.0 * _U) + _ABS
    bound = np.where(np.isfinite(bound) & np.isfinite(slack), bound, np.inf)
    return SlackBounds(np.asarray(slack), np.asarray(bound))
