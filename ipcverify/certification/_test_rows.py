"""Which test rows a certificate's test counts: fresh rows, each distinct row once.

:func:`fresh_test_rows` is the step of :func:`~ipcverify.certification.certify` that looks up
every test row's fingerprint (:mod:`ipcverify.data._fingerprints`) among the training and
calibration rows the model file records:

* a test row that is a training or calibration row -- in any order, subset or number of
  repeats -- is not fresh: the test data are **refused** (one such row is enough), with the
  number of rows of each set they hold. A test that drops them instead could not tell a chance
  coincidence from reuse, and a reused file is a mistake to fix, not to certify around;
* a test row that repeats an earlier test row is one sample: the test counts **each distinct row
  once**, and the certificate says how many were repeats. Test data made mostly of repeats
  (fewer distinct rows than :data:`~ipcverify.data._checks.MIN_DISTINCT_SHARE` of them) are
  refused, as for training and calibration.

A model file written before row fingerprints records none: then only an exact copy of the whole
file is refused (its content hash, :func:`~ipcverify.certification.check_inputs`), and
:class:`TestRows` says that the overlap could not be checked row by row. For the training rows,
the training data given to ``certify`` (for Theorem 1) are used when the model records none.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any, Literal

from ipcverify.certification._summary import Check
from ipcverify.contract._model import IPCModel
from ipcverify.data._checks import MIN_DISTINCT_SHARE
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._fingerprints import (
    SCHEME,
    Role,
    count_recorded,
    first_occurrences,
    recorded_rows,
    row_fingerprints,
)
from ipcverify.errors import DataError, DataWarning, Hint, InvalidInputError

#: How the test rows were checked against a set of rows: every row by fingerprints (recorded in the
#: model file, or computed from the training data given), an exact copy of the file only (a model
#: file from before row fingerprints), or not at all (nothing recorded; no calibration).
Checked = Literal["rows", "training data given", "file", "none", "not calibrated"]
_HOW: dict[Checked, str] = {
    "rows": "every row, by the row fingerprints the model file records",
    "training data given": "every row, against the training data given to certify",
    "file": "an exact copy of the whole file only: the model file records no row fingerprints",
    "none": "not at all: the model file records neither row fingerprints nor a hash of these rows",
    "not calibrated": "nothing to check: the model is not calibrated",
}


@dataclass(frozen=True, kw_only=True)
class TestRows:
    """The ``test_rows`` block of ``certificate.json``: the test rows counted, and how they were checked.

    Attributes
    ----------
    n : int
        Rows of the test data.
    distinct : int
        Distinct rows (by fingerprint): the rows the test counts, each once.
    training, calibration : str
        How the test rows were checked against the training and the calibration rows (a key of
        :data:`Checked`). Test data with a row of either set are refused, so every row checked is
        fresh.

    Examples
    --------
    >>> t = TestRows(n=10, distinct=8, training="rows", calibration="file")
    >>> t.repeated, t.unchecked()
    (2, ('calibration',))
    """

    __test__ = False  # not a pytest test class

    n: int
    distinct: int
    training: Checked
    calibration: Checked

    def __post_init__(self) -> None:
        if not (1 <= self.distinct <= self.n):
            raise InvalidInputError(f"test rows: need 1 <= distinct <= n; got {self.distinct} of {self.n}")
        for how in (self.training, self.calibration):
            if how not in _HOW:
                raise InvalidInputError(f"test rows: unknown check {how!r}; one of {', '.join(_HOW)}")

    @property
    def repeated(self) -> int:
        """Rows that repeat an earlier row (not counted again)."""
        return self.n - self.distinct

    def unchecked(self) -> tuple[Role, ...]:
        """The sets whose overlap with the test rows could not be checked row by row."""
        sets: tuple[tuple[Role, Checked], ...] = (
            ("training", self.training),
            ("calibration", self.calibration),
        )
        return tuple(role for role, how in sets if how in ("file", "none"))

    def sentence(self) -> str:
        """What the test counted, in words (for the held-out test's line).

        Examples
        --------
        >>> TestRows(n=300, distinct=300, training="rows", calibration="rows").sentence()
        'counted on 300 distinct test rows, none of them a training or calibration row (row fingerprints)'
        """
        roles = ("training", "calibration")
        fresh = [role for role in roles if getattr(self, role) in ("rows", "training data given")]
        none = f", none of them a {' or '.join(fresh)} row (row fingerprints)" if fresh else ""
        unknown = [role for role in roles if getattr(self, role) == "none"]  # a model built outside train
        if unknown:
            none += f"; the model records nothing of its {' or '.join(unknown)} rows to compare them with"
        return f"counted on {self.distinct:,} distinct test rows{none}"

    def how(self, role: Role) -> str:
        """How the test rows were checked against the ``role`` rows, in words."""
        return _HOW[self.training if role == "training" else self.calibration]

    def check(self) -> Check | None:
        """The summary's line on the test rows when there is news: repeats, or a model file too old to check.

        A model that records nothing of its training rows (a network not trained by ipcverify) gets
        no line: :meth:`sentence` says so on the held-out test's.

        Examples
        --------
        >>> TestRows(n=10, distinct=10, training="rows", calibration="rows").check() is None
        True
        >>> TestRows(n=10, distinct=5, training="file", calibration="rows").check().verdict
        '5 repeated rows counted once; overlap with training rows not checked'
        """
        verdicts, details = [], []
        if self.repeated:
            verdicts.append(f"{self.repeated:,} repeated rows counted once")
            details.append(
                f"{self.repeated:,} of {self.n:,} test rows repeat an earlier row; a repeated row is one "
                f"sample, so the test counts the {self.distinct:,} distinct rows once each (counting the "
                "repeats would tighten the bound without new evidence)"
            )
        old = [role for role in self.unchecked() if getattr(self, role) == "file"]  # from before fingerprints
        for role in old:
            verdicts.append(f"overlap with {role} rows not checked")
            details.append(
                f"the model file records no fingerprints of its {role} rows (written before ipcverify "
                f"recorded them): only an exact copy of the {role} file was refused; test rows that are "
                f"{role} rows in another order, a subset or repeated would count as fresh -- "
                f"{'retrain' if role == 'training' else 'recalibrate'} with this ipcverify to record them"
            )
        if not verdicts:
            return None
        return Check(
            name="fresh test rows", verdict="; ".join(verdicts), level="warn", detail="; ".join(details)
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""

        def check(how: Checked) -> dict[str, Any]:
            by_rows = how in ("rows", "training data given")
            return {"checked": how, "by_rows": by_rows, "overlap": 0 if by_rows else None, "how": _HOW[how]}

        return {
            "rows": self.n,
            "distinct": self.distinct,
            "repeated": self.repeated,
            "counted": self.distinct,
            "training_rows": check(self.training),
            "calibration_rows": check(self.calibration),
            "fingerprint": SCHEME,
        }


def fresh_test_rows(
    model: IPCModel, test_data: PerceptionDataset, train_data: PerceptionDataset | None = None
) -> tuple[PerceptionDataset, TestRows]:
    """The test data's distinct rows, and what was checked; refuse rows that are training or calibration rows.

    Parameters
    ----------
    model : IPCModel
        The model (its recorded row fingerprints).
    test_data : PerceptionDataset
        The test data (dimensions already checked).
    train_data : PerceptionDataset, optional
        The training data given to certify: the training rows when the model records none.

    Raises
    ------
    InvalidInputError
        If some test rows are training or calibration rows (the message counts them per set).
    DataError
        If most test rows repeat another (fewer distinct rows than half of them).

    Warns
    -----
    DataWarning
        If some test rows repeat an earlier one (each distinct row is counted once).
    Hint
        If the model file records no fingerprints of its training or calibration rows, but a
        hash of the file (written before row fingerprints): the overlap is checked for an exact
        copy only.

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify import example
    >>> from ipcverify.network import ModelConfig
    >>> from ipcverify import calibrate
    >>> cal = example(500, seed=1).data
    >>> net = example(config=ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")).model.network
    >>> m = calibrate(IPCModel(net), cal, 0.1, 0.05)
    >>> test = example(200, seed=2).data
    >>> twice = PerceptionDataset(*(np.vstack([a, a]) for a in (test.x, test.y, test.yhat)))
    >>> rows, record = fresh_test_rows(m, twice)
    >>> len(rows), record.repeated, record.calibration
    (200, 200, 'rows')
    >>> shuffled = cal.subset(np.random.default_rng(0).permutation(500)[:499])
    >>> fresh_test_rows(m, shuffled)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ipcverify.errors.InvalidInputError: synthetic[subset]: 499 of 499 test rows are rows of the calibration...
    """
    fingerprints = row_fingerprints(test_data)
    found: dict[Role, int] = {}
    how: dict[Role, Checked] = {}
    for role in ("calibration", "training"):
        recorded = recorded_rows(model.metadata, role)
        how[role] = "rows"
        if recorded is None and role == "training" and train_data is not None:
            recorded, how[role] = row_fingerprints(train_data), "training data given"
        if recorded is not None:
            found[role] = count_recorded(fingerprints, recorded)
        elif role == "calibration" and model.calibration is None:
            how[role] = "not calibrated"
        else:
            hashed = model.metadata.get("train_data_hash") if role == "training" else model.calibration
            how[role] = "file" if hashed is not None else "none"
    n = len(fingerprints)
    if reused := [f"{k:,} of {n:,} test rows are rows of the {role} data" for role, k in found.items() if k]:
        raise InvalidInputError(
            f"{test_data.source}: {', and '.join(reused)} (by their row fingerprints); a test counts only "
            "fresh rows, used neither for training nor for calibration -- certify on held-out rows (e.g. the "
            "test part of a split), or remove those rows"
        )
    first = first_occurrences(fingerprints)
    distinct = len(first)
    if distinct < math.ceil(MIN_DISTINCT_SHARE * n):
        raise DataError(
            f"{test_data.source}: only {distinct} distinct row{'s' if distinct != 1 else ''} among {n} test "
            "rows: a repeated row is one sample, so the test would count most rows again -- remove the "
            "duplicates or check how the file was assembled"
        )
    record = TestRows(n=n, distinct=distinct, training=how["training"], calibration=how["calibration"])
    for role in (r for r in record.unchecked() if how[r] == "file"):  # a model file from before fingerprints
        warnings.warn(
            Hint(
                f"{test_data.source}: the model file records no fingerprints of its {role} rows (an "
                f"ipcverify before row fingerprints wrote it), so only an exact copy of the {role} file was "
                f"refused: test rows that are {role} rows in another order, a subset or repeated would count "
                "as fresh"
            ),
            stacklevel=3,
        )
    if distinct == n:
        return test_data, record
    warnings.warn(
        DataWarning(
            f"{test_data.source}: {n - distinct:,} of {n:,} test rows repeat an earlier row; a repeated row "
            f"is one sample, so the test counts the {distinct:,} distinct rows once each"
        ),
        stacklevel=3,
    )
    rows = PerceptionDataset(
        test_data.x[first],
        test_data.y[first],
        test_data.yhat[first],
        source=test_data.source,
        x_columns=test_data.x_columns,
        y_columns=test_data.y_columns,
        yhat_columns=test_data.yhat_columns,
        extra={k: v[first] for k, v in test_data.extra.items()},
    )
    return rows, record
