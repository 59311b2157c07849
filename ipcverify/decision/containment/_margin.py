"""Float containment margins for whole batches (fast estimates, not proofs).

``max_{y in E(c, C)} a^T y = a^T c + ||C^{-T} a||``, so the slack of face ``j`` of
``{y : A y <= b}`` is ``b_j - a_j^T c - ||C^{-T} a_j||`` and ``E`` is inside iff every
slack is ``>= 0``. Here it is evaluated in float64: the sign decides containment only up
to rounding. :mod:`ipcverify.decision.containment._prove` decides it exactly.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ipcverify.errors import SetError
from ipcverify.sets._shapes import Box, Ellipsoid, Polytope

__all__ = ["support_slack", "contained_float"]

FloatArray = NDArray[np.float64]


def support_slack(inner: Ellipsoid, outer: Box | Polytope) -> FloatArray:
    """Float slack ``b_j - a_j^T c - ||C^{-T} a_j||`` of every face, shape (B, m).

    Vectorised over the batch (10^5 ellipsoids with ``n = 3`` take a few tens of
    milliseconds). The values are float estimates: a slack of ``0`` means touching;
    the sign decides containment only up to rounding. For a proof use
    :func:`prove` (exact).

    Examples
    --------
    >>> import numpy as np
    >>> e = Ellipsoid(np.zeros((1, 1)), np.full((1, 1, 1), 2.0))  # [-0.5, 0.5]
    >>> support_slack(e, Box([-1.0], [1.0]))
    array([[0.5, 0.5]])
    """
    if not isinstance(inner, Ellipsoid):
        raise SetError("inner must be an Ellipsoid")
    if isinstance(outer, Box):
        if outer.dim != inner.dim:
            raise SetError(f"box dimension {outer.dim} != ellipsoid dimension {inner.dim}")
        h = inner.half_widths()
        return np.concatenate([outer.upper - inner.centers - h, inner.centers - h - outer.lower], axis=1)
    if isinstance(outer, Polytope):
        if outer.dim != inner.dim:
            raise SetError(f"polytope dimension {outer.dim} != ellipsoid dimension {inner.dim}")
        cinv = np.linalg.inv(inner.shapes)
        z = np.einsum("bki,jk->bji", cinv, outer.A)  # C^{-T} a_j
        return outer.b - inner.centers @ outer.A.T - np.linalg.norm(z, axis=2)
    raise SetError(f"support_slack needs a Box or Polytope; got {type(outer).__name__}")


def contained_float(inner: Ellipsoid, outer: Box | Polytope) -> NDArray[np.bool_]:
    """Float-decided containment mask (B,): every face slack ``>= 0``.

    Fast but *not* a proof: near-touching sets can be misjudged by rounding.
    Use :func:`prove` / :func:`prove_batch` for exact
    certificates.

    Examples
    --------
    >>> import numpy as np
    >>> e = Ellipsoid(np.zeros((2, 1)), np.array([[[2.0]], [[0.5]]]))
    >>> contained_float(e, Box([-1.0], [1.0])).tolist()
    [True, False]
    """
    return np.asarray((support_slack(inner, outer) >= 0.0).all(axis=1), dtype=np.bool_)
