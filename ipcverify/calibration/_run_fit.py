"""The thresholds of the two run-level PAC claims that use every row of every run.

* :func:`expected_share_threshold` -- **expected share**: the smallest threshold ``t`` such that, at
  ``t`` and at every larger threshold, the runs' shares of rows above it reject ``mean >= epsilon``
  (:func:`~ipcverify.calibration._share_bound.share_rejects`); with probability at least ``1 - delta``
  the expected share of a new run's rows outside their sets is then at most ``epsilon`` (risk-controlling
  prediction sets, Bates et al. 2021).
* :func:`run_quantiles` -- **share of runs**: each run's own within-run ``(1 - epsilon)`` quantile, the
  smallest threshold that leaves at most ``epsilon`` of its rows outside; the PAC order statistic of
  these ``G`` numbers at ``(gamma, delta)`` bounds the share of new runs with more than ``epsilon`` of
  their rows outside.

Proofs: ``proofs/run_claims.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ipcverify.calibration._group_counts import allowed_outside
from ipcverify.calibration._share_bound import FLOOR_WEIGHT, LOG_MARGIN, share_rejects, share_upper_bound

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: Candidate thresholds tested at once are limited to this many shares (candidates x runs).
_BLOCK = 1 << 21


@dataclass(frozen=True, kw_only=True, eq=False)
class ShareThreshold:
    """The expected-share threshold and what the calibration runs say at it.

    Attributes
    ----------
    threshold : float or None
        The chosen threshold ``t`` (one of the scores); None if even the largest score is refused
        (too few runs for ``epsilon`` at ``delta``).
    mean_share : float
        The calibration runs' mean share of rows with a score above ``t`` (0 when refused).
    upper_bound : float
        :func:`~ipcverify.calibration._share_bound.share_upper_bound` of those shares (at most
        ``epsilon`` at a chosen threshold; descriptive: the claim is about ``epsilon``).
    """

    threshold: float | None
    mean_share: float
    upper_bound: float


def run_shares(scores: FloatArray, codes: IntArray, n_runs: int, threshold: float) -> FloatArray:
    """Each run's share of rows whose score exceeds ``threshold`` (runs in code order).

    Examples
    --------
    >>> run_shares(np.array([0.1, 2.0, 0.3, 0.4]), np.array([0, 0, 1, 1]), 2, 0.35).tolist()
    [0.5, 0.5]
    """
    sizes = np.bincount(codes, minlength=n_runs)
    over = np.bincount(codes, weights=(scores > threshold).astype(np.float64), minlength=n_runs)
    return over / sizes


def _product_rejects(shares: FloatArray, epsilon: float, delta: float) -> bool:
    """Whether the constant bet of the mixture alone rejects ``mean >= epsilon`` (then the mixture does).

    Its log e-value ``log FLOOR_WEIGHT + sum_{j <= i} log((1 - V_j) / (1 - epsilon))``, at its largest
    over ``i``, grows as the threshold grows (every share falls), so this test is monotone in ``t``.
    """
    if (shares >= 1.0).any():
        shares = shares[: int(np.argmax(shares >= 1.0))]  # the product is 0 from the first share of 1 on
        if shares.size == 0:
            return False
    path = np.cumsum(np.log1p(-shares) - math.log1p(-epsilon))
    return bool(math.log(FLOOR_WEIGHT) + float(path.max()) >= math.log(1.0 / delta) + LOG_MARGIN)


def expected_share_threshold(
    scores: FloatArray, codes: IntArray, n_runs: int, epsilon: float, delta: float
) -> ShareThreshold:
    """The smallest score ``t`` such that the shares reject ``mean >= epsilon`` at ``t`` and above.

    The runs' shares change only at the scores, so testing every distinct score from the largest
    down, and stopping at the first that is not rejected, tests every threshold above the result.
    Above the smallest score at which the mixture's constant bet alone rejects (found by bisection:
    that test is monotone in the threshold) every threshold is rejected, so the scan starts there.

    Parameters
    ----------
    scores : ndarray, shape (N,)
        Finite scores of the calibration rows.
    codes : ndarray of int, shape (N,)
        Each row's run, ``0 .. n_runs - 1`` (every run present).
    n_runs : int
        The number of runs ``G``.
    epsilon, delta : float
        Target expected share and confidence parameter.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> codes = np.repeat(np.arange(100), 50)
    >>> fit = expected_share_threshold(rng.random(5000), codes, 100, 0.2, 0.01)
    >>> round(fit.threshold, 3), round(fit.mean_share, 3), fit.upper_bound <= 0.2   # uniform scores
    (0.84, 0.159, True)
    """
    sizes = np.bincount(codes, minlength=n_runs).astype(np.float64)
    order = np.argsort(-scores, kind="stable")
    desc, run_of = scores[order], codes[order]
    first = np.flatnonzero(np.concatenate([[True], desc[1:] != desc[:-1]]))  # first row of each value
    values = desc[first]
    # candidate k (threshold values[k]) counts the rows before first[k]: rows of a larger score
    rank = np.repeat(np.arange(len(first)), np.diff(np.append(first, len(desc))))  # value index of each row

    def shares_at(k: int) -> FloatArray:
        return np.bincount(run_of[: first[k]], minlength=n_runs) / sizes

    lo, hi = -1, len(values)  # the constant bet rejects at every k <= lo, and at none >= hi
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if _product_rejects(shares_at(mid), epsilon, delta):
            lo = mid
        else:
            hi = mid
    chosen: int | None = None if lo < 0 else lo
    k0 = lo + 1
    counts = (
        np.bincount(run_of[: first[k0]], minlength=n_runs).astype(np.float64) if k0 < len(values) else None
    )
    cap = max(1, _BLOCK // n_runs)
    step = min(64, cap)  # blocks grow: the scan usually stops soon
    while counts is not None and k0 < len(values):
        k1 = min(len(values), k0 + step)
        step = min(2 * step, cap)
        block = np.zeros((k1 - k0, n_runs))
        rows = slice(first[k0], first[k1 - 1])  # rows counted by some candidate of the block after k0
        np.add.at(block, (rank[rows] - k0 + 1, run_of[rows]), 1.0)
        block = counts + np.cumsum(block, axis=0)
        ok = share_rejects(block / sizes, epsilon, delta)
        if not ok.all():
            fail = int(np.argmin(ok))
            chosen = None if k0 + fail == 0 else k0 + fail - 1
            break
        chosen = k1 - 1
        last = slice(first[k1 - 1], first[k1] if k1 < len(first) else len(desc))
        counts = block[-1] + np.bincount(run_of[last], minlength=n_runs)
        k0 = k1
    if chosen is None:
        return ShareThreshold(
            threshold=None, mean_share=0.0, upper_bound=share_upper_bound(np.zeros(n_runs), delta)
        )
    t = float(values[chosen])
    shares = run_shares(scores, codes, n_runs, t)
    return ShareThreshold(
        threshold=t, mean_share=float(shares.mean()), upper_bound=share_upper_bound(shares, delta)
    )


def run_quantiles(scores: FloatArray, codes: IntArray, n_runs: int, epsilon: float) -> FloatArray:
    """Each run's smallest threshold with at most ``epsilon`` of its rows above it (its quantile).

    For a run of ``L`` rows that is its ``L - floor(epsilon L)``-th smallest score: at that threshold
    at most ``floor(epsilon L)`` rows exceed it, and at any smaller one more do.

    Examples
    --------
    >>> s = np.array([1.0, 2.0, 3.0, 4.0, 10.0, 20.0])
    >>> run_quantiles(s, np.array([0, 0, 0, 0, 1, 1]), 2, 0.25).tolist()   # run 0 may leave 1 of 4 out
    [3.0, 20.0]
    """
    order = np.lexsort((scores, codes))
    sizes = np.bincount(codes, minlength=n_runs)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    keep = np.array([int(m) - allowed_outside(epsilon, int(m)) for m in sizes], dtype=np.intp)
    return scores[order][starts + keep - 1]
