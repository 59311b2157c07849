"""The spec of a grouped calibration: runs (flights, sequences) as the exchangeable units.

:class:`Grouped` is what a user passes to :func:`~ipcverify.contract.calibrate`; it fits a
:class:`~ipcverify.calibration.GroupedCalibration`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ipcverify.calibration._group_counts import GuaranteeKind, check_guarantee
from ipcverify.calibration._grouped import GroupedCalibration
from ipcverify.calibration._method import CalibrationRecord, CalibrationSample, CalibrationSpec
from ipcverify.calibration._threshold import check_seed
from ipcverify.errors import InvalidInputError


@dataclass(frozen=True, kw_only=True)
class Grouped(CalibrationSpec):
    """Grouped calibration, whole groups (flights, runs) as exchangeable units: a spec for ``calibrate()``.

    Parameters
    ----------
    column : str
        The column naming each calibration sample's group (any column of the data; it is not
        needed at predict time).
    guarantee : {"expected-share", "share-of-runs", "trajectory"}
        Bound a new group's expected share of samples outside their sets (``"expected-share"``,
        the default), the share of new groups with more than ``epsilon`` of their samples outside
        (``"share-of-runs"``, with ``gamma``), or the probability that a new group leaves its sets
        anywhere (``"trajectory"``). ``"sample"``, the earlier name of ``"expected-share"``, is
        accepted.
    gamma : float, optional
        ``"share-of-runs"`` only (required there): the share of new groups allowed more than
        ``epsilon`` outside.
    seed : int
        Recorded with the calibration.
    mode : {"pac", "marginal"}
        PAC (i.i.d. groups) or marginal (exchangeable groups) guarantee.

    Examples
    --------
    >>> Grouped(column="run").unit_column
    'run'
    >>> Grouped(column="run", guarantee="sample").guarantee
    'expected-share'
    >>> Grouped(column="run", guarantee="share-of-runs")
    Traceback (most recent call last):
    ...
    ipcverify.errors.InvalidInputError: a share-of-runs claim needs gamma, the share of new runs allowed \
more than epsilon of their rows outside (e.g. gamma=0.25)
    """

    column: str
    guarantee: GuaranteeKind = "expected-share"
    gamma: float | None = None
    seed: int = 0
    kind: ClassVar[str] = "grouped"
    record: ClassVar[CalibrationRecord] = GroupedCalibration

    def __post_init__(self) -> None:
        super().__post_init__()
        if not (isinstance(self.column, str) and self.column):
            raise InvalidInputError(f"a grouped calibration needs a group column name; got {self.column!r}")
        object.__setattr__(self, "guarantee", check_guarantee(self.guarantee))
        if self.guarantee == "share-of-runs":
            if self.gamma is None:
                raise InvalidInputError(
                    "a share-of-runs claim needs gamma, the share of new runs allowed more than epsilon of "
                    "their rows outside (e.g. gamma=0.25)"
                )
            _check_gamma(self.gamma)
        elif self.gamma is not None:
            raise InvalidInputError(
                f"gamma goes with the share-of-runs claim only, not with {self.guarantee!r}"
            )
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
            gamma=self.gamma,
            seed=self.seed,
            **sample.ids,
        )


def _check_gamma(gamma: float) -> None:
    if isinstance(gamma, bool) or not (isinstance(gamma, (int, float)) and 0.0 < gamma < 1.0):
        raise InvalidInputError(f"gamma must lie strictly between 0 and 1; got {gamma!r}")
