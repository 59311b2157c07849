"""The test counted per group (flight, run): a certificate's check that stays valid for correlated rows.

A row-level Clopper--Pearson bound on test violations assumes independent rows. Rows of one
flight share its conditions, so they are correlated and that interval is too narrow. Counting
one statistic per test group -- any violation (``trajectory``), or one seeded random sample
(``sample``; :func:`~ipcverify.calibration.group_violation_counts`) -- gives one
Bernoulli draw per group, i.i.d. when the test groups are, whatever happens within a group;
the exact binomial bounds then hold (``proofs/group_calibration.md`` section 6).
:func:`group_test_step` is the step of :func:`ipcverify.certification.certify` that does it; the
record is :class:`ipcverify.certification.GroupTest`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ipcverify._wording._spelling import option
from ipcverify.calibration._group_counts import (
    CountStatistic,
    allowed_outside,
    group_shares,
    group_violation_counts,
)
from ipcverify.calibration._protocol import Calibration, GroupUnit
from ipcverify.certification._test_result import Consistency, GroupTest, TestResult
from ipcverify.data._checks import group_like_counts
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._split import group_codes
from ipcverify.errors import InvalidInputError


def _group_labels(test_data: PerceptionDataset, column: str) -> NDArray[np.intp]:
    """Group codes of the test rows; refuse an unknown column or a single group."""
    names = (*test_data.x_columns, *test_data.y_columns, *test_data.yhat_columns, *test_data.extra)
    if column not in names:
        raise InvalidInputError(
            f"{test_data.source}: no group column {column!r} in the test data (columns: {', '.join(names)}); "
            f"name the column of flights or runs, e.g. {option('group_column', 'run')}"
        )
    codes, distinct = group_codes(test_data.column(column), f"{test_data.source}: group column {column!r}")
    if len(distinct) < 2:
        raise InvalidInputError(
            f"{test_data.source}: group column {column!r} has one group only ({distinct.tolist()[0]!r}); a "
            "group-level test needs test data from several independent groups (flights, runs) -- add "
            f"more, or drop {option('group_column')}"
        )
    return codes


def group_test_step(
    cal: Calibration | None,
    test_data: PerceptionDataset,
    violated: NDArray[np.bool_],
    delta: float,
    group_column: str | None,
) -> GroupTest | None:
    """Step 3b: the test counted per group of a column (flights, runs), valid for correlated rows.

    The column is ``group_column``, else the column of a run-level calibration if the test data
    has it, else the test data's one column that names runs (:func:`group_like_counts`), else
    there is no group test (None). The counts of
    :func:`~ipcverify.calibration.group_violation_counts` are bounded at ``1 - delta``
    (one-sided Clopper--Pearson), and the mean of the groups' shares of rows outside by the
    betting bounds (:meth:`TestResult.from_shares`). The statistic checked against the
    calibration's allowed rate is the one its claim is about: for a run-level calibration its own
    (and seed, or share limit); for a row-level one the mean share (the expected share of a
    random group's rows, which is what a row-level claim promises when run lengths are unrelated
    to their violations); the trajectory count is then only reported (any violation in a long
    flight is no row-level event).

    Parameters
    ----------
    cal, test_data, violated, delta
        As for :func:`~ipcverify.certification.test_results`.
    group_column : str or None
        The test data's group column (None: the calibration's, if any).

    Raises
    ------
    InvalidInputError
        If the column is not in the test data or has one group only.

    Examples
    --------
    >>> from ipcverify import example
    >>> ds = example(40, seed=0).data
    >>> ds = PerceptionDataset(ds.x, ds.y, ds.yhat, extra={"run": np.repeat(np.arange(8), 5)})
    >>> violated = np.zeros(40, dtype=bool); violated[[0, 1, 7]] = True
    >>> g = group_test_step(None, ds, violated, 0.05, "run")
    >>> g.n_groups, g.trajectory.violations, round(g.share.empirical_rate, 4), g.compared_unit
    (8, 2, 0.075, None)
    """
    claim = None if cal is None else cal.group_claim()
    if group_column is None:
        if claim is None or claim.column not in test_data.extra:
            group_column = _run_column(test_data)
            if group_column is None:
                return None
        else:
            group_column = claim.column
    codes = _group_labels(test_data, group_column)
    own = claim is not None and claim.column == group_column
    seed = claim.seed if claim is not None and own else 0
    units: tuple[CountStatistic, ...] = ("trajectory", "sample")
    counts = {u: group_violation_counts(violated, codes, u, seed) for u in units}
    what = {"trajectory": "any violation", "sample": "one random sample each"}
    res: dict[GroupUnit, TestResult] = {
        u: TestResult.from_counts(c.violations, c.n_groups, delta, f"groups of {group_column} ({what[u]})")
        for u, c in counts.items()
    }
    shares, outside, sizes = group_shares(violated, codes)
    res["share"] = TestResult.from_shares(shares, delta, f"groups of {group_column}")
    if own and claim is not None and claim.share_limit is not None:
        over = sum(
            int(o) > allowed_outside(claim.share_limit, int(m)) for o, m in zip(outside, sizes, strict=True)
        )
        res["share-of-runs"] = TestResult.from_counts(
            over, len(sizes), delta, f"groups of {group_column} (more than {claim.share_limit:g} outside)"
        )
    compared: GroupUnit | None = None
    if cal is None:
        consistency = Consistency(checked=False, reason="no calibration")
    elif claim is not None and not own:
        consistency = Consistency(
            checked=False,
            reason=f"the calibration's claim is about groups of {claim.column!r}, not of {group_column!r}",
        )
    else:
        compared = "share" if claim is None else claim.unit
        consistency = Consistency.check(cal.allowed_violation_rate(), res[compared])
    return GroupTest(
        column=group_column,
        n_groups=len(sizes),
        n_rows=int(len(codes)),
        seed=seed,
        trajectory=res["trajectory"],
        sample=res["sample"],
        share=res["share"],
        share_of_runs=res.get("share-of-runs"),
        compared_unit=compared,
        consistency=consistency,
    )


def _run_column(test_data: PerceptionDataset) -> str | None:
    """The test data's one column that names its runs (None: none, or several, which ask a choice)."""
    runs = group_like_counts(test_data)
    return next(iter(runs)) if len(runs) == 1 else None
