"""Empirical evaluation of an IPC on labelled data."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from ipcverify._wording._spelling import option
from ipcverify.calibration._group_counts import group_shares
from ipcverify.certification._test_result import TestResult
from ipcverify.contract._guarded import mark_row_level, mark_runs
from ipcverify.contract._model import IPCModel
from ipcverify.data._checks import group_like_counts
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import DataError, InvalidInputError
from ipcverify.guard._domain_report import DomainReport
from ipcverify.guard._index import one_blas_thread

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class BinCoverage:
    """Violation rate of an IPC per bin of one column (conditional coverage).

    A numeric column is cut at ``edges`` (quantile bins, or one bin per value when it has few);
    a text column (flight or run names) has one bin per value, named in ``labels``.

    Attributes
    ----------
    column : str
        The column binned.
    edges : tuple of float
        The bin edges of a numeric column (empty for a text column).
    counts, violations : tuple of int
        Samples and violations per bin.
    labels : tuple of str
        The name of each bin.
    """

    column: str
    edges: tuple[float, ...]
    counts: tuple[int, ...]
    violations: tuple[int, ...]
    labels: tuple[str, ...] = ()

    @property
    def rates(self) -> tuple[float, ...]:
        """Violation rate per bin (NaN for an empty bin)."""
        return tuple(v / c if c else float("nan") for v, c in zip(self.violations, self.counts, strict=True))

    def bin_names(self) -> tuple[str, ...]:
        """One display name per bin: its value (a text column) or ``lo..hi`` (a numeric one).

        Examples
        --------
        >>> v = np.array([False, True, False])
        >>> coverage_by_bin(np.array(["run_b", "run_a", "run_b"]), v, "flight").bin_names()
        ('run_a', 'run_b')
        >>> coverage_by_bin(np.array([0.5, 1.0, 2.0]), v, "x_0", bins=2).bin_names()
        ('0.5..1', '1..2')
        """
        if self.labels:
            return self.labels
        e = self.edges
        return tuple(f"{e[i]:.3g}..{e[min(i + 1, len(e) - 1)]:.3g}" for i in range(len(self.counts)))

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (``labels`` is empty for a numeric column, ``edges`` for a text one)."""
        return {
            "column": self.column,
            "edges": list(self.edges),
            "labels": list(self.labels),
            "counts": list(self.counts),
            "violations": list(self.violations),
            "rates": [None if np.isnan(r) else r for r in self.rates],
        }


@dataclass(frozen=True)
class Evaluation:
    """How an IPC did on a labelled dataset.

    Attributes
    ----------
    n, violations : int
        Number of samples and of samples with ``y`` outside its set.
    violation_rate : float
        ``violations / n``.
    log_volume_mean, log_volume_median : float
        Natural log of the sets' volumes (units of y cubed, for n = 3).
    mean_extent : tuple of float
        Mean full width of the sets' bounding boxes per dimension.
    by_bin : BinCoverage or None
        Violation rate per bin of a chosen column.
    calibrated : bool
        Whether the model's calibration was applied.
    domain : DomainReport or None
        How many samples lie outside the model's domain of validity, and the violations inside
        and outside it (None for a model without a domain test).
    by_run : RunEvaluation or None
        The same counted per run (flight), for data whose runs are named: the unit a claim about
        runs is about (None for data without runs).
    """

    n: int
    violations: int
    violation_rate: float
    log_volume_mean: float
    log_volume_median: float
    mean_extent: tuple[float, ...]
    calibrated: bool
    by_bin: BinCoverage | None = field(default=None)
    domain: DomainReport | None = field(default=None)
    by_run: RunEvaluation | None = field(default=None)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form with keys ``n``, ``violations``, ``violation_rate``, ``log_volume``, ...,
        ``domain`` (:meth:`DomainReport.to_dict`, or None)."""
        return {
            "n": self.n,
            "violations": self.violations,
            "violation_rate": self.violation_rate,
            "log_volume": {"mean": self.log_volume_mean, "median": self.log_volume_median},
            "mean_extent": list(self.mean_extent),
            "calibrated": self.calibrated,
            "by_bin": None if self.by_bin is None else self.by_bin.to_dict(),
            "domain": None if self.domain is None else self.domain.to_dict(),
            "by_run": None if self.by_run is None else self.by_run.to_dict(),
        }


@dataclass(frozen=True, kw_only=True)
class RunEvaluation:
    """How an IPC did per run (flight): the unit of a claim about runs, valid for correlated rows.

    Attributes
    ----------
    column : str
        The column that names the runs.
    n_runs : int
        Runs in the data.
    share : TestResult
        The mean of the runs' shares of rows outside their sets, with betting bounds at
        ``1 - delta`` (valid if the runs are i.i.d., whatever the correlation within a run).
    max_share : float
        The largest share of one run.
    runs_with_violation : int
        Runs with some row outside.
    outside_domain : float or None
        The mean of the runs' shares of queries outside the domain of validity (None without one).
    """

    column: str
    n_runs: int
    share: TestResult
    max_share: float
    runs_with_violation: int
    outside_domain: float | None

    def to_dict(self) -> dict[str, Any]:
        """Plain data."""
        return {
            "column": self.column,
            "n_runs": self.n_runs,
            "mean_share": self.share.empirical_rate,
            "share": self.share.to_dict(),
            "max_share": self.max_share,
            "runs_with_violation": self.runs_with_violation,
            "outside_domain": self.outside_domain,
        }


def evaluate_runs(
    violated: NDArray[np.bool_],
    runs: NDArray[Any],
    column: str,
    delta: float,
    outside: NDArray[np.bool_] | None,
) -> RunEvaluation:
    """Count violations per run (see :class:`RunEvaluation`).

    Parameters
    ----------
    violated : ndarray of bool, shape (N,)
        Whether each row's truth fell outside its set.
    runs : ndarray, shape (N,)
        Each row's run label.
    column : str
        The runs' column name.
    delta : float
        One minus the confidence of the bounds on the mean share.
    outside : ndarray of bool, shape (N,), optional
        Whether each query lies outside the domain of validity.

    Examples
    --------
    >>> ev = evaluate_runs(np.array([True, False, False, False]), np.array([1, 1, 2, 2]), "run", 0.05, None)
    >>> ev.n_runs, ev.share.empirical_rate, ev.runs_with_violation
    (2, 0.25, 1)
    """
    shares, counts, _ = group_shares(violated, runs, f"run column {column!r}")
    away = None if outside is None else float(group_shares(outside, runs)[0].mean())
    return RunEvaluation(
        column=column,
        n_runs=len(shares),
        share=TestResult.from_shares(shares, delta, f"runs of {column}"),
        max_share=float(shares.max()),
        runs_with_violation=int((counts > 0).sum()),
        outside_domain=away,
    )


def coverage_by_bin(
    values: NDArray[Any], violated: NDArray[np.bool_], column: str, bins: int = 10
) -> BinCoverage:
    """Violation counts per quantile bin of ``values`` (per value if few distinct, or if text).

    Parameters
    ----------
    values : ndarray, shape (N,)
        The column's value for each sample.
    violated : ndarray of bool, shape (N,)
        Whether each sample's truth fell outside its set.
    column : str
        The column's name.
    bins : int
        Number of quantile bins.

    Raises
    ------
    InvalidInputError
        If ``bins < 1``, or a value is missing (NaN, empty) or infinite.
    """
    if bins < 1:
        raise InvalidInputError(f"{option('bins')} must be >= 1; got {bins}")
    raw = np.asarray(values)
    if raw.shape != np.shape(violated) or raw.ndim != 1 or raw.size == 0:
        raise InvalidInputError(f"bin column {column!r}: need one value per sample; got shape {raw.shape}")
    missing = pd.isna(raw)
    if missing.any():
        r = int(np.flatnonzero(missing)[0])
        raise DataError(f"bin column {column!r}: row {r} (0-based) has no value; every sample needs one")
    try:
        v = raw.astype(np.float64)
    except (TypeError, ValueError):  # text: flight or run names
        v = None
    if v is None:
        labels, idx = np.unique(raw.astype(str), return_inverse=True)
        nb = len(labels)
        counts = np.bincount(idx, minlength=nb)
        viol = np.bincount(idx, weights=violated.astype(float), minlength=nb).astype(int)
        names = tuple(str(x) for x in labels)
        return BinCoverage(column, (), tuple(int(c) for c in counts), tuple(int(c) for c in viol), names)
    if not np.isfinite(v).all():
        r = int(np.flatnonzero(~np.isfinite(v))[0])
        raise DataError(
            f"bin column {column!r}: row {r} (0-based) is {v[r]:g}; bin by a column of finite values"
        )
    uniq = np.unique(v)
    if len(uniq) <= bins:
        edges = np.concatenate([uniq, [uniq[-1]]])
        idx = np.searchsorted(uniq, v)
        nb = len(uniq)
    else:
        edges = np.unique(np.quantile(v, np.linspace(0, 1, bins + 1)))
        idx = np.clip(np.searchsorted(edges, v, side="right") - 1, 0, len(edges) - 2)
        nb = len(edges) - 1
    counts = np.bincount(idx, minlength=nb)
    viol = np.bincount(idx, weights=violated.astype(float), minlength=nb).astype(int)
    return BinCoverage(
        column, tuple(float(e) for e in edges), tuple(int(c) for c in counts), tuple(int(c) for c in viol)
    )


@dataclass(frozen=True, kw_only=True)
class WorstBin:
    """The lowest coverage over the quantile bins of each state column and of ``||yhat||``.

    A smaller set bought by under-covering a hard region of the inputs shows here: the
    marginal guarantee averages over inputs, this does not.

    Attributes
    ----------
    by_column : mapping of str to (coverage, lower edge, upper edge, n)
        The worst bin of each column.
    column : str
        The column whose worst bin is the lowest overall.
    coverage : float
        That bin's coverage (1 - its violation rate).
    bins : int
        Quantile bins per column.
    """

    by_column: dict[str, tuple[float, float, float, int]]
    column: str
    coverage: float
    bins: int

    def to_dict(self) -> dict[str, Any]:
        """Plain data."""
        return {
            "bins": self.bins,
            "worst_column": self.column,
            "worst_coverage": self.coverage,
            "by_column": {
                c: {"coverage": v[0], "lower": v[1], "upper": v[2], "n": v[3]}
                for c, v in self.by_column.items()
            },
        }


def worst_bin_coverage(
    x: FloatArray, yhat: FloatArray, violated: NDArray[np.bool_], x_columns: tuple[str, ...], bins: int = 10
) -> WorstBin:
    """Worst-bin coverage over ``bins`` quantile bins of every state column and of ``||yhat||``.

    Parameters
    ----------
    x, yhat : ndarray, shapes (N, d) and (N, n)
        States and estimates.
    violated : ndarray of bool, shape (N,)
        Whether each truth fell outside its set.
    x_columns : tuple of str
        Names of the state columns.
    bins : int
        Number of quantile bins per column.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> x = rng.uniform(size=(1000, 1))
    >>> bad = x[:, 0] >= np.quantile(x[:, 0], 0.9)   # every sample of the top decile fails
    >>> w = worst_bin_coverage(x, rng.normal(size=(1000, 2)), bad, ("x_0",))
    >>> w.column, w.coverage
    ('x_0', 0.0)
    """
    columns = {name: np.asarray(x)[:, i] for i, name in enumerate(x_columns)}
    columns["||yhat||"] = np.linalg.norm(np.asarray(yhat), axis=1)
    worst: dict[str, tuple[float, float, float, int]] = {}
    for name, values in columns.items():
        cov = coverage_by_bin(values, violated, name, bins)
        rows = [
            (1.0 - v / c, cov.edges[i], cov.edges[min(i + 1, len(cov.edges) - 1)], c)
            for i, (c, v) in enumerate(zip(cov.counts, cov.violations, strict=True))
            if c
        ]
        worst[name] = min(rows, key=lambda r: r[0])
    column = min(worst, key=lambda c: worst[c][0])
    return WorstBin(by_column=worst, column=column, coverage=worst[column][0], bins=bins)


def evaluate(
    model: IPCModel,
    data: PerceptionDataset,
    bin_column: str | None = None,
    bins: int = 10,
    group_column: str | None = None,
) -> Evaluation:
    """Empirical violation rate, set volumes and extents of ``model`` on ``data``.

    Uses the model's calibrated sets if it carries a calibration, and counts the samples outside
    its domain of validity (with the violations inside and outside) if it carries a domain test.
    Data with runs (``group_column``, else the calibration's run column if the data have it, else
    the data's one column that names runs) are also counted per run (:class:`RunEvaluation`, bounds
    at the calibration's ``delta``, or 0.05 without one).

    Parameters
    ----------
    model : IPCModel
        The model.
    data : PerceptionDataset
        The data.
    bin_column : str, optional
        A column to report the violation rate per bin of (:func:`coverage_by_bin`).
    bins : int
        Number of bins.
    group_column : str, optional
        The column that names the runs (default: see above).

    Examples
    --------
    >>> from ipcverify import example
    >>> from ipcverify.training import train, TrainConfig
    >>> ds = example(300, seed=0).data
    >>> ev = evaluate(train(ds, train_config=TrainConfig(epochs=1)).model, ds)
    >>> ev.n
    300
    """
    if (data.x_dim, data.y_dim) != (model.config.x_dim, model.config.y_dim):
        raise InvalidInputError(
            f"{data.source}: data has x_dim={data.x_dim}, y_dim={data.y_dim} but the model "
            f"expects x_dim={model.config.x_dim}, y_dim={model.config.y_dim}"
        )
    with one_blas_thread():  # as fast idle, and not slowed by other busy processes (bench_threads)
        sets = model.predict_unguarded(data.x, data.yhat)
        violated = ~sets.contains(data.y)
        logvol = sets.log_volume()
        extent = 2.0 * sets.half_widths()
        outside = None if model.domain is None else ~model.domain.contains(data.x, data.yhat)
    by_bin = None
    if bin_column is not None:
        by_bin = coverage_by_bin(data.column(bin_column), violated, bin_column, bins)
    k = int(violated.sum())
    claim = None if model.calibration is None else model.calibration.group_claim()
    if group_column is None:
        runs = group_like_counts(data)
        if claim is not None and claim.column in data.extra:
            group_column = claim.column
        elif len(runs) == 1:
            group_column = next(iter(runs))
    delta = 0.05 if model.calibration is None else model.calibration.delta
    by_run = (
        None
        if group_column is None
        else evaluate_runs(violated, data.column(group_column), group_column, delta, outside)
    )
    return Evaluation(
        n=len(data),
        violations=k,
        violation_rate=k / len(data),
        log_volume_mean=float(np.mean(logvol)),
        log_volume_median=float(np.median(logvol)),
        mean_extent=tuple(float(e) for e in extent.mean(axis=0)),
        calibrated=model.calibration is not None,
        by_bin=by_bin,
        domain=None
        if model.domain is None or outside is None
        else mark_runs(
            model, mark_row_level(model, model.domain.report(data.x, data.yhat, violated)), data, outside
        ),
        by_run=by_run,
    )
