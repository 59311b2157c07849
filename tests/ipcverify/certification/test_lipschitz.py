"""L_g: per-sample gradients, the empirical lower estimate, and the sound upper bound's soundness."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from ipcverify.certification._lipschitz import (
    DataBox,
    empirical_lipschitz,
    per_sample_gradient_norms,
    sound_lipschitz,
)
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train

DATA = make_lagged_perception(400, seed=3)


def _network(cfg: ModelConfig, seed: int, weight_scale: float = 1.0, shape_bias: float = 0.0) -> IPCNetwork:
    torch.manual_seed(seed)
    net = IPCNetwork(cfg)
    net.set_normalisation(DATA.x[:, : cfg.x_dim], DATA.y[:, : cfg.y_dim], DATA.yhat[:, : cfg.y_dim])
    with torch.no_grad():
        for p in net.body.parameters():
            p.mul_(weight_scale)
        net.body[-1].bias[cfg.y_dim :] += shape_bias
    return net.eval()


def _max_gradient_in_ball_and_box(ball, net, box, radius, rng, n_theta=12, n_x=60) -> float:
    names, shapes, theta = ball.flat(net)
    worst = 0.0
    for i in range(n_theta):
        d = rng.standard_normal(theta.size)
        d /= np.linalg.norm(d)
        r = radius if i % 2 == 0 else radius * rng.random() ** (1.0 / theta.size)
        params = ball.unflat(names, shapes, theta + r * d)
        x, y, yh = ball.random_in_box(box, rng, n_x, corners=i % 3 == 0)
        worst = max(worst, float(per_sample_gradient_norms(net, x, y, yh, params=params).max()))
    return worst


def test_per_sample_gradients_match_a_plain_autograd_loop():
    cfg = ModelConfig(x_dim=6, y_dim=3, hidden=(8, 5), param="cholesky")
    net = _network(cfg, seed=1).double()
    norms = per_sample_gradient_norms(net, DATA.x[:6], DATA.y[:6], DATA.yhat[:6])
    for i in range(6):
        net.zero_grad()
        x, y, yh = (torch.tensor(a[i : i + 1]) for a in (DATA.x, DATA.y, DATA.yhat))
        g, _ = net.score(x, y, yh)
        g.sum().backward()
        ref = torch.sqrt(sum((p.grad**2).sum() for p in net.parameters()))
        assert norms[i] == pytest.approx(float(ref), rel=1e-10)


def test_sound_bound_exceeds_the_empirical_estimate_on_a_trained_model():
    data = make_lagged_perception(800, seed=4)
    m = train(
        data,
        ModelConfig(x_dim=6, y_dim=3, hidden=(16, 16), param="cholesky"),
        TrainConfig.recipe("v1", epochs=2),
    ).model
    low = empirical_lipschitz(m, data)
    low64 = empirical_lipschitz(m, data, dtype=torch.float64)
    assert low.value == pytest.approx(low64.value, rel=1e-4)
    high = sound_lipschitz(m, data, radius=0.1)
    assert high.value >= low64.value
    assert sound_lipschitz(m, data, radius=0.0).value <= high.value  # monotone in the radius
    assert low.n_samples == 800 and 0 <= low.argmax < 800


CONFIGS = [
    ModelConfig(x_dim=6, y_dim=3, hidden=(8, 6), param="cholesky", center="offset", activation="relu"),
    ModelConfig(x_dim=6, y_dim=3, hidden=(7,), param="full", center="raw", activation="tanh"),
    ModelConfig(x_dim=2, y_dim=2, hidden=(5, 5, 4), param="cholesky", center="raw", activation="elu"),
    ModelConfig(x_dim=1, y_dim=1, hidden=(3,), param="full", center="offset", activation="relu"),
]


@pytest.mark.parametrize("cfg", CONFIGS, ids=lambda c: f"{c.param}-{c.center}-{c.activation}-{len(c.hidden)}")
@pytest.mark.parametrize("radius", [0.0, 0.05, 0.5])
def test_sound_bound_dominates_gradients_in_the_ball_and_box(cfg, radius, ball):
    net = _network(cfg, seed=int(radius * 100) + cfg.y_dim, weight_scale=2.0)
    model = IPCModel(net)
    box = DataBox(
        DATA.x[:, : cfg.x_dim].min(0),
        DATA.x[:, : cfg.x_dim].max(0),
        DATA.y[:, : cfg.y_dim].min(0),
        DATA.y[:, : cfg.y_dim].max(0),
        DATA.yhat[:, : cfg.y_dim].min(0),
        DATA.yhat[:, : cfg.y_dim].max(0),
    )
    bound = sound_lipschitz(model, box, radius=radius).value
    worst = _max_gradient_in_ball_and_box(ball, net, box, radius, np.random.default_rng(17))
    assert worst <= bound


@pytest.mark.parametrize("shape_bias", [-12.0, 11.95, 14.0])
def test_sound_bound_holds_around_the_log_diagonal_clamp(shape_bias, ball):
    """Diagonal logits near or beyond the clamp at +/-12 (exp saturates, its derivative vanishes)."""
    cfg = ModelConfig(x_dim=6, y_dim=3, hidden=(6,), param="cholesky")
    net = _network(cfg, seed=5, weight_scale=0.3, shape_bias=shape_bias)
    model = IPCModel(net)
    box = DataBox.from_dataset(DATA)
    bound = sound_lipschitz(model, box, radius=0.2).value
    assert _max_gradient_in_ball_and_box(ball, net, box, 0.2, np.random.default_rng(3), n_theta=8) <= bound


def test_lipschitz_inequality_on_function_values(ball):
    """|g(theta1) - g(theta2)| <= L ||theta1 - theta2|| for pairs in the ball (no gradients involved)."""
    cfg = ModelConfig(x_dim=6, y_dim=3, hidden=(6, 6), param="cholesky")
    net = _network(cfg, seed=8, weight_scale=1.5).double()
    box = DataBox.from_dataset(DATA)
    radius = 0.3
    bound = sound_lipschitz(IPCModel(_network(cfg, seed=8, weight_scale=1.5)), box, radius=radius).value
    names, shapes, theta = ball.flat(net)
    rng = np.random.default_rng(9)
    x, y, yh = (torch.tensor(a) for a in ball.random_in_box(box, rng, 200, corners=False))
    for _ in range(20):
        a, b = (rng.standard_normal(theta.size) for _ in range(2))
        t1 = theta + radius * a / np.linalg.norm(a)
        t2 = theta + radius * rng.random() * b / np.linalg.norm(b)
        vals = []
        for t in (t1, t2):
            params = ball.unflat(names, shapes, t)
            c, C, _ = torch.func.functional_call(net, params, (x, yh))
            vals.append(torch.linalg.vector_norm(torch.einsum("bij,bj->bi", C, y - c), dim=1).numpy())
        assert (np.abs(vals[0] - vals[1]) <= bound * np.linalg.norm(t1 - t2) * (1 + 1e-9)).all()


@settings(derandomize=True, max_examples=15, deadline=None)
@given(
    hidden=st.lists(st.integers(1, 6), min_size=1, max_size=3),
    y_dim=st.integers(1, 3),
    param=st.sampled_from(["cholesky", "full"]),
    center=st.sampled_from(["offset", "raw"]),
    activation=st.sampled_from(["relu", "tanh", "elu"]),
    seed=st.integers(0, 1000),
    radius=st.floats(0.0, 1.0),
)
def test_sound_bound_property(hidden, y_dim, param, center, activation, seed, radius, ball):
    cfg = ModelConfig(
        x_dim=3, y_dim=y_dim, hidden=tuple(hidden), param=param, center=center, activation=activation
    )
    net = _network(cfg, seed=seed, weight_scale=1.5)
    box = DataBox(
        DATA.x[:, :3].min(0),
        DATA.x[:, :3].max(0),
        DATA.y[:, :y_dim].min(0),
        DATA.y[:, :y_dim].max(0),
        DATA.yhat[:, :y_dim].min(0),
        DATA.yhat[:, :y_dim].max(0),
    )
    bound = sound_lipschitz(IPCModel(net), box, radius=radius).value
    assert _max_gradient_in_ball_and_box(ball, net, box, radius, np.random.default_rng(seed), 6, 40) <= bound


def test_bad_inputs():
    m = IPCModel(_network(ModelConfig(x_dim=6, y_dim=3, hidden=(4,), param="cholesky"), seed=0))
    with pytest.raises(InvalidInputError, match=r"radius must be finite and >= 0"):
        sound_lipschitz(m, DATA, radius=-1.0)
    small = DataBox(np.zeros(2), np.ones(2), np.zeros(3), np.ones(3), np.zeros(3), np.ones(3))
    with pytest.raises(InvalidInputError, match=r"box has x_dim=2, y_dim=3; the model expects x_dim=6"):
        sound_lipschitz(m, small)
    with pytest.raises(InvalidInputError, match=r"box of x: a lower bound exceeds its upper bound"):
        DataBox(np.ones(2), np.zeros(2), np.zeros(3), np.ones(3), np.zeros(3), np.ones(3))
