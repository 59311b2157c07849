"""Do a log's violations come in runs? The check behind the row-by-row monitor's caveat.

The monitor's row-by-row test (:class:`~ipcverify.guard.ViolationMonitor`) assumes that each row
violates with probability at most epsilon *given the rows before it*. Rows of a real log are
correlated -- ``ipcverify ingest`` writes 0.5 s displacements every 0.25 s, so neighbouring rows
share half their interval -- and their violations come in runs: after a violation, the next row
violates far more often than the overall rate. Such a log can raise the alarm although its
overall rate is within the calibration's: the rule is stated on the log's facts -- the rate of
violation right after a violation against the overall rate -- not on any one log.
:class:`ViolationRuns` measures that, so the alarm can say so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

from ipcverify._wording._spelling import option
from ipcverify.errors import InvalidInputError

#: Level of the one-sided binomial test behind "the violations come in runs".
RUNS_LEVEL = 1e-3


@dataclass(frozen=True)
class ViolationRuns:
    """How often a row right after a violation violated too, against the log's overall rate.

    Attributes
    ----------
    rows : int
        Rows in the log.
    violations : int
        Rows whose truth fell outside its set.
    after : int
        Rows that come right after a violation (the last row has no successor).
    violations_after : int
        Of those, the rows that violated too.

    Examples
    --------
    >>> bursts = ViolationRuns.of([0, 1, 1, 1, 0, 0, 0, 0, 0, 0] * 30)
    >>> bursts.rate, round(bursts.rate_after, 3), bursts.clustered
    (0.3, 0.667, True)
    >>> ViolationRuns.of([0, 1] * 50).clustered  # alternating: never twice in a row
    False
    """

    rows: int
    violations: int
    after: int
    violations_after: int

    def __post_init__(self) -> None:
        if not (
            0 <= self.violations <= self.rows and 0 <= self.violations_after <= self.after <= self.violations
        ):
            raise InvalidInputError(
                "violation runs: need 0 <= violations_after <= after <= violations <= rows; got "
                f"{self.violations_after}, {self.after}, {self.violations}, {self.rows}"
            )

    @classmethod
    def of(cls, violated: ArrayLike) -> ViolationRuns:
        """Count the runs of a log's violations, in the log's order.

        Parameters
        ----------
        violated : array_like of bool (B,)
            Per row: the truth fell outside its set.
        """
        v = np.asarray(violated)
        if v.ndim != 1:
            raise InvalidInputError(f"violation runs: need one flag per row; got shape {v.shape}")
        v = v.astype(bool)
        before = v[:-1]
        return cls(
            rows=len(v),
            violations=int(v.sum()),
            after=int(before.sum()),
            violations_after=int(v[1:][before].sum()),
        )

    @property
    def rate(self) -> float:
        """The log's overall violation rate (0 for an empty log)."""
        return self.violations / self.rows if self.rows else 0.0

    @property
    def rate_after(self) -> float:
        """The violation rate of the rows right after a violation (0 if there are none)."""
        return self.violations_after / self.after if self.after else 0.0

    @property
    def p_value(self) -> float:
        """Chance of at least ``violations_after`` if each row after a violation violated at ``rate``."""
        if self.violations_after == 0:
            return 1.0
        return float(stats.binom.sf(self.violations_after - 1, self.after, self.rate))

    @property
    def clustered(self) -> bool:
        """The violations come in runs: far more follow a violation than the overall rate explains."""
        return self.p_value < RUNS_LEVEL

    def sentence(self) -> str:
        """The finding in words, for an alarm raised row by row."""
        return (
            f"the violations come in runs (of the {self.after} rows right after a violation, "
            f"{self.violations_after} violated too, {100 * self.rate_after:.0f} %, against "
            f"{100 * self.rate:.1f} % of all rows): neighbouring rows are correlated, and such runs can "
            "raise this alarm even when the overall rate is within the calibration's; monitor one "
            f"observation per run or time block ({option('group_column', 'COL')}) to tell the two apart"
        )

    def to_dict(self) -> dict[str, float | int | bool]:
        """Plain data for ``monitor.json``."""
        return {
            "rows": self.rows,
            "violations": self.violations,
            "after_violation": self.after,
            "violations_after_violation": self.violations_after,
            "rate": self.rate,
            "rate_after_violation": self.rate_after,
            "p_value": self.p_value,
            "clustered": self.clustered,
        }
