"""Grouped calibration: the exchangeable unit is a group of correlated samples (a flight, run, sequence).

Samples of one run share its conditions (wind, light, a biased sensor) and its slowly drifting
errors, so they are correlated, and a calibration that treats rows as exchangeable under-covers.
Here the *runs* are the exchangeable units: a column of the calibration data (e.g. ``run``) names
each sample's run; it is needed only to calibrate -- the result is one scale factor for every
query. Three claims (``guarantee=``), each using every row of every run:

* ``"expected-share"`` (the default): the expected share of a new run's rows outside their sets
  is at most ``epsilon``. PAC: the smallest threshold at which (and above which) the runs' shares
  reject ``mean >= epsilon`` with a betting test (:mod:`~ipcverify.calibration._share_bound`);
  with no violation in any run it reaches ``1 - (0.8 delta)^(1/G)``, near the floor
  ``1 - delta^(1/G)`` of any claim about a new run. Marginal: conformal risk control
  (:func:`~ipcverify.calibration.risk_control_threshold`).
* ``"share-of-runs"``: at least ``1 - gamma`` of new runs have at most ``epsilon`` of their rows
  outside. A run's statistic is its own within-run ``(1 - epsilon)`` quantile; the threshold is
  the PAC or split-conformal order statistic of the ``G`` statistics at ``gamma``.
* ``"trajectory"``: a new run stays inside its sets at *every* row with probability at least
  ``1 - epsilon``; the statistic of a run is its largest score.

PAC statements need i.i.d. runs; marginal ones exchangeable runs. Within a run samples may depend
on each other in any way. The number of runs, not of rows, decides what can be certified
(:func:`~ipcverify.calibration._group_fit.runs_needed`). Model files written before these claims
hold a per-sample claim from one random row per run (``method="one-per-group"``); they are read
and checked as before. Proofs: ``proofs/group_calibration.md`` and ``proofs/run_claims.md``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify._wording._spelling import option
from ipcverify.calibration._bounds import CalibrationMode, min_calibration_size
from ipcverify.calibration._group_counts import (
    CountStatistic,
    GuaranteeKind,
    allowed_outside,
    check_guarantee,
    group_shares,
    group_violation_counts,
)
from ipcverify.calibration._group_fit import METHOD_OF, group_threshold, runs_needed, smallest_run_rate
from ipcverify.calibration._grouped_checks import check_record
from ipcverify.calibration._protocol import (
    AllowedRate,
    CalibrationSummary,
    FloatArray,
    GroupClaim,
    GroupInfo,
    TestCounts,
    one_group,
    one_scale,
    summarize,
)
from ipcverify.calibration._share_bound import run_floor
from ipcverify.calibration._threshold import ScoreThreshold, check_eps_delta, check_mode
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError

#: Which calibration rows a method's threshold uses (the ``n`` of its summary), in words.
_USED = {
    "one-per-group": "one seeded random row of each group used",
    "group-max": "every row used, through each group's largest score",
    "risk-control": "every row used, by risk control over the groups",
    "share-bound": "every row used, through each group's share of rows outside (betting bound)",
    "run-quantile": "every row used, through each group's within-group quantile",
}
#: The method of a record written before the method was stored (from its guarantee and mode).
_LEGACY_METHOD = {("sample", "pac"): "one-per-group", ("sample", "marginal"): "risk-control"}
_INTS = ("n_groups", "k_groups", "n_rows", "n_used", "n_inside", "size_min", "size_max", "seed")
_FLOATS = ("epsilon", "delta", "order_statistic", "scale", "risk", "size_median", "gamma", "bound")
#: How :meth:`GroupedCalibration.from_dict` reads each field (``k_groups``/``risk``/... may be None).
_RECORD_TYPES: dict[str, Any] = {
    **dict.fromkeys(_INTS, lambda v: None if v is None else int(v)),
    **dict.fromkeys(_FLOATS, lambda v: None if v is None else float(v)),
    **dict.fromkeys(("column", "data_hash", "network_hash", "guarantee_kind", "mode", "method"), str),
}
_OPTIONAL = ("k_groups", "risk", "gamma", "bound")


@dataclass(frozen=True, kw_only=True)
class GroupedCalibration:
    """One scale factor calibrated with groups (flights, runs) as the exchangeable units.

    Built by :meth:`fit`; see the module docstring for the claims.

    Attributes
    ----------
    column : str
        The calibration data's group column (not needed at predict time).
    guarantee_kind : {"expected-share", "share-of-runs", "trajectory"}
        What the claim bounds (the module docstring).
    mode : {"pac", "marginal"}
    epsilon, delta : float
        Target share of a run's rows outside (for ``"trajectory"``: probability of any) and the
        confidence parameter.
    n_groups : int
        Calibration groups ``G``.
    k_groups : int or None
        Order statistic among the ``G`` group statistics (None for the expected share).
    order_statistic : float
        The selected score ``t``.
    scale : float
        ``t * (1 + SCALE_MARGIN)`` (at least ``MIN_SCALE``); the sets are ``E(c, C / scale)``.
    risk : float or None
        Expected share only: ``mean_g V_g(t)``, the calibration groups' mean share outside.
    n_rows, n_used, n_inside : int
        Calibration rows; those that entered the threshold; used rows with score ``<= t``.
    size_min, size_median, size_max : int, float, int
        Rows per group.
    seed : int
        Seeds the choice of one sample per group (records with ``method="one-per-group"``).
    data_hash, network_hash : str
        Identity of the calibration data and of the calibrated network.
    method : str
        How the threshold was chosen: ``"share-bound"``, ``"risk-control"``, ``"run-quantile"``,
        ``"group-max"`` (or ``"one-per-group"`` in earlier model files); empty: from the guarantee
        and mode.
    gamma : float or None
        ``"share-of-runs"`` only: the target share of new runs with more than ``epsilon`` of their
        rows outside.
    bound : float or None
        ``"share-bound"`` only: the upper confidence bound of the groups' shares at ``t`` (at most
        ``epsilon``).

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
    method: str = ""
    gamma: float | None = None
    bound: float | None = None
    kind: ClassVar[str] = "grouped"

    def __post_init__(self) -> None:
        check_mode(self.mode)
        check_eps_delta(self.epsilon, self.delta)
        stored = str(self.guarantee_kind)
        object.__setattr__(self, "guarantee_kind", check_guarantee(stored))
        method = (
            self.method
            or _LEGACY_METHOD.get((stored, self.mode))
            or METHOD_OF[(self.guarantee_kind, self.mode)]
        )
        object.__setattr__(self, "method", method)
        check_record(self)

    @property
    def group_threshold(self) -> ScoreThreshold | None:
        """The order statistic of the ``G`` group statistics as a checked record (None for a share bound).

        For ``"share-of-runs"`` its rate is ``gamma`` (the statistics are the runs' quantiles).
        """
        if self.k_groups is None:
            return None
        return ScoreThreshold(
            mode=self.mode,
            epsilon=self.epsilon if self.gamma is None else self.gamma,
            delta=self.delta,
            n=self.n_groups,
            k=self.k_groups,
            order_statistic=self.order_statistic,
            scale=self.scale,
        )

    @property
    def n(self) -> int:
        """Calibration rows whose scores were used (all rows, or one per group in earlier records)."""
        return self.n_used

    @property
    def certified_epsilon(self) -> float:
        """The share (or trajectory probability) certified: ``epsilon``, or the order statistic's PAC rate."""
        t = self.group_threshold
        if t is None or self.gamma is not None:
            return self.epsilon
        return t.certified_epsilon

    @property
    def certified_gamma(self) -> float | None:
        """``"share-of-runs"``: the share of new runs certified to exceed ``epsilon`` (at most ``gamma``)."""
        t = self.group_threshold
        return None if self.gamma is None or t is None else t.certified_epsilon

    @property
    def smallest_epsilon(self) -> float:
        """The smallest rate (``gamma`` for the share of runs) the ``G`` runs could certify at ``delta``."""
        return smallest_run_rate(self.guarantee_kind, self.mode, self.n_groups, self.delta)

    def scale_for(self, x: FloatArray, yhat: FloatArray) -> FloatArray:
        """The scale (same for every query), shape (B,)."""
        return one_scale(x, self.scale)

    def group_index(self, x: FloatArray, yhat: FloatArray) -> NDArray[np.intp]:
        """Every query is in the one calibrated group (zeros, shape (B,))."""
        return one_group(x)

    def groups(self) -> tuple[GroupInfo, ...]:
        """One group ``"all"``: ``n`` rows used, ``k`` of them inside, the scale."""
        return (GroupInfo(label="all", n=self.n_used, k=self.n_inside, scale=self.scale),)

    def allowed_violation_rate(self) -> AllowedRate:
        """The group-level rate a test may check (with one statistic per test group), if any."""
        if self.method == "share-bound":
            return AllowedRate(
                rate=self.epsilon,
                reason="w.p. 1 - delta the expected share of a new group's rows outside their sets is at "
                "most "
                "this; check it with the test groups' shares, not with correlated rows",
            )
        t = self.group_threshold
        if t is None:
            return AllowedRate(
                rate=None, reason="grouped conformal risk control (marginal) makes no per-draw claim"
            )
        what, unit = {
            "group-max": ("a new group leaves its sets at some sample", "one any-violation indicator"),
            "one-per-group": ("a random sample of a new group violates", "one random sample"),
            "run-quantile": (
                f"a new group has more than {self.epsilon:g} of its rows outside their sets",
                "one indicator (share above epsilon)",
            ),
        }[self.method]
        unit = f"check it with {unit} per test group, not with correlated rows"
        if self.mode == "pac":
            return AllowedRate(
                rate=t.allowed_rate(),
                reason=f"w.p. 1 - delta the probability that {what} is at most this; {unit}",
            )
        return AllowedRate(
            rate=t.allowed_rate(),
            reason=f"1 - delta quantile of the Beta(G - k + 1, k) probability that {what}; {unit}",
        )

    def test_counts(self, violated: NDArray[np.bool_], test_data: PerceptionDataset) -> TestCounts:
        """One statistic per test group (the test data needs the group column): its share, or a count."""
        if self.column not in test_data.extra:
            raise InvalidInputError(
                f"{test_data.source}: the calibration's claim is about runs (its calibration data named them "
                f"{self.column!r}), so the test is counted per run: name the column of the test data's runs "
                f"({option('group_column', 'COL')})"
            )
        labels = test_data.extra[self.column]
        unit = f"groups of {self.column}"
        if self.method in ("share-bound", "risk-control"):
            shares, outside, _ = group_shares(violated, labels)
            return TestCounts(
                violations=int((outside > 0).sum()),
                n=len(shares),
                unit=unit,
                shares=tuple(float(v) for v in shares),
            )
        if self.method == "run-quantile":
            _, outside, sizes = group_shares(violated, labels)
            over = sum(
                int(o) > allowed_outside(self.epsilon, int(m)) for o, m in zip(outside, sizes, strict=True)
            )
            return TestCounts(
                violations=int(over), n=len(sizes), unit=f"{unit} (more than {self.epsilon:g} outside)"
            )
        stat: CountStatistic = "trajectory" if self.method == "group-max" else "sample"
        counts = group_violation_counts(violated, labels, stat, self.seed)
        what = "any violation" if stat == "trajectory" else "one random sample each"
        return TestCounts(violations=counts.violations, n=counts.n_groups, unit=f"{unit} ({what})")

    def group_claim(self) -> GroupClaim:
        """The claim is about groups of ``column``, one statistic (and seed, or share limit) each."""
        unit = {
            "group-max": "trajectory",
            "one-per-group": "sample",
            "risk-control": "share",
            "share-bound": "share",
            "run-quantile": "share-of-runs",
        }[self.method]
        limit = self.epsilon if unit == "share-of-runs" else None
        return GroupClaim(column=self.column, unit=unit, seed=self.seed, share_limit=limit)  # type: ignore[arg-type]

    def summary(self) -> CalibrationSummary:
        """The typed record; groups, sizes, the claim, the method and what the runs allow in ``details``."""
        return summarize(
            self,
            certified_epsilon=self.certified_epsilon,
            grouping=(
                f"all samples, one scale; {self.n_groups} groups of {self.column} ({self.n_rows:,} rows) as "
                f"exchangeable units; {_USED[self.method]}"
            ),
            details={
                "group_column": self.column,
                "guarantee_kind": self.guarantee_kind,
                "method": self.method,
                "n_groups": self.n_groups,
                "min_groups": (
                    min_calibration_size(self.epsilon, self.delta, self.mode)
                    if self.method == "one-per-group"
                    else runs_needed(self.guarantee_kind, self.mode, self.epsilon, self.delta, self.gamma)
                ),
                "k_groups": self.k_groups,
                "n_rows": self.n_rows,
                "group_size_min": self.size_min,
                "group_size_median": self.size_median,
                "group_size_max": self.size_max,
                "order_statistic": self.order_statistic,
                "scale": self.scale,
                "risk": self.risk,
                "bound": self.bound,
                "gamma": self.gamma,
                "certified_gamma": self.certified_gamma,
                "smallest_epsilon": self.smallest_epsilon,
                "floor": run_floor(self.n_groups, self.delta),
                "seed": self.seed,
            },
        )

    def guarantee(self) -> str:
        """The guarantee in one plain sentence."""
        G, col = self.n_groups, self.column
        units = f"the {G} calibration groups (by {col!r})"
        if self.method == "one-per-group":
            units += " and the seeded choice of one sample per group"
        rows = "samples within a group may be correlated"
        if self.method == "run-quantile":
            gamma = (
                f"{self.certified_gamma:.4g} (target {self.gamma:g})"
                if self.mode == "pac"
                else f"{self.gamma:g}"
            )
            claim = (
                f"at most {gamma} of new groups have more than {self.epsilon:g} of their samples' ground "
                "truths "
                "outside their calibrated ellipsoids"
            )
        elif self.guarantee_kind == "trajectory":
            claim = (
                "the probability that a new group has its ground truth outside its calibrated ellipsoid at "
                f"some sample is at most {self.certified_epsilon:.4g}"
            )
            claim += f" (target {self.epsilon:g})" if self.mode == "pac" else ""
        else:
            claim = (
                "the expected fraction of a new group's samples whose ground truth lies outside its "
                "calibrated "
                f"ellipsoid is at most {self.certified_epsilon:.4g}"
            )
            claim += f" (target {self.epsilon:g})" if self.method == "one-per-group" else ""
        if self.mode == "pac":
            return (
                f"With probability at least {1 - self.delta:.6g} over the draw of {units}, {claim}, provided "
                f"calibration and deployment groups are i.i.d. ({rows})."
            )
        return (
            f"Averaged over the draw of {units}, {claim} (marginal, not per calibration set), provided "
            f"calibration and deployment groups are exchangeable ({rows})."
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form stored in the model file (``kind`` and every field)."""
        return {"kind": self.kind, **{f.name: getattr(self, f.name) for f in fields(self)}}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> GroupedCalibration:
        """Inverse of :meth:`to_dict` (also of records written before ``method``, ``gamma``, ``bound``)."""
        if data.get("kind", cls.kind) != cls.kind:
            raise InvalidInputError(f"not a grouped calibration record (kind {data.get('kind')!r})")
        defaults = {"method": "", "gamma": None, "bound": None}
        kw = {f.name: _RECORD_TYPES[f.name](data.get(f.name, defaults.get(f.name))) for f in fields(cls)}
        for name in _OPTIONAL:
            kw[name] = None if data.get(name) is None else kw[name]
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
        gamma: float | None = None,
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
            Target share of a run's rows outside (trajectory: probability of any) and the
            confidence parameter.
        mode : {"pac", "marginal"}
            Training-conditional (needs i.i.d. groups) or marginal (exchangeable groups).
        guarantee : {"expected-share", "share-of-runs", "trajectory"}
            The claim (see the module docstring).
        column : str
            The group column's name (recorded; used in messages).
        gamma : float, optional
            ``"share-of-runs"`` only (required there): the share of new runs that may have more
            than ``epsilon`` of their rows outside.
        seed : int
            Recorded (earlier per-sample records drew one row per group with it).
        data_hash, network_hash : str
            Identity of the calibration data and of the network.

        Raises
        ------
        SampleSizeError
            If there are fewer groups than the claim needs at ``(epsilon, delta)``; the message
            gives the minimum and the smallest rate the groups allow.
        InvalidInputError
            For bad scores, labels, mode, epsilon, delta, gamma or guarantee.

        Examples
        --------
        >>> from ipcverify.errors import SampleSizeError
        >>> runs = np.repeat(np.arange(20), 50)                 # 20 flights, 1000 rows
        >>> try:
        ...     GroupedCalibration.fit(np.ones(1000), runs, 0.1, 0.01, guarantee="expected-share",
        ...                            column="run", data_hash="d", network_hash="h")
        ... except SampleSizeError as exc:
        ...     print(str(exc).split(". ")[0])
        20 groups of column 'run' are too few for a pac expected-share claim at epsilon=0.1, delta=0.01: \
at least 46 groups are needed
        """
        fitted = group_threshold(
            scores, groups, epsilon, delta, mode, guarantee=guarantee, column=column, seed=seed, gamma=gamma
        )
        t = fitted.order_statistic
        return cls(
            column=column,
            guarantee_kind=check_guarantee(guarantee),
            mode=mode,
            epsilon=float(epsilon),
            delta=float(delta),
            n_groups=len(fitted.sizes),
            k_groups=fitted.k_groups,
            order_statistic=t,
            scale=fitted.scale,
            risk=fitted.risk,
            n_rows=int(np.asarray(scores).size),
            n_used=int(fitted.used.size),
            n_inside=int((fitted.used <= t).sum()),
            size_min=int(fitted.sizes.min()),
            size_median=float(np.median(fitted.sizes)),
            size_max=int(fitted.sizes.max()),
            seed=int(seed),
            data_hash=data_hash,
            network_hash=network_hash,
            method=fitted.method,
            gamma=None if gamma is None else float(gamma),
            bound=fitted.bound,
        )
