"""The calibrated threshold of one set of exchangeable scores: the core of every calibration.

``k`` is the order statistic that makes the stated guarantee hold
(:func:`ipcverify.calibration.calibration_index`); the stored scale is the ``k``-th smallest score
times ``1 + SCALE_MARGIN`` (a slightly larger set, so that float32 rounding differences
between batch sizes cannot turn a calibration sample on the boundary into a violation).
Proofs: ``proofs/pac_calibration.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

from ipcverify._wording._spelling import option
from ipcverify.calibration._bounds import (
    CalibrationMode,
    calibration_index,
    min_calibration_size,
    pac_epsilon,
)
from ipcverify.errors import InvalidInputError, SampleSizeError

#: Relative enlargement of the calibrated scale (float32 rounding guard; conservative).
SCALE_MARGIN = 1e-5
#: Scale used if the order statistic is zero (a perfect score); keeps C / s finite.
MIN_SCALE = 1e-30
#: The two guarantees: training-conditional (PAC) or marginal (split conformal).
MODES = ("pac", "marginal")


def check_eps_delta(epsilon: float, delta: float) -> None:
    """Refuse an ``epsilon`` or ``delta`` outside ``(0, 1)``."""
    for name, v in (("epsilon", epsilon), ("delta", delta)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and 0.0 < v < 1.0):
            raise InvalidInputError(f"{name} must lie strictly between 0 and 1; got {v!r}")


def check_mode(mode: str) -> None:
    """Refuse a mode other than ``"pac"`` or ``"marginal"``."""
    if mode not in MODES:
        raise InvalidInputError(f"mode must be 'pac' or 'marginal'; got {mode!r}")


def check_seed(seed: int) -> None:
    """Refuse a seed that is not a non-negative integer (a bool is not one; NumPy's generators
    take no negative seed)."""
    whole = isinstance(seed, (int, np.integer)) or (isinstance(seed, float) and seed.is_integer())
    if isinstance(seed, bool) or not whole:
        raise InvalidInputError(f"seed must be an integer; got {seed!r}")
    if seed < 0:
        raise InvalidInputError(f"{option('seed')} must be a non-negative integer; got {seed!r}")


@dataclass(frozen=True, kw_only=True)
class ScoreThreshold:
    """The calibrated threshold of one set of scores.

    Attributes
    ----------
    mode : {"pac", "marginal"}
    epsilon, delta : float
        Target violation rate and confidence parameter (``delta`` is recorded but
        plays no role in the marginal guarantee).
    n, k : int
        Calibration samples and the order statistic used (``1 <= k <= n``).
    order_statistic : float
        The ``k``-th smallest score.
    scale : float
        ``order_statistic * (1 + SCALE_MARGIN)`` (at least ``MIN_SCALE``).

    Examples
    --------
    >>> t = threshold_scores(np.arange(1.0, 101.0), epsilon=0.1, delta=0.05, mode="marginal")
    >>> t.k, t.order_statistic
    (91, 91.0)
    """

    mode: CalibrationMode
    epsilon: float
    delta: float
    n: int
    k: int
    order_statistic: float
    scale: float

    def __post_init__(self) -> None:
        check_mode(self.mode)
        check_eps_delta(self.epsilon, self.delta)
        if not (isinstance(self.n, int) and isinstance(self.k, int) and 1 <= self.k <= self.n):
            raise InvalidInputError(f"need integers 1 <= k <= n; got k={self.k!r}, n={self.n!r}")
        need = calibration_index(self.n, self.epsilon, self.delta, self.mode)
        if self.k < need:
            raise InvalidInputError(
                f"order statistic k={self.k} is below the k={need} that {self.mode} calibration "
                f"requires for n={self.n}, epsilon={self.epsilon:g}, delta={self.delta:g}; "
                "the record is inconsistent -- recalibrate"
            )
        if not (math.isfinite(self.scale) and self.scale > 0 and self.scale >= self.order_statistic):
            raise InvalidInputError(
                f"scale must be finite, > 0 and >= the order statistic; got scale={self.scale!r}, "
                f"order statistic={self.order_statistic!r}"
            )

    @property
    def certified_epsilon(self) -> float:
        """The violation rate actually certified: ``epsilon`` (marginal) or the tighter PAC value."""
        if self.mode == "marginal":
            return self.epsilon
        return min(self.epsilon, pac_epsilon(self.n, self.k, self.delta))

    def allowed_rate(self) -> float:
        """The violation rate that holds with probability ``1 - delta`` over the calibration draw.

        PAC: :attr:`certified_epsilon`. Marginal: the ``1 - delta`` quantile of the violation
        rate's law, ``Beta(n - k + 1, k)`` (continuous scores), since a marginal calibration
        makes no per-draw claim of its own.
        """
        if self.mode == "pac":
            return self.certified_epsilon
        return float(stats.beta.ppf(1.0 - self.delta, self.n - self.k + 1, self.k))

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form: every field, in order (``mode``, ``epsilon``, ..., ``scale``)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ScoreThreshold:
        """Inverse of :meth:`to_dict`."""
        return cls(
            mode=str(data["mode"]),  # type: ignore[arg-type]
            epsilon=float(data["epsilon"]),
            delta=float(data["delta"]),
            n=int(data["n"]),
            k=int(data["k"]),
            order_statistic=float(data["order_statistic"]),
            scale=float(data["scale"]),
        )


def threshold_scores(
    scores: ArrayLike, epsilon: float, delta: float, mode: CalibrationMode = "pac"
) -> ScoreThreshold:
    """Calibrate a threshold on exchangeable scores (the core of every calibration).

    Parameters
    ----------
    scores : array_like, shape (n,)
        Non-negative, finite nonconformity scores of held-out samples.
    epsilon, delta : float
        Target violation rate and confidence parameter.
    mode : {"pac", "marginal"}
        Which guarantee (see the module docstring).

    Raises
    ------
    SampleSizeError
        If ``n`` is too small for ``(epsilon, delta)``; the message states the minimum.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> t = threshold_scores(rng.random(1000), epsilon=0.05, delta=0.01)
    >>> t.k, round(t.scale, 3)
    (966, 0.967)
    """
    check_mode(mode)
    check_eps_delta(epsilon, delta)
    s = np.asarray(scores, dtype=np.float64).ravel()
    if s.size == 0:
        raise SampleSizeError(
            f"no calibration scores; need at least {min_calibration_size(epsilon, delta, mode)} samples"
        )
    if not np.isfinite(s).all() or (s < 0).any():
        raise InvalidInputError("calibration scores must be finite and >= 0")
    n = int(s.size)
    k = calibration_index(n, epsilon, delta, mode)
    order_stat = float(np.partition(s, k - 1)[k - 1])
    scale = max(order_stat * (1.0 + SCALE_MARGIN), MIN_SCALE)
    return ScoreThreshold(
        mode=mode,
        epsilon=float(epsilon),
        delta=float(delta),
        n=n,
        k=k,
        order_statistic=order_stat,
        scale=scale,
    )


def guarantee_sentence(t: ScoreThreshold, who: str) -> str:
    """The guarantee of one threshold in one plain sentence, about ``who`` (e.g. "a new sample")."""
    if t.mode == "pac":
        return (
            f"With probability at least {1 - t.delta:.6g} over the draw of the {t.n} calibration samples, "
            f"the probability that the ground truth of {who} lies outside its calibrated ellipsoid is at "
            f"most {t.certified_epsilon:.4g} (target {t.epsilon:g}), provided calibration and deployment "
            "samples are exchangeable (e.g. i.i.d. from one distribution)."
        )
    return (
        f"Averaged over the draw of the {t.n} calibration samples, the probability that the ground truth "
        f"of {who} lies outside its calibrated ellipsoid is at most {t.epsilon:g} (marginal, not "
        "per calibration set), provided calibration and deployment samples are exchangeable."
    )
