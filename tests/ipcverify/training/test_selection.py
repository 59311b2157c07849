"""The paper's recipe: its network, its start at yhat, and the rule that chooses what it leaves unstated."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from ipcverify.calibration._bounds import clopper_pearson_upper
from ipcverify.certification._baselines import fit_global_mahalanobis
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.data._dataset import PerceptionDataset, load_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._selection import Candidate, HingeSelection
from ipcverify.training._train import TrainConfig, select_hinge, train

REAL_LOG = Path(__file__).resolve().parents[3] / "data" / "euroc_mh04_vislam.csv"


def _cand(alpha: float, misses: int, volume: float, n: int = 1000) -> Candidate:
    return Candidate(alpha=alpha, lam=0.01, batch_size=64, val_n=n, val_misses=misses, val_log_volume=volume)


def test_the_rule_takes_the_smallest_volume_that_meets_the_target_else_the_fewest_misses():
    rule = HingeSelection(target_miss=0.002)
    record = rule.choose([_cand(0.1, 2, -9.0), _cand(0.3, 1, -8.0), _cand(1.0, 3, -12.0)])
    assert (record.chosen.alpha, record.target_met) == (0.1, True)  # 2/1000 meets 0.2 %; 3/1000 does not
    record = rule.choose([_cand(0.1, 5, -9.0), _cand(0.3, 4, -8.0), _cand(1.0, 4, -8.5)])
    assert (record.chosen.alpha, record.target_met) == (1.0, False)  # fewest misses, then smallest volume
    assert "no candidate met the target" in record.summary()
    assert record.to_dict()["chosen"]["val_misses"] == 4


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"alphas": ()}, "at least one value in alphas"),
        ({"alphas": (0.0,)}, "every alpha must be > 0"),
        ({"lams": (-1.0,)}, "every lambda must be >= 0"),
        ({"batch_sizes": (0,)}, "positive integer"),
        ({"target_miss": 1.0}, "target_miss"),
        ({"val_fraction": 0.0}, "val_fraction"),
    ],
)
def test_bad_rules_are_refused(kwargs, match):
    with pytest.raises(InvalidInputError, match=match):
        HingeSelection(**kwargs)


@pytest.mark.parametrize("center", ["raw", "offset"])
def test_the_paper_network_starts_with_its_centre_at_the_estimate(center):
    rng = np.random.default_rng(1)
    x, y = rng.normal(size=(200, 4)), rng.normal(scale=3.0, size=(200, 3)) + 5.0
    yhat = y + rng.normal(scale=0.1, size=y.shape)
    net = IPCNetwork(ModelConfig.recipe("paper", x_dim=4, y_dim=3, center=center, hidden=(6, 9)))
    net.set_normalisation(x, y, yhat)
    before = IPCModel(net).raw_arrays(x, yhat)[0]
    if center == "raw":  # a random network's centre is elsewhere (an offset one is near yhat already)
        assert np.abs(before - yhat).max() > 0.1
    net.start_at_estimate()
    centers, shapes = IPCModel(net).raw_arrays(x, yhat)  # the float64 engine of record
    assert np.abs(centers - yhat).max() < 1e-5 * np.abs(yhat).max()
    assert np.isfinite(shapes).all()


def test_starting_at_the_estimate_needs_relu_and_room_for_the_pass_through():
    for kwargs in ({"activation": "tanh"}, {"hidden": (5, 64)}):
        net = IPCNetwork(ModelConfig.recipe("paper", x_dim=2, y_dim=3, **kwargs))
        with pytest.raises(InvalidInputError, match="ReLU hidden layers of at least 2 \\* y_dim"):
            net.start_at_estimate()
    with pytest.raises(InvalidInputError, match="for the paper's heads"):
        train(make_lagged_perception(100, seed=0), ModelConfig(x_dim=6, y_dim=3, hidden=(8,)),
              TrainConfig(epochs=1, start_at_estimate=True))  # fmt: skip


def test_the_paper_recipe_is_the_papers_network_and_records_its_choice():
    ds = make_lagged_perception(400, seed=0)
    model = train(ds, recipe="paper").model
    d, n = ds.x_dim, ds.y_dim
    assert model.n_parameters == (d + n) * 64 + 64 + 64 * 128 + 128 + 128 * 12 + 12
    assert (model.config.param, model.config.center, model.config.n_outputs) == ("full", "raw", 12)
    tc = model.metadata["train_config"]
    sel = model.metadata["selection"]
    assert (tc["epochs"], tc["lr"], tc["loss"], tc["start_at_estimate"]) == (20, 1e-3, "hinge", True)
    assert (tc["alpha"], tc["lam"], tc["batch_size"]) == tuple(
        sel["chosen"][k] for k in ("alpha", "lam", "batch_size")
    )
    assert len(sel["candidates"]) == len(HingeSelection().grid()) and "rule" in sel["rule"]
    # the rule saw only training rows: the held-out share is a fraction of the 400
    assert {c["val_n"] for c in sel["candidates"]} == {80}
    # an explicit configuration is used as it is
    assert (
        "selection"
        not in train(ds, recipe="paper", train_config=TrainConfig.recipe("paper", epochs=1)).model.metadata
    )


def test_the_selection_is_deterministic_and_refuses_tiny_data():
    ds = make_lagged_perception(200, seed=3)
    mc = ModelConfig.recipe("paper", x_dim=6, y_dim=3, hidden=(8, 8))
    rule = HingeSelection(alphas=(0.1, 1.0), lams=(0.01,))
    a = select_hinge(ds, mc, TrainConfig.recipe("paper", epochs=2), rule)[1]
    b = select_hinge(ds, mc, TrainConfig.recipe("paper", epochs=2), rule)[1]
    assert a.to_dict()["candidates"] == b.to_dict()["candidates"]
    tiny = PerceptionDataset(np.zeros((2, 6)), np.ones((2, 3)), np.ones((2, 3)))
    with pytest.raises(InvalidInputError, match="too few training rows"):
        select_hinge(tiny, mc, TrainConfig.recipe("paper", epochs=1), rule)
    with pytest.raises(InvalidInputError, match="for the paper's heads"):
        select_hinge(ds, ModelConfig(x_dim=6, y_dim=3), TrainConfig(epochs=1), rule)


def _raw_miss_and_volume(model: IPCModel, test: PerceptionDataset) -> tuple[int, float]:
    centers, shapes = model.raw_arrays(test.x, test.yhat)
    g = np.linalg.norm(np.einsum("bij,bj->bi", shapes, test.y - centers), axis=1)
    return int(np.sum(g > 1.0)), float(np.mean(-np.linalg.slogdet(shapes)[1]))


def _by_run(ds: PerceptionDataset) -> tuple[PerceptionDataset, PerceptionDataset, PerceptionDataset]:
    key = np.array([f"{m}_{r}" for m, r in zip(ds.extra["method"], ds.extra["run"], strict=True)])
    runs = sorted(set(key.tolist()))
    order = np.random.default_rng(0).permutation(len(runs))
    parts = [np.isin(key, [runs[i] for i in order[a:b]]) for a, b in ((0, 8), (8, 14), (14, len(runs)))]
    return tuple(ds.subset(np.flatnonzero(p)) for p in parts)  # type: ignore[return-value]


@pytest.mark.slow
@pytest.mark.parametrize("source", ["euroc_by_run", "synthetic"])
def test_the_papers_contract_as_trained_covers_unseen_data_with_sets_smaller_than_a_global_ellipsoid(source):
    """Acceptance (issue 26): raw, no calibration, misses <= 2 % of held-out truths, with smaller sets
    than a global Mahalanobis ellipsoid calibrated at epsilon = 0.01 (PAC, delta = 0.001).

    Neither data set was used to design the recipe. The miss rate is checked by its one-sided 95 %
    Clopper-Pearson upper bound, which is stricter than the point rate the acceptance names.
    """
    torch.set_num_threads(1)
    if source == "synthetic":
        tr, cal, te = (make_lagged_perception(n, seed=s) for n, s in ((5000, 10), (5000, 11), (20000, 12)))
    else:
        tr, cal, te = _by_run(load_dataset(REAL_LOG))
    model = train(tr, recipe="paper").model
    misses, volume = _raw_miss_and_volume(model, te)
    assert clopper_pearson_upper(misses, len(te), 0.05) <= 0.02, (misses, len(te))
    glob = fit_global_mahalanobis(tr).calibrate(cal, 0.01, 0.001).predict(te.x, te.yhat)
    assert volume < float(np.mean(-np.linalg.slogdet(np.asarray(glob.shapes))[1]))


def test_the_certificate_records_the_rule_and_the_chosen_values(tmp_path, run_cli):
    """Issue 26: the rule and the values it chose are in the model file and in the certificate."""
    import json

    from ipcverify.io._modelio import save_model

    ds = make_lagged_perception(400, seed=0)
    rule = HingeSelection(alphas=(0.1, 1.0), lams=(0.01,))
    mc = ModelConfig.recipe("paper", x_dim=6, y_dim=3, hidden=(8, 8))
    model = train(ds, mc, TrainConfig.recipe("paper", epochs=1), select=rule).model
    save_model(model, tmp_path / "m.pt")
    r = run_cli("certify", tmp_path / "m.pt", "--out", tmp_path / "cert")
    assert r.code in (0, 1, 2) and "unstated settings chosen" in r.stdout, r.stdout + r.stderr
    cert = json.loads((tmp_path / "cert" / "certificate.json").read_text())
    chosen = cert["model"]["selection"]["chosen"]
    assert (chosen["alpha"], chosen["lam"]) == (
        cert["model"]["training"]["alpha"],
        cert["model"]["training"]["lam"],
    )
    assert "smallest held-out mean log-volume" in cert["model"]["selection"]["rule"]["rule"]
    assert "the rule" in (tmp_path / "cert" / "report.html").read_text()


def test_the_rule_can_hold_out_whole_groups(run_cli, tmp_path):
    """With group_column, whole flights are held out (rows of one flight are correlated)."""
    import itertools

    from ipcverify.data._dataset import save_dataset

    base = make_lagged_perception(550, seed=4)
    sizes = [10 * (i + 1) for i in range(10)]  # ten flights of 10, 20, ..., 100 rows
    flights = np.repeat(np.arange(10), sizes)
    ds = PerceptionDataset(base.x, base.y, base.yhat, extra={"flight": flights})
    mc = ModelConfig.recipe("paper", x_dim=6, y_dim=3, hidden=(8, 8))
    rule = HingeSelection(alphas=(1.0,), lams=(0.01,), group_column="flight")
    record = select_hinge(ds, mc, TrainConfig.recipe("paper", epochs=1), rule)[1]
    held = record.chosen.val_n
    assert held in {sum(c) for c in itertools.combinations(sizes, 2)}  # two whole flights of ten
    assert record.to_dict()["rule"]["group_column"] == "flight" and "groups (flight)" in rule.describe()
    save_dataset(ds, tmp_path / "flights.csv")
    r = run_cli("train", tmp_path / "flights.csv", "--out", tmp_path / "m.pt", "--recipe", "paper",
                "--epochs", "1", "--group-column", "flight")  # fmt: skip
    assert r.code == 0, r.stderr
    r = run_cli("train", tmp_path / "flights.csv", "--out", tmp_path / "m2.pt", "--group-column", "flight")
    assert r.code == 2 and "--group-column only chooses the paper recipe's" in r.stderr
    with pytest.raises(InvalidInputError, match="group_column must be a column name"):
        HingeSelection(group_column="")
