"""Seeded checks of the tightness tools: the diagnosis finds planted errors; the default beats the global."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks.diagnose_tightness import diagnose, toy_check  # noqa: E402
from benchmarks.oracle_data import make_fresh_lagged, make_hetlag  # noqa: E402
from ipcverify.certification._baselines import fit_global_mahalanobis  # noqa: E402
from ipcverify.contract._calibrate import calibrate  # noqa: E402
from ipcverify.training._train import TrainConfig, train  # noqa: E402


def test_the_diagnosis_recovers_a_planted_centre_bias_and_a_planted_shape_error():
    r = toy_check(seed=0, n=3000, m=300)
    assert r["all_passed"], r["checks"]
    f = {k: r[k]["factors"] for k in ("planted_centre_bias", "planted_rel_scale", "planted_orientation")}
    assert f["planted_centre_bias"]["centre"] > 1.3  # a whitened bias of norm 1: x1.46 at q = 0.99
    assert f["planted_orientation"]["orientation"] > 3.0  # aspect diag(2, 1, 1/2): x3.86
    assert r["planted_centre_bias"]["stats"]["mean_whitened_bias"] == pytest.approx(1.0, abs=1e-9)


def test_the_oracle_is_the_law_of_the_data():
    """Coverage of the exact oracle sets is 1 - epsilon: 20,000 draws, a binomial 5-sd band."""
    for make in (
        lambda n, s: make_hetlag(n, s, "gauss"),
        lambda n, s: make_hetlag(n, s, "t4"),
        make_fresh_lagged,
    ):
        data, orc = make(20_000, 4)
        covered = orc.sets(orc.radius(0.9)).contains(data.y)
        assert abs(covered.mean() - 0.9) < 5 * np.sqrt(0.09 / 20_000)


def test_the_diagnosis_factors_multiply_to_the_volume_ratio():
    data, orc = make_hetlag(2000, 5)
    gm = fit_global_mahalanobis(make_hetlag(2000, 6)[0]).calibrate(make_hetlag(2000, 7)[0], 0.05, 0.05)
    d = diagnose(
        gm.predict(data.x, data.yhat), orc, q=0.95, pac_k=gm.threshold.k, pac_n=gm.threshold.n, m=100
    )
    f, sym = d.factors, d.factors_symmetric
    ratio = d.volume_ratio
    assert f["centre"] * f["rel_scale"] * f["orientation"] * f["calibration"] == pytest.approx(ratio)
    assert sym["centre"] * sym["shape"] * sym["calibration"] == pytest.approx(ratio)
    assert f["pac_margin"] * f["draw"] == pytest.approx(f["calibration"])
    assert ratio > 5  # one ellipsoid for every input is far from the heteroscedastic oracle


def test_the_ratio_at_the_methods_own_coverage_compares_sizes_at_equal_coverage():
    """The oracle's own shape at a wider radius covers more than q: at q it is charged
    1.2^3 = 1.73x, at its own coverage 1x. The tolerance is five Monte Carlo standard errors
    of the coverage estimate (N m independent draws), carried to volume through the density
    of ||u|| (chi with 3 degrees of freedom): dV/V = 3 dq / (r f(r))."""
    n, m, q = 2000, 200, 0.99
    _, orc = make_hetlag(n, 8)
    wide = orc.sets(1.2 * orc.radius(q))
    d = diagnose(wide, orc, q=q, m=m, seed=3)
    covered = d.stats["population_coverage"]
    r = stats.chi.ppf(covered, 3)
    tol = 3 * 5 * np.sqrt(covered * (1 - covered) / (n * m)) / (r * stats.chi.pdf(r, 3))
    assert d.volume_ratio == pytest.approx(1.2**3, rel=1e-9)
    assert abs(np.log(d.volume_ratio_same_coverage)) < tol
    assert covered > q
    # a shape error is still charged at equal coverage
    gm = fit_global_mahalanobis(make_hetlag(2000, 6)[0]).calibrate(make_hetlag(2000, 7)[0], 0.05, 0.05)
    data, orc2 = make_hetlag(2000, 5)
    g = diagnose(gm.predict(data.x, data.yhat), orc2, q=0.95, m=100)
    assert g.volume_ratio_same_coverage > 5


def test_the_default_recipe_beats_the_global_ellipsoid_by_a_fixed_margin():
    """Deterministic: fixed data and training seeds. On heteroscedastic data the learned sets must be
    at most a quarter of the global ellipsoid's mean volume at the same PAC level (measured: ~0.03)."""
    train_data = make_hetlag(2000, 100)[0]
    cal_data = make_hetlag(2000, 101)[0]
    test = make_hetlag(2000, 102)[0]
    model = train(train_data, train_config=TrainConfig(seed=0)).model
    ipc = calibrate(model, cal_data, 0.05, 0.01).predict_unguarded(test.x, test.yhat)
    gm = fit_global_mahalanobis(train_data).calibrate(cal_data, 0.05, 0.01).predict(test.x, test.yhat)
    ratio = float(np.exp(ipc.log_volume()).mean() / np.exp(gm.log_volume()).mean())
    assert ratio < 0.25, ratio
    assert ipc.contains(test.y).mean() >= 0.95 - 3 * np.sqrt(0.05 * 0.95 / 2000)
