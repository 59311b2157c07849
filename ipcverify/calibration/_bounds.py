"""Exact binomial machinery behind ipcverify's certificates.

Every function here is distribution-free: it relies only on the calibration or
test samples being exchangeable (for example i.i.d.) with the data the contract
will meet in deployment. The proofs are in ``proofs/clopper_pearson.md`` and
``proofs/pac_calibration.md``.

* :func:`clopper_pearson_upper` / :func:`clopper_pearson_interval` -- exact
  binomial confidence bounds on a violation rate from ``k`` violations in ``n``
  held-out samples.
* :func:`pac_calibration_index` -- the order statistic ``k`` such that, with
  probability at least ``1 - delta`` over the calibration set, the contract scaled
  by the ``k``-th smallest score violates with probability at most ``epsilon``.
* :func:`marginal_conformal_index` -- split conformal's ``ceil((n + 1)(1 - epsilon))``.
* :func:`min_calibration_size` -- the smallest ``n`` for which either index exists.

Binomial tails come from :mod:`scipy.stats` (regularised incomplete beta
function, relative accuracy near 1e-15). Wherever rounding could tip a decision
the wrong way, the comparison is tightened by the relative margin
:data:`TAIL_MARGIN`, which can only make a result more conservative.
"""

from __future__ import annotations

import math
from fractions import Fraction
from functools import lru_cache
from typing import Literal

from scipy import stats

from ipcverify._wording._spelling import option, options
from ipcverify.errors import InvalidInputError, SampleSizeError

CalibrationMode = Literal["pac", "marginal"]

#: Relative safety margin on binomial tail comparisons (guards against rounding in
#: the incomplete beta function; it only ever makes a bound more conservative).
TAIL_MARGIN = 1e-9
#: Largest sample count whose binomial tail is evaluated (larger minimums are quoted in closed form).
_EXACT_N_LIMIT = 2**53


def count_text(n: int) -> str:
    """A sample count for a message: in full up to 15 digits, else rounded down to two digits.

    Rounded down, "at least ``count_text(n)`` are needed" stays true.

    Parameters
    ----------
    n : int
        The count.

    Examples
    --------
    >>> count_text(688), count_text(2995732273553990730853740629023464908749630263792079183)
    ('688', '2.9e+54')
    """
    digits = str(n)
    if len(digits) <= 15:
        return digits
    return f"{digits[0]}.{digits[1]}e+{len(digits) - 1}"


def _check_probability(name: str, value: float, *, open_interval: bool = True) -> float:
    v = float(value)
    ok = 0.0 < v < 1.0 if open_interval else 0.0 <= v <= 1.0
    if not (math.isfinite(v) and ok):
        raise InvalidInputError(f"{name} must lie strictly between 0 and 1; got {v!r}")
    return v


def _check_counts(k: int, n: int) -> tuple[int, int]:
    if int(n) != n or int(k) != k:
        raise InvalidInputError(f"k and n must be integers; got k={k!r}, n={n!r}")
    k, n = int(k), int(n)
    if n < 1:
        raise InvalidInputError(f"need at least one sample (n >= 1); got n={n}")
    if not 0 <= k <= n:
        raise InvalidInputError(f"the number of violations k must satisfy 0 <= k <= n; got k={k}, n={n}")
    return k, n


def clopper_pearson_upper(k: int, n: int, delta: float) -> float:
    """One-sided Clopper--Pearson upper confidence bound on a violation rate.

    With ``K ~ Binomial(n, p)`` the returned ``u(K)`` satisfies
    ``P(p <= u(K)) >= 1 - delta`` for every ``p``. It is the ``p`` solving
    ``P(Binomial(n, p) <= k) = delta``, i.e. the ``1 - delta`` quantile of
    ``Beta(k + 1, n - k)`` (and 1 when ``k = n``).

    Parameters
    ----------
    k : int
        Observed violations, ``0 <= k <= n``.
    n : int
        Held-out samples (independent of whatever produced the sets).
    delta : float
        Allowed probability that the bound is wrong, ``0 < delta < 1``.

    Returns
    -------
    float
        The upper bound, in ``[k / n, 1]``.

    Examples
    --------
    >>> round(clopper_pearson_upper(0, 100, 0.05), 5)  # the "rule of three": ~3/n
    0.02951
    >>> clopper_pearson_upper(5, 5, 0.1)
    1.0
    """
    k, n = _check_counts(k, n)
    delta = _check_probability("delta", delta)
    if k == n:
        return 1.0
    u = float(stats.beta.ppf(1.0 - delta, k + 1, n - k))
    # rounding guard: never report less than the observed rate, nudge upwards
    return min(1.0, max(u * (1.0 + TAIL_MARGIN), k / n))


def clopper_pearson_lower(k: int, n: int, delta: float) -> float:
    """One-sided Clopper--Pearson lower confidence bound (``delta`` quantile of ``Beta(k, n - k + 1)``).

    ``P(p >= lower(K)) >= 1 - delta`` for every ``p``; the bound is 0 when ``k = 0``.

    Parameters
    ----------
    k : int
        Observed violations, ``0 <= k <= n``.
    n : int
        Held-out samples (independent of whatever produced the sets), ``n >= 1``.
    delta : float
        Allowed probability that the bound is wrong, ``0 < delta < 1``.

    Returns
    -------
    float
        The lower bound, in ``[0, k / n]``.

    Examples
    --------
    >>> clopper_pearson_lower(0, 10, 0.05)
    0.0
    >>> round(clopper_pearson_lower(10, 10, 0.05), 4)
    0.7411
    """
    k, n = _check_counts(k, n)
    delta = _check_probability("delta", delta)
    if k == 0:
        return 0.0
    lo = float(stats.beta.ppf(delta, k, n - k + 1))
    return max(0.0, min(lo * (1.0 - TAIL_MARGIN), k / n))


def clopper_pearson_interval(k: int, n: int, delta: float) -> tuple[float, float]:
    """Two-sided Clopper--Pearson interval with coverage at least ``1 - delta``.

    Each side is a one-sided bound at ``delta / 2``.

    Parameters
    ----------
    k : int
        Observed violations, ``0 <= k <= n``.
    n : int
        Held-out samples (independent of whatever produced the sets), ``n >= 1``.
    delta : float
        Allowed probability that the interval misses ``p``, ``0 < delta < 1``.

    Returns
    -------
    tuple of float
        ``(lower, upper)`` with ``0 <= lower <= k / n <= upper <= 1``.

    Examples
    --------
    >>> lo, hi = clopper_pearson_interval(3, 100, 0.05)
    >>> round(lo, 4), round(hi, 4)
    (0.0062, 0.0852)
    """
    return clopper_pearson_lower(k, n, delta / 2.0), clopper_pearson_upper(k, n, delta / 2.0)


def _binom_cdf(m: int, n: int, p: float) -> float:
    return float(stats.binom.cdf(m, n, p))


@lru_cache(maxsize=256)
def _pac_min_n(epsilon: float, delta: float) -> int:
    """Smallest n with (1 - epsilon)^n <= delta (with the rounding margin).

    Beyond 2**53 samples (an epsilon of about 1e-15 or less) the closed form ``ln(delta) /
    ln(1 - epsilon)`` is returned as it is: the binomial tail cannot be evaluated at such an ``n``,
    and no calibration set comes near it, so only the message quoting it uses the value.
    """
    ratio = math.log(delta) / math.log1p(-epsilon)
    if not ratio <= _EXACT_N_LIMIT:  # also an infinite ratio (epsilon below 1e-308): -ln(1 - e) >= e
        return (
            math.ceil(ratio)
            if math.isfinite(ratio)
            else math.ceil(-Fraction(math.log(delta)) / Fraction(epsilon))
        )
    guess = max(1, math.ceil(ratio))
    threshold = delta * (1.0 - TAIL_MARGIN)
    n = max(1, guess - 2)
    for _ in range(64):  # the usual case: a few steps up from the closed form
        if _binom_cdf(0, n, epsilon) <= threshold:
            return n
        n += 1
    # a tiny epsilon: the margin moves the answer by about TAIL_MARGIN / epsilon, too many single
    # steps; (1 - epsilon)^n decreases in n, so gallop to an n that works and bisect back
    lo, hi, step = n - 1, n, 1
    while _binom_cdf(0, hi, epsilon) > threshold:
        lo, hi, step = hi, hi + step, 2 * step
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if _binom_cdf(0, mid, epsilon) <= threshold else (mid, hi)
    return hi


def pac_calibration_index(n: int, epsilon: float, delta: float) -> int:
    """Order statistic for a PAC (training-conditional) calibration.

    Returns the smallest ``k`` with ``P(Binomial(n, epsilon) <= n - k) <= delta``.
    If ``s`` is the ``k``-th smallest of ``n`` i.i.d. calibration scores, then with
    probability at least ``1 - delta`` over the calibration set,
    ``P(score > s) <= epsilon`` for a fresh sample (proofs/pac_calibration.md).

    Parameters
    ----------
    n : int
        Number of calibration samples.
    epsilon : float
        Target violation probability, ``0 < epsilon < 1``.
    delta : float
        Allowed probability that the calibration set is unlucky, ``0 < delta < 1``.

    Raises
    ------
    SampleSizeError
        If no ``k <= n`` works, i.e. ``(1 - epsilon)^n > delta``; the message gives
        the minimum ``n``.

    Examples
    --------
    >>> pac_calibration_index(5000, 0.01, 0.001)
    4971
    >>> pac_calibration_index(688, 0.01, 0.001)  # the minimum n: k = n
    688
    """
    epsilon = _check_probability("epsilon", epsilon)
    delta = _check_probability("delta", delta)
    if int(n) != n or n < 1:
        raise InvalidInputError(f"n must be a positive integer; got {n!r}")
    return _pac_index(int(n), epsilon, delta)


@lru_cache(maxsize=4096)
def _pac_index(n: int, epsilon: float, delta: float) -> int:
    threshold = delta * (1.0 - TAIL_MARGIN)
    if _binom_cdf(0, n, epsilon) > threshold:
        need = _pac_min_n(epsilon, delta)
        raise SampleSizeError(
            f"{n} calibration samples are too few for a PAC calibration at epsilon={epsilon:g}, "
            f"delta={delta:g}: at least {count_text(need)} are needed (n >= ln(delta) / ln(1 - epsilon)); "
            f"use more calibration data, a larger {options('epsilon', 'delta', last='or')}, or "
            f"{option('mode', 'marginal')}"
        )
    # largest m in [0, n - 1] with cdf(m) <= threshold; cdf is increasing in m
    lo, hi = 0, n - 1
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if _binom_cdf(mid, n, epsilon) <= threshold:
            lo = mid
        else:
            hi = mid - 1
    return n - lo


def pac_rows_allowing(outside: int, epsilon: float, delta: float) -> int:
    """The fewest calibration samples whose PAC scale lets ``outside`` of them lie outside their sets.

    The smallest ``n`` with ``P(Binomial(n, epsilon) <= outside) <= delta``, so that
    :func:`pac_calibration_index` gives ``k <= n - outside``. With ``outside = 0`` it is the minimum
    of :func:`min_calibration_size`; below ``pac_rows_allowing(1, ...)`` the scale is the largest
    calibration score, set by the single most unusual sample.

    Parameters
    ----------
    outside : int
        Calibration samples allowed outside their sets, ``>= 0``.
    epsilon, delta : float
        The target and the confidence parameter, each in ``(0, 1)``.

    Examples
    --------
    >>> pac_rows_allowing(0, 0.1, 0.01), pac_rows_allowing(1, 0.1, 0.01)
    (44, 64)
    >>> pac_calibration_index(63, 0.1, 0.01), pac_calibration_index(64, 0.1, 0.01)
    (63, 63)
    """
    epsilon = _check_probability("epsilon", epsilon)
    delta = _check_probability("delta", delta)
    if int(outside) != outside or outside < 0:
        raise InvalidInputError(f"outside must be a non-negative integer; got {outside!r}")
    threshold = delta * (1.0 - TAIL_MARGIN)
    lo, hi, step = 0, max(1, _pac_min_n(epsilon, delta)), 1  # cdf(outside, n) decreases in n
    while _binom_cdf(int(outside), hi, epsilon) > threshold:
        lo, hi, step = hi, hi + step, 2 * step
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if _binom_cdf(int(outside), mid, epsilon) <= threshold else (mid, hi)
    return hi


def pac_epsilon(n: int, k: int, delta: float) -> float:
    """The smallest violation rate certified by the ``k``-th of ``n`` scores at confidence ``1 - delta``.

    Equal to :func:`clopper_pearson_upper` ``(n - k, n, delta)``: the ``epsilon`` at
    which ``P(Binomial(n, epsilon) <= n - k) = delta``.

    Parameters
    ----------
    n : int
        Number of calibration scores, ``n >= 1``.
    k : int
        Rank of the score used as threshold, ``1 <= k <= n`` (``k = n``: the largest score).
    delta : float
        Allowed probability that the calibration set is unlucky, ``0 < delta < 1``.

    Returns
    -------
    float
        The certified violation rate, in ``(0, 1]``; it shrinks as ``k`` grows.

    Examples
    --------
    >>> k = pac_calibration_index(5000, 0.01, 0.001)
    >>> pac_epsilon(5000, k, 0.001) <= 0.01
    True
    """
    if int(k) != k or not 1 <= k <= n:
        raise InvalidInputError(f"k must be an integer in [1, n]; got k={k!r}, n={n!r}")
    return clopper_pearson_upper(int(n) - int(k), n, delta)


def marginal_conformal_index(n: int, epsilon: float) -> int:
    """Split-conformal order statistic ``ceil((n + 1)(1 - epsilon))``.

    The ``k``-th smallest of ``n`` exchangeable calibration scores bounds a fresh
    score with probability at least ``1 - epsilon``, on average over the calibration
    set (marginal coverage). The ceiling is computed exactly on the rational value
    of the float ``epsilon``.

    Parameters
    ----------
    n : int
        Number of calibration scores, ``n >= 1``.
    epsilon : float
        Target violation probability, ``0 < epsilon < 1``.

    Returns
    -------
    int
        The order statistic ``k``, ``1 <= k <= n``.

    Raises
    ------
    SampleSizeError
        If ``k > n`` (``n < 1 / epsilon - 1``); the message gives the minimum ``n``.

    Examples
    --------
    >>> marginal_conformal_index(99, 0.01)
    99
    >>> marginal_conformal_index(1000, 0.1)
    901
    """
    epsilon = _check_probability("epsilon", epsilon)
    if int(n) != n or n < 1:
        raise InvalidInputError(f"n must be a positive integer; got {n!r}")
    n = int(n)
    k = math.ceil((n + 1) * (1 - Fraction(epsilon)))
    if k > n:
        need = math.ceil(1 / Fraction(epsilon) - 1)
        raise SampleSizeError(
            f"{n} calibration samples are too few for marginal calibration at epsilon={epsilon:g}: "
            f"at least {count_text(need)} are needed (n >= 1/epsilon - 1); use more calibration data or a "
            "larger epsilon"
        )
    return max(k, 1)


def calibration_index(n: int, epsilon: float, delta: float, mode: CalibrationMode) -> int:
    """Dispatch to :func:`pac_calibration_index` or :func:`marginal_conformal_index`.

    Examples
    --------
    >>> calibration_index(1000, 0.1, 0.01, "marginal")
    901
    """
    if mode == "pac":
        return pac_calibration_index(n, epsilon, delta)
    if mode == "marginal":
        return marginal_conformal_index(n, epsilon)
    raise InvalidInputError(f"mode must be 'pac' or 'marginal'; got {mode!r}")


def min_calibration_size(epsilon: float, delta: float, mode: CalibrationMode = "pac") -> int:
    """The smallest number of calibration samples for which a calibration exists.

    Parameters
    ----------
    epsilon : float
        Target violation probability, ``0 < epsilon < 1``.
    delta : float
        Confidence parameter, ``0 < delta < 1`` (checked but unused in marginal mode).
    mode : {"pac", "marginal"}
        PAC: ``n >= ln(delta) / ln(1 - epsilon)``; marginal: ``n >= 1 / epsilon - 1``.

    Returns
    -------
    int
        The minimum ``n``, at least 1.

    Examples
    --------
    >>> min_calibration_size(0.01, 0.001, "pac")
    688
    >>> min_calibration_size(0.01, 0.001, "marginal")
    99
    """
    epsilon = _check_probability("epsilon", epsilon)
    delta = _check_probability("delta", delta)
    if mode == "pac":
        return _pac_min_n(epsilon, delta)
    if mode == "marginal":
        return max(1, math.ceil(1 / Fraction(epsilon) - 1))
    raise InvalidInputError(f"mode must be 'pac' or 'marginal'; got {mode!r}")


def smallest_marginal_epsilon(n: int) -> float:
    """A rate ``n`` samples allow in marginal mode: the least, ``1/(n + 1)``, rounded up to 3 digits.

    ``1 / (n + 1)`` rounded up to 3 significant digits and checked against
    :func:`min_calibration_size` (exact rational arithmetic), so that the value a message names
    is accepted when it is given back: for the domain test's ``--domain-flag-rate`` with ``n``
    calibration inputs (or groups).

    Parameters
    ----------
    n : int
        Samples (or groups) available, ``n >= 1``.

    Examples
    --------
    >>> smallest_marginal_epsilon(57), smallest_marginal_epsilon(10), smallest_marginal_epsilon(12345)
    (0.0173, 0.091, 8.1e-05)
    """
    if int(n) != n or n < 1:
        raise InvalidInputError(f"n must be a positive integer; got {n!r}")
    exact = Fraction(1, int(n) + 1)
    digits = 3 - math.floor(math.log10(exact)) - 1
    value = math.ceil(exact * 10**digits) / 10**digits
    while min_calibration_size(value, 0.5, "marginal") > n:  # guard the float division
        value = (math.ceil(value * 10**digits) + 1) / 10**digits
    return value


def smallest_epsilon(n: int, delta: float, mode: CalibrationMode = "pac") -> float:
    """The smallest ``epsilon`` on the grid 0.001, 0.002, ... for which ``n`` samples suffice.

    The inverse of :func:`min_calibration_size`, for messages that say what a small sample
    can certify: about ``1 - delta**(1/n)`` (PAC) or ``1/(n + 1)`` (marginal), rounded up to
    the grid and checked against :func:`min_calibration_size` (1.0 if no grid value works).

    Parameters
    ----------
    n : int
        Number of calibration samples available, ``n >= 1``.
    delta : float
        Confidence parameter, ``0 < delta < 1`` (no effect in marginal mode).
    mode : {"pac", "marginal"}
        The guarantee, as for :func:`min_calibration_size`.

    Examples
    --------
    >>> smallest_epsilon(20, 0.001, "pac"), smallest_epsilon(20, 0.001, "marginal")
    (0.293, 0.048)
    """
    if int(n) != n or n < 1:
        raise InvalidInputError(f"n must be a positive integer; got {n!r}")
    delta = _check_probability("delta", delta)
    exact = -math.expm1(math.log(delta) / n) if mode == "pac" else 1.0 / (n + 1)
    eps = math.ceil(exact * 1000) / 1000
    while eps < 1 and min_calibration_size(eps, delta, mode) > n:
        eps = round(eps + 0.001, 3)
    return min(eps, 1.0)
