"""calibrate(): scale factors, model-file records, Mondrian groups, refusals, end-to-end guarantees."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import torch
from scipy import stats

from ipcverify.calibration import Global, Mondrian
from ipcverify.calibration._bounds import marginal_conformal_index, pac_calibration_index
from ipcverify.calibration._global_scale import GlobalCalibration
from ipcverify.calibration._kinds import calibration_from_dict
from ipcverify.calibration._mondrian import MondrianCalibration
from ipcverify.calibration._threshold import SCALE_MARGIN, threshold_scores
from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import network_fingerprint
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import DataError, InvalidInputError, ModelFileError, SampleSizeError
from ipcverify.io._modelio import load_model, save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train


@pytest.fixture(scope="module")
def model():
    torch.manual_seed(0)
    data = make_lagged_perception(1500, seed=0)
    cfg = ModelConfig(x_dim=6, y_dim=3, hidden=(16, 16))
    return train(data, cfg, TrainConfig(epochs=3, batch_size=128)).model


@pytest.fixture(scope="module")
def cal_data():
    return make_lagged_perception(3000, seed=11)


def _with_discrete_column(ds: PerceptionDataset, seed: int) -> PerceptionDataset:
    """Replace x_2 by a label in {0, 1, 2} (e.g. a weather class) so it can be a Mondrian group."""
    rng = np.random.default_rng(seed)
    x = ds.x.copy()
    x[:, 2] = rng.integers(0, 3, len(ds))
    return PerceptionDataset(x, ds.y, ds.yhat, source="discrete")


def test_threshold_is_the_kth_order_statistic():
    rng = np.random.default_rng(3)
    s = rng.exponential(size=777)
    for mode in ("pac", "marginal"):
        t = threshold_scores(s, 0.05, 0.01, mode)
        k = pac_calibration_index(777, 0.05, 0.01) if mode == "pac" else marginal_conformal_index(777, 0.05)
        assert t.k == k and t.n == 777
        assert t.order_statistic == np.sort(s)[k - 1]
        assert t.scale == pytest.approx(t.order_statistic * (1 + SCALE_MARGIN), rel=1e-15)
        assert (s <= t.scale).sum() >= k


def test_a_threshold_record_is_its_fields_in_order_and_reads_back():
    t = threshold_scores(np.arange(1.0, 101.0), 0.1, 0.05, "marginal")
    assert t.to_dict() == {
        "mode": "marginal", "epsilon": 0.1, "delta": 0.05, "n": 100, "k": 91, "order_statistic": 91.0,
        "scale": 91.0 * (1 + SCALE_MARGIN),
    }  # fmt: skip
    assert list(t.to_dict()) == ["mode", "epsilon", "delta", "n", "k", "order_statistic", "scale"]
    assert type(t).from_dict(t.to_dict()) == t


def test_calibrate_attaches_a_global_scale(model, cal_data):
    cal_model = calibrate(model, cal_data, epsilon=0.05, delta=0.01)
    cal = cal_model.calibration
    assert isinstance(cal, GlobalCalibration) and model.calibration is None
    scores = model.raw_scores(cal_data.x, cal_data.y, cal_data.yhat)
    k = pac_calibration_index(len(cal_data), 0.05, 0.01)
    assert cal.threshold.k == k
    assert cal.threshold.order_statistic == pytest.approx(np.sort(scores)[k - 1], rel=1e-12)
    assert cal.data_hash == cal_data.content_hash()
    assert cal.network_hash == network_fingerprint(model.network)
    # predict uses E(c, C / s): a truth is inside iff its raw score is <= s
    sets = cal_model.predict_unguarded(cal_data.x, cal_data.yhat)
    raw = model.predict_raw(cal_data.x, cal_data.yhat)
    np.testing.assert_allclose(sets.shapes, raw.shapes / cal.threshold.scale, rtol=1e-12)
    assert (sets.contains(cal_data.y) == (scores <= cal.threshold.scale)).all()
    assert sets.contains(cal_data.y).sum() >= k


def test_calibration_survives_the_model_file(model, cal_data, tmp_path):
    cal_model = calibrate(model, cal_data, 0.05, 0.01, Global(mode="marginal"))
    save_model(cal_model, tmp_path / "m.pt")
    back = load_model(tmp_path / "m.pt")
    assert back.calibration == cal_model.calibration
    np.testing.assert_array_equal(
        back.predict_unguarded(cal_data.x, cal_data.yhat).shapes,
        cal_model.predict_unguarded(cal_data.x, cal_data.yhat).shapes,
    )


def test_a_tampered_calibration_record_is_refused(model, cal_data, tmp_path):
    rec = calibrate(model, cal_data, 0.05, 0.01).calibration.to_dict()
    rec["k"] = rec["k"] - 40  # an order statistic too small for the claimed (epsilon, delta)
    with pytest.raises(InvalidInputError, match=r"below the k=\d+ that pac calibration requires"):
        calibration_from_dict(rec)
    with pytest.raises(InvalidInputError, match=r"unknown calibration kind 'magic'"):
        calibration_from_dict({"kind": "magic"})
    # through load_model the same record gives a ModelFileError (a user error, exit 2)
    bad = calibrate(model, cal_data, 0.05, 0.01)
    good_path = tmp_path / "good.pt"
    save_model(bad, good_path)
    payload = torch.load(good_path, weights_only=True)
    payload["calibration"]["scale"] = -1.0
    torch.save(payload, tmp_path / "bad.pt")
    with pytest.raises(ModelFileError, match=r"damaged calibration record"):
        load_model(tmp_path / "bad.pt")


def test_refuses_to_calibrate_twice_unless_recalibrating(model, cal_data):
    once = calibrate(model, cal_data, 0.05, 0.01)
    with pytest.raises(InvalidInputError, match=r"already calibrated.*recalibrate=True"):
        calibrate(once, cal_data, 0.05, 0.01)
    other = make_lagged_perception(2000, seed=12)
    again = calibrate(once, other, 0.1, 0.01, recalibrate=True)
    fresh = calibrate(model, other, 0.1, 0.01)
    # recalibration works on the raw network: same scale as calibrating the uncalibrated model
    assert again.calibration.threshold == fresh.calibration.threshold


def test_refusals_have_messages(model, cal_data):
    wrong = PerceptionDataset(np.zeros((800, 4)), np.zeros((800, 3)), np.zeros((800, 3)), source="wrong.csv")
    with pytest.raises(InvalidInputError, match=r"wrong.csv: calibration data has x_dim=4.*expects x_dim=6"):
        calibrate(model, wrong, 0.05, 0.01)
    with pytest.raises(SampleSizeError, match=r"at least 688 are needed"):
        calibrate(model, cal_data.subset(np.arange(500)), 0.01, 0.001)
    with pytest.raises(InvalidInputError, match=r"epsilon must lie strictly between 0 and 1"):
        calibrate(model, cal_data, 1.5, 0.01)
    with pytest.raises(InvalidInputError, match=r"mode must be 'pac' or 'marginal'"):
        calibrate(model, cal_data, 0.05, 0.01, Global(mode="bayes"))
    with pytest.raises(
        InvalidInputError, match=r"method must be a calibration spec \(Global\(...\), .*got 'pac'"
    ):
        calibrate(model, cal_data, 0.05, 0.01, "pac")  # the old positional mode
    with pytest.raises(InvalidInputError, match=r"domain must be a DomainSpec.*got 0.01"):
        calibrate(model, cal_data, 0.05, 0.01, domain=0.01)
    with pytest.raises(InvalidInputError, match=r"part of the ground truth y"):
        calibrate(model, cal_data, 0.05, 0.01, Mondrian(column="y_0"))
    with pytest.raises(DataError, match=r"no column 'speed'"):
        calibrate(model, cal_data, 0.05, 0.01, Mondrian(column="speed"))
    extra = PerceptionDataset(
        cal_data.x, cal_data.y, cal_data.yhat, extra={"weather": np.zeros(len(cal_data))}, source="log.csv"
    )
    with pytest.raises(InvalidInputError, match=r"extra column of log.csv.*cannot see at predict time"):
        calibrate(model, extra, 0.05, 0.01, Mondrian(column="weather"))


def test_refuses_the_training_data():
    data = make_lagged_perception(900, seed=5)
    m = train(data, ModelConfig(x_dim=6, y_dim=3, hidden=(4,)), TrainConfig(epochs=1)).model
    with pytest.raises(
        InvalidInputError, match=r"900 of 900 calibration rows are rows of the model's training data"
    ):
        calibrate(m, data, 0.05, 0.01)


def test_mondrian_discrete_groups(model):
    data = _with_discrete_column(make_lagged_perception(4000, seed=21), seed=1)
    cm = calibrate(model, data, 0.05, 0.03, Mondrian(column="x_2"))
    cal = cm.calibration
    assert isinstance(cal, MondrianCalibration)
    assert [g.value for g in cal.group_scales] == [0.0, 1.0, 2.0]
    assert cal.group_delta == pytest.approx(0.01)  # Bonferroni over 3 groups
    scores = model.raw_scores(data.x, data.y, data.yhat)
    for g in cal.group_scales:
        mask = data.x[:, 2] == g.value
        t = threshold_scores(scores[mask], 0.05, 0.01, "pac")
        assert g.threshold == t
    f = cm.calibration.scale_for(data.x, data.yhat)
    expected = np.array([cal.group_scales[int(v)].threshold.scale for v in data.x[:, 2]])
    np.testing.assert_array_equal(f, expected)
    assert calibration_from_dict(cal.to_dict()) == cal
    unseen = data.x[:5].copy()
    unseen[:, 2] = 7.0
    with pytest.raises(InvalidInputError, match=r"value 7, a group never seen in calibration"):
        cm.predict_unguarded(unseen, data.yhat[:5])


def test_mondrian_too_small_group_is_refused(model):
    data = _with_discrete_column(make_lagged_perception(1000, seed=22), seed=2)
    with pytest.raises(SampleSizeError, match=r"Mondrian group 'x_2=\d' has \d+ calibration samples"):
        calibrate(model, data, 0.01, 0.001, Mondrian(column="x_2"))


def test_mondrian_continuous_bins(model, cal_data):
    cm = calibrate(
        model, cal_data, 0.1, 0.05, Mondrian(column="x_3", bins=4, edge_fraction=0.2, mode="marginal")
    )
    cal = cm.calibration
    assert cal.binning == "bins" and len(cal.group_scales) == 4 and len(cal.edges) == 3
    assert cal.n_edge == 600 and cal.n == len(cal_data) - 600
    idx = cal.group_index(cal_data.x, cal_data.yhat)
    v = cal_data.x[:, 3]
    lo = np.array([-math.inf, *cal.edges])[idx]
    hi = np.array([*cal.edges, math.inf])[idx]
    assert ((lo <= v) & (v < hi)).all()
    # values far outside the calibration range fall in the outer bins
    far = cal_data.x[:2].copy()
    far[:, 3] = [-1e6, 1e6]
    assert list(cal.group_index(far, cal_data.yhat[:2])) == [0, 3]
    assert calibration_from_dict(cal.to_dict()) == cal
    with pytest.raises(InvalidInputError, match=r"looks continuous.*bins=K"):
        calibrate(model, cal_data, 0.1, 0.05, Mondrian(column="x_3"))


# ----------------------------------------------------------------------------- end to end
ALPHA_E2E = 1e-3 / 2  # two checks below


@pytest.fixture(scope="module")
def pool(model):
    """A large i.i.d. pool; calibration sets are drawn from it with replacement, so the pool's
    empirical distribution *is* the data distribution and violation rates are exact."""
    data = make_lagged_perception(60_000, seed=31)
    return data, model.raw_scores(data.x, data.y, data.yhat)


def test_end_to_end_marginal_coverage_through_calibrate(model, pool):
    data, scores = pool
    rng = np.random.default_rng(5)
    n, eps = 200, 0.1
    viol = []
    for _ in range(250):
        sub = data.subset(rng.integers(0, len(data), n))
        s = calibrate(model, sub, eps, 0.5, Global(mode="marginal")).calibration.threshold.scale
        viol.append(np.mean(scores > s))
    res = stats.ttest_1samp(np.array(viol), eps, alternative="greater")
    assert res.pvalue >= ALPHA_E2E, f"mean violation {np.mean(viol):.4f} significantly above {eps}"


def test_end_to_end_pac_through_calibrate(model, pool):
    data, scores = pool
    rng = np.random.default_rng(6)
    n, eps, delta, reps = 300, 0.1, 0.2, 250
    bad = 0
    for i in range(reps):
        sub = data.subset(rng.integers(0, len(data), n))
        cm = calibrate(model, sub, eps, delta)
        s = cm.calibration.threshold.scale
        bad += np.mean(scores > s) > eps
        if i == 0:  # the sets the model predicts agree with the score rule
            inside = cm.predict_unguarded(data.x[:5000], data.yhat[:5000]).contains(data.y[:5000])
            assert (inside == (scores[:5000] <= s)).all()
    assert stats.binom.sf(bad - 1, reps, delta) >= ALPHA_E2E


@pytest.mark.parametrize(("n", "hinted"), [(63, True), (64, False)])
def test_a_scale_set_by_the_largest_score_is_said_with_the_rows_that_would_allow_one(model, n, hinted):
    data = make_lagged_perception(n, seed=31)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cal = calibrate(model, data, 0.1, 0.01, domain=None).calibration
    assert (cal.groups()[0].k == n) is hinted  # 63 samples: k = n; 64: one may lie outside
    said = [str(w.message) for w in caught if "largest of the" in str(w.message)]
    assert len(said) == hinted
    if hinted:
        assert f"largest of the {n} calibration scores" in said[0] and "64 samples would allow one" in said[0]
