"""Tests of the default architecture: the low-rank covariance head, its ensemble, its engine, its training."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from ipcverify.certification._lipschitz import theorem1_unavailable
from ipcverify.certification._theorem1 import TrainingStatistics, theorem1
from ipcverify.contract._model import IPCModel, network_fingerprint
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import ModelConfig
from ipcverify.network._lowrank import (
    SIGMA_FLOOR,
    LowRankEnsemble,
    fit_linear_stage,
    member_covariances,
    moment_match,
)
from ipcverify.network._lowrank_engine import LowRankEngine, cholesky_lower, lower_inverse
from ipcverify.training._lowrank import train_lowrank
from ipcverify.training._train import TrainConfig, train


def _random_network(cfg: ModelConfig, seed: int = 0, scale: float = 1.0) -> LowRankEnsemble:
    """An ensemble with O(1) random weights everywhere (not the near-identity initialisation)."""
    net = LowRankEnsemble(cfg)
    gen = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in net.parameters():
            p.copy_(scale * torch.randn(p.shape, generator=gen))
        rng = np.random.default_rng(seed)
        d_in, n = cfg.x_dim + cfg.y_dim, cfg.y_dim
        net.in_mean.copy_(torch.as_tensor(rng.normal(size=d_in)))
        net.in_std.copy_(torch.as_tensor(rng.uniform(0.5, 2.0, d_in)))
        net.sigma.copy_(torch.as_tensor(rng.uniform(0.01, 1.0, n)))
        net.lin_weight.copy_(torch.as_tensor(rng.normal(size=(d_in, n))))
        net.lin_bias.copy_(torch.as_tensor(rng.normal(size=n)))
    return net.eval()


CONFIGS = [
    ModelConfig(x_dim=4, y_dim=3, hidden=(8, 6)),
    ModelConfig(x_dim=2, y_dim=3, hidden=(5,), members=1, linear_center=False, activation="tanh"),
    ModelConfig(x_dim=3, y_dim=2, hidden=(4, 4, 3), members=3, activation="elu"),
    ModelConfig(x_dim=1, y_dim=1, hidden=(3,), members=2),
]


def _inputs(cfg: ModelConfig, rows: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.normal(size=(rows, cfg.x_dim)), rng.normal(size=(rows, cfg.y_dim))


@pytest.mark.parametrize("cfg", CONFIGS, ids=lambda c: f"n{c.y_dim}-K{c.members}-{c.activation}")
def test_shapes_are_lower_triangular_spd_with_finite_log_dets(cfg):
    net = _random_network(cfg)
    x, yhat = _inputs(cfg, 200)
    c, C, logdet = (t.detach().double().numpy() for t in net(torch.tensor(x), torch.tensor(yhat)))
    assert np.isfinite(c).all() and np.isfinite(C).all() and np.isfinite(logdet).all()
    assert np.all(np.triu(C, 1) == 0) and np.all(np.diagonal(C, axis1=1, axis2=2) > 0)
    P = np.transpose(C, (0, 2, 1)) @ C
    assert np.all(np.linalg.eigvalsh(P) > 0)
    np.testing.assert_allclose(logdet, np.linalg.slogdet(P)[1], rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("cfg", CONFIGS, ids=lambda c: f"n{c.y_dim}-K{c.members}-{c.activation}")
def test_the_float64_engine_matches_the_torch_network(cfg):
    net = _random_network(cfg, seed=2, scale=0.5)
    eng = LowRankEngine.from_network(net)
    x, yhat = _inputs(cfg, 300, seed=3)
    c, C = eng.batch(x, yhat)
    with torch.no_grad():  # the network in float64: the same arithmetic up to summation order
        tc, tC, _ = copy.deepcopy(net).double()(torch.tensor(x), torch.tensor(yhat))
    np.testing.assert_allclose(c, tc.numpy(), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(C, tC.numpy(), rtol=1e-9, atol=1e-9 * np.abs(C).max())
    # one query at a time: the same sets
    for i in range(0, 300, 37):
        ci, Ci = eng.single(x[i], yhat[i])
        np.testing.assert_allclose(ci, c[i], rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(Ci, C[i], rtol=1e-12, atol=1e-13 * np.abs(C[i]).max())


def test_one_query_far_out_gives_a_degenerate_set_not_an_exception():
    # inputs so large that the layers overflow: the compiled one-query kernel must give non-finite
    # entries where the batch path does (NumPy's error model: inf and NaN, never ZeroDivisionError)
    cfg = CONFIGS[0]
    eng = LowRankEngine.from_network(_random_network(cfg, seed=8, scale=0.5))
    for big, finite in ((1e150, True), (1e300, False)):
        x, yhat = np.full(cfg.x_dim, big), np.full(cfg.y_dim, -big)
        c, C = eng.batch(x[None], yhat[None])
        ci, Ci = eng.single(x, yhat)
        assert bool(np.isfinite(c).all() and np.isfinite(C).all()) is finite
        assert bool(np.isfinite(ci).all() and np.isfinite(Ci).all()) is finite
        if finite:
            np.testing.assert_allclose(ci, c[0], rtol=1e-12)
            np.testing.assert_allclose(Ci, C[0], rtol=1e-9, atol=1e-12 * np.abs(C[0]).max())


def test_one_query_of_the_wrong_shape_is_refused_before_the_compiled_kernel():
    cfg = CONFIGS[0]
    eng = LowRankEngine.from_network(_random_network(cfg))
    with pytest.raises(InvalidInputError, match=r"x of shape \(4,\) and yhat of shape \(3,\)"):
        eng.single(np.zeros(5), np.zeros(3))
    with pytest.raises(InvalidInputError, match=r"x of shape \(4,\) and yhat of shape \(3,\)"):
        eng.single(np.zeros(5), np.zeros(2))  # the right total length, split wrongly
    with pytest.raises(InvalidInputError, match=r"needs shape \(7,\) .* got shape \(6,\)"):
        eng.single_values(np.zeros(6))


@pytest.mark.parametrize("chunk", [1, 7, 64, 10_000])
def test_chunked_batches_give_the_same_sets_through_the_model(chunk):
    cfg = CONFIGS[0]
    model = IPCModel(_random_network(cfg, seed=4, scale=0.5))
    x, yhat = _inputs(cfg, 130, seed=5)
    c, C = model.engine.batch(x, yhat, chunk=130)
    cc, CC = model.raw_arrays(x, yhat, batch_size=chunk)
    np.testing.assert_allclose(cc, c, rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(CC, C, rtol=1e-12, atol=1e-13 * np.abs(C).max())


def test_a_chunk_below_one_row_is_refused_with_a_message():
    eng = LowRankEngine.from_network(_random_network(CONFIGS[0]))
    x, yhat = _inputs(CONFIGS[0], 3)
    with pytest.raises(InvalidInputError, match="chunk must be a positive number of rows; got 0"):
        eng.batch(x, yhat, chunk=0)


def test_moment_matching_is_the_mixtures_mean_and_covariance():
    cfg = ModelConfig(x_dim=2, y_dim=3, hidden=(6,), members=4)
    net = _random_network(cfg, seed=4, scale=0.7)
    x, yhat = _inputs(cfg, 50, seed=5)
    eng = LowRankEngine.from_network(net)
    z = (np.hstack([x, yhat]) - eng.in_mean) * eng.in_scale
    with torch.no_grad():
        o, h, V = (t.double().numpy() for t in net.heads(torch.tensor(z, dtype=torch.float32)))
    # by hand: an equal mixture of N(o_k, Sigma_k) has mean mean_k o_k and covariance
    # mean_k Sigma_k + mean_k o_k o_k^T - mean mean^T
    Sig = np.stack(
        [np.stack([np.diag(np.exp(2 * h[k, b])) + V[k, b] @ V[k, b].T for b in range(50)]) for k in range(4)]
    )
    mean = o.mean(0)
    cov = Sig.mean(0) + np.einsum("kbi,kbj->bij", o, o) / 4 - np.einsum("bi,bj->bij", mean, mean)
    m_eng, c_eng = eng.combined(z)
    np.testing.assert_allclose(m_eng, mean, rtol=1e-5, atol=1e-6)  # torch's float32 heads vs float64
    np.testing.assert_allclose(c_eng, cov, rtol=1e-4, atol=1e-5)
    m_t, c_t = moment_match(torch.tensor(o), member_covariances(torch.tensor(h), torch.tensor(V)))
    np.testing.assert_allclose(c_t.numpy(), cov, rtol=1e-10, atol=1e-12)
    # the centre is yhat + lin + sigma * mean and the shape chol(cov)^-1 / sigma
    c, C = eng.batch(x, yhat)
    np.testing.assert_allclose(c, yhat + z @ eng.lin_weight + eng.lin_bias + eng.sigma * m_eng, rtol=1e-12)
    inv = np.linalg.inv(np.linalg.cholesky(c_eng))
    np.testing.assert_allclose(C, inv / eng.sigma, rtol=1e-9, atol=1e-12)


def test_entrywise_cholesky_and_triangular_inverse_match_lapack():
    rng = np.random.default_rng(6)
    for n in (1, 2, 3, 5):
        A = rng.normal(size=(40, n, n))
        S = A @ np.transpose(A, (0, 2, 1)) + 0.1 * np.eye(n)
        L = cholesky_lower(S)
        np.testing.assert_allclose(L, np.linalg.cholesky(S), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(lower_inverse(L), np.linalg.inv(L), rtol=1e-9, atol=1e-10)
    bad = np.array([[[1.0, 2.0], [2.0, 1.0]]])  # indefinite: NaN, not an exception
    assert np.isnan(cholesky_lower(bad)).any()


def test_the_linear_stage_recovers_a_linear_bias_exactly():
    rng = np.random.default_rng(7)
    z = rng.normal(size=(500, 4))
    A, b = rng.normal(size=(4, 3)), rng.normal(size=3)
    w, c = fit_linear_stage(z, z @ A + b, ridge=0.0, linear=True)
    np.testing.assert_allclose(w, A, atol=1e-10)
    np.testing.assert_allclose(c, b, atol=1e-10)
    w0, c0 = fit_linear_stage(z, z @ A + b, ridge=0.0, linear=False)
    assert not w0.any() and np.allclose(c0, (z @ A + b).mean(0))


def _linear_bias_with_an_exact_axis(n: int, seed: int) -> PerceptionDataset:
    """y - yhat linear in the inputs plus noise on two axes, and exactly linear (no noise) on the third."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, (n, 2))
    yhat = rng.uniform(-1, 1, (n, 3))
    y = yhat + 0.3 * x[:, [0, 1, 0]] + 0.1
    y[:, :2] += 0.02 * (1 + np.abs(x)) * rng.standard_normal((n, 2))
    return PerceptionDataset(x, y, yhat)


def test_training_keeps_an_exactly_known_axis_finite_and_tight():
    data, test = _linear_bias_with_an_exact_axis(1500, 0), _linear_bias_with_an_exact_axis(500, 1)
    model = train(data, train_config=TrainConfig(epochs=5)).model
    sets = model.predict_unguarded(test.x, test.yhat)  # validates: finite, non-singular shapes
    sigma = model.network.sigma.numpy()
    assert sigma[2] == pytest.approx(SIGMA_FLOOR * (data.y - data.yhat)[:, 2].std(), rel=1e-9)  # the floor
    assert sigma[0] > 1e3 * sigma[2]
    err = np.abs(sets.centers - test.y)
    assert err[:, 2].max() < 1e-4 * err[:, 0].mean()


def test_members_train_as_if_alone():
    """Adam is elementwise and the loss a sum over members: member 0 of an ensemble is the 1-member model."""
    data = make_lagged_perception(400, seed=8)
    tc = TrainConfig(epochs=3, val_fraction=0.0, patience=None, seed=4)
    one, _ = train_lowrank(data, ModelConfig(x_dim=6, y_dim=3, hidden=(8,), members=1), tc)
    three, hist = train_lowrank(data, ModelConfig(x_dim=6, y_dim=3, hidden=(8,), members=3), tc)
    for (name, a), (_, b) in zip(one.named_parameters(), three.named_parameters(), strict=True):
        np.testing.assert_allclose(
            a.detach()[0].numpy(), b.detach()[0].numpy(), rtol=1e-4, atol=1e-6, err_msg=name
        )
    assert not torch.equal(three.body.layers[0].weight[0], three.body.layers[0].weight[1])
    assert [r["active_members"] for r in hist] == [3.0, 3.0, 3.0]


def test_early_stopping_freezes_members_one_by_one_at_their_best_epoch():
    data = make_lagged_perception(600, seed=9)
    net, hist = train_lowrank(
        data,
        ModelConfig(x_dim=6, y_dim=3, hidden=(8,), members=3),
        TrainConfig(epochs=40, lr=0.02, patience=2),
    )
    active = [r["active_members"] for r in hist]
    assert active == sorted(active, reverse=True) and active[-1] < 3
    assert all(np.isfinite(r["train_loss"]) and np.isfinite(r["val_loss"]) for r in hist)
    assert all(torch.isfinite(p).all() for p in net.parameters())


def test_fingerprint_covers_every_member():
    net = _random_network(ModelConfig(x_dim=2, y_dim=3, hidden=(4,)), seed=10)
    before = network_fingerprint(net)
    with torch.no_grad():
        net.body.layers[1].weight[4, 0, 0] += 1e-3  # the last member only
    assert network_fingerprint(net) != before


def test_default_training_records_theorem1_statistics():
    data = make_lagged_perception(300, seed=11)
    model = train(data, train_config=TrainConfig(epochs=1)).model
    assert theorem1_unavailable(model) is None and "theorem1_unavailable" not in model.metadata
    stats = TrainingStatistics.from_dict(model.metadata["training_statistics"])
    assert (stats.n, stats.alpha, stats.data_sha256) == (300, 1.0, data.content_hash())
    assert model.metadata["train_config"]["loss"] == "likelihood"
    # the same numbers as computing them again from the training data
    res_stored, res_fresh = theorem1(model, stats, 0.01), theorem1(model, data, 0.01)
    assert res_stored.to_dict() == res_fresh.to_dict()
    assert res_stored.n_parameters == model.n_parameters == sum(p.numel() for p in model.network.parameters())
    assert res_stored.sound.vacuous and res_stored.sound.lipschitz >= res_stored.optimistic.lipschitz > 0


def test_lowrank_network_refuses_a_paper_head_config():
    with pytest.raises(InvalidInputError, match="use ipcverify.network.build_network\\(config\\)"):
        LowRankEnsemble(ModelConfig.recipe("v1", x_dim=1, y_dim=1))
