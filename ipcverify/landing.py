"""Proposition 1 of the paper as code: when may the quadcopter trust a measurement?

The IPC returns an ellipsoid ``E`` that contains the landing pad's true position
``y`` with high probability. The landing state machine accepts the measurement
only if ``E`` fits the target box ``G`` (the paper's is ``[-0.05, 0.05]^2 x [0, 0.05]``;
the caller passes its own, e.g. the case study's); it then flies to the turn-off point
``P = [mid_x, mid_y, z_max]`` of ``E``'s bounding box, and Proposition 1 says
``P in {y} + G`` for every ``y in E``.

One decision rule, two precisions:

* :func:`landing_slack` is the float rule -- the relative slack of every face of the test,
  for one ellipsoid or a whole batch; :func:`landing_accept_float` applies it to batches.
* :class:`LandingRule` is the decision of record for one ellipsoid: the float rule rejects
  clear misses at once (rejecting is always safe: the controller measures again); anything
  else is decided by the exact :func:`landing_decision`, so every accept carries a proof.

:func:`landing_decision` proves exactly the statement the controller relies on,
``P - y in G`` for all ``y in E``, i.e. ``E`` is inside the box ``{P} + (-G) =
[P - G.upper, P - G.lower]``, and accepts only if that proof is PROVEN. The proof
is in ``proofs/proposition1.md``.

Rounding is handled so that the float ``P`` makes the statement true, not just a
nearby real point: ``mid_x`` and ``mid_y`` of the exact bounding box are the centre's
coordinates (floats already), and ``z_max = c_z + sqrt(P_zz)`` is irrational, so
``P_z`` is rounded *upward* to a float (checked exactly). The outer box
``[P - G.upper, P - G.lower]`` is rounded *inward* to floats, so the certified box
lies inside the exact one.

Examples
--------
>>> import numpy as np
>>> from ipcverify.sets import Ellipsoid
>>> from ipcverify.sets import Box, Ellipsoid
>>> G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])
>>> e = Ellipsoid([1.0, 2.0, 0.3], np.diag([40.0, 40.0, 80.0]))  # semi-axes .025,.025,.0125
>>> d = landing_decision(e, G)
>>> d.accept, d.turnoff.tolist(), d.certificate.status.name
(True, [1.0, 2.0, 0.3125], 'PROVEN')
>>> landing_decision(e.scaled(3.0), G).accept   # 0.15 wide: too uncertain, take another look
False
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from ipcverify.containment import (
    ContainmentCertificate,
    ExactEllipsoid,
    Status,
    Verification,
    prove_closed_form,
    verify,
)
from ipcverify.errors import SetError
from ipcverify.exact import exact_vector, float_down, float_up, sqnorm, sqrt_upper
from ipcverify.sets import Box, Ellipsoid

__all__ = [
    "PRECHECK_MARGIN",
    "LandingDecision",
    "LandingRule",
    "QueryDecision",
    "Verdict",
    "check_landing",
    "landing_accept_float",
    "landing_decision",
    "landing_slack",
    "turnoff_point",
]

FloatArray = NDArray[np.float64]

#: Relative margin by which the float rule must fail before a query is rejected without the
#: exact proof (anything closer goes to :func:`landing_decision`); also the float rule's
#: tolerance, so that the z face, which touches ``P`` by construction, is not lost to rounding.
PRECHECK_MARGIN = 1e-9


def _check_ellipsoid(ellipsoid: Ellipsoid) -> None:
    if not isinstance(ellipsoid, Ellipsoid) or ellipsoid.batch_size != 1 or ellipsoid.dim != 3:
        raise SetError(
            "landing needs a single 3-D ellipsoid (batch of 1, n = 3); for batches use "
            "landing_accept_float or call landing_decision per ellipsoid"
        )


def _check_target(target: Box) -> None:
    if not isinstance(target, Box) or target.dim != 3:
        raise SetError("the target G must be a 3-D Box")
    if not (target.lower < target.upper).all():
        raise SetError("the target G must have positive width in every coordinate")


def _turnoff(ex: ExactEllipsoid) -> FloatArray:
    """``[c_x, c_y, z_max rounded up]`` with ``(P_z - c_z)^2 >= ||row z of C^{-1}||^2`` exactly."""
    hz2 = sqnorm(ex.cinv[2])  # squared half-height P_zz
    pz = float_up(ex.c[2] + sqrt_upper(hz2, 64))
    return np.array([float(ex.c[0]), float(ex.c[1]), pz])


def turnoff_point(ellipsoid: Ellipsoid) -> FloatArray:
    """The turn-off point ``P = [mid_x, mid_y, z_max]`` of the ellipsoid's bounding box.

    ``mid_x = c_x`` and ``mid_y = c_y`` exactly; ``P_z`` is the smallest float found
    ``>= z_max = c_z + sqrt((C^T C)^{-1}_zz)`` (rounded upward, never below).

    Examples
    --------
    >>> import numpy as np
    >>> turnoff_point(Ellipsoid(np.zeros(3), np.diag([1.0, 1.0, 4.0]))).tolist()
    [0.0, 0.0, 0.25]
    """
    _check_ellipsoid(ellipsoid)
    return _turnoff(ExactEllipsoid.of(ellipsoid))


def _offset_box(p: FloatArray, target: Box) -> Box:
    """``[P - G.upper, P - G.lower]`` rounded inward to floats (a subset of the exact box)."""
    pq, gl, gu = exact_vector(p), exact_vector(target.lower), exact_vector(target.upper)
    lower = [float_up(a - b) for a, b in zip(pq, gu, strict=True)]
    upper = [float_down(a - b) for a, b in zip(pq, gl, strict=True)]
    if any(lo > up for lo, up in zip(lower, upper, strict=True)):
        raise SetError(
            "the box {P} + (-G) is narrower than one float spacing at the turn-off point; "
            "G is too small for coordinates of this magnitude"
        )
    return Box(np.asarray(lower, dtype=np.float64), np.asarray(upper, dtype=np.float64))


@dataclass(frozen=True, eq=False)
class LandingDecision:
    """What the landing state machine needs after one measurement.

    Parameters
    ----------
    accept : bool
        True iff the certificate is PROVEN: switch to ``Landing`` and fly to
        ``turnoff``. False: go to ``New Waypoint`` and measure again.
    turnoff : ndarray, shape (3,)
        The turn-off point ``P`` (defined even when not accepted).
    certificate : ContainmentCertificate
        ``E ⊆ [P - G.upper, P - G.lower]`` (closed form, decided exactly); its outer
        box is rounded inward, so it lies inside ``{P} + (-G)``.
    target : Box
        The target region ``G``.
    """

    accept: bool
    turnoff: FloatArray
    certificate: ContainmentCertificate
    target: Box

    def __post_init__(self) -> None:
        p = np.array(self.turnoff, dtype=np.float64, copy=True)
        if p.shape != (3,) or not np.isfinite(p).all():
            raise SetError("turnoff must be 3 finite numbers")
        p.setflags(write=False)
        object.__setattr__(self, "turnoff", p)
        if bool(self.accept) != (self.certificate.status is Status.PROVEN):
            raise SetError("accept must be True exactly when the certificate is PROVEN")
        object.__setattr__(self, "accept", bool(self.accept))


def landing_decision(ellipsoid: Ellipsoid, target: Box) -> LandingDecision:
    """Decide, with an exact certificate, whether to land on this measurement.

    Call once per measurement with the IPC's ellipsoid (about a millisecond for
    ``n = 3``: one exact 3x3 inverse and six exact face checks).

    Parameters
    ----------
    ellipsoid : Ellipsoid
        One 3-D ellipsoid ``E(c, C)`` from the IPC.
    target : Box
        The target region ``G`` (3-D, positive width in every coordinate).

    Returns
    -------
    LandingDecision
        ``accept`` is True only if ``P - y in G`` is PROVEN for every ``y in E``.

    Examples
    --------
    >>> import numpy as np
    >>> G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])
    >>> d = landing_decision(Ellipsoid(np.zeros(3), np.diag([20.0, 20.0, 40.0])), G)
    >>> d.accept, d.certificate.margin >= 0
    (True, True)
    """
    _check_ellipsoid(ellipsoid)
    _check_target(target)
    ex = ExactEllipsoid.of(ellipsoid)
    p = _turnoff(ex)
    cert = prove_closed_form(ellipsoid, _offset_box(p, target), ex)
    return LandingDecision(cert.status is Status.PROVEN, p, cert, target)


def check_landing(decision: LandingDecision) -> Verification:
    """Re-check a decision exactly: the certificate, and that its box lies in ``{P} + (-G)``.

    An accepted decision re-verifies as PROVEN only if :func:`verify` proves the
    certificate and ``box.lower >= P - G.upper``, ``box.upper <= P - G.lower`` hold
    exactly, and the certificate's inner set is the decision's ellipsoid.

    Examples
    --------
    >>> import numpy as np
    >>> G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])
    >>> d = landing_decision(Ellipsoid(np.zeros(3), np.diag([20.0, 20.0, 40.0])), G)
    >>> check_landing(d).status.name
    'PROVEN'
    """
    cert = decision.certificate
    v = verify(cert)
    if v.status is not Status.PROVEN:
        return v
    box = cert.outer
    if not isinstance(box, Box):
        return Verification(cert.status, Status.UNKNOWN, "the certificate's outer set is not a box")
    pq = exact_vector(decision.turnoff)
    gl, gu = exact_vector(decision.target.lower), exact_vector(decision.target.upper)
    lo, up = exact_vector(box.lower), exact_vector(box.upper)
    for i in range(3):
        if lo[i] < pq[i] - gu[i] or up[i] > pq[i] - gl[i]:
            return Verification(
                cert.status, Status.UNKNOWN, f"coordinate {i}: the box is not inside {{P}} + (-G)"
            )
    return Verification(cert.status, Status.PROVEN, v.reason + "; box inside {P} + (-G) exactly")


def landing_slack(centers: FloatArray, half_widths: FloatArray, target: Box) -> FloatArray:
    """The float landing rule: relative slack of every face of the test (negative: does not fit).

    For an ellipsoid with centre ``c`` and axis half-widths ``h`` (``sqrt(P_ii)``), the float
    turn-off point is ``P = [c_x, c_y, c_z + h_z]`` and the test is ``c - h >= P - G.upper``
    and ``c + h <= P - G.lower``; each face's slack is divided by the size of the numbers
    involved, so that it can be compared with a relative tolerance. Elementwise: ``centers``
    and ``half_widths`` may be one ellipsoid's ``(3,)`` arrays or a batch's ``(B, 3)``.

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
    _check_target(target)
    slack = landing_slack(ellipsoids.centers, ellipsoids.half_widths(), target)
    return np.asarray(slack.min(axis=-1) >= -PRECHECK_MARGIN, dtype=np.bool_)


def _half_widths_3(C: FloatArray) -> FloatArray:
    """``sqrt(((C^T C)^{-1})_ii)`` = norms of the rows of ``C^{-1}`` for a 3x3 ``C`` (float, fast)."""
    (a, b, c), (d, e, f), (g, h, i) = C.tolist()
    A, B, Cc = e * i - f * h, -(d * i - f * g), d * h - e * g
    det = a * A + b * B + c * Cc
    if not (math.isfinite(det) and det != 0.0):
        return np.full(3, math.inf)
    # rows of adj(C) (= columns of the cofactor matrix), i.e. rows of C^{-1} times det
    r0 = (A, -(b * i - c * h), b * f - c * e)
    r1 = (B, a * i - c * g, -(a * f - c * d))
    r2 = (Cc, -(a * h - b * g), a * e - b * d)
    ad = abs(det)
    return np.array([math.sqrt(u * u + v * v + w * w) / ad for u, v, w in (r0, r1, r2)])


class Verdict(Enum):
    """The answer to one query: land, measure again, or the query is outside the contract's domain."""

    ACCEPT = "accept: the set provably fits the target; fly to the turn-off point"
    REJECT = "reject: the set does not (provably) fit the target; measure again"
    OUTSIDE_DOMAIN = (
        "outside the domain of validity: the query is unlike every calibration sample (or its set is "
        "degenerate), so the contract certifies nothing for it; do not act on it, measure again"
    )


@dataclass(frozen=True, eq=False, slots=True)
class QueryDecision:
    """The landing answer for one ellipsoid.

    Attributes
    ----------
    center : ndarray, shape (3,)
        Centre of the ellipsoid decided on.
    shape : ndarray, shape (3, 3)
        Its shape matrix ``C`` (``E = {y : ||C (y - c)|| <= 1}``).
    accept : bool
        Land on this measurement. From :meth:`LandingRule.decide` it is True only if
        ``proof`` is an exact PROVEN landing decision.
    turnoff : ndarray, shape (3,)
        Turn-off point ``P``: the exact one (``P_z`` rounded up) when ``proof`` is
        given, else the float ``[c_x, c_y, c_z + h_z]``.
    proof : LandingDecision or None
        The exact decision, when it was computed (the float rule did not reject clearly).
    in_domain : bool
        The query lies inside the contract's domain of validity (and its set is not degenerate).
        A query outside is never accepted.
    proven : bool
        ``accept`` is backed by an exact proof.
    """

    center: FloatArray
    shape: FloatArray
    accept: bool
    turnoff: FloatArray
    proof: LandingDecision | None = None
    in_domain: bool = True
    proven: bool = field(init=False)

    def __post_init__(self) -> None:
        if self.proof is not None and self.accept != self.proof.accept:
            raise SetError("a decision with a proof must accept exactly when the proof does")
        if self.accept and not self.in_domain:
            raise SetError("a query outside the domain of validity is never accepted")
        object.__setattr__(self, "proven", bool(self.accept and self.proof is not None))

    @property
    def verdict(self) -> Verdict:
        """ACCEPT, REJECT or OUTSIDE_DOMAIN."""
        if not self.in_domain:
            return Verdict.OUTSIDE_DOMAIN
        return Verdict.ACCEPT if self.accept else Verdict.REJECT


@dataclass(frozen=True, eq=False)
class LandingRule:
    """The landing decision of record for one ellipsoid, against the caller's target ``G``.

    :meth:`decide` applies the float rule (:func:`landing_slack`) and rejects when the
    ellipsoid misses the target by more than :data:`PRECHECK_MARGIN` (relative); otherwise
    the exact :func:`landing_decision` decides, so every accept is exactly proven.
    :meth:`decide_float` is the float rule alone (fast, **not a proof**).

    Parameters
    ----------
    target : Box
        The target region ``G`` (3-D, positive width in every coordinate).

    Examples
    --------
    >>> import numpy as np
    >>> rule = LandingRule(Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05]))
    >>> d = rule.decide(np.zeros(3), np.diag([40.0, 40.0, 80.0]))
    >>> d.accept, d.proven, d.turnoff.tolist()
    (True, True, [0.0, 0.0, 0.0125])
    >>> rule.decide(np.zeros(3), np.diag([10.0, 40.0, 80.0])).proof is None  # clear reject
    True
    """

    target: Box

    def __post_init__(self) -> None:
        _check_target(self.target)

    def _float(self, center: FloatArray, shape: FloatArray) -> tuple[FloatArray, float]:
        c = np.asarray(center, dtype=np.float64)
        C = np.asarray(shape, dtype=np.float64)
        if c.shape != (3,) or C.shape != (3, 3):
            raise SetError(f"the landing decision needs a 3-D ellipsoid; got {c.shape} and {C.shape}")
        h = _half_widths_3(C)
        worst = float(landing_slack(c, h, self.target).min())
        p = c.copy()
        p[2] += h[2]
        return p, (worst if math.isfinite(worst) else -math.inf)

    def decide(self, center: FloatArray, shape: FloatArray) -> QueryDecision:
        """Float rule, then the exact proof unless the float rule rejects clearly.

        A degenerate set (singular or non-finite shape matrix) is answered OUTSIDE_DOMAIN.
        """
        p, worst = self._float(center, shape)
        if not np.isfinite(p).all():
            return QueryDecision(center, shape, False, p, in_domain=False)
        if worst < -PRECHECK_MARGIN:
            return QueryDecision(center, shape, False, p)
        proof = landing_decision(Ellipsoid(center, shape), self.target)
        return QueryDecision(center, shape, proof.accept, proof.turnoff.copy(), proof)

    def decide_float(self, center: FloatArray, shape: FloatArray) -> QueryDecision:
        """The float rule alone: accept iff every relative slack is ``>= -PRECHECK_MARGIN``."""
        p, worst = self._float(center, shape)
        if not np.isfinite(p).all():
            return QueryDecision(center, shape, False, p, in_domain=False)
        return QueryDecision(center, shape, worst >= -PRECHECK_MARGIN, p)

    def outside_domain(self, center: FloatArray, shape: FloatArray) -> QueryDecision:
        """The OUTSIDE_DOMAIN answer for a query the domain test flagged (no proof attempted)."""
        p, _ = self._float(center, shape)
        return QueryDecision(center, shape, False, p, in_domain=False)
