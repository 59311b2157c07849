"""Grouped calibration: the exchangeable unit is a group of correlated samples (a flight, run, sequence).

Samples of one flight share its conditions (wind, light, a biased sensor), so they are
correlated, and a calibration that treats rows as exchangeable under-covers. Here the
*groups* are the exchangeable units: a column of the calibration data (e.g. ``run``)
names each sample's group; it is needed only to calibrate -- the result is one scale
factor for every query. Two guarantees (``guarantee=``), each PAC or marginal:

* ``"trajectory"``: the statistic of a group is its largest score ``M_g``; the threshold
  is the PAC or split-conformal order statistic of the ``G`` maxima
  (:func:`~ipcverify.calibration.threshold_scores`). A new group then stays
  inside its sets at *every* sample with probability at least ``1 - epsilon``
  (PAC: with confidence ``1 - delta`` over the calibration groups; marginal: on average).
* ``"sample"``: a bound on ``E[V_new(t)]``, the expected fraction of a new group's samples
  outside their sets. PAC: one sample per group is drawn at random (seeded, independently
  of the scores) and the PAC order statistic of those ``G`` scores is used. Marginal:
  conformal risk control with the group losses ``V_g(t)`` (:func:`risk_control_threshold`).

PAC statements need independent, identically distributed groups; marginal ones need
exchangeable groups. Within a group samples may depend on each other in any way. The
number of groups, not of rows, decides what can be certified: ``G`` must be at least
:func:`~ipcverify.calibration.min_calibration_size` ``(epsilon, delta, mode)``. Proofs:
``proofs/group_calibration.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from fractions import Fraction
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats

from ipcverify.calibration._bounds import CalibrationMode, min_calibration_size, smallest_epsilon
from ipcverify.calibration._protocol import AllowedRate, CalibrationSummary, GroupClaim, GroupInfo, TestCounts
from ipcverify.calibration._threshold import (
    MIN_SCALE,
    SCALE_MARGIN,
    ScoreThreshold,
    check_eps_delta,
    check_mode,
    threshold_scores,
)
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._split import group_codes
from ipcverify.errors import InvalidInputError, SampleSizeError

__all__ = [
    "GUARANTEES",
    "GuaranteeKind",
    "GroupedCalibration",
    "GroupViolations",
    "group_violation_counts",
    "risk_control_threshold",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
GuaranteeKind = Literal["trajectory", "sample"]  # = protocol.GroupUnit
#: The two guarantees: every sample of a new group inside (trajectory), or a per-sample rate.
GUARANTEES = ("trajectory", "sample")
#: Relative slack when a stored risk-control record is re-checked (its mean risk is a rounded float).
RISK_RTOL = 1e-9
_INTS = ("n_groups", "k_groups", "n_rows", "n_used", "n_inside", "size_min", "size_max", "seed")
_FLOATS = ("epsilon", "delta", "order_statistic", "scale", "risk", "size_median")
#: How :meth:`GroupedCalibration.from_dict` reads each field (``k_groups``/``risk`` may be None).
_RECORD_TYPES: dict[str, Any] = {
    **dict.fromkeys(_INTS, lambda v: None if v is None else int(v)),
    **dict.fromkeys(_FLOATS, lambda v: None if v is None else float(v)),
    **dict.fromkeys(("column", "data_hash", "network_hash", "guarantee_kind", "mode"), str),
}


def _check_guarantee(guarantee: str) -> None:
    if guarantee not in GUARANTEES:
        raise InvalidInputError(
            f"guarantee must be 'trajectory' (every sample of a new group inside its set) or 'sample' "
            f"(the expected fraction of a new group's samples outside); got {guarantee!r}"
        )


def _group_layout(codes: IntArray, n_groups: int) -> tuple[IntArray, IntArray, IntArray]:
    """Rows sorted by group (stable), each group's first position in that order, group sizes."""
    order = np.argsort(codes, kind="stable")
    sizes = np.bincount(codes, minlength=n_groups).astype(np.intp)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.intp)
    return order, starts, sizes


def _one_per_group(codes: IntArray, n_groups: int, seed: int) -> IntArray:
    """Row index of one sample per group, uniformly at random within the group (seeded)."""
    order, starts, sizes = _group_layout(codes, n_groups)
    u = np.random.default_rng(seed).random(n_groups)
    pick = np.minimum((u * sizes).astype(np.intp), sizes - 1)
    return order[starts + pick]


def risk_control_threshold(scores: ArrayLike, groups: ArrayLike, epsilon: float) -> tuple[float, float]:
    """Conformal risk control over groups: the smallest ``t`` with ``(sum_g V_g(t) + 1) / (G + 1) <= eps``.

    ``V_g(t)`` is the fraction of group ``g``'s samples with score ``> t`` (a loss in
    ``[0, 1]``, non-increasing and right-continuous in ``t``). If the ``G`` calibration groups
    and a new group are exchangeable, ``E[V_new(t)] <= epsilon`` (proofs/group_calibration.md).
    The candidate is found in floating point and then settled in exact rational arithmetic,
    so the result is the exact infimum (always one of the scores).

    Returns ``(t, mean_g V_g(t))`` for scores (N,) with group labels (N,). Raises
    :class:`SampleSizeError` if ``G < 1 / epsilon - 1`` (no ``t`` satisfies the condition).

    Examples
    --------
    >>> s = np.array([0.1, 0.2, 0.3, 0.4, 1.0, 2.0, 3.0, 4.0])
    >>> risk_control_threshold(s, [0, 0, 1, 1, 2, 2, 3, 3], 0.5)
    (1.0, 0.375)
    """
    s = np.asarray(scores, dtype=np.float64).ravel()
    codes, labels = group_codes(groups, "risk control groups")
    G = len(labels)
    if len(codes) != len(s):
        raise InvalidInputError(f"{len(s)} scores but {len(codes)} group labels; give one label per score")
    eps = Fraction(epsilon)
    if eps * (G + 1) < 1:
        need = min_calibration_size(epsilon, 0.5, "marginal")
        raise SampleSizeError(
            f"{G} groups are too few for conformal risk control at epsilon={epsilon:g}: at least {need} "
            "groups are needed (G >= 1/epsilon - 1)"
        )
    sizes = np.bincount(codes, minlength=G)
    order = np.argsort(s, kind="stable")
    sorted_s = s[order]
    last = np.flatnonzero(np.concatenate([sorted_s[1:] != sorted_s[:-1], [True]]))
    risk_sum = G - np.cumsum(1.0 / sizes[codes[order]])[last]  # sum_g V_g at each distinct score
    budget = eps * (G + 1) - 1
    distinct_sizes = np.unique(sizes)

    def exact_risk_sum(j: int) -> Fraction:
        over = np.bincount(codes[s > sorted_s[last[j]]], minlength=G)
        return sum((Fraction(int(over[sizes == m].sum()), int(m)) for m in distinct_sizes), Fraction(0))

    # float candidate, then the exact infimum: the exact sum is decreasing in j, so step forward
    # while it fails and back while the previous one passes (a few steps at most)
    ok = np.flatnonzero(risk_sum <= float(budget))
    j = int(ok[0]) if ok.size else len(last) - 1
    while exact_risk_sum(j) > budget:  # at the largest score the sum is 0 <= budget
        j += 1
    while j > 0 and exact_risk_sum(j - 1) <= budget:
        j -= 1
    return float(sorted_s[last[j]]), float(exact_risk_sum(j) / G)


def _too_few_groups(
    G: int, column: str, epsilon: float, delta: float, mode: CalibrationMode, what: str
) -> str:
    need = min_calibration_size(epsilon, delta, mode)
    text = (
        f"{G} groups of column {column!r} are too few for a {mode} {what} calibration at "
        f"epsilon={epsilon:g}, delta={delta:g}: at least {need} groups are needed. The groups (flights, "
        "runs), not the rows, are the exchangeable units, so more rows per group do not help; collect "
        f"more independent groups, or raise --epsilon (with {G} groups the smallest is "
        f"{smallest_epsilon(G, delta, mode):g}"
    )
    if mode == "pac":
        marginal = min_calibration_size(epsilon, delta, "marginal")
        return text + f" at this delta) or --delta, or use --mode marginal (needs {marginal} groups)"
    return text + ")"


@dataclass(frozen=True, kw_only=True)
class GroupViolations:
    """``violations`` of ``n_groups`` test groups, one statistic per group (:func:`group_violation_counts`).

    ``unit="trajectory"``: a group counts if any of its samples violates; ``"sample"``: if one
    sample drawn at random (seeded) from it violates.
    """

    violations: int
    n_groups: int
    unit: GuaranteeKind

    def __post_init__(self) -> None:
        _check_guarantee(self.unit)
        if not (0 <= self.violations <= self.n_groups and self.n_groups >= 1):
            raise InvalidInputError(f"need 0 <= violations <= n_groups, n_groups >= 1; got {self}")


def group_violation_counts(
    violated: ArrayLike, groups: ArrayLike, unit: GuaranteeKind, seed: int = 0
) -> GroupViolations:
    """Count violations per test group, so that a binomial test is valid for correlated samples.

    Rows of one group are correlated, so a Clopper--Pearson bound from row counts is not
    valid; one statistic per group is, if the test groups are i.i.d. For ``unit="trajectory"``
    its mean is the probability that a group leaves its sets somewhere; for ``"sample"`` (one
    random sample per group) it is ``E[V_new]``, the expected violation fraction of a group.

    Examples
    --------
    >>> v = np.array([False, True, False, False, False, False])
    >>> group_violation_counts(v, [1, 1, 2, 2, 3, 3], "trajectory")
    GroupViolations(violations=1, n_groups=3, unit='trajectory')
    """
    _check_guarantee(unit)
    bad = np.asarray(violated, dtype=bool).ravel()
    codes, labels = group_codes(groups, "test groups")
    if len(codes) != len(bad):
        raise InvalidInputError(f"{len(bad)} violation flags but {len(codes)} group labels; give one per row")
    G = len(labels)
    if unit == "trajectory":
        count = int((np.bincount(codes, weights=bad.astype(np.float64), minlength=G) > 0).sum())
    else:
        count = int(bad[_one_per_group(codes, G, seed)].sum())
    return GroupViolations(violations=count, n_groups=G, unit=unit)


@dataclass(frozen=True, kw_only=True)
class GroupedCalibration:
    """One scale factor calibrated with groups (flights, runs) as the exchangeable units.

    Built by :meth:`fit`; see the module docstring for the guarantees.

    Attributes
    ----------
    column : str
        The calibration data's group column (not needed at predict time).
    guarantee_kind : {"trajectory", "sample"}
        Every sample of a new group inside (trajectory) or the expected per-sample rate.
    mode : {"pac", "marginal"}
    epsilon, delta : float
        Target violation rate and confidence parameter.
    n_groups : int
        Calibration groups ``G``.
    k_groups : int or None
        Order statistic among the ``G`` group statistics (None for risk control).
    order_statistic : float
        The selected score ``t``; ``scale = t * (1 + SCALE_MARGIN)`` (at least ``MIN_SCALE``).
    risk : float or None
        Risk control only: ``mean_g V_g(t)`` over the calibration groups.
    n_rows, n_used, n_inside : int
        Calibration rows; those that entered the threshold (all, or one per group); used rows
        with score ``<= t``.
    size_min, size_median, size_max : int, float, int
        Rows per group.
    seed : int
        Seeds the choice of one sample per group (``guarantee="sample"``, PAC).
    data_hash, network_hash : str
        Identity of the calibration data and of the calibrated network.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> runs = np.repeat(np.arange(60), 10)                 # 60 flights of 10 samples
    >>> scores = rng.normal(size=60)[runs] ** 2 + rng.random(600)
    >>> cal = GroupedCalibration.fit(scores, runs, 0.1, 0.1, "pac", guarantee="trajectory", column="run",
    ...                              data_hash="d", network_hash="h")
    >>> cal.n_groups, cal.k_groups, cal.groups()[0].n
    (60, 58, 600)
    >>> GroupedCalibration.from_dict(cal.to_dict()) == cal
    True
    """

    column: str
    guarantee_kind: GuaranteeKind
    mode: CalibrationMode
    epsilon: float
    delta: float
    n_groups: int
    k_groups: int | None
    order_statistic: float
    scale: float
    risk: float | None
    n_rows: int
    n_used: int
    n_inside: int
    size_min: int
    size_median: float
    size_max: int
    seed: int
    data_hash: str
    network_hash: str
    kind: ClassVar[str] = "grouped"

    def __post_init__(self) -> None:
        check_mode(self.mode)
        check_eps_delta(self.epsilon, self.delta)
        _check_guarantee(self.guarantee_kind)
        G = self.n_groups
        if not (isinstance(G, int) and G >= min_calibration_size(self.epsilon, self.delta, self.mode)):
            raise InvalidInputError(
                f"grouped calibration record: n_groups={G!r} is below the minimum for {self.mode} at "
                f"epsilon={self.epsilon:g}, delta={self.delta:g}; the record is inconsistent -- recalibrate"
            )
        if not (1 <= self.size_min <= self.size_median <= self.size_max) or not (
            G * self.size_min <= self.n_rows <= G * self.size_max
        ):
            raise InvalidInputError(
                "grouped calibration record: group sizes disagree with n_rows and n_groups"
            )
        expect_used = G if self.method == "one-per-group" else self.n_rows
        if self.n_used != expect_used or not (1 <= self.n_inside <= self.n_used):
            raise InvalidInputError(
                f"grouped calibration record: n_used={self.n_used}, n_inside={self.n_inside} are "
                f"inconsistent with method {self.method!r} ({expect_used} rows used)"
            )
        if self.method == "risk-control":
            r = self.risk
            if (
                self.k_groups is not None
                or r is None
                or not 0.0 <= r <= 1.0
                or (G * r + 1) / (G + 1) > self.epsilon * (1 + RISK_RTOL)
            ):
                raise InvalidInputError(
                    f"grouped calibration record: risk {r!r} breaks (G * risk + 1) / (G + 1) <= epsilon "
                    f"for G={G}, epsilon={self.epsilon:g}; the record is inconsistent -- recalibrate"
                )
        elif self.risk is not None or self.group_threshold is None:
            raise InvalidInputError(
                "grouped calibration record: an order-statistic method needs k_groups, no risk"
            )
        if not (math.isfinite(self.scale) and self.scale > 0 and self.scale >= self.order_statistic >= 0):
            raise InvalidInputError(
                f"scale must be finite, > 0 and >= the order statistic >= 0; got scale={self.scale!r}, "
                f"order statistic={self.order_statistic!r}"
            )

    @property
    def method(self) -> Literal["group-max", "one-per-group", "risk-control"]:
        """How the threshold was chosen: order statistic of group maxima, of one sample per group, or CRC."""
        if self.guarantee_kind == "trajectory":
            return "group-max"
        return "one-per-group" if self.mode == "pac" else "risk-control"

    @property
    def group_threshold(self) -> ScoreThreshold | None:
        """The order statistic of the ``G`` group statistics as a checked record (None for risk control)."""
        if self.k_groups is None:
            return None
        return ScoreThreshold(
            mode=self.mode,
            epsilon=self.epsilon,
            delta=self.delta,
            n=self.n_groups,
            k=self.k_groups,
            order_statistic=self.order_statistic,
            scale=self.scale,
        )

    @property
    def n(self) -> int:
        """Calibration rows whose scores were used (all rows, or one per group)."""
        return self.n_used

    @property
    def certified_epsilon(self) -> float:
        """PAC: ``min(epsilon, Clopper-Pearson bound for G, k)``; marginal: ``epsilon``."""
        t = self.group_threshold
        return self.epsilon if t is None else t.certified_epsilon

    def scale_for(self, x: FloatArray, yhat: FloatArray) -> FloatArray:
        """The scale (same for every query), shape (B,)."""
        return np.full(len(np.asarray(x)), self.scale)

    def group_index(self, x: FloatArray, yhat: FloatArray) -> NDArray[np.intp]:
        """Every query is in the one calibrated group (zeros, shape (B,))."""
        return np.zeros(len(np.asarray(x)), dtype=np.intp)

    def groups(self) -> tuple[GroupInfo, ...]:
        """One group ``"all"``: ``n`` rows used, ``k`` of them inside, the scale."""
        return (GroupInfo(label="all", n=self.n_used, k=self.n_inside, scale=self.scale),)

    def allowed_violation_rate(self) -> AllowedRate:
        """The group-level rate a test may check (with one statistic per test group), if any."""
        unit = (
            "check it with one any-violation indicator per test group"
            if self.guarantee_kind == "trajectory"
            else "check it with one random sample per test group"
        )
        unit += ", not with correlated rows"
        t = self.group_threshold
        if t is None:
            return AllowedRate(
                rate=None, reason="grouped conformal risk control (marginal) makes no per-draw claim"
            )
        what = (
            "a new group leaves its sets at some sample"
            if self.guarantee_kind == "trajectory"
            else "a random sample of a new group violates"
        )
        if self.mode == "pac":
            return AllowedRate(
                rate=t.certified_epsilon,
                reason=f"w.p. 1 - delta the probability that {what} is at most this; {unit}",
            )
        return AllowedRate(
            rate=float(stats.beta.ppf(1.0 - t.delta, t.n - t.k + 1, t.k)),
            reason=f"1 - delta quantile of the Beta(G - k + 1, k) probability that {what}; {unit}",
        )

    def test_counts(self, violated: NDArray[np.bool_], test_data: PerceptionDataset) -> TestCounts:
        """One statistic per test group (the test data needs the group column); see group_violation_counts."""
        if self.column not in test_data.extra:
            raise InvalidInputError(
                f"{test_data.source}: the calibration's claim is about groups of {self.column!r} (flights, "
                "runs), so the test data needs that column to be counted per group; add it, or test a "
                "row-level calibration"
            )
        labels = test_data.extra[self.column]
        counts = group_violation_counts(violated, labels, self.guarantee_kind, self.seed)
        what = "any violation" if self.guarantee_kind == "trajectory" else "one random sample each"
        return TestCounts(
            violations=counts.violations, n=counts.n_groups, unit=f"groups of {self.column} ({what})"
        )

    def group_claim(self) -> GroupClaim:
        """The claim is about groups of ``column``, one statistic (``guarantee_kind``, ``seed``) each."""
        return GroupClaim(column=self.column, unit=self.guarantee_kind, seed=self.seed)

    def summary(self) -> CalibrationSummary:
        """The typed record; groups, sizes, the guarantee kind and the method are in ``details``."""
        return CalibrationSummary(
            kind=self.kind,
            mode=self.mode,
            epsilon=self.epsilon,
            delta=self.delta,
            n=self.n_used,
            certified_epsilon=self.certified_epsilon,
            guarantee=self.guarantee(),
            data_sha256=self.data_hash,
            groups=self.groups(),
            grouping=f"all samples, one scale; {self.n_groups} groups of {self.column} as exchangeable units",
            details={
                "group_column": self.column,
                "guarantee_kind": self.guarantee_kind,
                "method": self.method,
                "n_groups": self.n_groups,
                "min_groups": min_calibration_size(self.epsilon, self.delta, self.mode),
                "k_groups": self.k_groups,
                "n_rows": self.n_rows,
                "group_size_min": self.size_min,
                "group_size_median": self.size_median,
                "group_size_max": self.size_max,
                "order_statistic": self.order_statistic,
                "scale": self.scale,
                "risk": self.risk,
                "seed": self.seed,
            },
        )

    def guarantee(self) -> str:
        """The guarantee in one plain sentence."""
        G, col = self.n_groups, self.column
        units = f"the {G} calibration groups (by {col!r})"
        if self.guarantee_kind == "trajectory":
            event = "a new group has its ground truth outside its calibrated ellipsoid at some sample"
        else:
            event = (
                "the expected fraction of a new group's samples whose ground truth lies outside its "
                "calibrated ellipsoid"
            )
            units += " and the seeded choice of one sample per group" if self.mode == "pac" else ""
        verb = "the probability that " + event if self.guarantee_kind == "trajectory" else event
        if self.mode == "pac":
            return (
                f"With probability at least {1 - self.delta:.6g} over the draw of {units}, {verb} is at most "
                f"{self.certified_epsilon:.4g} (target {self.epsilon:g}), provided calibration and "
                "deployment groups are i.i.d. (samples within a group may be correlated)."
            )
        return (
            f"Averaged over the draw of {units}, {verb} is at most {self.epsilon:g} (marginal, not per "
            "calibration set), provided calibration and deployment groups are exchangeable (samples within "
            "a group may be correlated)."
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form stored in the model file (``kind`` and every field)."""
        return {"kind": self.kind, **{f.name: getattr(self, f.name) for f in fields(self)}}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> GroupedCalibration:
        """Inverse of :meth:`to_dict`."""
        if data.get("kind", cls.kind) != cls.kind:
            raise InvalidInputError(f"not a grouped calibration record (kind {data.get('kind')!r})")
        kw = {f.name: _RECORD_TYPES[f.name](data[f.name]) for f in fields(cls)}
        for name in ("k_groups", "risk"):
            kw[name] = None if data[name] is None else kw[name]
        return cls(**kw)

    @classmethod
    def fit(
        cls,
        scores: ArrayLike,
        groups: ArrayLike,
        epsilon: float,
        delta: float,
        mode: CalibrationMode = "pac",
        *,
        guarantee: GuaranteeKind,
        column: str,
        seed: int = 0,
        data_hash: str,
        network_hash: str,
    ) -> GroupedCalibration:
        """Calibrate one scale factor with the groups of ``groups`` as the exchangeable units.

        Parameters
        ----------
        scores : array_like, shape (N,)
            Finite, non-negative scores ``g = ||C (y - c)||`` of the calibration rows.
        groups : array_like, shape (N,)
            Each row's group label (flight, run, sequence), e.g. ``data.column("run")``.
        epsilon, delta : float
            Target violation rate and confidence parameter.
        mode : {"pac", "marginal"}
            Training-conditional (needs i.i.d. groups) or marginal (exchangeable groups).
        guarantee : {"trajectory", "sample"}
            Every sample of a new group inside its set, or the expected fraction of a new
            group's samples outside (see the module docstring).
        column : str
            The group column's name (recorded; used in messages).
        seed : int
            Seeds the choice of one sample per group (``guarantee="sample"``, PAC); choose it
            before looking at the data.
        data_hash, network_hash : str
            Identity of the calibration data and of the network.

        Raises
        ------
        SampleSizeError
            If there are fewer groups than ``min_calibration_size(epsilon, delta, mode)``;
            the message gives the minimum number of groups.
        InvalidInputError
            For bad scores, labels, mode, epsilon, delta or guarantee.

        Examples
        --------
        >>> runs = np.repeat(np.arange(20), 50)                 # 20 flights, 1000 rows
        >>> try:
        ...     GroupedCalibration.fit(np.ones(1000), runs, 0.01, 0.001, guarantee="trajectory",
        ...                            column="run", data_hash="d", network_hash="h")
        ... except SampleSizeError as exc:
        ...     print(str(exc).split(". ")[0])
        20 groups of column 'run' are too few for a pac trajectory-level calibration at epsilon=0.01, \
delta=0.001: at least 688 groups are needed
        """
        check_mode(mode)
        check_eps_delta(epsilon, delta)
        _check_guarantee(guarantee)
        if isinstance(seed, bool) or int(seed) != seed:
            raise InvalidInputError(f"seed must be an integer; got {seed!r}")
        s = np.asarray(scores, dtype=np.float64).ravel()
        if s.size == 0 or not np.isfinite(s).all() or (s < 0).any():
            raise InvalidInputError("calibration scores must be a non-empty array of finite values >= 0")
        codes, labels = group_codes(groups, f"group column {column!r}")
        if len(codes) != len(s):
            raise InvalidInputError(
                f"{len(s)} calibration scores but {len(codes)} labels in group column {column!r}; "
                "give one group label per calibration row"
            )
        G = len(labels)
        if G < min_calibration_size(epsilon, delta, mode):
            raise SampleSizeError(_too_few_groups(G, column, epsilon, delta, mode, f"{guarantee}-level"))
        order, starts, sizes = _group_layout(codes, G)
        k_groups: int | None = None
        risk: float | None = None
        used = s
        if guarantee == "trajectory":
            t = threshold_scores(np.maximum.reduceat(s[order], starts), epsilon, delta, mode)
            k_groups, stat, scale = t.k, t.order_statistic, t.scale
        elif mode == "pac":
            used = s[_one_per_group(codes, G, int(seed))]
            t = threshold_scores(used, epsilon, delta, mode)
            k_groups, stat, scale = t.k, t.order_statistic, t.scale
        else:
            stat, risk = risk_control_threshold(s, codes, epsilon)
            scale = max(stat * (1.0 + SCALE_MARGIN), MIN_SCALE)
        return cls(
            column=column,
            guarantee_kind=guarantee,
            mode=mode,
            epsilon=float(epsilon),
            delta=float(delta),
            n_groups=G,
            k_groups=k_groups,
            order_statistic=stat,
            scale=scale,
            risk=risk,
            n_rows=int(s.size),
            n_used=int(used.size),
            n_inside=int((used <= stat).sum()),
            size_min=int(sizes.min()),
            size_median=float(np.median(sizes)),
            size_max=int(sizes.max()),
            seed=int(seed),
            data_hash=data_hash,
            network_hash=network_hash,
        )
