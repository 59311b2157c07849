"""Global Mahalanobis and Bonferroni box baselines: fitting, calibration, guarantees, errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from ipcverify.calibration._bounds import pac_calibration_index
from ipcverify.certification._baselines import Boxes, fit_bonferroni_box, fit_global_mahalanobis
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import InvalidInputError

TRAIN = make_lagged_perception(3000, seed=40)
CAL = make_lagged_perception(3000, seed=41)


def _gaussian_residuals(n: int, seed: int, cov: np.ndarray, mean: np.ndarray) -> PerceptionDataset:
    rng = np.random.default_rng(seed)
    yhat = rng.normal(size=(n, len(mean)))
    e = rng.multivariate_normal(mean, cov, size=n)
    return PerceptionDataset(np.zeros((n, 1)), yhat + e, yhat, source="gauss")


def test_mahalanobis_scores_are_mahalanobis_distances():
    base = fit_global_mahalanobis(TRAIN)
    e = TRAIN.y - TRAIN.yhat
    mu, cov = e.mean(0), np.cov(e, rowvar=False)
    d = e[:50] - mu
    ref = np.sqrt(np.einsum("bi,ij,bj->b", d, np.linalg.inv(cov), d))
    np.testing.assert_allclose(base.scores(TRAIN.subset(np.arange(50))), ref, rtol=1e-10)


def test_mahalanobis_calibration_uses_the_pac_order_statistic():
    base = fit_global_mahalanobis(TRAIN).calibrate(CAL, 0.02, 0.01)
    k = pac_calibration_index(len(CAL), 0.02, 0.01)
    assert base.threshold.k == k
    assert base.threshold.order_statistic == np.sort(base.scores(CAL))[k - 1]
    sets = base.predict(CAL.x, CAL.yhat)
    assert sets.contains(CAL.y).sum() >= k
    np.testing.assert_allclose(sets.g(CAL.y), base.scores(CAL) / base.threshold.scale, rtol=1e-10)


def test_mahalanobis_radius_matches_the_chi_law_for_gaussian_errors():
    """With Gaussian residuals the Mahalanobis score is chi(3): the calibrated radius is its quantile."""
    cov = np.array([[1.0, 0.3, 0.0], [0.3, 2.0, -0.4], [0.0, -0.4, 0.5]])
    mean = np.array([0.1, -0.2, 0.0])
    base = fit_global_mahalanobis(_gaussian_residuals(50_000, 1, cov, mean))
    cal = base.calibrate(_gaussian_residuals(20_000, 2, cov, mean), 0.1, 0.01, mode="marginal")
    # the order statistic near the 0.9 quantile has sd ~ sqrt(0.09 / n) / density; 5 sd tolerance
    q = stats.chi(3).ppf(0.9)
    sd = np.sqrt(0.9 * 0.1 / 20_000) / stats.chi(3).pdf(q)
    assert abs(cal.threshold.order_statistic - q) < 5 * sd + 0.01  # + estimation error of mean/cov


def test_box_union_bound_calibration():
    box = fit_bonferroni_box(TRAIN).calibrate(CAL, 0.03, 0.03)
    assert [t.epsilon for t in box.thresholds] == pytest.approx([0.01] * 3)
    assert [t.delta for t in box.thresholds] == pytest.approx([0.01] * 3)
    s = box.axis_scores(CAL)
    for j, t in enumerate(box.thresholds):
        assert t.order_statistic == np.sort(s[:, j])[t.k - 1]
    boxes = box.predict(CAL.x, CAL.yhat)
    inside = boxes.contains(CAL.y)
    per_axis = s <= np.array([t.scale for t in box.thresholds])
    assert (inside == per_axis.all(axis=1)).all()
    h = np.array([t.scale for t in box.thresholds])
    np.testing.assert_allclose(boxes.log_volume(), np.log(2 * h).sum())


def test_boxes_type():
    b = Boxes(np.zeros((2, 2)), np.ones((2, 2)))
    assert b.batch_size == 2 and list(b.contains(np.array([[0.5, 1.0], [1.5, 0.0]]))) == [True, False]
    with pytest.raises(InvalidInputError, match=r"lower <= upper"):
        Boxes(np.ones((1, 2)), np.zeros((1, 2)))


def test_errors():
    with pytest.raises(InvalidInputError, match=r"not calibrated yet"):
        fit_global_mahalanobis(TRAIN).predict(TRAIN.x, TRAIN.yhat)
    with pytest.raises(InvalidInputError, match=r"not calibrated yet"):
        fit_bonferroni_box(TRAIN).predict(TRAIN.x, TRAIN.yhat)
    flat = PerceptionDataset(np.zeros((10, 1)), np.ones((10, 2)), np.ones((10, 2)))
    with pytest.raises(InvalidInputError, match=r"covariance y - yhat is singular"):
        fit_global_mahalanobis(flat)
    with pytest.raises(InvalidInputError, match=r"need more than 2 training samples"):
        fit_global_mahalanobis(flat.subset([0, 1]))
    other = PerceptionDataset(np.zeros((10, 1)), np.ones((10, 2)), np.zeros((10, 2)))
    with pytest.raises(InvalidInputError, match=r"data has y_dim=2; the baseline has 3"):
        fit_global_mahalanobis(TRAIN).scores(other)
