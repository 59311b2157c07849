"""Tests of the IPC network, the paper's loss and training."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy import integrate, optimize, stats

from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._objectives import NonFiniteLossError, TrainConfig, hinge, ipc_loss, likelihood_loss
from ipcverify.training._train import train, warm_start_center


def test_loss_matches_hand_computation():
    # two samples, n = 2; C_1 = diag(2, 1), C_2 = I; alpha = 0.5, lam = 0.1
    C = torch.tensor([[[2.0, 0.0], [0.0, 1.0]], [[1.0, 0.0], [0.0, 1.0]]])
    c = torch.zeros(2, 2)
    y = torch.tensor([[0.3, 0.4], [1.2, 0.5]])
    g = torch.linalg.vector_norm(torch.einsum("bij,bj->bi", C, y - c), dim=1)
    logdet = torch.logdet(C.transpose(1, 2) @ C)
    loss, h, reg = ipc_loss(g, logdet, alpha=0.5, lam=0.1)
    # by hand: g1 = ||(0.6, 0.4)|| = sqrt(0.52); g2 = 1.3
    g1, g2 = np.sqrt(0.52), 1.3
    l1 = max(0.0, (g1 - 1) / 0.5 + 1)  # = 2 g1 - 1
    l2 = max(0.0, (g2 - 1) / 0.5 + 1)  # = 1.6
    hand_h = (l1 + l2) / 2
    hand_reg = -(np.log(4.0) + np.log(1.0)) / 2  # det(C1^T C1) = det diag(4, 1) = 4
    assert float(h) == pytest.approx(hand_h, rel=1e-6)
    assert float(reg) == pytest.approx(hand_reg, rel=1e-6)
    assert float(loss) == pytest.approx(hand_h + 0.1 * hand_reg, rel=1e-6)
    assert float(hinge(torch.tensor(-0.6), 0.5)) == 0.0


def test_likelihood_loss_matches_hand_computation():
    # the same batch: C_1 = diag(2, 1), C_2 = I; y_1 = (0.3, 0.4), y_2 = (1.2, 0.5), c = 0
    C = torch.tensor([[[2.0, 0.0], [0.0, 1.0]], [[1.0, 0.0], [0.0, 1.0]]])
    y = torch.tensor([[0.3, 0.4], [1.2, 0.5]])
    g = torch.linalg.vector_norm(torch.einsum("bij,bj->bi", C, y), dim=1)
    logdet = torch.logdet(C.transpose(1, 2) @ C)
    loss, sq, reg = likelihood_loss(g, logdet)
    # by hand: g1^2 = 0.6^2 + 0.4^2 = 0.52, g2^2 = 1.2^2 + 0.5^2 = 1.69; log det C = (log 2, 0)
    hand_sq = (0.52 + 1.69) / 2 / 2
    hand = hand_sq - (np.log(2.0) + 0.0) / 2
    assert float(sq) == pytest.approx(hand_sq, rel=1e-6)
    assert float(reg) == pytest.approx(-np.log(4.0) / 2, rel=1e-6)
    assert float(loss) == pytest.approx(hand, rel=1e-6)
    # and it is the Gaussian NLL of y under N(0, (C^T C)^{-1}) up to the constant (n/2) log(2 pi)
    nll = 0.0
    for Ci, yi in zip(C.double(), y.double(), strict=True):
        cov = torch.linalg.inv(Ci.T @ Ci)
        dist = torch.distributions.MultivariateNormal(torch.zeros(2, dtype=torch.float64), cov)
        nll -= float(dist.log_prob(yi)) / 2
    assert float(loss) == pytest.approx(nll - np.log(2 * np.pi), rel=1e-6)


def _v1(**kwargs: object) -> TrainConfig:
    """The paper's-head training settings of ipcverify's earlier default (the recipe "v1")."""
    return TrainConfig.recipe("v1", **kwargs)


def test_training_uses_the_configured_loss():
    data, _ = _heteroscedastic(300, 5)
    hist = train(data, train_config=_v1(epochs=1, loss="likelihood"), recipe="v1").history[-1]
    assert "fit_half_sq_score" in hist and "fit_hinge" not in hist
    # the recorded loss is the likelihood of the trained model
    m = train(data, train_config=_v1(epochs=1, loss="likelihood"), recipe="v1").model
    g = torch.tensor(m.raw_scores(data.x, data.y, data.yhat))
    _, C = m.raw_arrays(data.x, data.yhat)
    logdet = torch.tensor(np.linalg.slogdet(np.transpose(C, (0, 2, 1)) @ C)[1])
    assert hist["fit_loss"] == pytest.approx(float(likelihood_loss(g, logdet)[0]), rel=1e-4, abs=1e-4)
    # a warm-up of likelihood epochs changes the result of hinge training
    a = train(data, train_config=_v1(epochs=2), recipe="v1").model
    b = train(data, train_config=_v1(epochs=2, warmup_epochs=1), recipe="v1").model
    assert not np.allclose(a.raw_scores(data.x, data.y, data.yhat), b.raw_scores(data.x, data.y, data.yhat))


def _linear_bias(n: int, seed: int) -> PerceptionDataset:
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, (n, 2))
    yhat = rng.uniform(-1, 1, (n, 3))
    bias = x @ np.array([[0.3, -0.2, 0.1], [0.1, 0.2, -0.3]]) + 0.2 * yhat + 0.05
    return PerceptionDataset(x, yhat + bias + 0.02 * rng.standard_normal((n, 3)), yhat)


def _centre_sq_error(model: IPCModel, data: PerceptionDataset) -> float:
    centers, _ = model.raw_arrays(data.x, data.yhat)
    return float(np.mean(np.sum((data.y - centers) ** 2, axis=1)))


@pytest.mark.parametrize("center", ["offset", "raw"])
def test_center_warm_start_reduces_the_centre_error(center):
    train_data, test_data = _linear_bias(2000, 0), _linear_bias(2000, 1)
    mc = ModelConfig(x_dim=2, y_dim=3, hidden=(32, 32), center=center, param="cholesky")
    # directly: the least-squares head fits the bias the initial network does not
    torch.manual_seed(0)
    net = IPCNetwork(mc)
    net.set_normalisation(train_data.x, train_data.y, train_data.yhat)
    before = _centre_sq_error(IPCModel(net), test_data)
    t = [torch.tensor(a, dtype=torch.float32) for a in (train_data.x, train_data.y, train_data.yhat)]
    warm_start_center(net, *t)
    after = _centre_sq_error(IPCModel(net), test_data)
    assert after < 0.2 * before
    # through train(): after one epoch the warm-started centre is still much closer
    cold = train(train_data, mc, _v1(epochs=1)).model
    warm = train(train_data, mc, _v1(epochs=1, center_warm_start=True)).model
    assert _centre_sq_error(warm, test_data) < 0.5 * _centre_sq_error(cold, test_data)
    assert warm.metadata["train_config"]["center_warm_start"] is True


@pytest.mark.parametrize("param", ["cholesky", "full"])
@pytest.mark.parametrize("center", ["offset", "raw"])
def test_network_logdet_and_sets_are_consistent(param, center):
    torch.manual_seed(0)
    net = IPCNetwork(ModelConfig(x_dim=3, y_dim=3, hidden=(16, 16), param=param, center=center))
    rng = np.random.default_rng(0)
    x, y, yhat = rng.standard_normal((50, 3)), rng.standard_normal((50, 3)), rng.standard_normal((50, 3))
    net.set_normalisation(x, y, yhat)
    c, C, logdet = net(torch.tensor(x, dtype=torch.float32), torch.tensor(yhat, dtype=torch.float32))
    Cd = C.detach().double()  # reference in float64: C^T C squares the condition number
    assert torch.allclose(
        logdet.detach().double(), torch.logdet(Cd.transpose(1, 2) @ Cd), rtol=1e-4, atol=1e-4
    )
    if param == "cholesky":
        assert torch.all(torch.triu(C, diagonal=1) == 0)
        assert torch.all(torch.diagonal(C, dim1=1, dim2=2) > 0)
    m = IPCModel(net)
    e = m.predict_unguarded(x, yhat)
    assert np.allclose(e.g(y), m.raw_scores(x, y, yhat))
    # the float64 engine agrees with torch's float32 forward to float32 precision ...
    assert np.allclose(e.centers, c.detach().double().numpy(), rtol=1e-5, atol=1e-6)
    assert np.allclose(e.shapes, C.detach().double().numpy(), rtol=1e-5, atol=1e-5)
    # ... and with torch in float64 to float64 precision (same function, same weights)
    import copy

    net64 = copy.deepcopy(net).double()
    c64, C64, _ = net64(torch.tensor(x), torch.tensor(yhat))
    assert np.allclose(e.centers, c64.detach().numpy(), rtol=1e-12, atol=1e-13)
    assert np.allclose(e.shapes, C64.detach().numpy(), rtol=1e-12, atol=1e-13)


def _heteroscedastic(n: int, seed: int) -> tuple[PerceptionDataset, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, (n, 2))
    yhat = rng.uniform(-1, 1, (n, 3))
    sigma = 0.02 * (1 + 2 * np.abs(x[:, 0]))
    y = yhat + sigma[:, None] * rng.standard_normal((n, 3))
    return PerceptionDataset(x, y, yhat), sigma


def _optimal_ball_factor(alpha: float, lam: float, n: int) -> float:
    """k* minimising E[l(k r - 1)] - 2 n lam log k for r ~ chi_n (the population optimum
    of the paper's objective when y - yhat ~ N(0, sigma(x)^2 I): C = (k*/sigma(x)) I)."""
    chi = stats.chi(n)

    def objective(k: float) -> float:
        t = (1 - alpha) / k
        tail = integrate.quad(lambda r: r * chi.pdf(r), t, np.inf)[0]
        return (k * tail - (1 - alpha) * chi.sf(t)) / alpha - lam * 2 * n * np.log(k)

    return float(optimize.minimize_scalar(objective, bounds=(0.01, 5), method="bounded").x)


@pytest.mark.slow
def test_training_reaches_the_expected_violation_rate_and_size():
    alpha, lam = 0.3, 0.05
    k = _optimal_ball_factor(alpha, lam, 3)
    p_star = stats.chi(3).sf(1 / k)  # ~0.65 %
    train_data, _ = _heteroscedastic(5000, 0)
    test_data, sigma = _heteroscedastic(50_000, 1)
    model = train(train_data, train_config=_v1(alpha=alpha, lam=lam, seed=0), recipe="v1").model
    sets = model.predict_unguarded(test_data.x, test_data.yhat)
    # the learned radius follows sigma(x): half-width / sigma ~ 1/k* (to 10 %)
    ratio = np.median(sets.half_widths().mean(axis=1) / sigma)
    assert ratio == pytest.approx(1 / k, rel=0.10)
    # and its violation rate is that of the optimum, within a factor 2 (the network only
    # approximates the optimal shape; sampling error is ~ +-10 % here)
    rate = float(np.mean(~sets.contains(test_data.y)))
    assert p_star / 2 <= rate <= 2 * p_star
    # the volume term works: a global ball would need the largest sigma everywhere
    assert np.median(sets.half_widths()) < 0.8 * (0.06 / k)


@pytest.mark.parametrize("recipe", ["tight", "v1"])
def test_training_is_reproducible(recipe):
    data, _ = _heteroscedastic(400, 0)
    a = train(data, train_config=TrainConfig.recipe(recipe, epochs=2, seed=5), recipe=recipe).model
    b = train(data, train_config=TrainConfig.recipe(recipe, epochs=2, seed=5), recipe=recipe).model
    for (ka, va), (_, vb) in zip(a.network.state_dict().items(), b.network.state_dict().items(), strict=True):
        assert torch.equal(va, vb), ka
    c = train(data, train_config=TrainConfig.recipe(recipe, epochs=2, seed=6), recipe=recipe).model
    assert not np.array_equal(
        a.raw_scores(data.x, data.y, data.yhat), c.raw_scores(data.x, data.y, data.yhat)
    )


def test_cholesky_never_non_finite_with_aggressive_settings():
    data, _ = _heteroscedastic(500, 2)
    res = train(data, train_config=_v1(epochs=5, lr=0.05, lam=1.0, alpha=0.01), recipe="v1")
    assert all(np.isfinite(r["train_loss"]) for r in res.history)


def test_full_param_non_finite_loss_is_reported():
    data, _ = _heteroscedastic(200, 3)
    cfg = ModelConfig(x_dim=2, y_dim=3, hidden=(4,), param="full")
    torch.manual_seed(0)
    with pytest.raises(NonFiniteLossError, match="use param='cholesky'"):
        # a huge learning rate drives the full shape matrix to overflow
        train(data, cfg, _v1(epochs=30, lr=1e6, lam=10.0))


@pytest.mark.parametrize("recipe", ["tight", "v1"])
def test_early_stopping_and_history(recipe):
    data, _ = _heteroscedastic(600, 4)
    tc = TrainConfig.recipe(recipe, epochs=50, val_fraction=0.3, patience=2, lr=0.01)
    res = train(data, train_config=tc, recipe=recipe)
    assert len(res.history) < 50
    assert "val_loss" in res.history[0]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"epochs": 0}, "epochs must be >= 1"),
        ({"lr": -1.0}, "lr must be > 0"),
        ({"alpha": 0.0}, "alpha must be > 0"),
        ({"lam": -0.1}, "lam must be >= 0"),
        ({"batch_size": 0}, "batch_size must be >= 1"),
        ({"patience": 3, "val_fraction": 0.0}, "needs a validation split"),
        ({"schedule": "step"}, "schedule must be 'cosine' or 'constant'"),
        ({"linear_ridge": -1.0}, "linear_ridge must be >= 0"),
        ({"loss": "nll"}, "loss must be 'hinge' or 'likelihood'; got 'nll'"),
        ({"center_warm_start": "yes"}, "center_warm_start must be True or False"),
        ({"warmup_epochs": -1}, r"warmup_epochs must be in \[0, epochs=60\)"),
        ({"epochs": 5, "warmup_epochs": 5}, r"warmup_epochs must be in \[0, epochs=5\)"),
        ({"loss": "likelihood", "warmup_epochs": 2}, "only applies to loss='hinge'"),
        ({"seed": -1}, r"seed must be an integer in \[0, 2\*\*64\); got -1"),
        ({"seed": 2**64}, r"seed must be an integer in \[0, 2\*\*64\)"),
        ({"seed": 1.5}, r"seed must be an integer .*got 1\.5"),
    ],
)
def test_bad_train_config(kwargs, match):
    with pytest.raises(InvalidInputError, match=match):
        TrainConfig(**kwargs)


def test_unknown_recipe_is_refused_with_the_names():
    with pytest.raises(InvalidInputError, match="unknown recipe 'best'; choose one of tight, v1, paper"):
        TrainConfig.recipe("best")
    with pytest.raises(InvalidInputError, match="unknown recipe 'best'"):
        ModelConfig.recipe("best", x_dim=1, y_dim=1)
    with pytest.raises(InvalidInputError, match=r"members must be in \[1, 32\]; got 0 -- leave it out"):
        ModelConfig.recipe("tight", x_dim=1, y_dim=1, members=0)  # was silently the recipe's 5
    with pytest.raises(InvalidInputError, match="unknown recipe 'best'"):
        train(_heteroscedastic(50, 0)[0], recipe="best")


def test_bad_model_config_and_inputs():
    with pytest.raises(InvalidInputError, match="param must be"):
        ModelConfig(x_dim=1, y_dim=1, param="diag")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="hidden sizes must be positive"):
        ModelConfig(x_dim=1, y_dim=1, hidden=(0,))
    with pytest.raises(InvalidInputError, match="ensembles come with the low-rank head"):
        ModelConfig(x_dim=1, y_dim=1, param="cholesky", members=3)
    with pytest.raises(InvalidInputError, match="ensembles come with the low-rank head"):
        ModelConfig(x_dim=1, y_dim=1, param="full", linear_center=True)
    with pytest.raises(InvalidInputError, match="use center='offset'"):
        ModelConfig(x_dim=1, y_dim=1, center="raw")
    with pytest.raises(InvalidInputError, match=r"members must be in \[1, 32\]"):
        ModelConfig(x_dim=1, y_dim=1, members=33)
    with pytest.raises(
        InvalidInputError, match=r"hidden sizes 100000000000 make a network of more than 1e\+12"
    ):
        ModelConfig(x_dim=3, y_dim=2, hidden=(10**11,), members=2)  # a typo; torch would try to allocate it
    assert ModelConfig(x_dim=3, y_dim=2, hidden=(4000, 2495), members=10).hidden == (
        4000,
        2495,
    )  # 1e8: the limit
    with pytest.raises(InvalidInputError, match="members must be an integer"):
        ModelConfig(x_dim=1, y_dim=1, members=2.5)  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="linear_center must be True or False"):
        ModelConfig(x_dim=1, y_dim=1, linear_center="yes")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match=r"build it with ipcverify.network.build_network\(config\)"):
        IPCNetwork(ModelConfig(x_dim=1, y_dim=1))
    with pytest.raises(
        InvalidInputError, match="center_warm_start and start_at_estimate are for the paper's heads"
    ):
        train(_heteroscedastic(50, 0)[0], train_config=TrainConfig(epochs=1, center_warm_start=True))
    m = IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=3, hidden=(4,), param="cholesky")))
    with pytest.raises(InvalidInputError, match=r"expects x of shape \(B, 2\)"):
        m.predict_unguarded(np.zeros((3, 3)), np.zeros((3, 3)))
    data, _ = _heteroscedastic(50, 0)
    with pytest.raises(InvalidInputError, match="model expects x_dim=5"):
        train(data, ModelConfig(x_dim=5, y_dim=3), TrainConfig(epochs=1))
    with pytest.raises(InvalidInputError, match="too few samples"):
        train(_heteroscedastic(3, 0)[0], train_config=TrainConfig(epochs=1, val_fraction=0.1))
