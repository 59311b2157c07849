"""MAPIE's multivariate residual-normalised score as a peer (benchmark-only; needs ``mapie==1.6.0``).

MAPIE 1.6's experimental :class:`mapie.experimental.MultivariateResidualNormalisedScore`
(Braun, Berta, Jordan and Bach 2025) trains a network -- MAPIE's own ``Trainer``: a
ResNet-style MLP with a Cholesky head -- by Gaussian negative log-likelihood to predict a
mean ``mu(X)`` and a covariance ``Sigma(X)``; its conformity score is
``||Sigma(X)^{-1/2} (Y - mu(X))||``, whose level sets are ellipsoids.

How the benchmark uses it (so that its coverage is matched with every other method):

* ``X = concat(x, yhat)`` standardised with training statistics, and the target is
  the residual ``y - yhat`` divided by its per-axis training spread (MAPIE's trainer
  does not scale its inputs or targets; a careful user would). Its set for ``y`` is then
  ``E(yhat + sigma * mu, Sigma^{-1/2} diag(1 / sigma) / s)``.
* MAPIE 1.6 has no conformalisation step for this score (``get_estimation_distribution``
  raises ``NotImplementedError``: an ellipsoid is not an interval), so the radius ``s``
  is calibrated by :func:`ipcverify.calibration.threshold_scores` on MAPIE's scores of
  the calibration split, at the same ``(epsilon, delta, mode)`` as every other method.
  The scores are recomputed in float64 from the same ``Sigma`` as the sets, and checked
  against MAPIE's ``get_signed_conformity_scores`` (float32) to a relative 1e-4.
* Training: MAPIE's defaults (AdamW 1e-3, weight decay 1e-4, batch 32, 20 % of the
  training split held out to keep the best epoch) except the epoch count, which the
  benchmark sets (MAPIE's default, 300, takes minutes per fit on 2 cores).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray

from ipcverify.calibration._bounds import CalibrationMode
from ipcverify.calibration._threshold import ScoreThreshold, threshold_scores
from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.sets import Ellipsoid

__all__ = ["MAPIE_VERSION", "mapie_available", "MapieMultivariate", "fit_mapie_multivariate"]

FloatArray = NDArray[np.float64]
#: The MAPIE release the benchmark was written against.
MAPIE_VERSION = "1.6.0"


def mapie_available() -> str | None:
    """The installed MAPIE version if it is :data:`MAPIE_VERSION`, else None."""
    try:
        import mapie
    except ImportError:
        return None
    return mapie.__version__ if mapie.__version__ == MAPIE_VERSION else None


@dataclass(frozen=True, eq=False)
class MapieMultivariate:
    """A fitted MAPIE multivariate score with the benchmark's input and target scaling."""

    score: Any  # mapie.experimental.MultivariateResidualNormalisedScore
    in_mean: FloatArray
    in_std: FloatArray
    sigma: FloatArray
    threshold: ScoreThreshold | None = None

    def _inputs(self, x: FloatArray, yhat: FloatArray) -> NDArray[np.float32]:
        return ((np.hstack([x, yhat]) - self.in_mean) / self.in_std).astype(np.float32)

    def raw_arrays(self, x: FloatArray, yhat: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Centres (B, n) and unit-radius shapes ``Sigma^{-1/2} diag(1/sigma)`` (B, n, n), float64."""
        mu, cov = self.score.covariance_estimator_.get_distribution(self._inputs(x, yhat))
        cov = np.asarray(cov, dtype=np.float64)
        vals, vecs = np.linalg.eigh(cov)
        inv_half = (vecs / np.sqrt(vals)[:, None, :]) @ vecs.transpose(0, 2, 1)
        centers = np.asarray(yhat, dtype=np.float64) + self.sigma * np.asarray(mu, dtype=np.float64)
        return centers, inv_half / self.sigma

    def scores(self, data: PerceptionDataset) -> FloatArray:
        """Float64 scores ``||Sigma^{-1/2} ((y - yhat) / sigma - mu)||``, checked against MAPIE's own."""
        c, C = self.raw_arrays(data.x, data.yhat)
        g = np.linalg.norm(np.einsum("bij,bj->bi", C, data.y - c), axis=1)
        theirs = self.score.get_signed_conformity_scores(
            y=((data.y - data.yhat) / self.sigma).astype(np.float32), X=self._inputs(data.x, data.yhat)
        )
        if not np.allclose(g, theirs, rtol=1e-4, atol=1e-6):
            worst = float(np.max(np.abs(g - theirs) / np.maximum(np.abs(theirs), 1e-6)))
            raise InvalidInputError(f"MAPIE's scores and the float64 recomputation differ (rel. {worst:.2g})")
        return g

    def calibrate(
        self, calibration_data: PerceptionDataset, epsilon: float, delta: float, mode: CalibrationMode = "pac"
    ) -> MapieMultivariate:
        """Calibrate the radius with ipcverify's order statistic (same ``(epsilon, delta, mode)``)."""
        t = threshold_scores(self.scores(calibration_data), epsilon, delta, mode)
        return MapieMultivariate(self.score, self.in_mean, self.in_std, self.sigma, t)

    def predict(self, x: FloatArray, yhat: FloatArray) -> Ellipsoid:
        """Calibrated ellipsoids."""
        if self.threshold is None:
            raise InvalidInputError("calibrate the MAPIE peer first: .calibrate(calibration_data, ...)")
        c, C = self.raw_arrays(x, yhat)
        return Ellipsoid(c, C / self.threshold.scale)


def fit_mapie_multivariate(
    train_data: PerceptionDataset, epochs: int, seed: int = 0, batch_size: int = 32
) -> MapieMultivariate:
    """Fit MAPIE's covariance network on the training split (see the module docstring)."""
    if mapie_available() is None:
        raise InvalidInputError(f"the MAPIE peer needs mapie=={MAPIE_VERSION}: pip install -e '.[bench]'")
    from mapie.experimental import MultivariateResidualNormalisedScore

    inp = np.hstack([train_data.x, train_data.yhat])
    in_mean, in_std = inp.mean(axis=0), inp.std(axis=0)
    in_std = np.where(in_std > 0, in_std, 1.0)
    resid = train_data.y - train_data.yhat
    sigma = resid.std(axis=0)
    torch.manual_seed(seed)
    score = MultivariateResidualNormalisedScore(random_state=seed)
    X = ((inp - in_mean) / in_std).astype(np.float32)
    score.fit(X, (resid / sigma).astype(np.float32), num_epochs=epochs, batch_size=batch_size)
    return MapieMultivariate(score, in_mean, in_std, sigma)
