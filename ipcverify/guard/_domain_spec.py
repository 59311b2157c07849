"""The options of the domain-of-validity test that :func:`~ipcverify.contract.calibrate` fits.

:class:`DomainSpec` owns them (false-alarm rate, the column whose groups are the exchangeable
units, neighbour rank, seed) and builds the :class:`~ipcverify.guard.DomainModel` on the
calibration inputs; ``calibrate(..., domain=None)`` fits none.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

from ipcverify._wording._spelling import option
from ipcverify.calibration._bounds import min_calibration_size, smallest_marginal_epsilon
from ipcverify.calibration._threshold import check_seed
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._split import group_codes
from ipcverify.errors import Hint, InvalidInputError
from ipcverify.guard._domain import DEFAULT_FLAG_RATE, DEFAULT_K, DomainModel


@dataclass(frozen=True, kw_only=True)
class DomainSpec:
    """How to fit the domain-of-validity test on the calibration inputs.

    Parameters
    ----------
    flag_rate : float, optional
        False-alarm rate: an input exchangeable with the calibration inputs is flagged with
        probability at most ``flag_rate`` (``proofs/domain.md``). Default (None):
        :data:`~ipcverify.guard.DEFAULT_FLAG_RATE`, or, for a test fitted by groups too few for it,
        the smallest rate they allow (``1 / (G + 1)`` rounded up), with a
        :class:`~ipcverify.errors.Hint` that says so.
    group_column : str, optional
        Fit the test with the groups of this column (flights, runs) as the exchangeable units
        (leave-one-group-out distances, risk-control threshold: a new group's expected share of
        flagged queries is at most ``flag_rate``). Defaults to the calibration method's unit column
        (:attr:`~ipcverify.calibration.Grouped.unit_column`). Without it, calibration rows of one
        flight sit close to each other and a row-level threshold flags much of a *new* flight.
    k : int
        Neighbour rank of the distance.
    seed : int
        Seeds the choice of the reference subset when there are more than
        :data:`~ipcverify.guard.MAX_REFERENCE` calibration inputs.

    Examples
    --------
    >>> from ipcverify import example
    >>> DomainSpec(flag_rate=0.05).fit(example(500, seed=1).data).flag_rate
    0.05
    >>> DomainSpec().fit(example(500, seed=1).data).flag_rate
    0.01
    >>> DomainSpec(flag_rate=2.0)
    Traceback (most recent call last):
    ...
    ipcverify.errors.InvalidInputError: domain test: flag_rate must lie strictly between 0 and 1; got 2.0
    """

    flag_rate: float | None = None
    group_column: str | None = None
    k: int = DEFAULT_K
    seed: int = 0

    def __post_init__(self) -> None:
        if self.flag_rate is not None and (
            isinstance(self.flag_rate, bool)
            or not (isinstance(self.flag_rate, (int, float)) and 0.0 < self.flag_rate < 1.0)
        ):
            got = self.flag_rate
            raise InvalidInputError(
                f"domain test: {option('flag_rate')} must lie strictly between 0 and 1; got {got!r}"
            )
        if isinstance(self.k, bool) or not (isinstance(self.k, int) and self.k >= 1):
            raise InvalidInputError(f"domain test: k must be a positive integer; got {self.k!r}")
        if self.group_column is not None and not (isinstance(self.group_column, str) and self.group_column):
            raise InvalidInputError(
                f"domain test: group_column must be a column name; got {self.group_column!r}"
            )
        check_seed(self.seed)

    def units(self, unit_column: str | None = None) -> str | None:
        """The column whose groups are the exchangeable units: ``group_column``, else ``unit_column``."""
        return unit_column if self.group_column is None else self.group_column

    def fit(self, data: PerceptionDataset, unit_column: str | None = None) -> DomainModel:
        """Fit the test on the inputs ``(x, yhat)`` of ``data``.

        Parameters
        ----------
        data : PerceptionDataset
            The calibration data.
        unit_column : str, optional
            The calibration method's unit column, used when ``group_column`` is not given.

        Raises
        ------
        SampleSizeError
            If there are too few inputs (or groups) for ``flag_rate``.
        DataError
            If ``data`` has no such group column.
        """
        column = self.units(unit_column)
        groups = None if column is None else data.column(column)
        flag_rate = self.flag_rate
        if flag_rate is None:
            flag_rate = DEFAULT_FLAG_RATE
            if groups is not None:
                _, labels = group_codes(groups, f"{data.source}: group column {column!r}")
                G, need = len(labels), min_calibration_size(DEFAULT_FLAG_RATE, 0.5, "marginal")
                if G < need:
                    flag_rate = smallest_marginal_epsilon(G)
                    warnings.warn(
                        Hint(_too_few_groups(data.source, G, column, need, flag_rate)), stacklevel=3
                    )
        return DomainModel.fit(
            data.x, data.yhat, flag_rate=flag_rate, k=self.k, seed=int(self.seed), groups=groups
        )


def _too_few_groups(source: str, G: int, column: str | None, need: int, flag_rate: float) -> str:
    """The hint of a domain test that takes the smallest rate its groups allow."""
    return (
        f"{source}: the domain of validity is fitted with the {G} groups of {column!r} as its units, too few "
        f"for its default flag rate {DEFAULT_FLAG_RATE:g} ({need} are needed), so it uses {flag_rate:g}, "
        "the smallest they allow: a new group's expected share of queries flagged outside the domain is at "
        "most that"
    )
