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
:class:`~ipcverify.lowrank.LowRankEnsemble`; :func:`build_network` builds either from a
:class:`~ipcverify.architecture.ModelConfig`, and :class:`IPCModel` holds either.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from ipcverify.architecture import LOGDIAG_CLAMP, ModelConfig
from ipcverify.calibration.protocol import Calibration
from ipcverify.domain import DomainModel
from ipcverify.errors import InvalidInputError, SetError
from ipcverify.inference import InferenceEngine
from ipcverify.lowrank import LowRankEnsemble
from ipcverify.lowrank_engine import LowRankEngine
from ipcverify.nonsingular import checked_ellipsoid
from ipcverify.scoring import ScoredNetwork
from ipcverify.sets import Ellipsoid

__all__ = ["IPCNetwork", "IPCModel", "Network", "build_network", "engine_for", "network_fingerprint"]

FloatArray = NDArray[np.float64]
_ACTIVATIONS: dict[str, type[nn.Module]] = {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU}


class IPCNetwork(ScoredNetwork):
    """The neural network behind an IPC (float32, CPU).

    ``body`` is a plain :class:`torch.nn.Sequential` MLP; normalisation buffers
    ``in_mean``, ``in_std``, ``y_mean`` and ``sigma`` are stored in the state dict.

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
                f"with {config.members} member(s): build it with ipcverify.model.build_network(config)"
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
                f"the network's last layer is a {type(last).__name__}, not a Linear layer"
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


#: The networks an :class:`IPCModel` can hold.
Network = IPCNetwork | LowRankEnsemble


def build_network(config: ModelConfig) -> Network:
    """The untrained network of ``config``: a :class:`~ipcverify.lowrank.LowRankEnsemble` for the
    low-rank head, an :class:`IPCNetwork` for the paper's heads.

    Examples
    --------
    >>> type(build_network(ModelConfig(x_dim=2, y_dim=3))).__name__
    'LowRankEnsemble'
    >>> type(build_network(ModelConfig.recipe("v1", x_dim=2, y_dim=3))).__name__
    'IPCNetwork'
    """
    return LowRankEnsemble(config) if config.lowrank else IPCNetwork(config)


def engine_for(network: Network) -> InferenceEngine | LowRankEngine:
    """The float64 engine of record for ``network``."""
    if isinstance(network, LowRankEnsemble):
        return LowRankEngine.from_network(network)
    return InferenceEngine.from_network(network)


@dataclass(frozen=True, eq=False)
class IPCModel:
    """A trained inverse perception contract, optionally calibrated.

    Parameters
    ----------
    network : IPCNetwork or LowRankEnsemble
        The trained network (put in eval mode).
    calibration : Calibration, optional
        Scale factors applied to the raw sets; see :mod:`ipcverify.calibration`.
    metadata : mapping
        Plain data recorded with the model (training settings, data hash, history).
    domain : DomainModel, optional
        The domain of validity fitted at calibration (:mod:`ipcverify.domain`): queries it
        flags lie outside what the calibration certificate covers.

    Examples
    --------
    >>> import numpy as np
    >>> m = IPCModel(build_network(ModelConfig(x_dim=2, y_dim=3, hidden=(8,))))
    >>> m.predict(np.zeros((4, 2)), np.zeros((4, 3))).batch_size
    4
    """

    network: Network
    calibration: Calibration | None = None
    metadata: Mapping[str, Any] = field(default_factory=dict)
    domain: DomainModel | None = None

    def __post_init__(self) -> None:
        if self.domain is not None and len(self.domain.mean) != self.config.x_dim + self.config.y_dim:
            raise InvalidInputError(
                f"the domain model covers {len(self.domain.mean)} input columns but the network takes "
                f"{self.config.x_dim + self.config.y_dim} (x and yhat); refit it with calibrate"
            )
        self.network.eval()
        object.__setattr__(self, "_engine", engine_for(self.network))

    @property
    def engine(self) -> InferenceEngine | LowRankEngine:
        """The float64 NumPy evaluation of the network (:mod:`ipcverify.inference` or
        :mod:`ipcverify.lowrank_engine`)."""
        return self._engine  # type: ignore[attr-defined,no-any-return]

    @property
    def config(self) -> ModelConfig:
        """The network architecture."""
        return self.network.config

    @property
    def n_parameters(self) -> int:
        """Number of trainable scalar parameters ``p``."""
        return sum(p.numel() for p in self.network.parameters())

    def _check(self, x: Any, yhat: Any) -> tuple[FloatArray, FloatArray]:
        xa = np.asarray(x, dtype=np.float64)
        ya = np.asarray(yhat, dtype=np.float64)
        if xa.ndim == 1:
            xa = xa[None]
        if ya.ndim == 1:
            ya = ya[None]
        cfg = self.config
        if xa.shape[1:] != (cfg.x_dim,) or ya.shape[1:] != (cfg.y_dim,) or len(xa) != len(ya):
            raise InvalidInputError(
                f"the model expects x of shape (B, {cfg.x_dim}) and yhat of shape (B, {cfg.y_dim}); "
                f"got {xa.shape} and {ya.shape}"
            )
        if not (np.isfinite(xa).all() and np.isfinite(ya).all()):
            raise InvalidInputError("x and yhat must be finite")
        return xa, ya

    def raw_arrays(self, x: Any, yhat: Any, batch_size: int | None = None) -> tuple[FloatArray, FloatArray]:
        """Uncalibrated centres (B, n) and shapes (B, n, n), evaluated in float64.

        All of ipcverify evaluates a trained model through this one path (the
        float64 engine of :mod:`ipcverify.inference`), so calibration, certificates
        and the controller see exactly the same sets. ``batch_size`` rows are evaluated
        together (default: the engine's, :func:`ipcverify.inference.chunk_rows`, which keeps them in cache).
        """
        xa, ya = self._check(x, yhat)
        return self._engine.batch(xa, ya, batch_size)  # type: ignore[attr-defined,no-any-return]

    def predict_raw(self, x: Any, yhat: Any) -> Ellipsoid:
        """The network's own sets, ignoring any calibration."""
        return checked_ellipsoid(*self.raw_arrays(x, yhat))

    def predict(self, x: Any, yhat: Any) -> Ellipsoid:
        """The contract's sets: calibrated if the model carries a calibration.

        The shapes are divided by the calibration's scales (as :meth:`Ellipsoid.scaled` does)
        and validated once, by the cheap equivalent of the SVD test
        (:func:`ipcverify.nonsingular.checked_ellipsoid`).

        Parameters
        ----------
        x : array_like, shape (B, d) or (d,)
        yhat : array_like, shape (B, n) or (n,)
        """
        xa, ya = self._check(x, yhat)
        centers, shapes = self._engine.batch(xa, ya)  # type: ignore[attr-defined]
        if self.calibration is not None:
            f = np.asarray(self.calibration.scale_for(xa, ya), dtype=np.float64)
            if f.shape != (len(xa),) or not (np.isfinite(f).all() and (f > 0).all()):
                raise SetError("calibration scale factors must be finite and > 0, one per query")
            shapes /= f[:, None, None]
        try:
            return checked_ellipsoid(centers, shapes)
        except SetError as exc:
            raise SetError(_out_of_domain_message(str(exc), self.domain, xa, ya)) from None

    def raw_scores(self, x: Any, y: Any, yhat: Any) -> FloatArray:
        """Uncalibrated scores ``g = ||C (y - c)||`` (B,) in float64."""
        centers, shapes = self.raw_arrays(x, yhat)
        ya = np.asarray(y, dtype=np.float64).reshape(centers.shape)
        return np.linalg.norm(np.einsum("bij,bj->bi", shapes, ya - centers), axis=1)

    def require_calibration(self) -> Calibration:
        """The calibration, or an :class:`InvalidInputError` saying how to get one.

        Examples
        --------
        >>> m = IPCModel(build_network(ModelConfig(x_dim=1, y_dim=1, hidden=(2,))))
        >>> m.require_calibration()  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        ipcverify.errors.InvalidInputError: the model is not calibrated: ...
        """
        if self.calibration is None:
            raise InvalidInputError(
                "the model is not calibrated: its raw sets carry no guarantee -- calibrate it on held-out "
                "data first (ipcverify calibrate, or ipcverify.calibrate.calibrate)"
            )
        return self.calibration

    def with_calibration(
        self, calibration: Calibration | None, domain: DomainModel | None = None
    ) -> IPCModel:
        """A copy of this model carrying ``calibration`` and ``domain`` (the network is shared)."""
        return IPCModel(self.network, calibration, self.metadata, domain)


def _out_of_domain_message(error: str, domain: DomainModel | None, x: FloatArray, yhat: FloatArray) -> str:
    """Blame the input, not the model, when the network's set degenerates far from its data."""
    where = error.split(":", 1)[0].replace("ellipsoid", "input row")
    row = int(where.rsplit(" ", 1)[-1]) if where.rsplit(" ", 1)[-1].isdigit() else None
    far = ""
    if domain is not None and row is not None:
        d = float(domain.distance(x[row : row + 1], yhat[row : row + 1])[0])
        if d > domain.threshold:
            far = (
                f" (its distance to the calibration inputs is {d:.3g}, above the domain threshold "
                f"{domain.threshold:.3g})"
            )
    return (
        f"{where}: the contract's set is degenerate (singular or non-finite shape matrix) for this input, "
        f"which lies outside the domain the contract was trained and calibrated on{far}; the contract "
        "certifies nothing there -- drop such inputs, or retrain and recalibrate on data that covers them"
    )


def network_fingerprint(network: Network) -> str:
    """SHA-256 of a network's configuration and state dict (ties a calibration to its network).

    Every member of an ensemble is in the state dict, so every member is hashed.

    Examples
    --------
    >>> from ipcverify.architecture import ModelConfig
    >>> len(network_fingerprint(build_network(ModelConfig(x_dim=1, y_dim=1, hidden=(2,)))))
    64
    """
    h = hashlib.sha256(repr(sorted(network.config.to_dict().items())).encode())
    for name, t in sorted(network.state_dict().items()):
        h.update(name.encode())
        arr = t.detach().cpu().contiguous().numpy()
        h.update(str(arr.dtype).encode() + str(arr.shape).encode())
        h.update(arr.tobytes())
    return h.hexdigest()
