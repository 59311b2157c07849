"""How much the rows of a run tell: the within-run dependence of a log, measured at a calibrated scale.

Rows of one run are not independent samples, and how far they fall short decides what a row-level
claim is worth. :func:`measure_dependence` measures it on calibration data with runs:

* the **intra-run correlation** of the violation indicators ``1{score > t}`` (the one-way ANOVA
  estimator of the intraclass correlation);
* the **design effect** of the row violation rate: the variance of the rate estimated with runs as
  the units (the ratio estimator's variance, Kish 1965) over its variance if the rows were
  independent, and the **effective number of independent rows** ``N / design effect``;
* the **autocorrelation time** of the scores within runs: ``1 + 2 sum_k rho_k`` over the lags
  within a run, about the log's overall mean (so that a run's own level counts as dependence, as
  its slow drift does), summed up to Sokal's automatic window (the smallest ``M >= 5 tau(M)``).

These are descriptions, not guarantees: the run-level claims (``proofs/run_claims.md``) need none
of them. A design effect near 1 and a short autocorrelation time say that the rows behave like
independent samples; a large one says that a row-level claim counts the same information many times.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.data._split import group_codes
from ipcverify.errors import InvalidInputError

FloatArray = NDArray[np.float64]
#: Sokal's window constant: the autocorrelation sum stops at the first lag ``M >= SOKAL_C * tau(M)``.
SOKAL_C = 5.0


@dataclass(frozen=True, kw_only=True)
class RunDependence:
    """The within-run dependence of calibration data at a threshold (:func:`measure_dependence`).

    Attributes
    ----------
    column : str
        The column naming the runs.
    n_runs, n_rows : int
        Runs and rows.
    threshold : float
        The score above which a row counts as a violation (the calibrated scale).
    violation_rate : float
        Share of the rows above it.
    icc : float or None
        Intra-run correlation of the violation indicators (None when no row, or every row, is
        above the threshold).
    design_effect : float or None
        Variance of the row rate with runs as the units over its variance for independent rows.
    effective_rows : float or None
        ``n_rows / design_effect``, at most ``n_rows``: the independent rows the data are worth.
    autocorrelation_time : float or None
        Integrated autocorrelation time of the scores within runs, in rows (None if no run has two
        rows or the scores do not vary within runs).

    Examples
    --------
    >>> runs = np.repeat(np.arange(40), 25)
    >>> d = measure_dependence((runs % 4 == 0).astype(float), runs, 0.5, "run")  # whole runs in or out
    >>> d.violation_rate, d.icc, round(d.effective_rows, 1)
    (0.25, 1.0, 39.0)
    """

    column: str
    n_runs: int
    n_rows: int
    threshold: float
    violation_rate: float
    icc: float | None
    design_effect: float | None
    effective_rows: float | None
    autocorrelation_time: float | None

    def __post_init__(self) -> None:
        if not (1 <= self.n_runs <= self.n_rows) or not (0.0 <= self.violation_rate <= 1.0):
            raise InvalidInputError(f"inconsistent dependence record: {self}")

    def sentence(self) -> str:
        """What the dependence means for a row-level claim, in one sentence."""
        if self.effective_rows is None:
            return (
                f"{self.n_rows:,} rows in {self.n_runs} runs of {self.column!r}; at the calibrated scale no "
                "row, or every row, is outside, so their correlation cannot be measured"
            )
        tau = (
            ""
            if self.autocorrelation_time is None
            else f", scores' autocorrelation time {self.autocorrelation_time:.3g} rows"
        )
        return (
            f"{self.n_rows:,} rows in {self.n_runs} runs of {self.column!r} are worth about "
            f"{self.effective_rows:,.0f} independent rows (design effect {self.design_effect:.3g}, intra-run "
            f"correlation of the violations {self.icc:.3g}{tau})"
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain data, with the sentence."""
        return {**asdict(self), "statement": self.sentence()}


def _autocorrelation_time(scores: FloatArray, codes: NDArray[np.intp], n_runs: int) -> float | None:
    """Pooled within-run autocorrelation time of the scores about their overall mean, with Sokal's window."""
    order = np.argsort(codes, kind="stable")  # rows of a run stay in file order
    sizes = np.bincount(codes, minlength=n_runs)
    longest = int(sizes.max())
    if longest < 2:
        return None
    cov = np.zeros(longest)
    pairs = np.zeros(longest)
    start, mean = 0, float(scores.mean())
    for L in sizes:
        x = scores[order[start : start + L]] - mean
        start += L
        if L < 2:
            continue
        n = 1 << int(2 * L - 1).bit_length()
        f = np.fft.rfft(x, n)
        cov[:L] += np.fft.irfft(f * np.conj(f), n)[:L]
        pairs[:L] += np.arange(L, 0, -1)
    if cov[0] <= 0:
        return None
    rho = cov / np.where(pairs > 0, pairs, 1) / (cov[0] / pairs[0])
    tau = 1.0
    for m in range(1, longest):
        tau += 2.0 * rho[m]
        if m >= SOKAL_C * tau:
            break
    return max(float(tau), 1.0 / longest)


def measure_dependence(scores: ArrayLike, runs: ArrayLike, threshold: float, column: str) -> RunDependence:
    """Measure how correlated the rows of each run are, at ``threshold`` (see the module docstring).

    Parameters
    ----------
    scores : array_like, shape (N,)
        The calibration rows' scores, each run's rows in time (file) order.
    runs : array_like, shape (N,)
        Each row's run label.
    threshold : float
        Rows with a score above it count as violations (the calibrated scale).
    column : str
        The run column's name (for the record).

    Returns
    -------
    RunDependence

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> d = measure_dependence(rng.random(20000), np.repeat(np.arange(200), 100), 0.9, "run")
    >>> round(d.design_effect, 1), round(d.autocorrelation_time, 1)   # independent rows
    (1.0, 1.0)
    """
    s = np.asarray(scores, dtype=np.float64).ravel()
    codes, labels = group_codes(runs, f"run column {column!r}")
    if len(codes) != len(s) or not np.isfinite(s).all():
        raise InvalidInputError(f"need one finite score per row of run column {column!r}")
    G, N = len(labels), len(s)
    sizes = np.bincount(codes, minlength=G).astype(np.float64)
    outside = np.bincount(codes, weights=(s > threshold).astype(np.float64), minlength=G)
    p = float(outside.sum() / N)
    icc = deff = effective = None
    if 0.0 < p < 1.0 and G >= 2:
        shares = outside / sizes
        msb = float((sizes * (shares - p) ** 2).sum() / (G - 1))
        msw = float((sizes * shares * (1 - shares)).sum() / (N - G)) if N > G else 0.0
        n0 = (N - float((sizes**2).sum()) / N) / (G - 1)
        denominator = msb + (n0 - 1.0) * msw
        icc = None if denominator <= 0 else (msb - msw) / denominator
        variance_runs = G / (G - 1) * float(((outside - p * sizes) ** 2).sum()) / N**2
        deff = variance_runs / (p * (1 - p) / N)
        effective = N if deff <= 1.0 else N / deff
    tau = _autocorrelation_time(s, codes, G)
    return RunDependence(
        column=column,
        n_runs=G,
        n_rows=N,
        threshold=float(threshold),
        violation_rate=p,
        icc=None if icc is None else float(icc),
        design_effect=None if deff is None else float(deff),
        effective_rows=None if effective is None else float(effective),
        autocorrelation_time=tau,
    )
