"""Certified versus empirical unsafe landings, and whether the closed loop stays in the data.

Certified bound (``proofs/landing_safety.md``)
----------------------------------------------
An unsafe landing of the state machine implies that the accepted query ``J`` had its
truth outside its ellipsoid (the exact accept test and the exact cut test do the rest).
Summing over the at most ``M`` contract queries of a run,

    P(unsafe) <= sum_j P(N >= j and y outside E_j) <= eps * E[N] <= eps * M,

provided **assumption A** holds: given that a run makes its ``j``-th query, that query
``(x_C, yhat_C, y_C)`` is distributed like the calibration data, so the PAC calibration's
``P(violation) <= eps`` applies to it. The calibration makes ``eps`` true with probability
at least ``1 - delta`` over its draw. :func:`certified_bound` reports ``M eps`` (needs
nothing else) and ``eps * UCB(E[N])`` with a Hoeffding upper confidence bound on the mean
number of queries from the campaign (another ``delta``).

Assumption A is an idealisation: the closed loop chooses where to measure, so its
queries are not literally draws from the calibration distribution. Two checks quantify
the gap:

* :func:`.coverage.coverage_check` — nearest-neighbour distances of the closed-loop queries to the
  calibration set, in the network's standardised input space, against the distances of
  held-out test samples (drawn like the calibration data) to the same set; a closed-loop
  exceedance rate of the test's ``q``-quantile significantly above ``1 - q`` flags a
  *coverage shift*. Per-feature ranges are reported too.
* :func:`closed_loop_violations` — how often the closed loop's own queries (first query of
  each run, accepted query of each run, all queries) had the truth outside the ellipsoid,
  with Clopper--Pearson intervals; a rate significantly above ``eps`` contradicts A.

Examples
--------
>>> b = certified_bound(0.002, 0.001, max_queries=8, queries_per_run=[2, 2, 3])
>>> round(b.union_bound, 6), b.vacuous
(0.016, False)
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from case_studies.quad_landing.landing.runs import LandingRun, Outcome
from ipcverify.calibration._bounds import (
    clopper_pearson_interval,
    clopper_pearson_lower,
    clopper_pearson_upper,
)
from ipcverify.errors import InvalidInputError

__all__ = [
    "ASSUMPTION_A",
    "CertifiedBound",
    "ClosedLoopViolations",
    "EmpiricalVsCertified",
    "ViolationRate",
    "certified_bound",
    "closed_loop_violations",
    "hoeffding_upper",
    "unsafe_vs_certified",
]


#: The assumption under which the certified bound holds, in words.
ASSUMPTION_A = (
    "Given that a landing run makes its j-th IPC query, that query (x_C, yhat_C, y_C) is distributed "
    "like the calibration samples (i.i.d. from one distribution); the calibration samples are i.i.d. "
    "draws from that distribution; and the pad lies on the floor (y_z = floor height)."
)


@dataclass(frozen=True, kw_only=True)
class CertifiedBound:
    """The certified upper bound on ``P(unsafe landing)`` under assumption A (:func:`certified_bound`).

    Attributes
    ----------
    epsilon, delta : float
        The calibration's certified violation rate and confidence parameter.
    max_queries : int
        Cap ``M`` on contract queries per run.
    union_bound : float
        ``min(1, M eps)``, at confidence ``union_confidence = 1 - delta``.
    runs_for_mean : int
        Runs whose query counts bound ``E[N]``.
    mean_queries : float or None
        Their mean number of queries (None without runs).
    mean_queries_upper : float
        Hoeffding upper confidence bound on ``E[N]``.
    refined_bound : float
        ``min(1, eps UCB(E[N]))``, at confidence ``refined_confidence``.
    assumption : str
        Assumption A in words.
    vacuous : bool
        The union bound is 1.
    """

    epsilon: float
    delta: float
    max_queries: int
    union_bound: float
    union_confidence: float
    runs_for_mean: int
    mean_queries: float | None
    mean_queries_upper: float
    refined_bound: float
    refined_confidence: float
    assumption: str
    vacuous: bool

    def to_dict(self) -> dict[str, Any]:
        """Plain data for ``summary.json`` (``landing.ipc.certified``)."""
        return dataclasses.asdict(self)


@dataclass(frozen=True, kw_only=True)
class EmpiricalVsCertified:
    """The empirical unsafe rate of a campaign beside the certified bound (:func:`unsafe_vs_certified`).

    Attributes
    ----------
    runs, unsafe : int
        Runs, and unsafe ones.
    certified_union, certified_refined : float
        The union and refined certified bounds.
    unsafe_rate : float or None
        ``unsafe / runs`` (None without runs, as are the fields below).
    unsafe_interval : (float, float) or None
        Two-sided Clopper--Pearson interval of the unsafe rate.
    bound_at_least_rate : bool or None
        The union bound is at least the point rate.
    consistent : bool or None
        The one-sided lower bound of the unsafe rate does not exceed the refined bound
        (False: the data refute the certified bound).
    confidence : float or None
        Confidence of the interval and the lower bound.
    """

    runs: int
    unsafe: int
    certified_union: float
    certified_refined: float
    unsafe_rate: float | None = None
    unsafe_interval: tuple[float, float] | None = None
    bound_at_least_rate: bool | None = None
    consistent: bool | None = None
    confidence: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain data for ``summary.json``; the rate and its checks only when there are runs."""
        return {f.name: v for f in dataclasses.fields(self) if (v := getattr(self, f.name)) is not None}


def hoeffding_upper(values: Sequence[float], low: float, high: float, delta: float) -> float:
    """One-sided Hoeffding upper confidence bound on the mean of i.i.d. values in ``[low, high]``.

    ``P(mean_true > mean + (high - low) sqrt(ln(1/delta) / (2 n))) <= delta``.

    Examples
    --------
    >>> round(hoeffding_upper([1, 1, 1, 1], 0, 2, 0.05), 4)
    2.0
    """
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        return float(high)
    if not (0 < delta < 1) or high < low or np.any(v < low) or np.any(v > high):
        raise InvalidInputError("need 0 < delta < 1 and values within [low, high]")
    width = (high - low) * math.sqrt(math.log(1.0 / delta) / (2.0 * v.size))
    return float(min(high, v.mean() + width))


def certified_bound(
    epsilon: float,
    delta: float,
    *,
    max_queries: int,
    queries_per_run: Sequence[int],
    delta_queries: float | None = None,
) -> CertifiedBound:
    """The certified upper bound on ``P(unsafe landing)`` under assumption A.

    Parameters
    ----------
    epsilon : float
        The calibration's certified violation rate (``certified_epsilon``).
    delta : float
        The calibration's confidence parameter.
    max_queries : int
        Cap ``M`` on contract queries per run.
    queries_per_run : sequence of int
        Contract queries (measurements with a detection) of each run of an independent
        campaign, for the refined bound.
    delta_queries : float, optional
        Confidence parameter of the bound on ``E[N]`` (default ``delta``).

    Returns
    -------
    CertifiedBound
        ``union_bound = min(1, M eps)`` (confidence ``1 - delta``), ``refined_bound =
        min(1, eps UCB(E[N]))`` (confidence ``1 - delta - delta_queries``), the inputs, the
        assumption and ``vacuous`` (the union bound is 1).
    """
    if not (0 < epsilon < 1 and 0 < delta < 1):
        raise InvalidInputError("epsilon and delta must lie strictly between 0 and 1")
    if isinstance(max_queries, bool) or int(max_queries) != max_queries or max_queries < 1:
        raise InvalidInputError(f"max_queries must be a positive integer, got {max_queries!r}")
    dq = delta if delta_queries is None else delta_queries
    counts = [int(c) for c in queries_per_run]
    ucb = hoeffding_upper(counts, 0, max_queries, dq)
    union = min(1.0, max_queries * epsilon)
    return CertifiedBound(
        epsilon=epsilon,
        delta=delta,
        max_queries=int(max_queries),
        union_bound=union,
        union_confidence=1 - delta,
        runs_for_mean=len(counts),
        mean_queries=float(np.mean(counts)) if counts else None,
        mean_queries_upper=ucb,
        refined_bound=min(1.0, epsilon * ucb),
        refined_confidence=1 - delta - dq,
        assumption=ASSUMPTION_A,
        vacuous=union >= 1.0,
    )


@dataclass(frozen=True)
class ViolationRate:
    """How many of ``n`` queries had the truth outside the set, with a Clopper--Pearson interval.

    ``rate``, ``interval`` and ``upper`` are None when ``n`` is 0; ``contradicts_epsilon`` is
    None when no ``epsilon`` was tested (dependent queries: descriptive only).
    """

    n: int
    violations: int
    rate: float | None = None
    interval: tuple[float, float] | None = None
    upper: float | None = None
    contradicts_epsilon: bool | None = None

    def to_dict(self) -> dict[str, Any]:
        """As in ``summary.json``: only ``n`` and ``violations`` when there were no queries."""
        out: dict[str, Any] = {"n": self.n, "violations": self.violations}
        if self.n:
            interval = None if self.interval is None else list(self.interval)
            out.update(rate=self.rate, interval=interval, upper=self.upper)
            if self.contradicts_epsilon is not None:
                out["contradicts_epsilon"] = self.contradicts_epsilon
        return out


def _rate(k: int, n: int, delta: float, epsilon: float | None = None) -> ViolationRate:
    if not n:
        return ViolationRate(n=n, violations=k)
    contradicts = None if epsilon is None else bool(clopper_pearson_lower(k, n, delta) > epsilon)
    return ViolationRate(
        n=n,
        violations=k,
        rate=k / n,
        interval=clopper_pearson_interval(k, n, delta),
        upper=clopper_pearson_upper(k, n, delta),
        contradicts_epsilon=contradicts,
    )


@dataclass(frozen=True)
class ClosedLoopViolations:
    """How often the closed loop's own queries had the truth outside the contract's set.

    ``first`` (one per run, independent across runs), ``accepted`` (the query each landed or
    settle-aborted run accepted; what an unsafe landing needs), ``every`` (all queries with a
    detection, dependent within a run; descriptive; ``"all"`` in ``summary.json``).
    """

    first: ViolationRate
    accepted: ViolationRate
    every: ViolationRate
    confidence: float
    epsilon: float

    def to_dict(self) -> dict[str, Any]:
        """``summary.json``'s ``landing.closed_loop``."""
        return {
            "first": self.first.to_dict(),
            "accepted": self.accepted.to_dict(),
            "all": self.every.to_dict(),
            "confidence": self.confidence,
            "epsilon": self.epsilon,
        }


def closed_loop_violations(
    runs: Sequence[LandingRun], epsilon: float, delta: float = 0.05
) -> ClosedLoopViolations:
    """How often the closed loop's own queries had the truth outside the contract's set.

    ``contradicts_epsilon`` of ``first`` and ``accepted`` is True when the one-sided
    Clopper--Pearson lower bound (confidence ``1 - delta``) exceeds ``epsilon``.

    Examples
    --------
    >>> closed_loop_violations([], 0.01).first.n
    0
    """
    first = [r.queries[0].truth_inside for r in runs if r.queries and r.queries[0].detected]
    accepted = [q.truth_inside for r in runs for q in r.queries if q.accepted]
    every = [q.truth_inside for r in runs for q in r.queries if q.detected]
    return ClosedLoopViolations(
        first=_rate(sum(1 for t in first if not t), len(first), delta, epsilon),
        accepted=_rate(sum(1 for t in accepted if not t), len(accepted), delta, epsilon),
        every=_rate(sum(1 for t in every if not t), len(every), delta),
        confidence=1 - delta,
        epsilon=epsilon,
    )


def unsafe_vs_certified(
    runs: Sequence[LandingRun], bound: CertifiedBound, delta: float = 0.05
) -> EmpiricalVsCertified:
    """The empirical unsafe rate beside the certified bound; ``consistent`` is False if the data refute it.

    Examples
    --------
    >>> b = certified_bound(0.002, 0.001, max_queries=8, queries_per_run=[1])
    >>> unsafe_vs_certified([], b).runs
    0
    """
    n = len(runs)
    k = sum(1 for r in runs if r.outcome is Outcome.UNSAFE)
    union, refined = bound.union_bound, bound.refined_bound
    if not n:
        return EmpiricalVsCertified(runs=0, unsafe=0, certified_union=union, certified_refined=refined)
    return EmpiricalVsCertified(
        runs=n,
        unsafe=k,
        certified_union=union,
        certified_refined=refined,
        unsafe_rate=k / n,
        unsafe_interval=clopper_pearson_interval(k, n, delta),
        bound_at_least_rate=bool(union >= k / n),
        consistent=bool(clopper_pearson_lower(k, n, delta) <= refined),
        confidence=1 - delta,
    )
