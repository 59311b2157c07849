"""Violations of test data counted per group (flight, run), and the choice of one sample per group.

Rows of one group are correlated, so a binomial bound on rows is not valid; one statistic per
group is, if the groups are i.i.d. The statistics (``GROUP_STATISTICS``): any sample of the group
outside its set (``"trajectory"``), one sample drawn at random (seeded) from it outside
(``"sample"``), its share of rows outside (``"share"``, a value in ``[0, 1]``), or whether that share
exceeds a limit (``"share-of-runs"``). The guarantees of
:class:`~ipcverify.calibration.GroupedCalibration` (``GUARANTEES``) are checked with them.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.data._split import group_codes
from ipcverify.errors import InvalidInputError

IntArray = NDArray[np.intp]
#: What a claim about runs bounds: a new run's expected share of rows outside, the share of new runs
#: with more than epsilon of their rows outside, or the probability that a new run leaves its sets anywhere.
GuaranteeKind = Literal["expected-share", "share-of-runs", "trajectory"]
#: The three run-level guarantees.
GUARANTEES: tuple[GuaranteeKind, ...] = ("expected-share", "share-of-runs", "trajectory")
#: Earlier names of a guarantee, still read from model files and accepted from Python.
LEGACY_GUARANTEES: dict[str, GuaranteeKind] = {"sample": "expected-share"}
#: The count statistics of a test group (the ``"share"`` statistic is a value, not a count).
CountStatistic = Literal["trajectory", "sample"]


def check_guarantee(guarantee: str) -> GuaranteeKind:
    """The guarantee's name, refused unless it is one of ``GUARANTEES`` (or an earlier name of one).

    Examples
    --------
    >>> check_guarantee("sample")
    'expected-share'
    """
    if guarantee in LEGACY_GUARANTEES:
        return LEGACY_GUARANTEES[guarantee]
    if guarantee not in GUARANTEES:
        raise InvalidInputError(
            "guarantee must be 'expected-share' (a new run's expected share of rows outside its sets), "
            "'share-of-runs' (the share of new runs with more than epsilon of their rows outside) or "
            f"'trajectory' (every row of a new run inside); got {guarantee!r}"
        )
    return guarantee  # type: ignore[return-value]


def allowed_outside(epsilon: float, size: int) -> int:
    """``floor(epsilon * size)`` in exact arithmetic: the rows a run of ``size`` may have outside.

    Examples
    --------
    >>> allowed_outside(0.1, 30), allowed_outside(0.1, 9), allowed_outside(0.29, 100)
    (3, 0, 28)
    """
    return int(Fraction(epsilon) * int(size))


def group_shares(
    violated: ArrayLike, groups: ArrayLike, what: str = "test groups"
) -> tuple[NDArray[np.float64], IntArray, IntArray]:
    """Each group's share of rows outside their sets, its count of such rows and its size (label order).

    Parameters
    ----------
    violated : array_like of bool, shape (N,)
        Whether each row lies outside its set.
    groups : array_like, shape (N,)
        Each row's group label (flight, run; none missing).
    what : str
        How to name the labels in an error.

    Examples
    --------
    >>> shares, outside, sizes = group_shares([True, False, False, False], ["a", "a", "b", "b"])
    >>> shares.tolist(), outside.tolist(), sizes.tolist()
    ([0.5, 0.0], [1, 0], [2, 2])
    """
    bad = np.asarray(violated, dtype=bool).ravel()
    codes, labels = group_codes(groups, what)
    if len(codes) != len(bad):
        raise InvalidInputError(f"{len(bad)} violation flags but {len(codes)} group labels; give one per row")
    G = len(labels)
    sizes = np.bincount(codes, minlength=G).astype(np.intp)
    outside = np.bincount(codes, weights=bad.astype(np.float64), minlength=G).astype(np.intp)
    return outside / sizes, outside, sizes


def group_layout(codes: IntArray, n_groups: int) -> tuple[IntArray, IntArray, IntArray]:
    """Rows sorted by group (stable), each group's first position in that order, group sizes."""
    order = np.argsort(codes, kind="stable")
    sizes = np.bincount(codes, minlength=n_groups).astype(np.intp)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.intp)
    return order, starts, sizes


def one_per_group(codes: IntArray, n_groups: int, seed: int) -> IntArray:
    """Row index of one sample per group, uniformly at random within the group (seeded)."""
    order, starts, sizes = group_layout(codes, n_groups)
    u = np.random.default_rng(seed).random(n_groups)
    pick = np.minimum((u * sizes).astype(np.intp), sizes - 1)
    return order[starts + pick]


@dataclass(frozen=True, kw_only=True)
class GroupViolations:
    """``violations`` of ``n_groups`` test groups, one statistic per group (:func:`group_violation_counts`).

    ``unit="trajectory"``: a group counts if any of its samples violates; ``"sample"``: if one
    sample drawn at random (seeded) from it violates.

    Attributes
    ----------
    violations : int
        Test groups whose statistic is a violation, ``0 <= violations <= n_groups``.
    n_groups : int
        Test groups ``G >= 1`` (the binomial sample size of a test on these counts).
    unit : {"trajectory", "sample"}
        The statistic of a group, as above.
    """

    violations: int
    n_groups: int
    unit: CountStatistic

    def __post_init__(self) -> None:
        _check_statistic(self.unit)
        if not (0 <= self.violations <= self.n_groups and self.n_groups >= 1):
            raise InvalidInputError(f"need 0 <= violations <= n_groups, n_groups >= 1; got {self}")


def _check_statistic(unit: str) -> None:
    if unit not in ("trajectory", "sample"):
        raise InvalidInputError(f"a group count is 'trajectory' or 'sample'; got {unit!r}")


def group_violation_counts(
    violated: ArrayLike, groups: ArrayLike, unit: CountStatistic, seed: int = 0
) -> GroupViolations:
    """Count violations per test group, so that a binomial test is valid for correlated samples.

    Rows of one group are correlated, so a Clopper--Pearson bound from row counts is not
    valid; one statistic per group is, if the test groups are i.i.d. For ``unit="trajectory"``
    its mean is the probability that a group leaves its sets somewhere; for ``"sample"`` (one
    random sample per group) it is ``E[V_new]``, the expected violation fraction of a group.

    Parameters
    ----------
    violated : array_like of bool, shape (N,)
        Whether each test sample lies outside its set.
    groups : array_like, shape (N,)
        Each sample's group label (flight, run; numbers or strings, none missing).
    unit : {"trajectory", "sample"}
        The statistic of a group: any of its samples violates, or one sample drawn uniformly
        at random from it does.
    seed : int
        Seeds the draw of one sample per group (``unit="sample"`` only; ignored otherwise).

    Returns
    -------
    GroupViolations
        Violating groups among the ``G`` distinct labels.

    Raises
    ------
    InvalidInputError
        If ``unit`` is unknown, the lengths differ, or a label is missing.

    Examples
    --------
    >>> v = np.array([False, True, False, False, False, False])
    >>> group_violation_counts(v, [1, 1, 2, 2, 3, 3], "trajectory")
    GroupViolations(violations=1, n_groups=3, unit='trajectory')
    """
    _check_statistic(unit)
    bad = np.asarray(violated, dtype=bool).ravel()
    codes, labels = group_codes(groups, "test groups")
    if len(codes) != len(bad):
        raise InvalidInputError(f"{len(bad)} violation flags but {len(codes)} group labels; give one per row")
    G = len(labels)
    if unit == "trajectory":
        count = int((np.bincount(codes, weights=bad.astype(np.float64), minlength=G) > 0).sum())
    else:
        count = int(bad[one_per_group(codes, G, seed)].sum())
    return GroupViolations(violations=count, n_groups=G, unit=unit)
