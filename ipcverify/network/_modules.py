"""The IPC network: (x, yhat) -> ellipsoid E(c, C) that should contain y.

Architecture (paper, "Machine learning setup"): an MLP on ``concat(x, yhat)`` with
hidden sizes (64, 128). Inputs are standardised with statistics stored in the
model. The raw output is split into a centre head and a shape head:

* centre ``offset`` (default): ``c = yhat + sigma * o``; centre ``raw``:
  ``c = mu_y + sigma * o`` where ``o`` is the network's centre output and
  ``sigma`` the per-dimension scale of the residual ``y - yhat`` (stored).
* shape ``cholesky``: ``L`` lower-triangular with diagonal
  ``exp(clamp(l_ii, -12, 12))``, so ``log det(C^T C)`` is finite and cheap;
  shape ``full``: the paper's ``n^2`` raw entries. Either way
  ``C = L diag(1 / sigma)``, i.e. ``||C (y - c)|| = ||L ((y - c) / sigma)||``.

That is :class:`IPCNetwork`, the network of the recipes ``"v1"`` and ``"paper"``. The
default recipe's network, the low-rank head and its ensemble, is
:class:`~ipcverify.network.LowRankEnsemble`; :func:`build_network` builds either from a
:class:`~ipcverify.network.ModelConfig`, and :class:`~ipcverify.contract.IPCModel` holds
either (as :class:`~ipcverify.network.NetworkWeights`, building the torch network only when
training, the Lipschitz bound or the export asks for it).
"""

from __future__ import annotations

import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import LOGDIAG_CLAMP, ModelConfig
from ipcverify.network._lowrank import LowRankEnsemble
from ipcverify.network._scoring import ScoredNetwork

FloatArray = NDArray[np.float64]
_ACTIVATIONS: dict[str, type[nn.Module]] = {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU}


class IPCNetwork(ScoredNetwork):
    """The neural network behind an IPC (float32, CPU).

    ``body`` is a plain :class:`torch.nn.Sequential` MLP; normalisation buffers
    ``in_mean``, ``in_std``, ``y_mean`` and ``sigma`` are stored in the state dict.

    Parameters
    ----------
    config : ModelConfig
        The architecture, with a ``"cholesky"`` or ``"full"`` head (a low-rank config raises
        :class:`InvalidInputError`: use :func:`build_network`).

    Examples
    --------
    >>> net = IPCNetwork(ModelConfig(x_dim=2, y_dim=3, hidden=(8,), param="cholesky"))
    >>> c, C, logdet = net(torch.zeros(5, 2), torch.zeros(5, 3))
    >>> tuple(C.shape), tuple(logdet.shape)
    ((5, 3, 3), (5,))
    """

    # buffers registered in __init__ (declared so type checkers see Tensors, not Tensor | Module)
    in_mean: torch.Tensor
    in_std: torch.Tensor
    y_mean: torch.Tensor
    sigma: torch.Tensor
    _tril_rows: torch.Tensor
    _tril_cols: torch.Tensor
    _diag_mask: torch.Tensor
    _tril_embed: torch.Tensor

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        if config.lowrank:
            raise InvalidInputError(
                "IPCNetwork builds the paper's heads ('cholesky', 'full'); this config has the low-rank head "
                f"with {config.members} member(s): build it with ipcverify.network.build_network(config)"
            )
        self.config = config
        d, n = config.x_dim, config.y_dim
        act = _ACTIVATIONS[config.activation]
        layers: list[nn.Module] = []
        width = d + n
        for h in config.hidden:
            layers += [nn.Linear(width, h), act()]
            width = h
        layers.append(nn.Linear(width, config.n_outputs))
        self.body = nn.Sequential(*layers)
        self.register_buffer("in_mean", torch.zeros(d + n))
        self.register_buffer("in_std", torch.ones(d + n))
        self.register_buffer("y_mean", torch.zeros(n))
        self.register_buffer("sigma", torch.ones(n))
        rows, cols = torch.tril_indices(n, n)
        self.register_buffer("_tril_rows", rows, persistent=False)
        self.register_buffer("_tril_cols", cols, persistent=False)
        self.register_buffer("_diag_mask", rows == cols, persistent=False)
        embed = torch.zeros(len(rows), n * n)
        embed[torch.arange(len(rows)), rows * n + cols] = 1.0
        # maps the packed lower triangle to a flat n*n matrix without in-place ops
        self.register_buffer("_tril_embed", embed, persistent=False)

    @property
    def output_layer(self) -> nn.Linear:
        """The last linear layer (centre rows first, then the shape rows)."""
        last = self.body[-1]
        if not isinstance(last, nn.Linear):
            raise InvalidInputError(
                f"the network's last layer is of type {type(last).__name__}, not a Linear layer"
            )
        return last

    def set_normalisation(self, x: FloatArray, y: FloatArray, yhat: FloatArray) -> None:
        """Set input standardisation and output scale from training data."""
        inp = np.concatenate([x, yhat], axis=1)
        mean = inp.mean(axis=0)
        std = inp.std(axis=0)
        std = np.where(std > 1e-12 * np.maximum(1.0, np.abs(mean)), std, 1.0)
        resid = y - yhat if self.config.center == "offset" else y - y.mean(axis=0)
        sigma = resid.std(axis=0)
        scale = np.maximum(np.abs(y).max(axis=0), 1.0)
        sigma = np.where(sigma > 1e-9 * scale, sigma, 1e-3 * scale)
        with torch.no_grad():
            self.in_mean.copy_(torch.as_tensor(mean, dtype=torch.float32))
            self.in_std.copy_(torch.as_tensor(std, dtype=torch.float32))
            self.y_mean.copy_(torch.as_tensor(y.mean(axis=0), dtype=torch.float32))
            self.sigma.copy_(torch.as_tensor(sigma, dtype=torch.float32))

    def start_at_estimate(self) -> None:
        """Set the weights so that the centre output is exactly ``yhat`` (in place).

        An initialisation, for the paper's network, whose centre is predicted outright: its
        ReLU layers pass each standardised ``yhat_i`` through as the pair
        ``relu(z_i), relu(-z_i)`` (units ``2i, 2i + 1`` of every hidden layer, which then
        read nothing else), and the centre rows of the output layer undo the
        standardisation, so ``c = yhat`` before the first step. The other units keep their
        random initialisation and the shape rows are untouched; training then moves every
        weight. The normalisation must already be set (:meth:`set_normalisation`).

        Raises
        ------
        InvalidInputError
            Unless the activation is ReLU and every hidden layer has at least ``2 n`` units.

        Examples
        --------
        >>> net = IPCNetwork(ModelConfig(x_dim=1, y_dim=2, hidden=(4, 6), param="full", center="raw"))
        >>> rng = np.random.default_rng(0)
        >>> x, y = rng.normal(size=(50, 1)), rng.normal(size=(50, 2))
        >>> net.set_normalisation(x, y, y + 0.1)
        >>> net.start_at_estimate()
        >>> xt, yt = torch.tensor(x[:3], dtype=torch.float32), torch.tensor(y[:3] + 0.1, dtype=torch.float32)
        >>> bool(torch.allclose(net(xt, yt)[0], yt, atol=1e-5))
        True
        """
        cfg = self.config
        n, d = cfg.y_dim, cfg.x_dim
        if cfg.activation != "relu" or min(cfg.hidden) < 2 * n:
            raise InvalidInputError(
                "starting the centre at yhat needs ReLU hidden layers of at least 2 * y_dim units each; "
                f"this network has activation={cfg.activation!r}, hidden={cfg.hidden}"
            )
        linear = [m for m in self.body if isinstance(m, nn.Linear)]
        pair = torch.arange(2 * n)
        sign = torch.tensor([1.0, -1.0]).repeat(n)
        with torch.no_grad():
            first = linear[0]
            first.weight[: 2 * n] = 0.0
            first.bias[: 2 * n] = 0.0
            first.weight[pair, d + pair // 2] = sign
            for layer in linear[1:-1]:
                layer.weight[: 2 * n] = 0.0
                layer.bias[: 2 * n] = 0.0
                layer.weight[pair, pair] = 1.0
            last = linear[-1]
            last.weight[:n] = 0.0
            last.bias[:n] = 0.0
            if cfg.center == "raw":  # c = y_mean + sigma o: o = (mean + std z - y_mean) / sigma
                s, mu = self.in_std[d:], self.in_mean[d:]
                last.weight[pair // 2, pair] = sign * (s / self.sigma)[pair // 2]
                last.bias[:n] = (mu - self.y_mean) / self.sigma

    def forward(self, x: torch.Tensor, yhat: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Centres (B, n), shape matrices C (B, n, n) and ``log det(C^T C)`` (B,)."""
        n = self.config.y_dim
        z = (torch.cat([x, yhat], dim=1) - self.in_mean) / self.in_std
        out = self.body(z)
        o, s = out[:, :n], out[:, n:]
        base = yhat if self.config.center == "offset" else self.y_mean.expand_as(yhat)
        center = base + self.sigma * o
        inv_sigma = 1.0 / self.sigma
        if self.config.param == "full":
            L = s.reshape(-1, n, n)
            logdet_L2 = 2.0 * torch.linalg.slogdet(L)[1]
        else:
            vals = torch.where(self._diag_mask, torch.exp(torch.clamp(s, -LOGDIAG_CLAMP, LOGDIAG_CLAMP)), s)
            L = (vals @ self._tril_embed).reshape(-1, n, n)
            logdet_L2 = 2.0 * torch.clamp(s[:, self._diag_mask], -LOGDIAG_CLAMP, LOGDIAG_CLAMP).sum(1)
        C = L * inv_sigma
        logdet = logdet_L2 + 2.0 * torch.log(inv_sigma).sum()
        return center, C, logdet


#: The networks an :class:`~ipcverify.contract.IPCModel` can hold.
Network = IPCNetwork | LowRankEnsemble


def build_network(config: ModelConfig) -> Network:
    """The untrained network of ``config``: a :class:`~ipcverify.network.LowRankEnsemble` for the
    low-rank head, an :class:`IPCNetwork` for the paper's heads.

    Parameters
    ----------
    config : ModelConfig
        The architecture; its ``param`` chooses the class. The weights are freshly initialised.

    Examples
    --------
    >>> type(build_network(ModelConfig(x_dim=2, y_dim=3))).__name__
    'LowRankEnsemble'
    >>> type(build_network(ModelConfig.recipe("v1", x_dim=2, y_dim=3))).__name__
    'IPCNetwork'
    """
    return LowRankEnsemble(config) if config.lowrank else IPCNetwork(config)
