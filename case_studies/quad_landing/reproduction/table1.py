"""Table I of the paper: the buffer-1 IPC's violation rate on test data at buffer sizes 1..5.

For each buffer size ``b`` the test set is flown on the same paths and flights (only the
camera lag differs); the row holds ``n``, the number of violations (``y`` outside the
calibrated ellipsoid), the rate, a one-sided Clopper--Pearson upper bound and a two-sided
interval. The intervals are simultaneous over the rows (Bonferroni: each row at
``delta / rows``), so "the rate rises with the buffer size" can be read off them.

The bounds treat the test samples as independent draws. They are not quite: they are
10 Hz samples along a few dozen continuous paths and flights, so neighbouring samples are
correlated and the intervals are somewhat too narrow. ``paths_with_violations`` counts
the distinct paths/flights a row's violations fall on, to show whether they cluster.

Examples
--------
>>> PAPER_TABLE1[1], PAPER_TABLE1[5]
(0.0019, 0.1105)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from case_studies.quad_landing.reproduction.record import Record
from ipcverify.calibration._bounds import clopper_pearson_interval, clopper_pearson_upper
from ipcverify.contract import IPCModel
from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError

__all__ = ["PAPER_TABLE1", "Table1Row", "RatesRising", "Table1", "table1", "table1_text"]

#: The paper's Table I: error of the IPC learned at buffer size 1, per buffer size.
PAPER_TABLE1: dict[int, float] = {1: 0.0019, 2: 0.0093, 3: 0.0205, 4: 0.0407, 5: 0.1105}


@dataclass(frozen=True, kw_only=True)
class Table1Row(Record):
    """One row of Table I: the IPC's violations on the test set of one buffer size.

    Attributes
    ----------
    buffer_size : int
        The test set's camera buffer size.
    n, violations : int
        Test samples, and those with ``y`` outside the calibrated ellipsoid.
    rate : float
        ``violations / n``.
    upper : float
        One-sided Clopper--Pearson upper bound of the rate.
    interval : (float, float)
        Two-sided Clopper--Pearson interval.
    confidence : float
        Simultaneous confidence of all rows' bounds.
    paper_rate : float or None
        The paper's rate at this buffer size.
    paths, paths_with_violations : int or None
        Distinct paths/flights in the test set, and those with a violation (None when the
        test set does not say which path a sample is from).
    """

    buffer_size: int
    n: int
    violations: int
    rate: float
    upper: float
    interval: tuple[float, float]
    confidence: float
    paper_rate: float | None
    paths: int | None
    paths_with_violations: int | None

    def __post_init__(self) -> None:
        if not 0 <= self.violations <= self.n:
            raise InvalidInputError(
                f"a Table I row needs 0 <= violations <= n, got {self.violations}/{self.n}"
            )

    def to_dict(self) -> dict[str, Any]:
        """The row as written to ``summary.json`` (``table1.<buffer size>``): the fields but the
        buffer size (the row's key), and the path counts only when the test set has paths."""
        out = super().to_dict()
        del out["buffer_size"]
        if self.paths is None:
            del out["paths"], out["paths_with_violations"]
        return out


@dataclass(frozen=True)
class RatesRising(Record):
    """Whether Table I's rates rise with the buffer size (``summary.json``'s ``table1_rising``).

    ``strict`` — every rate is above the previous one; ``separated`` — every row's
    interval lies entirely above the previous row's (a statement at the rows' simultaneous
    confidence).
    """

    strict: bool
    separated: bool


@dataclass(frozen=True)
class Table1:
    """Table I: one :class:`Table1Row` per buffer size, in increasing buffer size.

    Examples
    --------
    >>> row = Table1Row(buffer_size=1, n=10, violations=0, rate=0.0, upper=0.26, interval=(0.0, 0.3),
    ...                 confidence=0.95, paper_rate=0.0019, paths=None, paths_with_violations=None)
    >>> table = Table1((row,))
    >>> table.row(1).n, table.buffers, table.rising()
    (10, (1,), RatesRising(strict=True, separated=True))
    """

    rows: tuple[Table1Row, ...]

    def __post_init__(self) -> None:
        sizes = [r.buffer_size for r in self.rows]
        if not sizes or sizes != sorted(set(sizes)):
            raise InvalidInputError(f"Table I needs rows of distinct, increasing buffer sizes, got {sizes}")

    @property
    def buffers(self) -> tuple[int, ...]:
        """The buffer sizes of the rows."""
        return tuple(r.buffer_size for r in self.rows)

    def row(self, buffer_size: int) -> Table1Row:
        """The row of ``buffer_size``."""
        for r in self.rows:
            if r.buffer_size == buffer_size:
                return r
        raise InvalidInputError(f"Table I has no row for buffer size {buffer_size}; it has {self.buffers}")

    def rising(self) -> RatesRising:
        """Whether the rates rise with the buffer size (:class:`RatesRising`)."""
        pairs = list(zip(self.rows, self.rows[1:], strict=False))
        return RatesRising(
            strict=all(b.rate > a.rate for a, b in pairs),
            separated=all(b.interval[0] > a.interval[1] for a, b in pairs),
        )

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """``summary.json``'s ``table1``: the rows keyed by buffer size."""
        return {str(r.buffer_size): r.to_dict() for r in self.rows}


def table1(model: IPCModel, tests: Mapping[int, PerceptionDataset], delta: float = 0.05) -> Table1:
    """Table I for ``model`` on ``tests`` (buffer size -> test set).

    Parameters
    ----------
    model : IPCModel
        The calibrated IPC (learned at buffer size 1).
    tests : mapping of int to PerceptionDataset
        Test data per buffer size, never used for training or calibration.
    delta : float
        Family-wise error of all rows' bounds together; each row uses ``delta / rows``.

    Returns
    -------
    Table1
        One row per buffer size (:class:`Table1Row`).

    Examples
    --------
    >>> from ipcverify import example
    >>> from ipcverify.network import ModelConfig
    >>> m = example(10, config=ModelConfig(x_dim=2, y_dim=3, hidden=(4,), param="cholesky")).model
    >>> ds = PerceptionDataset(np.zeros((10, 2)), np.ones((10, 3)) * 100, np.zeros((10, 3)))
    >>> table1(m, {1: ds}).row(1).violations
    10
    """
    if not tests:
        raise InvalidInputError("Table I needs at least one test set")
    if not 0 < delta < 1:
        raise InvalidInputError(f"delta must lie strictly between 0 and 1, got {delta!r}")
    each = delta / len(tests)
    return Table1(tuple(_row(model, b, tests[b], each, 1 - delta) for b in sorted(tests)))


def _row(model: IPCModel, b: int, data: PerceptionDataset, each: float, confidence: float) -> Table1Row:
    violated = ~model.predict_unguarded(data.x, data.yhat).contains(data.y)
    n, k = len(data), int(violated.sum())
    paths = hit = None
    if "path" in data.extra:
        keys = data.extra["path"].astype(np.int64)
        if "source" in data.extra:
            keys = keys * 2 + data.extra["source"].astype(np.int64)
        paths, hit = int(len(np.unique(keys))), int(len(np.unique(keys[violated])))
    lo, hi = clopper_pearson_interval(k, n, each)
    return Table1Row(
        buffer_size=int(b),
        n=n,
        violations=k,
        rate=k / n,
        upper=clopper_pearson_upper(k, n, each),
        interval=(lo, hi),
        confidence=confidence,
        paper_rate=PAPER_TABLE1.get(b),
        paths=paths,
        paths_with_violations=hit,
    )


def table1_text(table: Table1) -> str:
    """Table I as a Markdown table beside the paper's row (for the README and the CLI).

    Examples
    --------
    >>> row = Table1Row(buffer_size=1, n=10, violations=0, rate=0.0, upper=0.26, interval=(0.0, 0.3),
    ...                 confidence=0.95, paper_rate=0.0019, paths=None, paths_with_violations=None)
    >>> print(table1_text(Table1((row,))).splitlines()[2])
    | this reproduction | 0.00 % (0/10; [0.00, 30.00] %) |
    """
    head = "| buffer size | " + " | ".join(str(b) for b in table.buffers) + " |"
    sep = "|---|" + "---|" * len(table.rows)
    ours = (
        "| this reproduction | "
        + " | ".join(
            f"{100 * r.rate:.2f} % ({r.violations}/{r.n}; "
            f"[{100 * r.interval[0]:.2f}, {100 * r.interval[1]:.2f}] %)"
            for r in table.rows
        )
        + " |"
    )
    paper = (
        "| paper | "
        + " | ".join(f"{100 * PAPER_TABLE1[b]:.2f} %" if b in PAPER_TABLE1 else "—" for b in table.buffers)
        + " |"
    )
    lines = [head, sep, ours]
    if any(b in PAPER_TABLE1 for b in table.buffers):
        lines.append(paper)
    return "\n".join(lines)
