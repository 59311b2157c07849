"""The landing decision of record for one ellipsoid: :class:`LandingRule` and its :class:`QueryDecision`.

One decision rule, two precisions:

* :func:`~ipcverify.decision.landing_slack` is the float rule -- the relative slack of every face
  of the test, for one ellipsoid or a whole batch (:mod:`ipcverify.decision._landing_float`);
* :class:`LandingRule` is the decision of record for one ellipsoid. It is decided in float64
  with a rigorous bound on the rounding error (:func:`ipcverify.decision.landing_by_bound`,
  ``proofs/float_landing.md``): the same accept/reject and the same turn-off point as the
  exact :func:`~ipcverify.decision.landing_decision` (Proposition 1,
  :mod:`ipcverify.decision._landing_proof`), at the cost of a few microseconds; only when a
  margin lies inside its rounding band does the exact rational proof decide. Either way every
  answer is proven, and an accept's exact certificate is at hand (:attr:`QueryDecision.proof`).

Examples
--------
>>> import numpy as np
>>> from ipcverify.sets import Box
>>> d = LandingRule(Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])).decide(np.zeros(3), np.eye(3) * 40)
>>> d.verdict.name, d.proven
('ACCEPT', True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from ipcverify.decision._landing_bound import bound_target, landing_by_bound_compiled
from ipcverify.decision._landing_float import (
    PRECHECK_MARGIN,
    half_widths_3,
    half_widths_values,
    landing_slack,
)
from ipcverify.decision._landing_proof import LandingDecision, check_target, landing_decision
from ipcverify.errors import IPCVerifyError, SetError
from ipcverify.sets._box import Box
from ipcverify.sets._ellipsoid import Ellipsoid

FloatArray = NDArray[np.float64]


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
        check_target(self.target)
        lower, upper = tuple(self.target.lower.tolist()), tuple(self.target.upper.tolist())
        object.__setattr__(self, "_bounds", (lower, upper) if bound_target(lower, upper) else None)
        object.__setattr__(self, "_bounds_lists", (list(lower), list(upper)))

    def _float(self, center: FloatArray, shape: FloatArray) -> tuple[FloatArray, float]:
        c, C = _arrays(center, shape)
        h = half_widths_3(C)
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
        c, h, (lo, up) = values[:3], half_widths_values(values[3:]), self._bounds_lists  # type: ignore[attr-defined]
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
        p[2] += half_widths_3(C)[2]
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
        p[2] += half_widths_values(values[3:])[2]
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
