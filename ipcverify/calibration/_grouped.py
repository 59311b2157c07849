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
  conformal risk control with the group losses ``V_g(t)``
  (:func:`~ipcverify.calibration.risk_control_threshold`).

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
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.calibration._bounds import CalibrationMode, min_calibration_size
from ipcverify.calibration._group_counts import (
    GuaranteeKind,
    check_guarantee,
    group_violation_counts,
)
from ipcverify.calibration._group_fit import group_threshold
from ipcverify.calibration._method import CalibrationRecord, CalibrationSample, CalibrationSpec
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
from ipcverify.calibration._threshold import (
    ScoreThreshold,
    check_eps_delta,
    check_mode,
    check_seed,
)
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError

#: Which calibration rows a method's threshold uses (the ``n`` of its summary), in words.
_USED = {
    "one-per-group": "one seeded random row of each group used",
    "group-max": "every row used, through each group's largest score",
    "risk-control": "every row used, by risk control over the groups",
}
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
        The selected score ``t``.
    scale : float
        ``t * (1 + SCALE_MARGIN)`` (at least ``MIN_SCALE``); the sets are ``E(c, C / scale)``.
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
        check_guarantee(self.guarantee_kind)
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
        return one_scale(x, self.scale)

    def group_index(self, x: FloatArray, yhat: FloatArray) -> NDArray[np.intp]:
        """Every query is in the one calibrated group (zeros, shape (B,))."""
        return one_group(x)

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
                rate=t.allowed_rate(),
                reason=f"w.p. 1 - delta the probability that {what} is at most this; {unit}",
            )
        return AllowedRate(
            rate=t.allowed_rate(),
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
        >>> from ipcverify.errors import SampleSizeError
        >>> runs = np.repeat(np.arange(20), 50)                 # 20 flights, 1000 rows
        >>> try:
        ...     GroupedCalibration.fit(np.ones(1000), runs, 0.01, 0.001, guarantee="trajectory",
        ...                            column="run", data_hash="d", network_hash="h")
        ... except SampleSizeError as exc:
        ...     print(str(exc).split(". ")[0])
        20 groups of column 'run' are too few for a pac trajectory-level calibration at epsilon=0.01, \
delta=0.001: at least 688 groups are needed
        """
        fitted = group_threshold(
            scores, groups, epsilon, delta, mode, guarantee=guarantee, column=column, seed=seed
        )
        t = fitted.order_statistic
        return cls(
            column=column,
            guarantee_kind=guarantee,
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
        )


@dataclass(frozen=True, kw_only=True)
class Grouped(CalibrationSpec):
    """Grouped calibration, whole groups (flights, runs) as exchangeable units: a spec for ``calibrate()``.

    Parameters
    ----------
    column : str
        The column naming each calibration sample's group (any column of the data; it is not
        needed at predict time).
    guarantee : {"sample", "trajectory"}
        Bound the expected share of a new group's samples outside their sets (``"sample"``), or
        the probability that a new group leaves its sets anywhere (``"trajectory"``).
    seed : int
        Seeds the choice of one sample per group (``guarantee="sample"``, PAC).
    mode : {"pac", "marginal"}
        PAC (i.i.d. groups) or marginal (exchangeable groups) guarantee.

    Examples
    --------
    >>> Grouped(column="run").unit_column
    'run'
    >>> Grouped(column="run", guarantee="always")
    Traceback (most recent call last):
    ...
    ipcverify.errors.InvalidInputError: guarantee must be 'trajectory' (every sample of a new group \
inside its set) or 'sample' (the expected fraction of a new group's samples outside); got 'always'
    """

    column: str
    guarantee: GuaranteeKind = "sample"
    seed: int = 0
    kind: ClassVar[str] = "grouped"
    record: ClassVar[CalibrationRecord] = GroupedCalibration

    def __post_init__(self) -> None:
        super().__post_init__()
        if not (isinstance(self.column, str) and self.column):
            raise InvalidInputError(f"a grouped calibration needs a group column name; got {self.column!r}")
        check_guarantee(self.guarantee)
        check_seed(self.seed)

    @property
    def unit_column(self) -> str:
        """The group column: its groups are the exchangeable units (also of the domain test by default)."""
        return self.column

    def fit(self, sample: CalibrationSample) -> GroupedCalibration:
        """Calibrate one scale with the groups of the data's column as the units."""
        return GroupedCalibration.fit(
            sample.scores,
            sample.rows().column(self.column),
            sample.epsilon,
            sample.delta,
            self.mode,
            guarantee=self.guarantee,
            column=self.column,
            seed=self.seed,
            **sample.ids,
        )
