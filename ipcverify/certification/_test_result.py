"""What the fresh test data says: violation counts with exact binomial bounds, per row and per group.

* :class:`TestResult` -- violations on fresh test data and exact (Clopper--Pearson) bounds;
* :class:`GroupTestResult` -- the same for one calibration group;
* :class:`Consistency` -- does the test data contradict the calibration's claim?
* :class:`GroupTest` -- the test counted per group (flight, run): valid for correlated rows.

:class:`~ipcverify.certification._certificate.Certificate` holds them; ``proofs/clopper_pearson.md``
proves the bounds and the consistency rule.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from ipcverify.calibration._bounds import (
    clopper_pearson_interval,
    clopper_pearson_lower,
    clopper_pearson_upper,
)
from ipcverify.calibration._protocol import GROUP_UNITS, AllowedRate, GroupUnit
from ipcverify.calibration._share_bound import share_lower_bound, share_upper_bound
from ipcverify.errors import InvalidInputError

#: What a test counted: units outside (a binomial count), or the mean of the units' shares outside.
Statistic = Literal["count", "mean"]
_BOUND = {
    "count": "one-sided Clopper-Pearson upper bound at confidence 1 - delta",
    "mean": "one-sided betting upper bound on the mean of the units' shares at confidence 1 - delta "
    "(valid for i.i.d. units with shares in [0, 1])",
}


@dataclass(frozen=True, kw_only=True)
class TestResult:
    """Violations of the contract on a test set and their exact binomial bounds.

    Attributes
    ----------
    n : int
        Test units: samples, or groups (flights, runs).
    violations : int or float
        Units whose truth lies outside its set; for ``statistic="mean"`` the sum of the units'
        shares of rows outside (so ``violations / n`` is their mean share).
    delta : float
        Confidence parameter of the bounds.
    upper_bound : float
        One-sided upper bound at ``1 - delta`` (Clopper--Pearson, or a betting bound for a mean).
    lower_bound : float
        One-sided lower bound at ``1 - delta`` (used for the consistency check).
    interval : tuple of float
        Two-sided interval at ``1 - delta``.
    unit : str
        What was counted: ``"samples"``, or groups (flights, runs) for a calibration whose
        claim is about groups (their rows are correlated, so rows are not the unit).
    statistic : {"count", "mean"}
        A binomial count of units outside, or the mean of the units' shares outside
        (:meth:`from_shares`).

    Examples
    --------
    >>> t = TestResult.from_counts(3, 1000, 0.001)
    >>> round(t.upper_bound, 4)
    0.013
    >>> TestResult.from_shares([0.0, 0.1, 0.05, 0.05], 0.05, "runs").counted()
    'mean share 5 % outside over 4 test runs'
    """

    __test__ = False  # not a pytest test class

    n: int
    violations: float
    delta: float
    upper_bound: float
    lower_bound: float
    interval: tuple[float, float]
    unit: str = "samples"
    statistic: Statistic = "count"

    def __post_init__(self) -> None:
        if not (0 <= self.violations <= self.n and self.n >= 1):
            raise InvalidInputError(f"need 0 <= violations <= n, n >= 1; got {self.violations}, {self.n}")
        if not (self.lower_bound <= self.violations / self.n <= self.upper_bound):
            raise InvalidInputError("test bounds must bracket the empirical rate")
        if self.statistic not in _BOUND or (
            self.statistic == "count" and int(self.violations) != self.violations
        ):
            raise InvalidInputError(f"a test counts units ('count', a whole number) or a 'mean'; got {self}")

    @classmethod
    def from_counts(cls, violations: int, n: int, delta: float, unit: str = "samples") -> TestResult:
        """Compute the bounds from counts."""
        return cls(
            n=int(n),
            violations=int(violations),
            delta=float(delta),
            upper_bound=clopper_pearson_upper(violations, n, delta),
            lower_bound=clopper_pearson_lower(violations, n, delta),
            interval=clopper_pearson_interval(violations, n, delta),
            unit=unit,
        )

    @classmethod
    def from_shares(cls, shares: ArrayLike, delta: float, unit: str) -> TestResult:
        """Bound the mean of the test units' shares of rows outside (betting bounds, i.i.d. units).

        Parameters
        ----------
        shares : array_like of float
            Each test unit's share of rows outside its sets, in ``[0, 1]``, in a fixed order.
        delta : float
            One minus the confidence of each one-sided bound (the interval is at ``1 - delta``).
        unit : str
            What the units are, for reports.
        """
        x = [float(v) for v in np.asarray(shares, dtype=np.float64).ravel()]
        return cls(
            n=len(x),
            violations=float(sum(x)),
            delta=float(delta),
            upper_bound=share_upper_bound(x, delta),
            lower_bound=share_lower_bound(x, delta),
            interval=(share_lower_bound(x, delta / 2), share_upper_bound(x, delta / 2)),
            unit=unit,
            statistic="mean",
        )

    def counted(self) -> str:
        """What was counted: "3 of 1,000 test samples" or "mean share 4.2 % outside over 4 test runs"."""
        if self.statistic == "mean":
            return f"mean share {100 * self.empirical_rate:.3g} % outside over {self.n:,} test {self.unit}"
        return f"{int(self.violations):,} of {self.n:,} test {self.unit}"

    @property
    def empirical_rate(self) -> float:
        """``violations / n``."""
        return self.violations / self.n

    @property
    def vacuous(self) -> bool:
        """The upper bound is 1: the test bounds nothing (too few test units, or all outside)."""
        return self.upper_bound >= 1.0

    def bound_text(self, spec: str = ".4g") -> str:
        """The upper bound as the reports write it, saying so when it is vacuous.

        Parameters
        ----------
        spec : str
            The format specification of the number (``".4%"`` for a percentage).

        Examples
        --------
        >>> TestResult.from_counts(3, 1000, 0.001).bound_text()
        '0.013'
        >>> TestResult.from_counts(2, 2, 0.05).bound_text()
        '1 (vacuous: it bounds nothing)'
        >>> TestResult.from_counts(2, 2, 0.05).bound_text(".1%")
        '100.0% (vacuous: it bounds nothing)'
        """
        return f"{self.upper_bound:{spec}}" + (" (vacuous: it bounds nothing)" if self.vacuous else "")

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""
        return {
            "n": self.n,
            "violations": self.violations,
            "empirical_rate": self.empirical_rate,
            "upper_bound": self.upper_bound,
            "vacuous": self.vacuous,
            "lower_bound": self.lower_bound,
            "interval": list(self.interval),
            "delta": self.delta,
            "unit": self.unit,
            "statistic": self.statistic,
            "bound": _BOUND[self.statistic],
        }


@dataclass(frozen=True, kw_only=True)
class GroupTestResult:
    """The test result of one calibration group (``result`` is None if no test sample fell in it).

    Attributes
    ----------
    label : str
        The calibration group's readable name (its Mondrian group's label, e.g. ``"run=3"`` or
        ``"0.5 <= speed < 1.2"``).
    result : TestResult or None
        The Clopper-Pearson bounds counted on the test rows that fall in the group (rows, not
        groups of rows); None if no test row falls in it.

    Examples
    --------
    >>> GroupTestResult(label="x_0=1", result=None).to_dict()["n"]
    0
    """

    label: str
    result: TestResult | None

    def to_dict(self) -> dict[str, Any]:
        """``{label, **result}``, or ``{label, n: 0, violations: 0, upper_bound: None}``."""
        if self.result is None:
            return {"label": self.label, "n": 0, "violations": 0, "upper_bound": None}
        return {"label": self.label, **self.result.to_dict()}


@dataclass(frozen=True, kw_only=True)
class Consistency:
    """Does the test data contradict the calibration's claim? (false-alarm probability <= 2 delta).

    Built by :meth:`check`: the claim is contradicted when the test set's one-sided lower
    bound exceeds the rate the calibration allows.

    Attributes
    ----------
    checked : bool
        Whether the comparison was made.
    consistent : bool or None
        Whether the test data is consistent with the claim (None: not checked).
    allowed_rate : float or None
        The violation rate the calibration allows.
    test_lower_bound : float or None
        The test set's one-sided lower bound.
    rule : str
        The rule applied, in words.
    reason : str
        Why no comparison was made.

    Examples
    --------
    >>> t = TestResult.from_counts(50, 1000, 0.001)
    >>> Consistency.check(AllowedRate(rate=0.01, reason="pac"), t).consistent
    False
    """

    checked: bool
    consistent: bool | None = None
    allowed_rate: float | None = None
    test_lower_bound: float | None = None
    rule: str = ""
    reason: str = ""

    @classmethod
    def check(cls, allowed: AllowedRate | None, test: TestResult) -> Consistency:
        """Compare the test lower bound with the allowed rate (if the calibration claims one)."""
        if allowed is None:
            return cls(checked=False, reason="no calibration")
        if allowed.rate is None:
            return cls(checked=False, reason=allowed.reason)
        return cls(
            checked=True,
            consistent=bool(test.lower_bound <= allowed.rate),
            allowed_rate=allowed.rate,
            test_lower_bound=test.lower_bound,
            rule=f"contradiction if the test lower bound exceeds the allowed rate ({allowed.reason})",
        )

    def to_dict(self) -> dict[str, Any]:
        """``{checked, reason}`` or ``{checked, consistent, allowed_rate, test_lower_bound, rule}``."""
        if not self.checked:
            return {"checked": False, "reason": self.reason}
        return {
            "checked": True,
            "consistent": self.consistent,
            "allowed_rate": self.allowed_rate,
            "test_lower_bound": self.test_lower_bound,
            "rule": self.rule,
        }


@dataclass(frozen=True, kw_only=True)
class GroupTest:
    """The test counted per group (flight, run): one Bernoulli per test group, valid for correlated rows.

    A row-level Clopper--Pearson bound assumes independent rows; rows of one flight are
    correlated, so it can be far too narrow. Counting one statistic per group
    (:func:`~ipcverify.calibration.group_violation_counts`) gives ``n_groups`` i.i.d.
    Bernoulli draws when the test groups are i.i.d., whatever the dependence within a group
    (``proofs/group_calibration.md`` section 6). Built by
    :func:`ipcverify.certification._certify.group_test_step`.

    Attributes
    ----------
    column : str
        The test data's group column.
    n_groups, n_rows : int
        Test groups and test rows.
    seed : int
        Seeds the choice of one sample per group (``sample``).
    trajectory : TestResult
        Groups with any violation: bounds on the probability that a new group leaves its sets
        somewhere.
    sample : TestResult
        Groups whose one randomly chosen sample violates: bounds on the expected share of a new
        group's samples outside their sets (a random sample of a random group).
    compared_unit : {"trajectory", "sample", "share", "share-of-runs"} or None
        The statistic checked against the calibration's allowed rate (None: not checked).
    consistency : Consistency
        That check (the same rule as the row-level one).
    share : TestResult or None
        The mean of the groups' shares of rows outside (betting bounds, every row counted): bounds
        on the expected share of a new group's samples outside, as ``sample`` but tighter.
    share_of_runs : TestResult or None
        For a share-of-runs claim: groups with more than the claim's share of rows outside.

    Examples
    --------
    >>> t = TestResult.from_counts(1, 30, 0.01, "groups of run (any violation)")
    >>> s = TestResult.from_counts(0, 30, 0.01, "groups of run (one random sample each)")
    >>> g = GroupTest(column="run", n_groups=30, n_rows=600, seed=0, trajectory=t, sample=s,
    ...               compared_unit=None, consistency=Consistency(checked=False, reason="no calibration"))
    >>> g.to_dict()["trajectory"]["violations"], round(g.to_dict()["sample"]["upper_bound"], 3)
    (1, 0.142)
    """

    __test__ = False  # not a pytest test class

    column: str
    n_groups: int
    n_rows: int
    seed: int
    trajectory: TestResult
    sample: TestResult
    compared_unit: GroupUnit | None
    consistency: Consistency
    share: TestResult | None = None
    share_of_runs: TestResult | None = None

    def __post_init__(self) -> None:
        sizes = {r.n for r in (self.trajectory, self.sample, self.share, self.share_of_runs) if r is not None}
        if not (2 <= self.n_groups <= self.n_rows) or sizes != {self.n_groups}:
            raise InvalidInputError(
                f"a group test needs 2 <= n_groups <= n_rows and both counts over n_groups; got "
                f"n_groups={self.n_groups}, n_rows={self.n_rows}"
            )
        if self.sample.violations > self.trajectory.violations:
            raise InvalidInputError(
                "a group whose random sample violates has a violation: sample <= trajectory"
            )
        if self.compared_unit is not None and self.compared_unit not in GROUP_UNITS:
            raise InvalidInputError(
                f"compared_unit must be one of {GROUP_UNITS} or None; got {self.compared_unit!r}"
            )

    @property
    def compared(self) -> TestResult | None:
        """The statistic checked against the calibration (None if none was)."""
        return None if self.compared_unit is None else self.result(self.compared_unit)

    def result(self, unit: GroupUnit) -> TestResult | None:
        """The test result of one statistic (None if it was not computed)."""
        return {
            "trajectory": self.trajectory,
            "sample": self.sample,
            "share": self.share,
            "share-of-runs": self.share_of_runs,
        }[unit]

    def sentence(self) -> str:
        """What the group counts say, in one or two sentences."""
        t, s = self.trajectory, self.sample
        conf = f"{1 - t.delta:.6g}"
        if self.share is not None:
            expected = (
                f"the expected share of a new group's samples outside their sets is at most "
                f"{self.share.bound_text()} (mean share {100 * self.share.empirical_rate:.3g} % over "
                f"{self.share.n} "
                "groups, every row counted)"
            )
        else:
            expected = (
                f"a random sample of a new group violates with probability at most {s.bound_text()} "
                f"({s.violations} of {s.n} randomly chosen samples outside)"
            )
        text = (
            f"Counted per group of {self.column!r} ({self.n_groups} test groups, {self.n_rows} rows; "
            "valid if the test groups are i.i.d., whatever the correlation within a group): with confidence "
            f"{conf}, {expected}, and a new group leaves its sets somewhere with probability at most "
            f"{t.bound_text()} ({t.violations} of {t.n} groups)."
        )
        if self.share_of_runs is not None:
            r = self.share_of_runs
            text += f" {r.violations} of {r.n} groups have more of their rows outside than the claim allows."
        c = self.consistency
        if c.checked and not c.consistent:
            text += (
                f" The group-level {self.compared_unit} count CONTRADICTS the calibration: its lower bound "
                f"{c.test_lower_bound:.4g} exceeds the allowed rate {c.allowed_rate:.4g}."
            )
        return text

    def to_dict(self) -> dict[str, Any]:
        """``{column, n_groups, n_rows, seed, trajectory, sample, compared_unit, consistency, statement}``."""
        return {
            "column": self.column,
            "n_groups": self.n_groups,
            "n_rows": self.n_rows,
            "seed": self.seed,
            "trajectory": self.trajectory.to_dict(),
            "sample": self.sample.to_dict(),
            "share": None if self.share is None else self.share.to_dict(),
            "share_of_runs": None if self.share_of_runs is None else self.share_of_runs.to_dict(),
            "compared_unit": self.compared_unit,
            "consistency": self.consistency.to_dict(),
            "statement": self.sentence(),
            "assumption": "test groups i.i.d. from deployment; rows within a group may be correlated",
        }
