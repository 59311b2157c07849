"""Confidence bounds on the mean of i.i.d. values in ``[0, 1]``: the runs' shares of rows outside their sets.

A log of ``G`` runs (flights, drives) gives, at a threshold ``t``, one number per run: the share
``V_j(t)`` of its rows whose score exceeds ``t``. When the runs are i.i.d., these shares are i.i.d.
values in ``[0, 1]`` whatever the correlation of the rows within a run, and their mean is the
expected share of a new run's rows outside their sets. This module bounds that mean.

* :func:`share_rejects` -- the test of ``H0: mean >= a`` behind the upper bound: a mixture of two
  betting e-processes (Waudby-Smith and Ramdas, 2023), weight :data:`FLOOR_WEIGHT` on the largest
  safe constant bet ``prod_j (1 - V_j) / (1 - a)`` (with no violation in any run it reaches the floor
  ``1 - (FLOOR_WEIGHT delta)^(1/G)``, close to the limit ``1 - delta^(1/G)`` of any distribution-free
  claim) and the rest on the predictable plug-in bets, which adapt to how much the shares vary.
* :func:`share_upper_bound` / :func:`share_lower_bound` -- the confidence bounds (the lower one, for
  held-out tests, is the predictable plug-in betting bound alone).
* :func:`smallest_share_epsilon`, :func:`runs_for_share`, :func:`run_floor` -- what ``G`` runs can
  support.

Every comparison with ``log(1 / delta)`` is tightened by :data:`LOG_MARGIN`, which can only make a
bound more conservative. Proofs: ``proofs/run_claims.md``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.errors import InvalidInputError

FloatArray = NDArray[np.float64]

#: Weight of the constant bet ``lambda = 1 / (1 - a)`` in the upper-bound mixture (the rest goes to the
#: predictable plug-in bets): with no violation in any of ``G`` runs the bound is
#: ``1 - (FLOOR_WEIGHT delta)^(1/G)``, at most ``1 + ln(1/FLOOR_WEIGHT) / ln(1/delta)`` times the floor.
FLOOR_WEIGHT = 0.8
#: The plug-in bets are capped at this fraction of the largest safe bet (Waudby-Smith and Ramdas's ``c``).
BET_CAP = 0.75
#: An e-value must exceed ``1 / delta`` by this much in log (rounding in long sums cannot tip a test).
LOG_MARGIN = 1e-9
_BISECTION_STEPS = 40


def check_shares(shares: ArrayLike, what: str = "shares") -> FloatArray:
    """``shares`` as a float array of shape ``(..., G)``, refused unless every value lies in ``[0, 1]``.

    Parameters
    ----------
    shares : array_like
        Values in ``[0, 1]``, one per run (the last axis).
    what : str
        How to name them in an error.

    Examples
    --------
    >>> check_shares([0.0, 0.5]).tolist()
    [0.0, 0.5]
    """
    x = np.asarray(shares, dtype=np.float64)
    if x.ndim == 0 or x.shape[-1] == 0:
        raise InvalidInputError(f"{what}: need at least one value")
    if not (np.isfinite(x).all() and (x >= 0).all() and (x <= 1).all()):
        raise InvalidInputError(f"{what} must be finite numbers in [0, 1]")
    return x


def _check_delta(delta: float) -> float:
    if isinstance(delta, bool) or not (isinstance(delta, (int, float)) and 0.0 < delta < 1.0):
        raise InvalidInputError(f"delta must lie strictly between 0 and 1; got {delta!r}")
    return float(delta)


def _plug_in_bets(x: FloatArray, alpha: float, cap: FloatArray) -> FloatArray:
    """Predictable plug-in bets ``min(sqrt(2 ln(1/alpha) / (G sigma2_{i-1})), cap)`` along the last axis.

    ``sigma2_i = (1/4 + sum_{j <= i} (x_j - mu_j)^2) / (i + 1)`` with ``mu_j = (1/2 + sum_{l <= j} x_l) /
    (j + 1)``: each bet depends only on the values before it.
    """
    G = x.shape[-1]
    i = np.arange(1, G + 1, dtype=np.float64)
    mu = (0.5 + np.cumsum(x, axis=-1)) / (i + 1)
    var = (0.25 + np.cumsum((x - mu) ** 2, axis=-1)) / (i + 1)
    before = np.concatenate([np.full(x.shape[:-1] + (1,), 0.25), var[..., :-1]], axis=-1)
    return np.minimum(np.sqrt(2.0 * math.log(1.0 / alpha) / (G * before)), cap[..., None])


def _log_product_bet(x: FloatArray, a: FloatArray) -> FloatArray:
    """``log prod_{j <= i} (1 - x_j) / (1 - a)`` along the last axis (``-inf`` after a value of 1)."""
    logs = np.full(x.shape, -np.inf)
    below = x < 1.0
    logs[below] = np.log1p(-x[below])
    return np.cumsum(logs - np.log1p(-a)[..., None], axis=-1)


def share_log_e_value(shares: ArrayLike, a: float | ArrayLike, delta: float) -> FloatArray:
    """The largest log e-value against ``H0: mean >= a`` over the runs seen so far (upper-bound side).

    ``K_i = w prod_{j <= i} (1 - V_j)/(1 - a) + (1 - w) prod_{j <= i} (1 + l_j (a - V_j))``, with
    ``w = FLOOR_WEIGHT`` and the plug-in bets ``l_j`` tuned for ``(1 - FLOOR_WEIGHT) delta`` and capped at
    ``BET_CAP / (1 - a)``. Under ``H0`` with i.i.d. runs, ``K`` is a non-negative supermartingale
    with ``K_0 = 1`` (``proofs/run_claims.md``), so ``P(max_i K_i >= 1 / delta) <= delta``.

    Parameters
    ----------
    shares : array_like, shape (..., G)
        The runs' shares, in a fixed order chosen before seeing them (ipcverify uses the runs'
        label order).
    a : float or array_like, shape (...)
        The null mean(s), in ``(0, 1)``.
    delta : float
        The level the plug-in bets are tuned for.

    Returns
    -------
    ndarray, shape (...)
        ``max_i log K_i``.

    Examples
    --------
    >>> round(float(share_log_e_value([0.0] * 20, 0.2, 0.01)), 3)   # below log(100) = 4.605
    4.326
    """
    x = check_shares(shares)
    av = np.broadcast_to(np.asarray(a, dtype=np.float64), x.shape[:-1]).copy()
    if not ((av > 0) & (av < 1)).all():
        raise InvalidInputError(f"the null mean must lie strictly between 0 and 1; got {a!r}")
    delta = _check_delta(delta)
    bets = _plug_in_bets(x, (1.0 - FLOOR_WEIGHT) * delta, BET_CAP / (1.0 - av))
    log_adaptive = np.cumsum(np.log1p(bets * (av[..., None] - x)), axis=-1)
    log_all_in = _log_product_bet(x, av)
    mixed = np.logaddexp(math.log(FLOOR_WEIGHT) + log_all_in, math.log1p(-FLOOR_WEIGHT) + log_adaptive)
    return np.max(mixed, axis=-1)


def share_rejects(shares: ArrayLike, a: float | ArrayLike, delta: float) -> NDArray[np.bool_]:
    """Whether the shares reject ``H0: mean >= a`` at level ``delta`` (:func:`share_log_e_value`).

    Parameters
    ----------
    shares : array_like, shape (..., G)
        The runs' shares, in ``[0, 1]``.
    a : float or array_like, shape (...)
        The null mean(s), in ``(0, 1)``.
    delta : float
        The level.

    Examples
    --------
    >>> bool(share_rejects([0.0] * 20, 0.2, 0.01)), bool(share_rejects([0.0] * 20, 0.215, 0.01))
    (False, True)
    """
    level = math.log(1.0 / _check_delta(delta)) + LOG_MARGIN
    return np.asarray(share_log_e_value(shares, a, delta) >= level)


def _log_lower_e_value(x: FloatArray, a: float, delta: float) -> float:
    """``max_i log prod_{j <= i} (1 + l_j (V_j - a))``: the plug-in betting test of ``H0: mean <= a``."""
    bets = _plug_in_bets(x, delta, np.asarray(BET_CAP / a))
    return float(np.max(np.cumsum(np.log1p(bets * (x - a)))))


def _bisect(rejects_at: object, lo: float, hi: float) -> float:
    """The boundary of a monotone test between ``lo`` (not rejected) and ``hi`` (rejected), rounded up."""
    test = rejects_at  # a callable: float -> bool
    for _ in range(_BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        if test(mid):  # type: ignore[operator]
            hi = mid
        else:
            lo = mid
    return hi


def share_upper_bound(shares: ArrayLike, delta: float) -> float:
    """An upper confidence bound on the mean of i.i.d. shares in ``[0, 1]`` (level ``1 - delta``).

    The smallest ``a`` at which :func:`share_rejects` rejects ``H0: mean >= a`` (found by
    bisection: the test is monotone in ``a``), or 1 if none below 1 does. With probability at least
    ``1 - delta`` the mean is below it.

    Parameters
    ----------
    shares : array_like, shape (G,)
        The runs' shares, in a fixed order.
    delta : float
        One minus the confidence.

    Examples
    --------
    >>> round(share_upper_bound([0.0] * 20, 0.01), 4)       # the floor of 20 runs is 0.2057
    0.2113
    >>> round(share_upper_bound([0.1] * 200, 0.01), 3)
    0.121
    """
    x = check_shares(shares).ravel()
    delta = _check_delta(delta)
    hi = 1.0 - 1e-12
    if not share_rejects(x, hi, delta):
        return 1.0
    return _bisect(lambda a: bool(share_rejects(x, a, delta)), max(float(x.mean()), 1e-12), hi)


def share_lower_bound(shares: ArrayLike, delta: float) -> float:
    """A lower confidence bound on the mean of i.i.d. shares in ``[0, 1]`` (level ``1 - delta``).

    The largest ``a`` at which the predictable plug-in betting test of ``H0: mean <= a`` does not
    reject (Waudby-Smith and Ramdas, 2023); 0 if it rejects at no ``a > 0``. A held-out test of a
    claim "mean at most epsilon" contradicts it when this bound exceeds ``epsilon``.

    Parameters
    ----------
    shares : array_like, shape (G,)
        The runs' shares, in a fixed order.
    delta : float
        One minus the confidence.

    Examples
    --------
    >>> share_lower_bound([0.0] * 5, 0.01)
    0.0
    >>> round(share_lower_bound([0.5] * 200, 0.01), 3)
    0.485
    """
    x = check_shares(shares).ravel()
    delta = _check_delta(delta)
    level = math.log(1.0 / delta) + LOG_MARGIN
    lo = 1e-12
    if _log_lower_e_value(x, lo, delta) < level:
        return 0.0
    # the test of mean <= a rejects for every a below the boundary; find the largest that does not
    hi = min(float(x.mean()), 1.0 - 1e-12)
    if _log_lower_e_value(x, hi, delta) >= level:
        return hi
    a_lo, a_hi = lo, hi  # rejected at a_lo, not rejected at a_hi
    for _ in range(_BISECTION_STEPS):
        mid = 0.5 * (a_lo + a_hi)
        if mid <= a_lo or mid >= a_hi:
            break
        if _log_lower_e_value(x, mid, delta) >= level:
            a_lo = mid
        else:
            a_hi = mid
    return a_lo


def run_floor(n_runs: int, delta: float) -> float:
    """``1 - delta^(1/G)``: no distribution-free claim about a new run goes below this from ``G`` runs.

    A run that is entirely bad with probability ``q`` is absent from all ``G`` calibration runs
    with probability ``(1 - q)^G``, which exceeds ``delta`` for every ``q`` below the floor
    (``proofs/run_claims.md``).

    Parameters
    ----------
    n_runs : int
        The number ``G`` of independent runs.
    delta : float
        One minus the confidence.

    Examples
    --------
    >>> round(run_floor(20, 0.01), 4), round(run_floor(44, 0.01), 4)
    (0.2057, 0.0994)
    """
    if isinstance(n_runs, bool) or int(n_runs) != n_runs or n_runs < 1:
        raise InvalidInputError(f"the number of runs must be a positive integer; got {n_runs!r}")
    return -math.expm1(math.log(_check_delta(delta)) / int(n_runs))


def smallest_share_epsilon(n_runs: int, delta: float) -> float:
    """The smallest expected share that ``G`` runs can certify at ``delta``: the bound with no violation.

    At most ``1 - (FLOOR_WEIGHT delta)^(1/G)`` (the constant bet alone), within
    ``1 + ln(1/FLOOR_WEIGHT) / ln(1/delta)`` of :func:`run_floor`.

    Parameters
    ----------
    n_runs : int
        The number ``G`` of runs.
    delta : float
        One minus the confidence.

    Examples
    --------
    >>> round(smallest_share_epsilon(20, 0.01), 4), round(run_floor(20, 0.01), 4)
    (0.2113, 0.2057)
    """
    floor = run_floor(n_runs, delta)  # validates both
    bound = share_upper_bound(np.zeros(int(n_runs)), delta)
    return max(bound, floor)


def runs_for_share(epsilon: float, delta: float) -> int:
    """The fewest runs for which an expected share of ``epsilon`` can be certified at ``delta``.

    The smallest ``G`` with :func:`smallest_share_epsilon` ``(G, delta) <= epsilon``: with fewer runs
    no set, however large, is certified. Tight sets need more.

    Parameters
    ----------
    epsilon : float
        The target expected share, in ``(0, 1)``.
    delta : float
        One minus the confidence.

    Examples
    --------
    >>> runs_for_share(0.1, 0.01), runs_for_share(0.227, 0.01)
    (46, 19)
    """
    if isinstance(epsilon, bool) or not (isinstance(epsilon, (int, float)) and 0.0 < epsilon < 1.0):
        raise InvalidInputError(f"epsilon must lie strictly between 0 and 1; got {epsilon!r}")
    delta = _check_delta(delta)
    G = max(1, math.ceil(math.log(FLOOR_WEIGHT * delta) / math.log1p(-epsilon)))  # the constant bet alone
    while G > 1 and share_rejects(np.zeros(G - 1), epsilon, delta):
        G -= 1
    while not share_rejects(np.zeros(G), epsilon, delta):  # pragma: no cover - the start always suffices
        G += 1
    return G
