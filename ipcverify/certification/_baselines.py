"""State-independent baselines an IPC should beat, calibrated with the same bounds.

* :class:`GlobalMahalanobis` -- one ellipsoid shape for every input, centred on
  ``yhat + mean(e)`` with ``e = y - yhat``: ``E(yhat + mu, Sigma^{-1/2} / s)`` where
  ``mu, Sigma`` are the mean and covariance of the training residuals and ``s`` a
  calibrated radius (the Mahalanobis distance's order statistic).
* :class:`BonferroniBox` -- an axis-aligned box ``yhat + mu +/- h`` whose half-widths
  are calibrated per axis at ``epsilon / n`` (and ``delta / n`` in PAC mode); the union
  bound gives the same ``(epsilon, delta)`` statement for the box.

Both are fitted on training data and calibrated on held-out data through
:func:`ipcverify.calibration.threshold_scores`, so their guarantees are exactly those
of a calibrated IPC (``proofs/pac_calibration.md``); only the sets' sizes differ.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.calibration._bounds import CalibrationMode
from ipcverify.calibration._threshold import ScoreThreshold, threshold_scores
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.sets._ellipsoid import Ellipsoid

FloatArray = NDArray[np.float64]


def _residuals(data: PerceptionDataset) -> FloatArray:
    return np.asarray(data.y - data.yhat, dtype=np.float64)


def _not_calibrated(name: str) -> InvalidInputError:
    return InvalidInputError(
        f"the {name} baseline is not calibrated yet; call .calibrate(calibration_data, ...)"
    )


@dataclass(frozen=True)
class Boxes:
    """A batch of axis-aligned boxes ``[lower, upper]`` (B, n).

    Parameters
    ----------
    lower, upper : ndarray, shape (B, n)
        Lower and upper corners of each box.

    Examples
    --------
    >>> b = Boxes(np.zeros((1, 2)), np.array([[2.0, 3.0]]))
    >>> bool(b.contains(np.array([[1.0, 1.0]]))[0]), round(float(b.log_volume()[0]), 4)
    (True, 1.7918)
    """

    lower: FloatArray
    upper: FloatArray

    def __post_init__(self) -> None:
        lo = np.array(self.lower, dtype=np.float64, ndmin=2)
        hi = np.array(self.upper, dtype=np.float64, ndmin=2)
        if lo.shape != hi.shape or lo.ndim != 2:
            raise InvalidInputError(f"box bounds must both have shape (B, n); got {lo.shape} and {hi.shape}")
        if not (np.isfinite(lo).all() and np.isfinite(hi).all()) or (lo > hi).any():
            raise InvalidInputError("box bounds must be finite with lower <= upper")
        lo.setflags(write=False)
        hi.setflags(write=False)
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", hi)

    @property
    def batch_size(self) -> int:
        """Number of boxes."""
        return int(self.lower.shape[0])

    def contains(self, y: ArrayLike) -> NDArray[np.bool_]:
        """``y_b`` lies in box ``b`` (boundary included)."""
        p = np.asarray(y, dtype=np.float64)
        return np.asarray(((p >= self.lower) & (p <= self.upper)).all(axis=1), dtype=np.bool_)

    def log_volume(self) -> FloatArray:
        """Natural log of each box's volume (``-inf`` for a flat box)."""
        with np.errstate(divide="ignore"):
            return np.log(self.upper - self.lower).sum(axis=1)


@dataclass(frozen=True, kw_only=True)
class GlobalMahalanobis:
    """One Mahalanobis ellipsoid around ``yhat + mean`` for every input.

    Attributes
    ----------
    mean : array (n,)
        Mean training residual ``y - yhat``.
    shape : array (n, n)
        ``L^{-1}`` with ``Sigma = L L^T`` the residual covariance, so that
        ``||shape (e - mean)||`` is the Mahalanobis distance.
    threshold : ScoreThreshold or None
        The calibrated radius (``None`` until :meth:`calibrate`).

    Examples
    --------
    >>> from ipcverify import example
    >>> base = fit_global_mahalanobis(example(2000, seed=0).data)
    >>> cal = base.calibrate(example(2000, seed=1).data, epsilon=0.05, delta=0.01)
    >>> cal.predict(np.zeros((2, 6)), np.zeros((2, 3))).batch_size
    2
    """

    mean: FloatArray
    shape: FloatArray
    threshold: ScoreThreshold | None = None

    def __post_init__(self) -> None:
        m = np.array(self.mean, dtype=np.float64).ravel()
        s = np.array(self.shape, dtype=np.float64)
        if s.shape != (m.size, m.size) or not (np.isfinite(m).all() and np.isfinite(s).all()):
            raise InvalidInputError("Mahalanobis baseline: mean (n,) and shape (n, n) must be finite")
        m.setflags(write=False)
        s.setflags(write=False)
        object.__setattr__(self, "mean", m)
        object.__setattr__(self, "shape", s)

    def scores(self, data: PerceptionDataset) -> FloatArray:
        """Mahalanobis distances ``||shape (y - yhat - mean)||`` (n,)."""
        if data.y_dim != self.mean.size:
            raise InvalidInputError(f"data has y_dim={data.y_dim}; the baseline has {self.mean.size}")
        return np.linalg.norm((_residuals(data) - self.mean) @ self.shape.T, axis=1)

    def calibrate(
        self, calibration_data: PerceptionDataset, epsilon: float, delta: float, mode: CalibrationMode = "pac"
    ) -> GlobalMahalanobis:
        """The baseline with its radius calibrated on held-out data."""
        return replace(self, threshold=threshold_scores(self.scores(calibration_data), epsilon, delta, mode))

    def predict(self, x: ArrayLike, yhat: ArrayLike) -> Ellipsoid:
        """Calibrated sets ``E(yhat + mean, shape / scale)`` (``x`` is ignored: the baseline is global)."""
        if self.threshold is None:
            raise _not_calibrated("Mahalanobis")
        yh = np.asarray(yhat, dtype=np.float64).reshape(-1, self.mean.size)
        shapes = np.broadcast_to(self.shape / self.threshold.scale, (len(yh), *self.shape.shape))
        return Ellipsoid(yh + self.mean, shapes)


def fit_global_mahalanobis(train_data: PerceptionDataset) -> GlobalMahalanobis:
    """Fit the residual mean and covariance on training data (uncalibrated baseline).

    Parameters
    ----------
    train_data : PerceptionDataset
        Training data; its residuals ``y - yhat`` give the mean and covariance.

    Raises
    ------
    InvalidInputError
        If the residual covariance is singular (fewer than ``n + 1`` distinct samples,
        or a residual that is always zero).
    """
    e = _residuals(train_data)
    if len(e) <= e.shape[1]:
        raise InvalidInputError(f"need more than {e.shape[1]} training samples to fit a covariance")
    cov = np.atleast_2d(np.cov(e, rowvar=False))
    try:
        L = np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        raise InvalidInputError(
            "the residual covariance y - yhat is singular (some direction never varies); "
            "a Mahalanobis ellipsoid does not exist for this data"
        ) from None
    return GlobalMahalanobis(mean=e.mean(axis=0), shape=np.linalg.inv(L))


@dataclass(frozen=True, kw_only=True)
class BonferroniBox:
    """Axis-aligned box ``yhat + mean +/- h`` calibrated per axis at ``epsilon / n``.

    Attributes
    ----------
    mean : ndarray, shape (n,)
        Mean residual ``y - yhat`` of the training data: the boxes are centred at ``yhat + mean``.
    thresholds : tuple of ScoreThreshold
        Per-axis half-widths ``h``, calibrated at ``epsilon / n`` each (empty before :meth:`calibrate`).

    Examples
    --------
    >>> from ipcverify import example
    >>> box = fit_bonferroni_box(example(2000, seed=0).data)
    >>> box = box.calibrate(example(3000, seed=1).data, epsilon=0.05, delta=0.01)
    >>> len(box.thresholds)
    3
    """

    mean: FloatArray
    thresholds: tuple[ScoreThreshold, ...] = ()

    def __post_init__(self) -> None:
        m = np.array(self.mean, dtype=np.float64).ravel()
        if not np.isfinite(m).all():
            raise InvalidInputError("box baseline: mean must be finite")
        if self.thresholds and len(self.thresholds) != m.size:
            raise InvalidInputError(f"box baseline: need one threshold per axis ({m.size})")
        m.setflags(write=False)
        object.__setattr__(self, "mean", m)

    def axis_scores(self, data: PerceptionDataset) -> FloatArray:
        """``|y_j - yhat_j - mean_j|`` per sample and axis (N, n)."""
        if data.y_dim != self.mean.size:
            raise InvalidInputError(f"data has y_dim={data.y_dim}; the baseline has {self.mean.size}")
        return np.abs(_residuals(data) - self.mean)

    def calibrate(
        self, calibration_data: PerceptionDataset, epsilon: float, delta: float, mode: CalibrationMode = "pac"
    ) -> BonferroniBox:
        """Per-axis calibration at ``epsilon / n`` (``delta / n``); union bound: ``(epsilon, delta)``."""
        s = self.axis_scores(calibration_data)
        n = s.shape[1]
        ths = tuple(threshold_scores(s[:, j], epsilon / n, delta / n, mode) for j in range(n))
        return replace(self, thresholds=ths)

    def predict(self, x: ArrayLike, yhat: ArrayLike) -> Boxes:
        """Calibrated boxes (``x`` is ignored)."""
        if not self.thresholds:
            raise _not_calibrated("Bonferroni box")
        yh = np.asarray(yhat, dtype=np.float64).reshape(-1, self.mean.size)
        h = np.array([t.scale for t in self.thresholds])
        return Boxes(yh + self.mean - h, yh + self.mean + h)


def fit_bonferroni_box(train_data: PerceptionDataset) -> BonferroniBox:
    """Fit the residual mean on training data (uncalibrated box baseline).

    Parameters
    ----------
    train_data : PerceptionDataset
        Training data; its residuals ``y - yhat`` give the mean.
    """
    return BonferroniBox(mean=_residuals(train_data).mean(axis=0))
