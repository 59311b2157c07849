"""Tests of the IPC network, the paper's loss and training."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy import integrate, optimize, stats

from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.model import IPCModel, IPCNetwork, ModelConfig
from ipcverify.training import NonFiniteLossError, TrainConfig, hinge, ipc_loss, train


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
    e = m.predict(x, yhat)
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
    model = train(train_data, train_config=TrainConfig(alpha=alpha, lam=lam, seed=0)).model
    sets = model.predict(test_data.x, test_data.yhat)
    # the learned radius follows sigma(x): half-width / sigma ~ 1/k* (to 10 %)
    ratio = np.median(sets.half_widths().mean(axis=1) / sigma)
    assert ratio == pytest.approx(1 / k, rel=0.10)
    # and its violation rate is that of the optimum, within a factor 2 (the network only
    # approximates the optimal shape; sampling error is ~ +-10 % here)
    rate = float(np.mean(~sets.contains(test_data.y)))
    assert p_star / 2 <= rate <= 2 * p_star
    # the volume term works: a global ball would need the largest sigma everywhere
    assert np.median(sets.half_widths()) < 0.8 * (0.06 / k)


def test_training_is_reproducible():
    data, _ = _heteroscedastic(400, 0)
    a = train(data, train_config=TrainConfig(epochs=2, seed=5)).model
    b = train(data, train_config=TrainConfig(epochs=2, seed=5)).model
    for (ka, va), (_, vb) in zip(a.network.state_dict().items(), b.network.state_dict().items(), strict=True):
        assert torch.equal(va, vb), ka


def test_cholesky_never_non_finite_with_aggressive_settings():
    data, _ = _heteroscedastic(500, 2)
    res = train(data, train_config=TrainConfig(epochs=5, lr=0.05, lam=1.0, alpha=0.01))
    assert all(np.isfinite(r["train_loss"]) for r in res.history)


def test_full_param_non_finite_loss_is_reported():
    data, _ = _heteroscedastic(200, 3)
    cfg = ModelConfig(x_dim=2, y_dim=3, hidden=(4,), param="full")
    torch.manual_seed(0)
    with pytest.raises(NonFiniteLossError, match="use --param cholesky"):
        # a huge learning rate drives the full shape matrix to overflow
        train(data, cfg, TrainConfig(epochs=30, lr=1e6, lam=10.0))


def test_early_stopping_and_history():
    data, _ = _heteroscedastic(600, 4)
    res = train(data, train_config=TrainConfig(epochs=50, val_fraction=0.3, patience=2, lr=0.01))
    assert len(res.history) < 50
    assert "val_loss" in res.history[0]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"epochs": 0}, "epochs must be >= 1"),
        ({"lr": -1.0}, "lr must be > 0"),
        ({"alpha": 0.0}, "alpha must be > 0"),
        ({"lam": -0.1}, "lam must be >= 0"),
        ({"batch_size": 0}, "batch size must be >= 1"),
        ({"patience": 3}, "needs a validation split"),
    ],
)
def test_bad_train_config(kwargs, match):
    with pytest.raises(InvalidInputError, match=match):
        TrainConfig(**kwargs)


def test_bad_model_config_and_inputs():
    with pytest.raises(InvalidInputError, match="param must be"):
        ModelConfig(x_dim=1, y_dim=1, param="diag")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="hidden sizes must be positive"):
        ModelConfig(x_dim=1, y_dim=1, hidden=(0,))
    m = IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=3, hidden=(4,))))
    with pytest.raises(InvalidInputError, match=r"expects x of shape \(B, 2\)"):
        m.predict(np.zeros((3, 3)), np.zeros((3, 3)))
    data, _ = _heteroscedastic(50, 0)
    with pytest.raises(InvalidInputError, match="model expects x_dim=5"):
        train(data, ModelConfig(x_dim=5, y_dim=3), TrainConfig(epochs=1))
