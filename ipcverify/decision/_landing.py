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
* :class:`LandingRule` is the decision of record for one ellipsoid. It is decided in float64
  with a rigorous bound on the rounding error (:func:`ipcverify.decision.landing_by_bound`,
  ``proofs/float_landing.md``): the same accept/reject and the same turn-off point as the
  exact :func:`landing_decision`, at the cost of a few microseconds; only when a margin lies
  inside its rounding band does the exact rational proof decide. Either way every answer is
  proven, and an accept's exact certificate is at hand (:attr:`QueryDecision.proof`).

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
>>> from ipcverify.sets._shapes import Ellipsoid
>>> from ipcverify.sets._shapes import Box, Ellipsoid
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

from ipcverify.decision._landing_bound import bound_target, landing_by_bound_compiled
from ipcverify.decision.containment import (
    ContainmentCertificate,
    ExactEllipsoid,
    Status,
    Verification,
    prove_closed_form,
    verify,
)
from ipcverify.errors import IPCVerifyError, SetError
from ipcverify.sets._exact import exact_vector, float_down, float_up, sqnorm, sqrt_upper
from ipcverify.sets._shapes import Box, Ellipsoid

__all__ = [
    "PRECHECK_MARGIN",
    "DecidedBy",
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

#: Tolerance of the float rule (:func:`landing_slack`, :meth:`LandingRule.decide_float`, not a
#: proof): relative slacks down to ``-PRECHECK_MARGIN`` count as fitting, so that the z face,
#: which touches ``P`` by construction, is not lost to rounding.
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
    cert = prove_closed_form(ellipsoid, _offset_box(p, target), ex, fast=False)
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
    return np.array(_half_widths_values(C.ravel().tolist()))


def _half_widths_values(flat: list[float]) -> list[float]:
    """:func:`_half_widths_3` of a row-major ``C`` given as 9 Python floats, as 3 floats."""
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


class Verdict(Enum):
    """The answer to one query: land, measure again, or the query is outside the contract's domain."""

    ACCEPT = "accept: the set provably fits the target; fly to the turn-off point"
    REJECT = "reject: the set does not (provably) fit the target; measure again"
    OUTSIDE_DOMAIN = (
        "outside the domain of validity: the query is unlike every calibration sample (or its set is "
        "degenerate), so the contract certifies nothing for it; do not act on it, measure again"
    )


class DecidedBy(Enum):
    """How a :class:`QueryDecision` was reached."""

    BOUND = (
        "float64 margins beyond their rigorous rounding bound (exact integers for the turn-off height "
        "when needed): a proof, see proofs/float_landing.md"
    )
    EXACT = "exact rational arithmetic (landing_decision): a proof, with its certificate"
    FLOAT_RULE = "the float rule alone (decide_float): not a proof"
    DOMAIN = "nothing decided: the query is outside the domain of validity or its set is degenerate"


class FastPathError(IPCVerifyError):
    """The exact proof disagrees with a decision of the float-bound fast path (a bug: please report)."""


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
        Land on this measurement. From :meth:`LandingRule.decide` it is True only if the
        ellipsoid provably fits (:attr:`decided_by` BOUND or EXACT).
    turnoff : ndarray, shape (3,)
        Turn-off point ``P``: from :meth:`LandingRule.decide` the exact decision's (``P_z``
        rounded up), else the float ``[c_x, c_y, c_z + h_z]``.
    decided_by : DecidedBy
        How the answer was reached (BOUND and EXACT are proofs).
    in_domain : bool
        The query lies inside the contract's domain of validity (and its set is not degenerate).
        A query outside is never accepted.
    target : Box or None
        The target ``G`` decided against (needed to produce :attr:`proof` on demand).
    exact : LandingDecision or None
        The exact decision, when it has been computed (see :attr:`proof`).
    proven : bool
        ``accept`` is backed by a proof.
    """

    center: FloatArray
    shape: FloatArray
    accept: bool
    turnoff: FloatArray
    decided_by: DecidedBy
    in_domain: bool = True
    target: Box | None = None
    exact: LandingDecision | None = None
    proven: bool = field(init=False)

    def __post_init__(self) -> None:
        if self.exact is not None and self.accept != self.exact.accept:
            raise SetError("a decision with an exact proof must accept exactly when the proof does")
        if self.accept and not self.in_domain:
            raise SetError("a query outside the domain of validity is never accepted")
        proof_kind = self.decided_by is DecidedBy.BOUND or self.decided_by is DecidedBy.EXACT
        object.__setattr__(self, "proven", bool(self.accept and proof_kind))

    @property
    def verdict(self) -> Verdict:
        """ACCEPT, REJECT or OUTSIDE_DOMAIN."""
        if not self.in_domain:
            return Verdict.OUTSIDE_DOMAIN
        return Verdict.ACCEPT if self.accept else Verdict.REJECT

    @property
    def proof(self) -> LandingDecision | None:
        """The exact decision with its certificate (:func:`landing_decision`), or None.

        Always available for a proven accept: computed on first access (about a millisecond)
        when the float-bound path decided, and checked to agree with it (accept and turn-off
        point). For a reject, only when the exact path decided it.

        Raises
        ------
        FastPathError
            If the exact proof disagrees with the fast path's decision (never expected).
        """
        if self.exact is None and self.proven and self.target is not None:
            exact = landing_decision(Ellipsoid(self.center, self.shape), self.target)
            if exact.accept != self.accept or not np.array_equal(exact.turnoff, self.turnoff):
                raise FastPathError(
                    f"the exact proof ({exact.accept}, P = {exact.turnoff.tolist()}) disagrees with the "
                    f"float-bound decision ({self.accept}, P = {self.turnoff.tolist()}) for c = "
                    f"{self.center.tolist()}, C = {self.shape.tolist()}: please report this as a bug"
                )
            object.__setattr__(self, "exact", exact)
        return self.exact


@dataclass(frozen=True, eq=False)
class LandingRule:
    """The landing decision of record for one ellipsoid, against the caller's target ``G``.

    :meth:`decide` decides ``E ⊆ [P - G.upper, P - G.lower]`` in float64 with a rigorous
    bound on the rounding error (:func:`~ipcverify.decision.landing_by_bound`): the same
    answer and turn-off point as the exact :func:`landing_decision`; a margin inside its
    rounding band (rare) is decided by :func:`landing_decision` itself. Every answer is
    proven. :meth:`decide_float` is the float rule alone (fast, **not a proof**).

    Parameters
    ----------
    target : Box
        The target region ``G`` (3-D, positive width in every coordinate).

    Examples
    --------
    >>> import numpy as np
    >>> rule = LandingRule(Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05]))
    >>> d = rule.decide(np.zeros(3), np.diag([40.0, 40.0, 80.0]))
    >>> d.accept, d.proven, d.decided_by.name, d.turnoff.tolist()
    (True, True, 'BOUND', [0.0, 0.0, 0.0125])
    >>> d.proof.certificate.status.name          # the exact certificate, on demand
    'PROVEN'
    >>> rule.decide(np.zeros(3), np.diag([10.0, 40.0, 80.0])).verdict.name
    'REJECT'
    """

    target: Box

    def __post_init__(self) -> None:
        _check_target(self.target)
        lower, upper = tuple(self.target.lower.tolist()), tuple(self.target.upper.tolist())
        object.__setattr__(self, "_bounds", (lower, upper) if bound_target(lower, upper) else None)
        object.__setattr__(self, "_bounds_lists", (list(lower), list(upper)))

    def _float(self, center: FloatArray, shape: FloatArray) -> tuple[FloatArray, float]:
        c, C = _arrays(center, shape)
        h = _half_widths_3(C)
        worst = float(landing_slack(c, h, self.target).min())
        p = c.copy()
        p[2] += h[2]
        return p, (worst if math.isfinite(worst) else -math.inf)

    def decide(self, center: FloatArray, shape: FloatArray) -> QueryDecision:
        """The decision of record: float64 with a rigorous rounding bound, else the exact proof.

        A degenerate set (singular -- by the rule of :class:`~ipcverify.sets.Ellipsoid` -- or
        non-finite shape matrix) is answered OUTSIDE_DOMAIN.
        """
        c, C = _arrays(center, shape)
        return self._decide(c.tolist(), C.ravel().tolist(), c, C)

    def decide_values(self, center: list[float], shape: list[float]) -> QueryDecision:
        """:meth:`decide` for a centre (3 floats) and a row-major shape matrix (9 floats) as Python floats.

        The same decision, without converting arrays to floats and back (the single-query
        path of :class:`ipcverify.decision.IPCQuery` computes its sets in Python floats).

        Examples
        --------
        >>> rule = LandingRule(Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05]))
        >>> d = rule.decide_values([0.0, 0.0, 0.0], [40.0, 0.0, 0.0, 0.0, 40.0, 0.0, 0.0, 0.0, 80.0])
        >>> d.accept, d.decided_by.name, d.turnoff.tolist()
        (True, 'BOUND', [0.0, 0.0, 0.0125])
        """
        both = _values_array(center, shape)
        values = both.tolist()  # float64 values whatever the caller's number types
        return self._decide(values[:3], values[3:], both[:3], both[3:].reshape(3, 3))

    def _decide(self, cl: list[float], flat: list[float], c: FloatArray, C: FloatArray) -> QueryDecision:
        """:meth:`decide` given the set both as floats (for the bound) and as arrays (for the answer)."""
        bounds = self._bounds  # type: ignore[attr-defined]
        if bounds is not None:
            r = landing_by_bound_compiled(cl, flat, *bounds)
            if r is not None:
                p = np.array((cl[0], cl[1], r.turnoff_z))
                return QueryDecision(c, C, r.accept, p, DecidedBy.BOUND, True, self.target)
        return self.decide_exact(c, C)

    def decide_exact(self, center: FloatArray, shape: FloatArray) -> QueryDecision:
        """The exact rational decision alone (:func:`landing_decision`), as a :class:`QueryDecision`."""
        c, C = _arrays(center, shape)
        try:
            e = Ellipsoid(c, C)
        except SetError:  # non-finite or singular: nothing to decide
            return self.outside_domain(c, C)
        try:
            proof = landing_decision(e, self.target)
        except OverflowError:  # a set too large for float's range (half-widths near 1e154): degenerate
            return self.outside_domain(c, C)
        return QueryDecision(
            c, C, proof.accept, proof.turnoff.copy(), DecidedBy.EXACT, True, self.target, proof
        )

    def decide_float(self, center: FloatArray, shape: FloatArray) -> QueryDecision:
        """The float rule alone: accept iff every relative slack is ``>= -PRECHECK_MARGIN``."""
        p, worst = self._float(center, shape)
        if not np.isfinite(p).all():
            return self.outside_domain(center, shape)
        c, C = _arrays(center, shape)
        return QueryDecision(c, C, worst >= -PRECHECK_MARGIN, p, DecidedBy.FLOAT_RULE, True, self.target)

    def decide_float_values(self, center: list[float], shape: list[float]) -> QueryDecision:
        """:meth:`decide_float` for a centre (3 floats) and a row-major shape (9 floats).

        The same operations, one element at a time, on Python floats: the same decision and ``P``.
        """
        both = _values_array(center, shape)
        values = both.tolist()
        c, h, (lo, up) = values[:3], _half_widths_values(values[3:]), self._bounds_lists  # type: ignore[attr-defined]
        p = [c[0], c[1], c[2] + h[2]]
        c_arr, C_arr = both[:3], both[3:].reshape(3, 3)
        if not all(map(math.isfinite, p)):
            return self.outside_domain(c_arr, C_arr)
        slack = [((p[i] - lo[i]) - (c[i] + h[i])) / _size(p, c, h, lo, up, i) for i in range(3)]
        slack += [((c[i] - h[i]) - (p[i] - up[i])) / _size(p, c, h, lo, up, i) for i in range(3)]
        worst = min(slack) if all(v == v for v in slack) else math.nan  # NumPy's min: NaN wins
        accept = (worst if math.isfinite(worst) else -math.inf) >= -PRECHECK_MARGIN
        return QueryDecision(c_arr, C_arr, accept, np.array(p), DecidedBy.FLOAT_RULE, True, self.target)

    def outside_domain(self, center: FloatArray, shape: FloatArray) -> QueryDecision:
        """The OUTSIDE_DOMAIN answer for a query the domain test flagged (no proof attempted).

        Its turn-off point is the float ``[c_x, c_y, c_z + h_z]`` (``inf`` for a degenerate set).
        """
        c, C = _arrays(center, shape)
        p = c.copy()
        p[2] += _half_widths_3(C)[2]
        return QueryDecision(c, C, False, p, DecidedBy.DOMAIN, False, self.target)

    def outside_domain_values(self, center: list[float], shape: list[float]) -> QueryDecision:
        """:meth:`outside_domain` for a centre (3 floats) and a row-major shape (9 floats).

        Examples
        --------
        >>> rule = LandingRule(Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05]))
        >>> d = rule.outside_domain_values([0.0, 0.0, 1.0], [2.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 4.0])
        >>> d.verdict.name, d.turnoff.tolist()
        ('OUTSIDE_DOMAIN', [0.0, 0.0, 1.25])
        """
        both = _values_array(center, shape)
        values = both.tolist()
        p = np.array(values[:3])
        p[2] += _half_widths_values(values[3:])[2]
        return QueryDecision(both[:3], both[3:].reshape(3, 3), False, p, DecidedBy.DOMAIN, False, self.target)


def _size(p: list[float], c: list[float], h: list[float], lo: list[float], up: list[float], i: int) -> float:
    """:func:`landing_slack`'s scale of face ``i``, summed in its order."""
    return 1.0 + abs(p[i]) + abs(c[i]) + h[i] + abs(lo[i]) + abs(up[i])


def _values_array(center: list[float], shape: list[float]) -> FloatArray:
    """Centre (3 floats) and row-major shape (9 floats) as one float64 array of 12 values."""
    if len(center) != 3 or len(shape) != 9:
        raise SetError(
            f"the landing decision needs a 3-D ellipsoid: 3 centre and 9 shape values; got "
            f"{len(center)} and {len(shape)}"
        )
    return np.array(center + shape, dtype=np.float64)


def _arrays(center: FloatArray, shape: FloatArray) -> tuple[FloatArray, FloatArray]:
    c = np.asarray(center, dtype=np.float64)
    C = np.asarray(shape, dtype=np.float64)
    if c.shape != (3,) or C.shape != (3, 3):
        raise SetError(f"the landing decision needs a 3-D ellipsoid; got {c.shape} and {C.shape}")
    return c, C
