"""What the domain test found on a batch of queries: the ``domain`` block of ``certificate.json``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from scipy import stats

from ipcverify._wording._spelling import regroup_domain
from ipcverify._wording._verdicts import domain_verdict
from ipcverify.calibration._bounds import smallest_marginal_epsilon
from ipcverify.calibration._share_bound import share_lower_bound
from ipcverify.errors import InvalidInputError

#: Level of the one-sided binomial test behind "far more queries outside than false alarms explain".
WELL_ABOVE_LEVEL = 1e-3


@dataclass(frozen=True, kw_only=True)
class DomainReport:
    """The ``domain`` block of ``certificate.json``: how many queries of a batch lie outside.

    Attributes
    ----------
    method : str
        The test, in words.
    flag_rate : float
        Its flag rate: the share of in-distribution queries it flags.
    threshold : float
        The whitened distance beyond which a query is flagged.
    n_reference : int
        Calibration inputs the test was fitted on.
    n, outside : int
        Queries checked and queries flagged.
    violations_inside, violations_outside : int or None
        Violations among the queries inside and outside the domain (None: no labels).
    row_level_column : str or None
        A column of the calibration data that names runs (flights, segments), when the test was
        fitted row by row. Rows of one run are near-copies of each other, so a row-level
        threshold is short, and queries of a new run fall outside more often than ``flag_rate``
        even without a shift; a share well above ``flag_rate`` then has two explanations. None: the
        test was fitted with whole groups, or no such column is known.
    row_level_groups : int or None
        How many groups of ``row_level_column`` the calibration data held (None: not known),
        for the smallest ``--domain-flag-rate`` a test fitted by group allows.
    run_column : str or None
        When the queries come in runs: the column that names them (the claim's, or the queries'
        one run-like column); then "far more outside than false alarms explain" is decided with
        the runs as the units (their shares outside), not the correlated rows.
    run_shares : tuple of float or None
        Each run's share of queries outside the domain (with ``run_column``).

    Examples
    --------
    >>> r = DomainReport(method="knn", flag_rate=0.01, threshold=2.0, n_reference=100, n=50, outside=5)
    >>> r.outside_fraction, r.well_above_flag_rate
    (0.1, True)
    """

    method: str
    flag_rate: float
    threshold: float
    n_reference: int
    n: int
    outside: int
    violations_inside: int | None = None
    violations_outside: int | None = None
    row_level_column: str | None = None
    row_level_groups: int | None = None
    run_column: str | None = None
    run_shares: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if (self.run_column is None) != (self.run_shares is None) or (
            self.run_shares is not None and not all(0.0 <= v <= 1.0 for v in self.run_shares)
        ):
            raise InvalidInputError("run shares in [0, 1] go with the run column, and only with it")
        if not (0 <= self.outside <= self.n):
            raise InvalidInputError(f"need 0 <= outside <= n; got {self.outside}, {self.n}")
        if self.row_level_column is not None and not self.row_level_column.strip():
            raise InvalidInputError("a row-level column is named by a non-empty string")
        if self.row_level_groups is not None and (self.row_level_column is None or self.row_level_groups < 2):
            raise InvalidInputError(
                f"row_level_groups counts the groups (>= 2) of row_level_column; got {self.row_level_groups}"
            )

    def sentence(self) -> str:
        """What the domain test found and what the certificate does (not) promise, in words."""
        if self.n == 0:
            return (
                f"The domain of validity is the region within distance {self.threshold:.3g} (whitened) of "
                f"the {self.n_reference} calibration inputs; queries beyond it are flagged, and "
                f"in-distribution queries are flagged at a rate of at most {self.flag_rate:g}."
            )
        text = (
            f"{self.outside} of {self.n} queries ({100 * self.outside_fraction:.2f} %) lie outside the "
            f"domain of validity (in-distribution queries are flagged at most {100 * self.flag_rate:g} % of "
            "the time)"
        )
        if self.outside == 0:
            return text + "."
        text += (
            "; the certificate promises nothing for them: they are unlike every calibration sample, so "
            "the exchangeability it rests on fails there"
        )
        if self.violations_outside is not None and self.violations_inside is not None:
            inside = self.n - self.outside
            rate_in = self.violations_inside / inside if inside else float("nan")
            text += (
                f" (violations: {self.violations_outside} of {self.outside} outside, "
                f"{self.violations_inside} of {inside} inside"
                + (f", {100 * rate_in:.2f} %" if inside else "")
                + ")"
            )
        if self.run_shares is not None:
            text += (
                f"; counted by its {len(self.run_shares)} runs of {self.run_column!r}, a run's mean share "
                f"outside is {100 * sum(self.run_shares) / len(self.run_shares):.2f} %"
            )
        if self.well_above_flag_rate:
            text += ". That is far more than false alarms explain: the deployment data have shifted"
            if (col := self.row_level_column) is not None:
                text += (
                    f", or the test, fitted row by row while rows of one {col} are near-copies of each "
                    f"other, has a threshold too short for a new {col}; refit it with whole groups "
                    f"({regroup_domain(col, self.regroup_flag_rate)}) to tell the two apart"
                )
        return text + "."

    @property
    def regroup_flag_rate(self) -> float | None:
        """The flag rate a test refitted by :attr:`row_level_column` needs, if above :attr:`flag_rate`.

        The test by groups needs a flag rate of at least ``1 / (G + 1)`` with ``G`` groups; None
        when the current rate is enough, or the number of groups is not known.

        Examples
        --------
        >>> DomainReport(method="knn", flag_rate=0.01, threshold=1.0, n_reference=400, n=0, outside=0,
        ...              row_level_column="run", row_level_groups=10).regroup_flag_rate  # 1/11, rounded up
        0.091
        """
        if self.row_level_groups is None:
            return None
        smallest = smallest_marginal_epsilon(self.row_level_groups)
        return smallest if smallest > self.flag_rate else None

    @property
    def outside_fraction(self) -> float:
        """Share of the queries outside the domain (0 for an empty batch)."""
        return self.outside / self.n if self.n else 0.0

    @property
    def well_above_flag_rate(self) -> bool:
        """The outside share is above what false alarms explain, at level 0.001.

        With the queries' runs known (:attr:`run_shares`, two or more runs), the runs' mean share
        outside is tested (its betting lower bound exceeds ``flag_rate``), since the rows of a run are
        correlated; otherwise the rows (a one-sided binomial test).
        """
        if self.n == 0 or self.outside == 0:
            return False
        if self.run_shares is not None and len(self.run_shares) >= 2:
            return bool(share_lower_bound(self.run_shares, WELL_ABOVE_LEVEL) > self.flag_rate)
        return bool(stats.binom.sf(self.outside - 1, self.n, self.flag_rate) < WELL_ABOVE_LEVEL)

    @property
    def verdict(self) -> str:
        """The domain verdict of these facts, as the wording layer words it (summary, CLI and page alike)."""
        return domain_verdict(
            present=True,
            radius_zero=self.threshold == 0,
            queries=self.n,
            well_above=self.well_above_flag_rate,
            row_level=self.row_level_column is not None,
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (the keys of ``certificate.json["domain"]``)."""
        return {
            "method": self.method,
            "flag_rate": self.flag_rate,
            "threshold": self.threshold,
            "n_reference": self.n_reference,
            "n": self.n,
            "outside": self.outside,
            "outside_fraction": self.outside_fraction,
            "well_above_flag_rate": self.well_above_flag_rate,
            "violations_inside": self.violations_inside,
            "violations_outside": self.violations_outside,
            "row_level_column": self.row_level_column,
            "row_level_groups": self.row_level_groups,
            "run_column": self.run_column,
            "runs": None if self.run_shares is None else len(self.run_shares),
            "run_mean_outside": None
            if self.run_shares is None
            else sum(self.run_shares) / len(self.run_shares),
            "statement": self.sentence(),
        }
