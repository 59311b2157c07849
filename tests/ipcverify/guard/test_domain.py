"""The domain-of-validity test: its false-alarm guarantee, its power on shifts, storage, queries."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.decision._landing import Verdict
from ipcverify.decision._landing_query import LandingQuery
from ipcverify.decision._query import IPCQuery
from ipcverify.errors import DataError, InvalidInputError, SampleSizeError, SetError
from ipcverify.guard._domain import DomainModel
from ipcverify.guard._domain_report import DomainReport
from ipcverify.io._modelio import load_model, save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.sets._box import Box
from ipcverify.training._train import TrainConfig, train

G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])
#: Level of the one-sided binomial tests below (seeded: deterministic, but the tolerance is statistical).
LEVEL = 1e-3


def _draw(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Correlated, non-Gaussian inputs: a curved 2-D manifold in 5-D plus noise."""
    u = rng.uniform(-1, 1, (n, 2))
    x = np.column_stack([u[:, 0], u[:, 1], u[:, 0] ** 2]) + 0.05 * rng.standard_normal((n, 3))
    yhat = np.column_stack([np.sin(2 * u[:, 0]), u[:, 0] * u[:, 1]]) + 0.05 * rng.standard_normal((n, 2))
    return x, yhat


def _false_alarms(flag_rate_fit: float, draws: int = 1500, n: int = 300) -> int:
    """One fresh exchangeable query per independent calibration draw: flagged or not."""
    flagged = 0
    for seed in range(draws):
        rng = np.random.default_rng(seed)
        x, yhat = _draw(rng, n + 1)
        dom = DomainModel.fit(x[:n], yhat[:n], flag_rate=flag_rate_fit)
        flagged += int(not dom.contains(x[n:], yhat[n:])[0])
    return flagged


@pytest.mark.slow
def test_in_distribution_false_alarm_rate_is_at_most_the_flag_rate():
    """Marginal guarantee: P(flag) <= flag_rate, so the count is stochastically below
    Binomial(draws, flag_rate)."""
    flag_rate, draws = 0.05, 1500
    flagged = _false_alarms(flag_rate, draws)
    p_value = stats.binom.sf(flagged - 1, draws, flag_rate)  # P(Bin(draws, flag_rate) >= flagged)
    assert p_value > LEVEL, f"{flagged}/{draws} flagged at flag_rate={flag_rate}"


@pytest.mark.slow
def test_the_false_alarm_check_has_power_against_a_wrong_threshold():
    """A threshold fitted at 3 flag_rate, claimed as flag_rate, is caught by the same test."""
    flag_rate, draws = 0.05, 1500
    flagged = _false_alarms(3 * flag_rate, draws)
    assert stats.binom.sf(flagged - 1, draws, flag_rate) < LEVEL, f"{flagged}/{draws} not caught"


def test_shifted_queries_are_flagged_and_in_range_gaps_too():
    rng = np.random.default_rng(0)
    x, yhat = _draw(rng, 3000)
    dom = DomainModel.fit(x, yhat, flag_rate=0.01)
    xt, yt = _draw(np.random.default_rng(1), 2000)
    assert 1 - dom.contains(xt, yt).mean() < 0.03
    assert 1 - dom.contains(3 * xt, 3 * yt).mean() > 0.9  # ranges x3
    # inside every column's range, but off the manifold: x_2 = x_0^2 broken
    off = xt.copy()
    off[:, 2] = 1.0 - off[:, 2]
    inside_ranges = ((off >= x.min(0)) & (off <= x.max(0))).all(axis=1)
    assert inside_ranges.mean() > 0.9
    assert 1 - dom.contains(off[inside_ranges], yt[inside_ranges]).mean() > 0.5


def test_single_query_membership_agrees_with_the_batch():
    rng = np.random.default_rng(2)
    x, yhat = _draw(rng, 2000)
    dom = DomainModel.fit(x, yhat, flag_rate=0.05, k=3)
    xt, yt = _draw(np.random.default_rng(3), 300)
    xt[::3] *= 2.5
    batch = dom.contains(xt, yt)
    single = [dom.contains_one(np.concatenate([a, b])) for a, b in zip(xt, yt, strict=True)]
    assert batch.tolist() == single and 0 < batch.sum() < len(batch)
    assert not dom.contains_one(np.full(5, np.nan))


def test_fit_refuses_too_few_inputs_and_bad_settings():
    x, yhat = _draw(np.random.default_rng(4), 50)
    with pytest.raises(SampleSizeError, match=r"needs at least 99 calibration inputs; got 50") as exc:
        DomainModel.fit(x, yhat, flag_rate=0.01)
    assert str(exc.value).endswith(
        "(with 50 inputs the flag rate must be at least 1/51: flag_rate=0.0197 works)"
    )
    assert DomainModel.fit(x, yhat, flag_rate=0.0197).flag_rate == 0.0197  # the flag rate it names is enough
    with pytest.raises(SampleSizeError, match="needs at least"):
        DomainModel.fit(x, yhat, flag_rate=0.0196)  # and 1/51 = 0.019607... is the least
    with pytest.raises(InvalidInputError, match="flag_rate must lie strictly between 0 and 1"):
        DomainModel.fit(x, yhat, flag_rate=1.5)
    with pytest.raises(InvalidInputError, match="k must be a positive integer"):
        DomainModel.fit(x, yhat, flag_rate=0.1, k=0)
    dom = DomainModel.fit(x, yhat, flag_rate=0.1)
    with pytest.raises(InvalidInputError, match="fitted on 5"):
        dom.contains(np.zeros((1, 2)), np.zeros((1, 2)))


def test_report_counts_and_says_what_the_certificate_does_not_promise():
    r = DomainReport(
        method="m", flag_rate=0.01, threshold=1.0, n_reference=500, n=1000, outside=300,
        violations_inside=7, violations_outside=40,
    )  # fmt: skip
    assert r.well_above_flag_rate and r.outside_fraction == 0.3
    text = r.sentence()
    assert "300 of 1000 queries (30.00 %)" in text and "promises nothing" in text and "shifted" in text
    quiet = DomainReport(method="m", flag_rate=0.01, threshold=1.0, n_reference=500, n=1000, outside=12)
    assert not quiet.well_above_flag_rate  # 12 of 1000 at a flag rate of 1 %: what false alarms explain
    assert r.to_dict()["outside_fraction"] == 0.3 and r.to_dict()["statement"] == text


@pytest.fixture(scope="module")
def calibrated():
    data = make_lagged_perception(1500, seed=0)
    model = train(data, ModelConfig(x_dim=6, y_dim=3, hidden=(16,)), TrainConfig(epochs=2, seed=0)).model
    return calibrate(model, make_lagged_perception(2000, seed=1), 0.05, 0.01)


def test_calibrate_fits_the_domain_and_the_model_file_keeps_it(calibrated, tmp_path):
    dom = calibrated.domain
    assert dom is not None and dom.n == 2000 and dom.flag_rate == 0.01
    save_model(calibrated, tmp_path / "m.pt")
    again = load_model(tmp_path / "m.pt").domain
    assert again is not None and again.threshold == dom.threshold
    np.testing.assert_array_equal(again.reference, dom.reference)
    none = calibrate(
        calibrated, make_lagged_perception(2000, seed=1), 0.05, 0.01, recalibrate=True, domain=None
    )
    assert none.domain is None


def test_the_query_path_answers_outside_domain_never_accept(calibrated):
    q = LandingQuery(IPCQuery(calibrated), Box([-10.0, -10.0, -10.0], [10.0, 10.0, 10.0]))
    test = make_lagged_perception(50, seed=7)
    inside = q.decide(test.x[0], test.yhat[0])
    assert inside.in_domain and inside.verdict in (Verdict.ACCEPT, Verdict.REJECT)
    far = q.decide(test.x[0] * 40.0, test.yhat[0] * 40.0)
    assert far.verdict is Verdict.OUTSIDE_DOMAIN and not far.accept and far.proof is None
    assert q.decide_float(test.x[0] * 40.0, test.yhat[0] * 40.0).verdict is Verdict.OUTSIDE_DOMAIN


def test_a_degenerate_set_is_an_outside_domain_answer_not_an_accept():
    q = LandingQuery(
        IPCQuery(IPCModel(IPCNetwork(ModelConfig(x_dim=1, y_dim=3, hidden=(2,), param="cholesky")))), G
    )
    d = q.rule.decide(np.zeros(3), np.zeros((3, 3)))
    assert d.verdict is Verdict.OUTSIDE_DOMAIN and not d.accept


@pytest.mark.parametrize(("recipe", "far"), [("v1", 1e30), ("tight", 1e200)])
def test_a_singular_set_on_a_far_input_blames_the_input(recipe, far):
    data = make_lagged_perception(600, seed=0)
    model = train(data, train_config=TrainConfig.recipe(recipe, epochs=1), recipe=recipe).model
    cal = calibrate(model, make_lagged_perception(800, seed=1), 0.05, 0.01)
    with pytest.raises(
        SetError, match=r"input row 0 \(0-based\): the contract's set is degenerate .* outside the domain"
    ):
        cal.predict_unguarded(np.full((1, 6), far), np.zeros((1, 3)))
    q = LandingQuery(IPCQuery(cal), Box([-10.0, -10.0, -10.0], [10.0, 10.0, 10.0]))
    assert q.decide(np.full(6, far), np.zeros(3)).verdict is Verdict.OUTSIDE_DOMAIN


def test_predict_sets_decides_in_domain_without_the_distances_and_computes_them_when_read(calibrated):
    from ipcverify.contract._prediction import predict_sets
    from ipcverify.data._dataset import PerceptionInputs

    test = make_lagged_perception(300, seed=9)
    x = test.x.copy()
    x[:40] += 50.0  # states never seen
    pred = predict_sets(calibrated, PerceptionInputs(x, test.yhat))
    assert "distance" not in vars(pred)  # not computed by predict_sets itself
    d = pred.distance
    dom = calibrated.domain
    assert np.array_equal(pred.in_domain, (d <= dom.threshold) & ~pred.singular)
    assert not pred.in_domain[:40].any() and pred.in_domain[40:].mean() > 0.9
    assert pred.domain is not None and pred.domain.outside == int((d > dom.threshold).sum())


def test_repeated_calibration_inputs_are_one_point_each_and_the_radius_is_not_0():
    """Every input twice (a doubled calibration file) gave radius 0 and flagged every fresh query."""
    x, yhat = _draw(np.random.default_rng(21), 400)
    once = DomainModel.fit(x, yhat, flag_rate=0.05)
    rng = np.random.default_rng(22)
    order = np.r_[np.arange(400), rng.integers(0, 400, 700)]  # every input, then 700 repeats of them
    repeated = DomainModel.fit(x[order], yhat[order], flag_rate=0.05)
    assert repeated.n == once.n == 400 and repeated.threshold == once.threshold > 0
    for name in ("mean", "whitening", "reference"):
        np.testing.assert_array_equal(getattr(repeated, name), getattr(once, name))
    fresh_x, fresh_yhat = _draw(np.random.default_rng(23), 1000)
    np.testing.assert_array_equal(repeated.contains(fresh_x, fresh_yhat), once.contains(fresh_x, fresh_yhat))
    groups = np.r_[np.arange(400) // 10, 1000 + np.arange(700)]  # a repeat keeps its first input's group
    by_group = DomainModel.fit(x[order], yhat[order], flag_rate=0.05, groups=groups)
    assert by_group.n == 400 and by_group.n_groups == 40 and by_group.threshold > 0


def test_the_threshold_is_raised_to_the_smallest_positive_score_and_all_zero_scores_are_refused():
    """Inputs distinct in float64 whose whitened distances underflow to 0: the radius is never 0."""
    rng = np.random.default_rng(24)
    base = rng.uniform(-1.0, 1.0, (300, 2))
    tiny = np.r_[np.zeros(300), np.full(300, 1e-300)][:, None]  # twins that differ by 1e-300 only
    x, yhat = np.hstack([np.vstack([base, base]), tiny]), np.vstack([base, base])[:, :1]
    with pytest.raises(
        DataError, match=r"lie at distance 0 from each other in float64, so no radius can be set"
    ):
        DomainModel.fit(x, yhat, flag_rate=0.01)
    spread = rng.uniform(-1.0, 1.0, (5, 2))  # 5 inputs without a twin: 5 positive scores of 605
    x2 = np.vstack([x, np.hstack([spread, np.zeros((5, 1))])])
    yhat2 = np.vstack([yhat, spread[:, :1]])
    dom = DomainModel.fit(x2, yhat2, flag_rate=0.01)
    from scipy.spatial import cKDTree

    loo = cKDTree(dom.reference).query(dom.reference, k=2)[0][:, 1]
    assert (loo == 0).sum() == 600 and dom.threshold == loo[loo > 0].min() > 0
