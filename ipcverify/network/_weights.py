"""A trained network's weights as NumPy arrays: what a model file holds, usable without torch.

:class:`NetworkWeights` is the state dict of an IPC network (:mod:`ipcverify.network._modules`) in
NumPy, checked against the layout its :class:`~ipcverify.network.ModelConfig` implies
(:func:`state_layout`: every name, shape and dtype, as ``load_state_dict(strict=True)``
would check them). The float64 engines (:mod:`ipcverify.network._engine`,
:mod:`ipcverify.network._lowrank_engine`) are built from it, so a model read from a file predicts,
calibrates and is monitored without importing torch; :meth:`NetworkWeights.to_network`
builds the torch network when training, the Lipschitz bound or the export need it.

Examples
--------
>>> from ipcverify.network import ModelConfig
>>> layout = state_layout(ModelConfig.recipe("v1", x_dim=2, y_dim=3, hidden=(4,)))
>>> [(name, shape) for name, (shape, dtype, parameter) in layout.items() if parameter]
[('body.0.weight', (4, 5)), ('body.0.bias', (4,)), ('body.2.weight', (9, 4)), ('body.2.bias', (9,))]
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import ModelConfig

if TYPE_CHECKING:
    from ipcverify.network._modules import Network

#: One state-dict entry: shape, dtype name, and whether it is a trained parameter (else a buffer).
Entry = tuple[tuple[int, ...], str, bool]


def state_layout(config: ModelConfig) -> dict[str, Entry]:
    """Every state-dict entry of ``config``'s network, in the network's order.

    Examples
    --------
    >>> cfg = ModelConfig(x_dim=2, y_dim=3, hidden=(8,), members=4)
    >>> state_layout(cfg)["body.layers.1.weight"], state_layout(cfg)["sigma"]
    (((4, 8, 15), 'float32', True), ((3,), 'float64', False))
    """
    d_in, n = config.x_dim + config.y_dim, config.y_dim
    widths = [d_in, *config.hidden, config.n_outputs]
    layout: dict[str, Entry] = {}
    if not config.lowrank:  # ipcverify.network.IPCNetwork: float32 buffers, then nn.Sequential
        for name, size in (("in_mean", d_in), ("in_std", d_in), ("y_mean", n), ("sigma", n)):
            layout[name] = ((size,), "float32", False)
        for i, (a, b) in enumerate(zip(widths[:-1], widths[1:], strict=True)):
            layout[f"body.{2 * i}.weight"] = ((b, a), "float32", True)
            layout[f"body.{2 * i}.bias"] = ((b,), "float32", True)
        return layout
    k = config.members  # ipcverify.network.LowRankEnsemble: float64 buffers, float32 stacked layers
    for name, shape in (
        ("in_mean", (d_in,)),
        ("in_std", (d_in,)),
        ("sigma", (n,)),
        ("lin_weight", (d_in, n)),
        ("lin_bias", (n,)),
    ):
        layout[name] = (shape, "float64", False)
    stacked = [
        (f"body.layers.{i}", a, b) for i, (a, b) in enumerate(zip(widths[:-1], widths[1:], strict=True))
    ]
    if config.linear_center:
        stacked.append(("center_skip", d_in, n))
    stacked.append(("factor_skip", d_in, n * n))
    for prefix, a, b in stacked:
        layout[f"{prefix}.weight"] = ((k, a, b), "float32", True)
        layout[f"{prefix}.bias"] = ((k, 1, b), "float32", True)
    return layout


@dataclass(frozen=True, eq=False)
class NetworkWeights:
    """The state dict of an IPC network as read-only NumPy arrays, checked against its layout.

    Parameters
    ----------
    config : ModelConfig
        The architecture the weights belong to: it fixes the entries, shapes and dtypes the state
        must have (:func:`state_layout`).
    state : mapping of str to array
        Every entry of :func:`state_layout` with its shape, in a floating dtype (the layout's,
        unless the network was converted, e.g. with ``.double()``), nothing else. Stored as
        read-only copies, in the layout's order. :meth:`from_state_dict` casts to the layout's
        dtypes, as ``load_state_dict`` does (a model file is read so, and its values checked
        finite, by :func:`ipcverify.io.load_model`).

    Raises
    ------
    InvalidInputError
        If an entry is missing, unknown, of the wrong shape or not floating (the message names it).

    Examples
    --------
    >>> cfg = ModelConfig.recipe("v1", x_dim=1, y_dim=1, hidden=(2,))
    >>> state = {k: np.zeros(shape, dtype) for k, (shape, dtype, _) in state_layout(cfg).items()}
    >>> w = NetworkWeights(cfg, state)
    >>> w.n_parameters, len(w.fingerprint())
    (12, 64)
    >>> NetworkWeights(cfg, {**state, "body.0.bias": np.zeros(3, "float32")})
    Traceback (most recent call last):
    ...
    ipcverify.errors.InvalidInputError: parameter 'body.0.bias' has shape (3,) and dtype float32; \
the network's is (2,), float32
    """

    config: ModelConfig
    state: Mapping[str, NDArray[Any]]

    def __post_init__(self) -> None:
        layout = state_layout(self.config)
        given = dict(self.state)
        missing, unknown = set(layout) - set(given), set(given) - set(layout)
        if missing or unknown:
            raise InvalidInputError(
                f"the state dict does not match the architecture: missing {sorted(missing)}, "
                f"unexpected {sorted(unknown)}"
            )
        state: dict[str, NDArray[Any]] = {}
        for name, (shape, dtype, _) in layout.items():
            value = given[name]
            if not isinstance(value, np.ndarray) or value.shape != shape or value.dtype.kind != "f":
                got = (
                    f"shape {value.shape} and dtype {value.dtype}"
                    if isinstance(value, np.ndarray)
                    else f"type {type(value).__name__}"
                )
                raise InvalidInputError(f"parameter {name!r} has {got}; the network's is {shape}, {dtype}")
            arr = np.array(value, order="C")
            arr.setflags(write=False)
            state[name] = arr
        object.__setattr__(self, "state", state)

    @classmethod
    def from_state_dict(cls, config: ModelConfig, state: Mapping[str, Any]) -> NetworkWeights:
        """The weights ``load_state_dict(strict=True)`` gives a new network of ``config``: entries
        checked by name and shape, floating values cast to the network's dtypes.

        Examples
        --------
        >>> cfg = ModelConfig.recipe("v1", x_dim=1, y_dim=1, hidden=(2,))
        >>> state = {k: np.ones(shape) for k, (shape, _, _) in state_layout(cfg).items()}  # float64
        >>> NetworkWeights.from_state_dict(cfg, state).state["body.0.weight"].dtype
        dtype('float32')
        """
        layout = state_layout(config)
        cast = dict(state)
        with np.errstate(over="ignore", invalid="ignore"):  # too large for float32: inf, refused later
            for name, value in cast.items():
                if name in layout and isinstance(value, np.ndarray) and value.dtype.kind == "f":
                    cast[name] = value.astype(layout[name][1])
        return cls(config, cast)

    @classmethod
    def of(cls, source: Network | NetworkWeights) -> NetworkWeights:
        """The weights of a torch network (copied), or ``source`` itself if it is weights already."""
        return weights_and_network(source)[0]

    @classmethod
    def from_network(cls, network: Network) -> NetworkWeights:
        """The weights of a torch network (copied)."""
        state = {k: v.detach().cpu().numpy().copy() for k, v in network.state_dict().items()}
        return cls(network.config, state)

    def to_network(self) -> Network:
        """The torch network with these weights (in eval mode); imports torch."""
        import torch

        from ipcverify.network._modules import build_network

        net = build_network(self.config)
        net.load_state_dict({k: torch.from_numpy(v.copy()) for k, v in self.state.items()}, strict=True)
        net.eval()
        return net

    @property
    def n_parameters(self) -> int:
        """Number of trainable scalar parameters ``p`` (the buffers do not count)."""
        layout = state_layout(self.config)
        return sum(int(self.state[name].size) for name, (_, _, parameter) in layout.items() if parameter)

    def fingerprint(self) -> str:
        """SHA-256 of the configuration and every entry (:func:`ipcverify.contract.network_fingerprint`)."""
        h = hashlib.sha256(repr(sorted(self.config.to_dict().items())).encode())
        for name, arr in sorted(self.state.items()):
            h.update(name.encode())
            h.update(str(arr.dtype).encode() + str(arr.shape).encode())
            h.update(arr.tobytes())
        return h.hexdigest()


def weights_and_network(source: Network | NetworkWeights) -> tuple[NetworkWeights, Network | None]:
    """A network's weights and the torch network itself (None if ``source`` is weights already).

    Examples
    --------
    >>> cfg = ModelConfig.recipe("v1", x_dim=1, y_dim=1, hidden=(2,))
    >>> w = NetworkWeights(cfg, {k: np.ones(s, t) for k, (s, t, _) in state_layout(cfg).items()})
    >>> weights_and_network(w) == (w, None)
    True
    """
    if isinstance(source, NetworkWeights):
        return source, None
    return NetworkWeights.from_network(source), source
