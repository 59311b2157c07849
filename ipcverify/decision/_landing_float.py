"""The float landing rule: the relative slack of every face of Proposition 1's test (not a proof).

For simulation, plotting and the float rule of :meth:`ipcverify.decision.LandingRule.decide_float`;
the decision of record is proven (:mod:`ipcverify.decision._landing`, ``proofs/float_landing.md``).

Examples
--------
>>> import numpy as np
>>> from ipcverify.sets import Box, Ellipsoid
>>> G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])
>>> landing_accept_float(Ellipsoid(np.zeros(3), np.eye(3) * 40), G).tolist()
[True]
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ipcverify.decision._landing_proof import check_target
from ipcverify.errors import SetError
from ipcverify.sets._box import Box
from ipcverify.sets._ellipsoid import Ellipsoid

FloatArray = NDArray[np.float64]

#: Tolerance of the float rule (:func:`landing_slack`, :meth:`LandingRule.decide_float`, not a
#: proof): relative slacks down to ``-PRECHECK_MARGIN`` count as fitting, so that the z face,
#: which touches ``P`` by construction, is not lost to rounding.
PRECHECK_MARGIN = 1e-9


def landing_slack(centers: FloatArray, half_widths: FloatArray, target: Box) -> FloatArray:
    """The float landing rule: relative slack of every face of the test (negative: does not fit).

    For an ellipsoid with centre ``c`` and axis half-widths ``h`` (``sqrt(P_ii)``), the float
    turn-off point is ``P = [c_x, c_y, c_z + h_z]`` and the test is ``c - h >= P - G.upper``
    and ``c + h <= P - G.lower``; each face's slack is divided by the size of the numbers
    involved, so that it can be compared with a relative tolerance. Elementwise: ``centers``
    and ``half_widths`` may be one ellipsoid's ``(3,)`` arrays or a batch's ``(B, 3)``.

    Parameters
    ----------
    centers : ndarray, shape (3,) or (B, 3)
        The ellipsoids' centres ``c``.
    half_widths : ndarray, shape (3,) or (B, 3)
        Their bounding boxes' half-widths ``h`` (same shape as ``centers``); an infinite or
        NaN half-width gives slack ``-inf`` (no fit).
    target : Box
        The 3-D target region ``G``.

    Returns
    -------
    ndarray, shape (..., 6)
        The upper-face slacks of the three axes, then the lower-face ones.

    Examples
    --------
    >>> G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])
    >>> s = landing_slack(np.zeros(3), np.array([0.025, 0.025, 0.0125]), G)
    >>> bool(s.min() >= 0), bool(landing_slack(np.zeros(3), np.full(3, 0.06), G).min() >= 0)
    (True, False)
    """
    c = np.asarray(centers, dtype=np.float64)
    h = np.asarray(half_widths, dtype=np.float64)
    p = c.copy()
    lo, up = target.lower, target.upper
    with np.errstate(invalid="ignore", over="ignore"):  # an infinite half-width gives NaN: no fit
        p[..., 2] += h[..., 2]
        upper_slack = (p - lo) - (c + h)  # box face P - G.lower
        lower_slack = (c - h) - (p - up)  # box face P - G.upper
        size = 1.0 + np.abs(p) + np.abs(c) + h + np.abs(lo) + np.abs(up)
        out = np.concatenate([upper_slack / size, lower_slack / size], axis=-1)
    return np.where(np.isnan(out), -np.inf, out)


def landing_accept_float(ellipsoids: Ellipsoid, target: Box) -> NDArray[np.bool_]:
    """Float-decided acceptance for a whole batch (simulation and plotting): :func:`landing_slack`.

    Not a proof: near-threshold ellipsoids may differ from :func:`landing_decision`, which
    is exact and is what the controller's decision of record (:class:`LandingRule`) uses.

    Parameters
    ----------
    ellipsoids : Ellipsoid
        A batch of 3-D ellipsoids (any other dimension raises :class:`SetError`).
    target : Box
        The 3-D target region ``G`` (positive width in every coordinate).

    Returns
    -------
    ndarray of bool, shape (B,)
        True where every face's slack is at least ``-PRECHECK_MARGIN``.

    Examples
    --------
    >>> import numpy as np
    >>> G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])
    >>> e = Ellipsoid(np.zeros((2, 3)), np.stack([np.eye(3) * 40, np.eye(3) * 10]))
    >>> landing_accept_float(e, G).tolist()
    [True, False]
    """
    if not isinstance(ellipsoids, Ellipsoid) or ellipsoids.dim != 3:
        raise SetError("landing_accept_float needs a batch of 3-D ellipsoids")
    check_target(target)
    slack = landing_slack(ellipsoids.centers, ellipsoids.half_widths(), target)
    return np.asarray(slack.min(axis=-1) >= -PRECHECK_MARGIN, dtype=np.bool_)


def half_widths_3(C: FloatArray) -> FloatArray:
    """``sqrt(((C^T C)^{-1})_ii)`` = norms of the rows of ``C^{-1}`` for a 3x3 ``C`` (float, fast)."""
    return np.array(half_widths_values(C.ravel().tolist()))


def half_widths_values(flat: list[float]) -> list[float]:
    """:func:`half_widths_3` of a row-major ``C`` given as 9 Python floats, as 3 floats."""
    a, b, c, d, e, f, g, h, i = flat
    A, B, Cc = e * i - f * h, -(d * i - f * g), d * h - e * g
    det = a * A + b * B + c * Cc
    if not (math.isfinite(det) and det != 0.0):
        return [math.inf] * 3
    # rows of adj(C) (= columns of the cofactor matrix), i.e. rows of C^{-1} times det
    r0 = (A, -(b * i - c * h), b * f - c * e)
    r1 = (B, a * i - c * g, -(a * f - c * d))
    r2 = (Cc, -(a * h - b * g), a * e - b * d)
    ad = abs(det)
    return [math.sqrt(u * u + v * v + w * w) / ad for u, v, w in (r0, r1, r2)]
