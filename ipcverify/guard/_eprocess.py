"""The betting e-process behind the online monitor: a test supermartingale for "mean at most epsilon".

The bets (:class:`BettingEProcess`) are a fixed mixture, one third each, of

* constant bets ``lambda = c / epsilon`` for ``c = 1/2, 1/4, ...`` down to ``epsilon / 4``
  (log-optimal, up to the mixture's cost, for a violation rate that is too high from the
  start: the best ``c`` for a rate ``p`` is about ``(p - epsilon) / (1 - epsilon)``), and
* two adaptive bets, Kelly's ``lambda = (p_hat - epsilon) / (epsilon (1 - epsilon))`` with
  ``p_hat`` an exponentially weighted rate of the past with memory ``5 / epsilon`` and
  ``40 / epsilon`` observations (clipped to ``[0, 1 / (2 epsilon)]``). They bet nothing while
  the recent rate looks fine, so a long in-control stretch costs them little, and they react
  to a shift within about their memory.

Observations may also be fractions in ``[0, 1]`` (e.g. one per flight: the share of its
samples outside their sets); H0 then reads "conditional mean at most epsilon".
Proof: ``proofs/monitor.md``; :class:`~ipcverify.guard.ViolationMonitor` turns the e-process
into alarms.
"""

from __future__ import annotations

import numbers

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter
from scipy.special import logsumexp

from ipcverify.errors import InvalidInputError

FloatArray = NDArray[np.float64]

#: Largest bet as a fraction of 1 / null rate: a non-violation costs at most this share of the wealth.
MAX_BET_FRACTION = 0.5
#: Memories of the adaptive bets, in units of 1 / null rate observations.
ADAPTIVE_MEMORIES = (5.0, 40.0)
_CHUNK = 1 << 15


def check_rate(name: str, value: float) -> float:
    """``value`` as a float if it is a real number strictly between 0 and 1 (a rate, a confidence).

    Examples
    --------
    >>> check_rate("epsilon", 0.05)
    0.05
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not (0.0 < value < 1.0):
        shown = float(value) if isinstance(value, numbers.Real) else value
        raise InvalidInputError(f"{name} must lie strictly between 0 and 1; got {shown!r}")
    return float(value)


class BettingEProcess:
    """A test supermartingale for H0: each observation in ``[0, 1]`` has conditional mean ``<= null_rate``.

    ``K_t = sum_c w_c prod_{i <= t} (1 + lambda_{c,i} (X_i - null_rate))`` with fixed weights
    ``w_c`` (summing to 1) and bets ``lambda_{c,i} in [0, MAX_BET_FRACTION / null_rate]`` that
    depend only on ``X_1 .. X_{i-1}`` (see the module docstring). Under H0, ``K`` is a
    non-negative supermartingale with ``K_0 = 1``, so ``P(sup_t K_t >= 1 / delta) <= delta``.

    Parameters
    ----------
    null_rate : float
        The rate ``epsilon`` of H0, in ``(0, 1)``.

    Examples
    --------
    >>> e = BettingEProcess(0.1)
    >>> path = e.advance([0, 0, 1, 1, 1, 1])
    >>> path.shape, bool(path[-1] > path[1]), e.n
    ((6,), True, 6)
    """

    def __init__(self, null_rate: float) -> None:
        self.null_rate = check_rate("null rate", null_rate)
        eps = self.null_rate
        fractions = [MAX_BET_FRACTION]
        while fractions[-1] / 2 >= eps / 4:
            fractions.append(fractions[-1] / 2)
        #: The constant bets lambda = c / null_rate.
        self.lambdas = np.array(fractions) / eps
        self.decays = np.array([1.0 - eps / m for m in ADAPTIVE_MEMORIES])
        J, A = len(self.lambdas), len(self.decays)
        # one third on the constant bets, one third on each adaptive bet (the weights sum to 1)
        self.log_weights = np.log(np.concatenate([np.full(J, 1.0 / (3 * J)), np.full(A, 2.0 / (3 * A))]))
        self._log_wealth = np.zeros(J + A)
        self._num = np.zeros(A)  # exponentially weighted sums of the past observations
        self._den = np.zeros(A)  # ... and of ones
        self.n = 0

    @property
    def log_value(self) -> float:
        """``log K_t`` after the observations so far (0 before any)."""
        return float(logsumexp(self.log_weights + self._log_wealth))

    def _adaptive_bets(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The adaptive bets (A, m) for the next observations ``x`` (each from the ones before it),
        and the exponentially weighted sums after ``x`` (committed by :meth:`advance`)."""
        eps, prior = self.null_rate, 1.0 / self.null_rate  # one pseudo-violation in 1 / eps samples
        bets = np.empty((len(self.decays), len(x)))
        num_end, den_end = self._num.copy(), self._den.copy()
        for a, g in enumerate(self.decays):
            num = lfilter([1.0], [1.0, -g], x, zi=[g * self._num[a]])[0]
            den = lfilter([1.0], [1.0, -g], np.ones_like(x), zi=[g * self._den[a]])[0]
            num_before = np.concatenate([[self._num[a]], num[:-1]])
            den_before = np.concatenate([[self._den[a]], den[:-1]])
            p_hat = (num_before + prior * eps) / (den_before + prior)
            bets[a] = np.clip((p_hat - eps) / (eps * (1.0 - eps)), 0.0, MAX_BET_FRACTION / eps)
            if len(x):
                num_end[a], den_end[a] = num[-1], den[-1]
        return bets, num_end, den_end

    def advance(self, observations: ArrayLike) -> FloatArray:
        """Consume observations in ``[0, 1]``; returns ``log K_t`` after each of them.

        Raises
        ------
        InvalidInputError
            If an observation is not a finite number in ``[0, 1]``.
        """
        x = np.asarray(observations, dtype=np.float64).ravel()
        if not (np.isfinite(x).all() and (x >= 0).all() and (x <= 1).all()):
            raise InvalidInputError("observations must be finite numbers in [0, 1] (1 = violation)")
        out = np.empty(len(x))
        for lo in range(0, len(x), _CHUNK):
            xc = x[lo : lo + _CHUNK]
            adaptive, num, den = self._adaptive_bets(xc)
            bets = np.vstack([np.repeat(self.lambdas[:, None], len(xc), axis=1), adaptive])
            path = self._log_wealth[:, None] + np.cumsum(np.log1p(bets * (xc - self.null_rate)), axis=1)
            out[lo : lo + len(xc)] = logsumexp(self.log_weights[:, None] + path, axis=0)
            if len(xc):
                self._log_wealth, self._num, self._den = path[:, -1].copy(), num, den
        self.n += len(x)
        return out
