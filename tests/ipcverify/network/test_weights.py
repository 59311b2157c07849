"""Network weights in NumPy: the layout matches the torch networks, and models built from them agree."""

from __future__ import annotations

import hashlib
import itertools

import numpy as np
import pytest
import torch

from ipcverify.contract._model import IPCModel, network_fingerprint
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import ModelConfig
from ipcverify.network._modules import build_network
from ipcverify.network._weights import NetworkWeights, state_layout

CONFIGS = [
    ModelConfig(x_dim=2, y_dim=3, hidden=(8,), members=m, linear_center=lin, activation=act)
    for m, lin, act in itertools.product((1, 3), (True, False), ("relu", "tanh"))
] + [
    ModelConfig.recipe(recipe, x_dim=d, y_dim=n, hidden=hidden, activation=act)
    for recipe, (d, n), hidden, act in itertools.product(
        ("v1", "paper"), ((1, 1), (4, 2)), ((5,), (6, 7, 3)), ("relu", "elu")
    )
]


def _random(config: ModelConfig, seed: int):
    torch.manual_seed(seed)
    net = build_network(config)
    with torch.no_grad():
        for t in net.state_dict().values():
            t.copy_(torch.randn(t.shape, dtype=t.dtype) * 0.3 + (1.0 if t.dim() == 1 else 0.0))
        net.in_std.abs_().add_(0.5)
        net.sigma.abs_().add_(0.5)
    return net


@pytest.mark.parametrize("config", CONFIGS, ids=str)
def test_the_layout_is_the_torch_networks_state_dict(config):
    net = build_network(config)
    layout = state_layout(config)
    state = net.state_dict()
    assert list(layout) == list(state)  # names, in the network's order
    for name, (shape, dtype, parameter) in layout.items():
        assert (shape, dtype) == (tuple(state[name].shape), str(state[name].dtype).removeprefix("torch."))
        assert parameter == (name in dict(net.named_parameters()))
    assert NetworkWeights.from_network(net).n_parameters == sum(p.numel() for p in net.parameters())


def _fingerprint_as_written_before(net) -> str:
    """The network hash calibrations stored before weights existed (from the torch tensors)."""
    h = hashlib.sha256(repr(sorted(net.config.to_dict().items())).encode())
    for name, t in sorted(net.state_dict().items()):
        h.update(name.encode())
        arr = t.detach().cpu().contiguous().numpy()
        h.update(str(arr.dtype).encode() + str(arr.shape).encode())
        h.update(arr.tobytes())
    return h.hexdigest()


@pytest.mark.parametrize("config", CONFIGS[::3], ids=str)
def test_weights_round_trip_and_keep_the_fingerprint(config):
    net = _random(config, seed=1)
    w = NetworkWeights.from_network(net)
    assert w.fingerprint() == network_fingerprint(net) == _fingerprint_as_written_before(net)
    back = w.to_network()
    assert _fingerprint_as_written_before(back) == w.fingerprint()
    assert all(not a.flags.writeable for a in w.state.values())


@pytest.mark.parametrize("config", CONFIGS[::2], ids=str)
def test_a_model_from_weights_is_the_model_from_its_network(config):
    net = _random(config, seed=2)
    rng = np.random.default_rng(3)
    x, yhat = rng.random((50, config.x_dim)), rng.random((50, config.y_dim))
    from_net = IPCModel(net)
    from_weights = IPCModel(NetworkWeights.from_network(net))
    a, b = from_net.raw_arrays(x, yhat), from_weights.raw_arrays(x, yhat)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert from_weights.n_parameters == from_net.n_parameters
    assert from_net.network is net  # a model built from a network keeps that very network
    built = from_weights.network  # built on first use, once
    assert built is from_weights.network and network_fingerprint(built) == network_fingerprint(net)
    assert not built.training


def test_wrong_weights_are_refused_by_name():
    cfg = ModelConfig.recipe("v1", x_dim=2, y_dim=2, hidden=(3,))
    good = {k: np.ones(s, t) for k, (s, t, _) in state_layout(cfg).items()}
    NetworkWeights(cfg, good)
    cases = {
        r"missing \['body.2.bias'\]": {k: v for k, v in good.items() if k != "body.2.bias"},
        r"unexpected \['extra'\]": {**good, "extra": np.ones(1, "float32")},
        r"'body.0.weight' has shape \(4, 3\) and dtype float32; the network's is \(3, 4\)": {
            **good,
            "body.0.weight": np.ones((4, 3), "float32"),
        },
        r"'sigma' has shape \(2,\) and dtype int64": {**good, "sigma": np.ones(2, dtype=np.int64)},
        r"'in_mean' has type list": {**good, "in_mean": [0.0, 0.0, 0.0, 0.0]},
    }
    for message, state in cases.items():
        with pytest.raises(InvalidInputError, match=message):
            NetworkWeights(cfg, state)


def test_a_state_dict_is_cast_to_the_networks_dtypes_as_load_state_dict_does():
    cfg = ModelConfig(x_dim=2, y_dim=2, hidden=(3,), members=2)
    net = _random(cfg, seed=4)
    as_double = {k: v.double().numpy() for k, v in net.state_dict().items()}
    w = NetworkWeights.from_state_dict(cfg, as_double)
    assert w.fingerprint() == network_fingerprint(net)  # float32 entries back to float32, exactly
    ref = build_network(cfg)
    ref.load_state_dict({k: torch.from_numpy(v) for k, v in as_double.items()}, strict=True)
    assert network_fingerprint(ref) == w.fingerprint()
    # a network converted to float64 keeps its dtype (the engine evaluates it as given)
    doubled = NetworkWeights.from_network(net.double())
    assert all(a.dtype == np.float64 for a in doubled.state.values())
