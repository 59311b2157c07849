"""Violations of test data counted per group (flight, run), and the choice of one sample per group.

Rows of one group are correlated, so a binomial bound on rows is not valid; one statistic per
group is, if the groups are i.i.d. The two statistics (``GUARANTEES``) are the two guarantees
of :class:`~ipcverify.calibration.GroupedCalibration`: any sample of the group outside its set
(``"trajectory"``), or one sample drawn at random (seeded) from it outside (``"sample"``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.data._split import group_codes
from ipcverify.errors import InvalidInputError

IntArray = NDArray[np.intp]
GuaranteeKind = Literal["trajectory", "sample"]  # = protocol.GroupUnit
#: The two guarantees: every sample of a new group inside (trajectory), or a per-sample rate.
GUARANTEES = ("trajectory", "sample")


def check_guarantee(guarantee: str) -> None:
    """Refuse a guarantee other than ``"trajectory"`` or ``"sample"``."""
    if guarantee not in GUARANTEES:
        raise InvalidInputError(
            f"guarantee must be 'trajectory' (every sample of a new group inside its set) or 'sample' "
            f"(the expected fraction of a new group's samples outside); got {guarantee!r}"
        )


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
    unit: GuaranteeKind

    def __post_init__(self) -> None:
        check_guarantee(self.unit)
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
    check_guarantee(unit)
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
