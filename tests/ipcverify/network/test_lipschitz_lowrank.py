"""L_g for the default low-rank ensemble: per-sample gradients, and the sound bound's soundness.

The bound (proofs/lipschitz_lowrank.md) must dominate every per-sample gradient norm at every
parameter vector in the ball and every X in the box, and the Lipschitz inequality must hold on
function values computed by the float64 engine (no gradients involved).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from ipcverify.certification._lipschitz import (
    DataBox,
    Theorem1UnavailableError,
    empirical_lipschitz,
    per_sample_gradient_norms,
    sound_lipschitz,
    theorem1_unavailable,
)
from ipcverify.contract._model import IPCModel
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import LOGDIAG_CLAMP, ModelConfig
from ipcverify.network._lipschitz_lowrank import (
    ensemble_gradient_norms,
    ensemble_scores,
    score_gradient_bound,
    sound_lipschitz_lowrank,
)
from ipcverify.network._lowrank import LowRankEnsemble, member_covariances, moment_match
from ipcverify.training._train import TrainConfig, train

DATA = make_lagged_perception(400, seed=3)


def _data(cfg: ModelConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return DATA.x[:, : cfg.x_dim], DATA.y[:, : cfg.y_dim], DATA.yhat[:, : cfg.y_dim]


def _box(cfg: ModelConfig) -> DataBox:
    x, y, yh = _data(cfg)
    return DataBox(x.min(0), x.max(0), y.min(0), y.max(0), yh.min(0), yh.max(0))


def _network(
    cfg: ModelConfig, seed: int, scale: float = 0.5, diag_bias: float | None = None
) -> LowRankEnsemble:
    """Normalisation and linear stage fitted on DATA; every weight random N(0, scale^2) (float32)."""
    net = LowRankEnsemble(cfg)
    net.fit_normalisation(*_data(cfg), ridge=1e-3)
    gen = torch.Generator().manual_seed(seed)
    n = cfg.y_dim
    with torch.no_grad():
        for p in net.parameters():
            p.copy_(scale * torch.randn(p.shape, generator=gen))
        if diag_bias is not None:  # log-diagonals near (or beyond) the clamp
            net.body.layers[-1].bias[:, :, n : 2 * n] = diag_bias
    return net.eval()


def _direction(names, shapes, rng: np.random.Generator, size: int) -> np.ndarray:
    """A unit vector: spread over all parameters, or (every other draw) over one parameter tensor only."""
    d = rng.standard_normal(size)
    if rng.random() < 0.5:
        which = rng.integers(len(names))
        starts = np.cumsum([0] + [int(np.prod(s)) for s in shapes])
        mask = np.zeros(size, dtype=bool)
        mask[starts[which] : starts[which + 1]] = True
        d[~mask] = 0.0
    return d / np.linalg.norm(d)


def _max_gradient_in_ball_and_box(ball, net, box, radius, rng, n_theta=12, n_x=60) -> float:
    names, shapes, theta = ball.flat(net)
    worst = 0.0
    for i in range(n_theta):
        d = _direction(names, shapes, rng, theta.size)
        r = radius if i % 2 == 0 else radius * rng.random() ** (1.0 / theta.size)
        params = ball.unflat(names, shapes, theta + r * d)
        x, y, yh = ball.random_in_box(box, rng, n_x, corners=i % 3 == 0)
        norms = ensemble_gradient_norms(net, x, y, yh, params=params, dtype=torch.float64)
        worst = max(worst, float(norms.max()))
    return worst


CONFIGS = [
    ModelConfig(x_dim=6, y_dim=3, hidden=(8, 6), members=3, activation="relu"),
    ModelConfig(x_dim=6, y_dim=3, hidden=(7,), members=1, linear_center=False, activation="tanh"),
    ModelConfig(x_dim=2, y_dim=2, hidden=(5, 5, 4), members=2, activation="elu"),
    ModelConfig(x_dim=1, y_dim=1, hidden=(3,), members=4, linear_center=False, activation="relu"),
]


def _ids(cfg: ModelConfig) -> str:
    return f"n{cfg.y_dim}-K{cfg.members}-{cfg.activation}-lin{int(bool(cfg.linear_center))}-{len(cfg.hidden)}"


@pytest.mark.parametrize("cfg", CONFIGS, ids=_ids)
def test_gradient_norms_match_a_plain_autograd_loop_through_the_network_s_own_forward(cfg, ball):
    net = _network(cfg, seed=1)
    names, shapes, theta = ball.flat(net)
    params = ball.unflat(names, shapes, theta + 0.05 * np.random.default_rng(0).standard_normal(theta.size))
    x, y, yh = (a[:6] for a in _data(cfg))
    fast = ensemble_gradient_norms(net, x, y, yh, params=params, dtype=torch.float64)
    ref_net = copy.deepcopy(net).double()
    with torch.no_grad():
        for k, p in ref_net.named_parameters():
            p.copy_(params[k])
    for i in range(6):
        ref_net.zero_grad()
        g, _ = ref_net.score(*(torch.tensor(a[i : i + 1]) for a in (x, y, yh)))  # forward: ||C (y - c)||
        g.sum().backward()
        ref = torch.sqrt(sum((p.grad**2).sum() for p in ref_net.parameters()))
        assert fast[i] == pytest.approx(float(ref), rel=1e-9)
    # the dispatcher of ipcverify.certification._lipschitz gives the same numbers;
    # float32 members agree to float32
    same = per_sample_gradient_norms(net, x, y, yh, params=params, dtype=torch.float64)
    np.testing.assert_array_equal(same, fast)
    f32 = ensemble_gradient_norms(net, x, y, yh)
    f64 = ensemble_gradient_norms(net, x, y, yh, dtype=torch.float64)
    np.testing.assert_allclose(f32, f64, rtol=1e-3)


def test_scores_are_the_engine_s():
    cfg = CONFIGS[0]
    net = _network(cfg, seed=2)
    x, y, yh = _data(cfg)
    g = ensemble_scores(net, *(torch.tensor(a) for a in (x, y, yh))).detach().numpy()
    np.testing.assert_allclose(g, IPCModel(net).raw_scores(x, y, yh), rtol=1e-5)


def test_the_score_gradient_lemma_holds_and_is_attained():
    """||d g / d(o_k, h_k, V_k)|| <= sqrt(1/(K mu) + g^2 max(1, 1/(K mu))) for random member outputs.

    The heart of the bound (proofs/lipschitz_lowrank.md, step 3), checked by autograd through the
    library's own moment matching; the largest ratio shows the inequality is tight (one member,
    V = 0), so an error in it would be caught.
    """
    rng = np.random.default_rng(0)
    worst = 0.0
    rows = 200  # independent draws per (K, n), evaluated as one batch

    def scales(*shape: int) -> np.ndarray:
        return rng.choice([0.0, 0.01, 1.0, 10.0], size=(1, rows) + (1,) * len(shape))

    for K in range(1, 5):
        for n in range(1, 4):
            o = rng.normal(size=(K, rows, n)) * (scales(n) + 0.01)
            h = rng.uniform(-LOGDIAG_CLAMP, LOGDIAG_CLAMP, (K, rows, n)) / 4
            V = rng.normal(size=(K, rows, n, n)) * scales(n, n)
            t = rng.normal(size=(rows, n)) * (scales(n)[0] * 10 + 0.01)
            o, h, V = (torch.tensor(a, requires_grad=True) for a in (o, h, V))
            mean, cov = moment_match(o, member_covariances(h, V))
            chol = torch.linalg.cholesky(cov)
            g = torch.linalg.vector_norm(
                torch.linalg.solve_triangular(chol, (torch.tensor(t) - mean).unsqueeze(-1), upper=False),
                dim=(1, 2),
            )
            grads = torch.autograd.grad(g.sum(), (o, h, V))  # rows are independent: row b's own gradient
            norm = torch.sqrt(sum((d**2).flatten(2).sum(2).sum(0) for d in grads)).numpy()
            mu = torch.exp(2 * h.detach()).mean(0).min(1).values.numpy()
            scores = g.detach().numpy()
            for b in range(rows):
                bound = score_gradient_bound(float(mu[b]), float(scores[b]), K)
                assert norm[b] <= bound
                worst = max(worst, norm[b] / bound)
    assert worst > 0.99


@pytest.mark.parametrize("cfg", CONFIGS, ids=_ids)
@pytest.mark.parametrize("radius", [0.0, 0.05, 0.5])
@pytest.mark.parametrize("scale", [0.05, 0.7])
def test_sound_bound_dominates_gradients_in_the_ball_and_box(cfg, radius, scale, ball):
    """Small weights (the bound within a factor ~5-50 of the largest gradient found) and large ones."""
    net = _network(cfg, seed=int(radius * 100) + cfg.members, scale=scale)
    box = _box(cfg)
    bound = sound_lipschitz(IPCModel(net), box, radius=radius).value
    worst = _max_gradient_in_ball_and_box(ball, net, box, radius, np.random.default_rng(17))
    assert 0 < worst <= bound


@pytest.mark.parametrize("diag_bias", [-LOGDIAG_CLAMP, -11.9, LOGDIAG_CLAMP - 0.05, 14.0, -14.0])
def test_sound_bound_holds_around_the_log_diagonal_clamp(diag_bias, ball):
    """Log-diagonals near or beyond the clamp at +/-12 (exp saturates, its derivative vanishes)."""
    cfg = ModelConfig(x_dim=6, y_dim=3, hidden=(6,), members=2)
    net = _network(cfg, seed=5, scale=0.05, diag_bias=diag_bias)
    box = _box(cfg)
    bound = sound_lipschitz(IPCModel(net), box, radius=0.2).value
    assert _max_gradient_in_ball_and_box(ball, net, box, 0.2, np.random.default_rng(3), n_theta=8) <= bound


def _engine_scores(net: LowRankEnsemble, params: dict[str, torch.Tensor], x, y, yh) -> np.ndarray:
    """g by the float64 engine of record (NumPy), at the parameters ``params``."""
    moved = copy.deepcopy(net).double()
    with torch.no_grad():
        for k, p in moved.named_parameters():
            p.copy_(params[k])
    return IPCModel(moved).raw_scores(x, y, yh)


@pytest.mark.parametrize("cfg", CONFIGS[:3], ids=_ids)
def test_lipschitz_inequality_on_function_values(cfg, ball):
    """|g(theta1) - g(theta2)| <= L ||theta1 - theta2|| for pairs in the ball (no gradients involved)."""
    net = _network(cfg, seed=8, scale=0.05)  # small weights: the bound is within ~10x of the truth
    box = _box(cfg)
    radius = 0.3
    bound = sound_lipschitz(IPCModel(net), box, radius=radius).value
    names, shapes, theta = ball.flat(net)
    rng = np.random.default_rng(9)
    x, y, yh = ball.random_in_box(box, rng, 200, corners=False)
    for _ in range(10):
        t1 = theta + radius * _direction(names, shapes, rng, theta.size)
        t2 = theta + radius * rng.random() * _direction(names, shapes, rng, theta.size)
        g1, g2 = (_engine_scores(net, ball.unflat(names, shapes, t), x, y, yh) for t in (t1, t2))
        assert (np.abs(g1 - g2) <= bound * np.linalg.norm(t1 - t2) * (1 + 1e-9)).all()


@settings(derandomize=True, max_examples=15, deadline=None)
@given(
    hidden=st.lists(st.integers(1, 5), min_size=1, max_size=3),
    y_dim=st.integers(1, 3),
    members=st.integers(1, 4),
    linear_center=st.booleans(),
    activation=st.sampled_from(["relu", "tanh", "elu"]),
    seed=st.integers(0, 1000),
    radius=st.floats(0.0, 1.0),
    scale=st.floats(0.05, 1.5),
)
def test_sound_bound_property(hidden, y_dim, members, linear_center, activation, seed, radius, scale, ball):
    cfg = ModelConfig(
        x_dim=3,
        y_dim=y_dim,
        hidden=tuple(hidden),
        members=members,
        linear_center=linear_center,
        activation=activation,
    )
    net = _network(cfg, seed=seed, scale=scale)
    box = _box(cfg)
    bound = sound_lipschitz(IPCModel(net), box, radius=radius).value
    assert _max_gradient_in_ball_and_box(ball, net, box, radius, np.random.default_rng(seed), 6, 40) <= bound


def test_sound_bound_grows_with_the_radius_and_the_box():
    cfg = CONFIGS[0]
    net = _network(cfg, seed=4)
    box = _box(cfg)
    values = [sound_lipschitz_lowrank(net, box, r).value for r in (0.0, 0.1, 1.0)]
    assert values == sorted(values) and values[0] < values[2]
    wide = DataBox(box.x_lo - 1, box.x_hi + 1, box.y_lo - 1, box.y_hi + 1, box.yhat_lo - 1, box.yhat_hi + 1)
    assert sound_lipschitz_lowrank(net, wide, 0.1).value > values[1]


def test_sound_bound_exceeds_the_empirical_estimate_on_a_trained_default_model():
    data = make_lagged_perception(800, seed=4)
    model = train(data, ModelConfig(x_dim=6, y_dim=3, hidden=(16, 16)), TrainConfig(epochs=3)).model
    assert theorem1_unavailable(model) is None
    low = empirical_lipschitz(model, data)
    low64 = empirical_lipschitz(model, data, dtype=torch.float64)
    assert low.value == pytest.approx(low64.value, rel=1e-3)
    high = sound_lipschitz(model, data, radius=0.1)
    assert high.value >= low64.value > 0
    assert sound_lipschitz(model, data, radius=0.0).value <= high.value
    assert low.n_samples == 800 and 0 <= low.argmax < 800
    # the statistics stored at training time hold the same empirical estimate
    assert model.metadata["training_statistics"]["empirical_lipschitz"] == pytest.approx(low.value, rel=1e-6)


def test_bad_inputs():
    cfg = CONFIGS[0]
    net = _network(cfg, seed=0)
    x, y, yh = _data(cfg)
    with pytest.raises(InvalidInputError, match=r"radius must be finite and >= 0"):
        sound_lipschitz(IPCModel(net), DATA, radius=float("nan"))
    small = DataBox(np.zeros(2), np.ones(2), np.zeros(3), np.ones(3), np.zeros(3), np.ones(3))
    with pytest.raises(InvalidInputError, match=r"box has x_dim=2, y_dim=3; the model expects x_dim=6"):
        sound_lipschitz(IPCModel(net), small)
    with pytest.raises(InvalidInputError, match=r"unknown parameter name\(s\) for this network: nope"):
        ensemble_gradient_norms(net, x, y, yh, params={"nope": torch.zeros(1)})
    name = "factor_skip.bias"
    with pytest.raises(InvalidInputError, match=r"parameter factor_skip.bias needs shape \(3, 1, 9\)"):
        ensemble_gradient_norms(net, x, y, yh, params={name: torch.zeros(2)})
    with pytest.raises(InvalidInputError, match=r"chunk_size must be a positive number of samples"):
        ensemble_gradient_norms(net, x, y, yh, chunk_size=0)
    # a network of neither class is refused with the reason (Theorem 1 covers both kinds ipcverify builds)
    with pytest.raises(
        Theorem1UnavailableError, match=r"no Lipschitz bound is derived for a network of class Linear"
    ):
        per_sample_gradient_norms(torch.nn.Linear(2, 2), x, y, yh)
