"""Each network kind's float64 engine implements the one engine interface (ipcverify.network.Engine)."""

from __future__ import annotations

import inspect

import numpy as np
import pytest
import torch

from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import ModelConfig
from ipcverify.network._engine import InferenceEngine
from ipcverify.network._interface import engine_for, is_network
from ipcverify.network._kind import Engine
from ipcverify.network._lipschitz_ball import DataBox
from ipcverify.network._lowrank_engine import LowRankEngine
from ipcverify.network._modules import build_network
from ipcverify.network._weights import NetworkWeights

#: One configuration per network kind (and the heads of the dense kind), with the engine class expected.
KINDS = [
    (ModelConfig(x_dim=4, y_dim=3, hidden=(8,), members=2), LowRankEngine),
    (ModelConfig(x_dim=4, y_dim=2, hidden=(8,), members=3), LowRankEngine),
    (ModelConfig.recipe("v1", x_dim=4, y_dim=3, hidden=(8,)), InferenceEngine),
    (ModelConfig.recipe("paper", x_dim=4, y_dim=3, hidden=(8,)), InferenceEngine),
    (ModelConfig.recipe("v1", x_dim=4, y_dim=2, hidden=(8,)), InferenceEngine),
]
#: The interface's attributes (declared, read-only: a field or a property of each engine).
ATTRIBUTES = [
    name
    for name, kind in Engine.__annotations__.items()
    if not name.startswith("_") and not str(kind).startswith("ClassVar")
]
#: The interface's members (methods and attributes).
MEMBERS = [
    name for name, value in vars(Engine).items() if not name.startswith("_") and callable(value)
] + ATTRIBUTES


def _network(cfg: ModelConfig, seed: int = 0):
    torch.manual_seed(seed)
    net = build_network(cfg)
    with torch.no_grad():  # away from the initial state, so that every head matters
        for p in net.parameters():
            p.add_(0.3 * torch.randn_like(p))
    return net.eval()


def test_the_interface_has_every_member_the_callers_use():
    assert set(MEMBERS) >= {
        "config",
        "in_mean",
        "in_scale",
        "chunk",
        "batch",
        "single",
        "single_values",
        "prepare",
        "float64_layers",
        "onnx_nodes",
        "gradient_norms",
        "sound_lipschitz",
    }


@pytest.mark.parametrize(
    ("cfg", "kind"), KINDS, ids=lambda v: getattr(v, "param", getattr(v, "__name__", ""))
)
def test_each_engine_satisfies_the_interface(cfg, kind):
    net = _network(cfg)
    eng = engine_for(net)
    assert type(eng) is kind and isinstance(eng, Engine) and is_network(net)
    assert type(engine_for(NetworkWeights.from_network(net))) is kind
    for name in MEMBERS:  # every member, with the interface's parameters in the same order
        if name in ATTRIBUTES:
            getattr(eng, name)  # readable (a field or a property)
            continue
        theirs, ours = getattr(Engine, name), getattr(type(eng), name)
        assert list(inspect.signature(ours).parameters) == list(inspect.signature(theirs).parameters), name
    assert eng.config == cfg and eng.chunk >= 64
    d, n = cfg.x_dim, cfg.y_dim
    rng = np.random.default_rng(1)
    x, yhat = rng.normal(size=(5, d)), rng.normal(size=(5, n))
    centers, shapes = eng.batch(x, yhat)
    eng.prepare()
    for i in range(5):
        c, flat = eng.single_values(np.concatenate((x[i], yhat[i])))
        assert len(c) == n and len(flat) == n * n
        np.testing.assert_allclose(c, centers[i], rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(np.reshape(flat, (n, n)), shapes[i], rtol=1e-12, atol=1e-14)
        c1, C1 = eng.single(x[i], yhat[i])
        np.testing.assert_allclose(C1, shapes[i], rtol=1e-12, atol=1e-14)
    z = ((np.hstack([x, yhat]) - eng.in_mean) * eng.in_scale).astype(np.float64)
    assert eng.float64_layers(z) is not None


@pytest.mark.parametrize(("cfg", "kind"), KINDS[:1] + KINDS[2:3], ids=["lowrank", "cholesky"])
def test_each_engine_gives_its_kinds_lipschitz_numbers(cfg, kind):
    data = make_lagged_perception(60, seed=3)
    cfg = ModelConfig(**{**cfg.to_dict(), "x_dim": data.x_dim, "hidden": tuple(cfg.hidden)})
    net = _network(cfg, seed=2)
    eng = engine_for(net)
    norms = eng.gradient_norms(net, data.x, data.y, data.yhat, None, 32, torch.float64)
    assert norms.shape == (60,) and (norms > 0).all()
    bound = eng.sound_lipschitz(net, DataBox.from_dataset(data), 0.05)
    assert bound.value >= norms.max()  # the sound bound covers every gradient at theta_hat
    # an engine refuses a network of the other kind
    other = build_network(
        ModelConfig.recipe("v1", x_dim=data.x_dim, y_dim=3, hidden=(4,))
        if kind is LowRankEngine
        else ModelConfig(x_dim=data.x_dim, y_dim=3, hidden=(4,))
    )
    with pytest.raises(
        InvalidInputError, match=r"this is for a \w+ network; got a \w+ \(ask the network's own"
    ):
        eng.sound_lipschitz(other, DataBox.from_dataset(data), 0.05)
    with pytest.raises(InvalidInputError, match="ask the network's own engine"):
        eng.gradient_norms(other, data.x, data.y, data.yhat, None, 32, torch.float64)


def test_only_networks_of_the_two_kinds_are_networks():
    assert not is_network(torch.nn.Linear(2, 2))
    assert not is_network(
        NetworkWeights.from_network(build_network(ModelConfig(x_dim=1, y_dim=1, hidden=(2,))))
    )
