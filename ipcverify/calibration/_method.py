"""What a calibration kind's spec provides: the object a user passes to :func:`~ipcverify.contract.calibrate`.

A spec (:class:`CalibrationMethod`) is a frozen record of a kind's options that checks them
when it is made and fits the kind's calibration on a :class:`CalibrationSample`;
``calibrate()`` scores the data, builds the sample and calls ``fit`` without asking which kind
it holds. :class:`CalibrationSpec` is the base of the built-in specs (the mode, its check, rows
as the exchangeable units). The registry (:mod:`ipcverify.calibration._kinds`) maps kind names
to specs and their calibration classes (:class:`CalibrationRecord`), which read model files back.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

from ipcverify.calibration._bounds import CalibrationMode
from ipcverify.calibration._protocol import Calibration, FloatArray
from ipcverify.calibration._threshold import check_mode
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError


@dataclass(frozen=True, kw_only=True, eq=False)
class CalibrationSample:
    """What a spec fits on: the calibration rows' scores and data, the target, and the identities to record.

    Attributes
    ----------
    scores : ndarray, shape (N,)
        The network's raw scores ``g = ||C (y - c)||`` of the calibration rows.
    data : PerceptionDataset or None
        The calibration rows (columns a kind groups by are read from it).
    epsilon, delta : float
        Target violation rate and confidence parameter.
    data_hash, network_hash : str
        Identity of the calibration data and of the network, recorded in the calibration.

    Examples
    --------
    >>> import numpy as np
    >>> s = CalibrationSample(scores=np.ones(3), data=None, epsilon=0.1, delta=0.1, data_hash="d",
    ...                       network_hash="h")
    >>> s.ids
    {'data_hash': 'd', 'network_hash': 'h'}
    """

    scores: FloatArray
    data: PerceptionDataset | None
    epsilon: float
    delta: float
    data_hash: str
    network_hash: str

    @property
    def ids(self) -> dict[str, str]:
        """``data_hash`` and ``network_hash``, as keyword arguments of the calibration classes' ``fit``."""
        return {"data_hash": self.data_hash, "network_hash": self.network_hash}

    def rows(self) -> PerceptionDataset:
        """The calibration data (a kind that groups by a column needs it)."""
        if self.data is None:
            raise InvalidInputError(
                "this calibration kind reads a column of the calibration data; pass the data"
            )
        return self.data


class CalibrationRecord(Protocol):
    """A calibration class as a reader of its stored records (``cls.from_dict``)."""

    @property
    def kind(self) -> str:
        """The ``kind`` its records carry."""
        ...

    def from_dict(self, data: Mapping[str, Any]) -> Calibration:
        """Rebuild a calibration from its ``to_dict()`` form."""
        ...


class CalibrationMethod(Protocol):
    """A calibration kind as the user chooses it: a frozen spec of its options that fits the calibration."""

    #: The kind's name, the ``kind`` of the calibrations it fits (the registry's key).
    kind: ClassVar[str]
    #: The calibration class it fits, which reads its stored records back.
    record: ClassVar[CalibrationRecord]

    @property
    def unit_column(self) -> str | None:
        """The column whose groups (flights, runs) are the exchangeable units; None: the rows are."""
        ...

    def fit(self, sample: CalibrationSample) -> Calibration:
        """Calibrate on ``sample``; raises :class:`~ipcverify.errors.SampleSizeError` if it is too small."""
        ...


@dataclass(frozen=True, kw_only=True)
class CalibrationSpec:
    """The base of the built-in specs: the guarantee's mode (checked when made), rows as the units.

    Parameters
    ----------
    mode : {"pac", "marginal"}
        Training-conditional (PAC: with probability ``1 - delta`` over the calibration draw) or
        marginal (split conformal: on average over calibration draws) guarantee.
    """

    mode: CalibrationMode = "pac"

    def __post_init__(self) -> None:
        check_mode(self.mode)

    @property
    def unit_column(self) -> str | None:
        """None: the rows are the exchangeable units."""
        return None
