"""The options of the domain-of-validity test that :func:`~ipcverify.contract.calibrate` fits.

:class:`DomainSpec` owns them (false-alarm rate, the column whose groups are the exchangeable
units, neighbour rank, seed) and builds the :class:`~ipcverify.guard.DomainModel` on the
calibration inputs; ``calibrate(..., domain=None)`` fits none.
"""

from __future__ import annotations

from dataclasses import dataclass

from ipcverify.calibration._threshold import check_seed
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.guard._domain import DEFAULT_ALPHA, DEFAULT_K, DomainModel


@dataclass(frozen=True, kw_only=True)
class DomainSpec:
    """How to fit the domain-of-validity test on the calibration inputs.

    Parameters
    ----------
    alpha : float
        False-alarm rate: an input exchangeable with the calibration inputs is flagged with
        probability at most ``alpha`` (``proofs/domain.md``).
    group_column : str, optional
        Fit the test with the groups of this column (flights, runs) as the exchangeable units
        (leave-one-group-out distances, risk-control threshold: a new group's expected share of
        flagged queries is at most ``alpha``). Defaults to the calibration method's unit column
        (:attr:`~ipcverify.calibration.Grouped.unit_column`). Without it, calibration rows of one
        flight sit close to each other and a row-level threshold flags much of a *new* flight.
    k : int
        Neighbour rank of the distance.
    seed : int
        Seeds the choice of the reference subset when there are more than
        :data:`~ipcverify.guard.MAX_REFERENCE` calibration inputs.

    Examples
    --------
    >>> from ipcverify.data._synthetic import make_lagged_perception
    >>> DomainSpec(alpha=0.05).fit(make_lagged_perception(500, seed=1)).alpha
    0.05
    >>> DomainSpec(alpha=2.0)
    Traceback (most recent call last):
    ...
    ipcverify.errors.InvalidInputError: domain test: alpha must lie strictly between 0 and 1; got 2.0
    """

    alpha: float = DEFAULT_ALPHA
    group_column: str | None = None
    k: int = DEFAULT_K
    seed: int = 0

    def __post_init__(self) -> None:
        if isinstance(self.alpha, bool) or not (
            isinstance(self.alpha, (int, float)) and 0.0 < self.alpha < 1.0
        ):
            raise InvalidInputError(
                f"domain test: alpha must lie strictly between 0 and 1; got {self.alpha!r}"
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
            If there are too few inputs (or groups) for ``alpha``.
        DataError
            If ``data`` has no such group column.
        """
        column = self.units(unit_column)
        return DomainModel.fit(
            data.x,
            data.yhat,
            alpha=self.alpha,
            k=self.k,
            seed=int(self.seed),
            groups=None if column is None else data.column(column),
        )
