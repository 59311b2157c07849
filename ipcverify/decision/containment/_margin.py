"""Float containment margins for whole batches (fast estimates, not proofs).

``max_{y in E(c, C)} a^T y = a^T c + ||C^{-T} a||``, so the slack of face ``j`` of
``{y : A y <= b}`` is ``b_j - a_j^T c - ||C^{-T} a_j||`` and ``E`` is inside iff every
slack is ``>= 0``. Each shape computes its slacks
(:meth:`ipcverify.sets.FacedSet.support_slack`). Here it is evaluated in float64: the sign
decides containment only up to rounding. :mod:`ipcverify.decision.containment._prove` decides it exactly.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ipcverify.errors import SetError
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._faces import FacedSet

FloatArray = NDArray[np.float64]


def support_slack(inner: Ellipsoid, outer: FacedSet) -> FloatArray:
    """Float slack ``b_j - a_j^T c - ||C^{-T} a_j||`` of every face, shape (B, m).

    Vectorised over the batch (10^5 ellipsoids with ``n = 3`` take a few tens of
    milliseconds). The values are float estimates: a slack of ``0`` means touching;
    the sign decides containment only up to rounding. For a proof use
    :func:`prove` (exact).

    Parameters
    ----------
    inner : Ellipsoid
        A batch of ``B`` ellipsoids of dimension ``n``.
    outer : FacedSet
        A Box, Polytope or other set given by ``m`` faces ``a_j^T y <= b_j``, of dimension ``n``
        (anything else raises :class:`SetError`).

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify.sets import Box
    >>> e = Ellipsoid(np.zeros((1, 1)), np.full((1, 1, 1), 2.0))  # [-0.5, 0.5]
    >>> support_slack(e, Box([-1.0], [1.0]))
    array([[0.5, 0.5]])
    """
    check_faced_pair(inner, outer, "support_slack")
    return outer.support_slack(inner)


def check_faced_pair(inner: Ellipsoid, outer: FacedSet, what: str) -> None:
    """Refuse anything but a batch of ellipsoids and a set given by faces of the same dimension."""
    if not isinstance(inner, Ellipsoid):
        raise SetError("inner must be an Ellipsoid")
    if not isinstance(outer, FacedSet):
        raise SetError(
            f"{what} needs a Box, Polytope or other set given by faces; got {type(outer).__name__}"
        )
    if outer.dim != inner.dim:
        raise SetError(f"{outer.kind} dimension {outer.dim} != ellipsoid dimension {inner.dim}")


def contained_float(inner: Ellipsoid, outer: FacedSet) -> NDArray[np.bool_]:
    """Float-decided containment mask (B,): every face slack ``>= 0``.

    Fast but *not* a proof: near-touching sets can be misjudged by rounding.
    Use :func:`prove` / :func:`prove_batch` for exact
    certificates.

    Parameters
    ----------
    inner : Ellipsoid
        A batch of ``B`` ellipsoids.
    outer : FacedSet
        A set given by faces, of the same dimension (as :func:`support_slack`).

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify.sets import Box
    >>> e = Ellipsoid(np.zeros((2, 1)), np.array([[[2.0]], [[0.5]]]))
    >>> contained_float(e, Box([-1.0], [1.0])).tolist()
    [True, False]
    """
    return np.asarray((support_slack(inner, outer) >= 0.0).all(axis=1), dtype=np.bool_)
