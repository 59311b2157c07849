"""The low-rank covariance head and its ensemble: the network of the default recipe ``"tight"``.

For standardised inputs ``z = (concat(x, yhat) - in_mean) / in_std`` every member ``k``
of the ensemble predicts, in *standardised output units* ``t = (y - yhat - lin(z)) / sigma``:

* a centre offset ``o_k = MLP_k(z)[:n] + S_k z + s_k`` (``S_k, s_k`` a trainable affine map,
  zero at the start);
* a covariance ``Sigma_k = diag(exp(2 h_k)) + V_k V_k^T`` with ``h_k = clip(MLP_k(z)[n:2n])``
  and the ``n x n`` factor ``V_k = MLP_k(z)[2n:] + F_k z + f_k``. The affine path into ``V``
  is there because lag-type errors are rank one with a factor linear in the state
  (delay times velocity).

``lin(z) = A z + b`` is the **linear centre stage**: the ridge least-squares fit of
``y - yhat`` on ``[z, 1]``, solved in float64 before training and kept fixed (the trainable
``S_k`` refines it). ``sigma`` is the per-column spread of what it leaves, floored at
``1e-6`` of the raw residual's spread so that an exactly known coordinate keeps a finite
shape. The members are combined by **moment matching**: ``o = mean_k o_k`` and
``Sigma = mean_k (Sigma_k + (o_k - o)(o_k - o)^T)``, so the sets widen where the members
disagree. With ``M = chol(Sigma)`` the contract's sets are ``E(c, C)`` with::

    c = yhat + lin(z) + sigma * o,      C = M^-1 diag(1 / sigma),

so ``||C (y - c)||^2 = (t - o)^T Sigma^-1 (t - o)``. The float64 engine of record is
:mod:`ipcverify.network._lowrank_engine`; this module is the torch form used for training.
Why each part is there: ``docs/benchmarks.md`` ("The default recipe").
"""

from __future__ import annotations

import math

import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import LOGDIAG_CLAMP, ModelConfig
from ipcverify.network._scoring import ScoredNetwork

FloatArray = NDArray[np.float64]
#: Floor of ``sigma`` relative to the spread of the raw residual ``y - yhat``.
SIGMA_FLOOR = 1e-6
_ACTIVATIONS: dict[str, type[nn.Module]] = {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU}
#: Initial scale of the output layer and of the factor's affine path (small: start near Sigma = I).
_OUT_INIT = 0.01


class StackedLinear(nn.Module):
    """``K`` independent affine maps evaluated together: (B, i) or (K, B, i) -> (K, B, o).

    Parameters
    ----------
    members : int
        ``K``, the number of maps.
    d_in, d_out : int
        Input and output widths; weight ``(K, d_in, d_out)`` and bias ``(K, 1, d_out)`` start
        at zero (:meth:`reset` initialises them).

    Examples
    --------
    >>> layer = StackedLinear(members=3, d_in=4, d_out=2)
    >>> tuple(layer(torch.zeros(5, 4)).shape), tuple(layer(torch.zeros(3, 5, 4)).shape)
    ((3, 5, 2), (3, 5, 2))
    """

    def __init__(self, members: int, d_in: int, d_out: int) -> None:
        super().__init__()
        self.weight = nn.Parameter(torch.zeros(members, d_in, d_out))
        self.bias = nn.Parameter(torch.zeros(members, 1, d_out))

    def reset(self, generators: list[torch.Generator], scale: float, bias: bool) -> None:
        """``nn.Linear``'s initialisation per member (uniform, bound ``1/sqrt(d_in)``), times ``scale``."""
        d_in = self.weight.shape[1]
        bound = 1.0 / math.sqrt(d_in) if d_in else 0.0
        with torch.no_grad():
            for k, gen in enumerate(generators):
                self.weight[k].uniform_(-bound, bound, generator=gen).mul_(scale)
                if bias:
                    self.bias[k].uniform_(-bound, bound, generator=gen).mul_(scale)
                else:
                    self.bias[k].zero_()

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        """Apply every member's map (a 2-D input is shared by all members)."""
        if h.dim() == 2:
            return torch.matmul(h, self.weight) + self.bias
        return torch.baddbmm(self.bias, h, self.weight)


class StackedMLP(nn.Module):
    """``K`` MLPs of the same shape evaluated together (one batched matmul per layer).

    Parameters
    ----------
    members : int
        ``K``, the number of MLPs.
    d_in : int
        Input width.
    hidden : tuple of int
        Widths of the hidden layers (empty: one affine map).
    d_out : int
        Output width.
    activation : str
        The hidden non-linearity: ``"relu"``, ``"tanh"`` or ``"elu"``.
    """

    def __init__(self, members: int, d_in: int, hidden: tuple[int, ...], d_out: int, activation: str) -> None:
        super().__init__()
        widths = [d_in, *hidden, d_out]
        self.layers = nn.ModuleList(
            StackedLinear(members, a, b) for a, b in zip(widths[:-1], widths[1:], strict=True)
        )
        self.act = _ACTIVATIONS[activation]()

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        """Raw outputs (K, B, d_out) of every member for inputs (B, d_in) or (K, B, d_in)."""
        last = len(self.layers) - 1
        for i, layer in enumerate(self.layers):
            z = layer(z)
            if i < last:
                z = self.act(z)
        return z


def member_covariances(log_diag: torch.Tensor, factor: torch.Tensor) -> torch.Tensor:
    """``diag(exp(2 h)) + V V^T`` for ``h`` (..., n) and ``V`` (..., n, n).

    Parameters
    ----------
    log_diag : torch.Tensor, shape (..., n)
        ``h``, the log standard deviations of the diagonal part (clamped by the caller).
    factor : torch.Tensor, shape (..., n, n)
        ``V``, the low-rank factor.
    """
    return torch.diag_embed(torch.exp(2.0 * log_diag)) + factor @ factor.transpose(-1, -2)


def moment_match(offsets: torch.Tensor, covariances: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Combine members (first axis): mean offset, mean covariance plus the spread of the offsets.

    Parameters
    ----------
    offsets : torch.Tensor, shape (K, ..., n)
        Each member's centre offset.
    covariances : torch.Tensor, shape (K, ..., n, n)
        Each member's covariance. One member gives its own offset and covariance back.

    Examples
    --------
    >>> o = torch.tensor([[[1.0]], [[-1.0]]]); S = torch.ones(2, 1, 1, 1)
    >>> [t.flatten().tolist() for t in moment_match(o, S)]
    [[0.0], [2.0]]
    """
    mean = offsets.mean(dim=0)
    dev = offsets - mean
    return mean, covariances.mean(dim=0) + (dev.unsqueeze(-1) * dev.unsqueeze(-2)).mean(dim=0)


def fit_linear_stage(
    z: FloatArray, r: FloatArray, ridge: float, linear: bool
) -> tuple[FloatArray, FloatArray]:
    """Ridge least squares of the residual ``r`` (N, n) on ``[z, 1]``: weight (d, n) and bias (n,).

    The penalty is ``ridge * N`` on the weights (not the bias). With ``linear=False`` only
    the mean residual is fitted.

    Parameters
    ----------
    z : ndarray, shape (N, d)
        Standardised inputs.
    r : ndarray, shape (N, n)
        Residuals to fit.
    ridge : float
        Penalty per row (0: plain least squares; a singular system falls back to ``lstsq``).
    linear : bool
        Fit the weight; False returns a zero weight and the mean residual.

    Examples
    --------
    >>> z = np.linspace(-1, 1, 20)[:, None]
    >>> w, b = fit_linear_stage(z, 3 * z + 1, ridge=0.0, linear=True)
    >>> np.round(w, 9).tolist(), np.round(b, 9).tolist()
    ([[3.0]], [1.0])
    """
    n_rows, d = z.shape
    if not linear:
        return np.zeros((d, r.shape[1])), r.mean(axis=0)
    feats = np.hstack([z, np.ones((n_rows, 1))])
    pen = np.full(d + 1, ridge * n_rows)
    pen[-1] = 0.0
    try:
        sol = np.linalg.solve(feats.T @ feats + np.diag(pen), feats.T @ r)
    except np.linalg.LinAlgError:
        sol = np.linalg.lstsq(feats, r, rcond=None)[0]
    return sol[:d], sol[d]


class LowRankEnsemble(ScoredNetwork):
    """The default network: ``members`` low-rank-head MLPs sharing one normalisation (see the module).

    The normalisation and the linear centre stage are float64 buffers; the members'
    weights are float32 parameters stacked along a first axis of size ``members``.

    Parameters
    ----------
    config : ModelConfig
        With ``param="lowrank"``.

    Examples
    --------
    >>> net = LowRankEnsemble(ModelConfig(x_dim=2, y_dim=3, hidden=(8,), members=4))
    >>> c, C, logdet = net(torch.zeros(5, 2), torch.zeros(5, 3))
    >>> tuple(c.shape), tuple(C.shape), tuple(logdet.shape)
    ((5, 3), (5, 3, 3), (5,))
    """

    in_mean: torch.Tensor
    in_std: torch.Tensor
    sigma: torch.Tensor
    lin_weight: torch.Tensor
    lin_bias: torch.Tensor

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        if not config.lowrank:
            raise InvalidInputError(
                f"LowRankEnsemble builds the low-rank head; this config has param={config.param!r}: "
                "use ipcverify.network.build_network(config)"
            )
        self.config = config
        k, n = config.members, config.y_dim
        d_in = config.x_dim + n
        self.body = StackedMLP(k, d_in, config.hidden, config.n_outputs, config.activation)
        self.center_skip = StackedLinear(k, d_in, n) if config.linear_center else None
        self.factor_skip = StackedLinear(k, d_in, n * n)
        f64 = torch.float64
        self.register_buffer("in_mean", torch.zeros(d_in, dtype=f64))
        self.register_buffer("in_std", torch.ones(d_in, dtype=f64))
        self.register_buffer("sigma", torch.ones(n, dtype=f64))
        self.register_buffer("lin_weight", torch.zeros(d_in, n, dtype=f64))
        self.register_buffer("lin_bias", torch.zeros(n, dtype=f64))
        self.initialise(0)

    @property
    def members(self) -> int:
        """Number of networks in the ensemble."""
        return self.config.members

    def initialise(self, seed: int) -> None:
        """Initialise every member's weights from its own generator (seed ``1000 * seed + k``).

        Hidden layers as ``nn.Linear``; the output layer and the factor's affine path at
        1 % of that (the sets start near ``Sigma = I``); the centre's affine path at zero.
        """
        gens = [torch.Generator().manual_seed(1000 * seed + k) for k in range(self.members)]
        layers = list(self.body.layers)
        for layer in layers[:-1]:
            layer.reset(gens, 1.0, bias=True)  # type: ignore[operator]
        layers[-1].reset(gens, _OUT_INIT, bias=False)  # type: ignore[operator]
        self.factor_skip.reset(gens, _OUT_INIT, bias=False)
        if self.center_skip is not None:
            self.center_skip.reset(gens, 0.0, bias=False)

    def fit_normalisation(
        self, x: FloatArray, y: FloatArray, yhat: FloatArray, ridge: float
    ) -> tuple[FloatArray, FloatArray]:
        """Set the input standardisation, the linear centre stage and ``sigma`` from training data.

        Returns the standardised inputs ``z`` (N, d + n) and targets ``t`` (N, n), float64.
        """
        inp = np.concatenate([x, yhat], axis=1)
        mean = inp.mean(axis=0)
        std = inp.std(axis=0)
        std = np.where(std > 1e-12 * np.maximum(1.0, np.abs(mean)), std, 1.0)
        z = (inp - mean) / std
        r = y - yhat
        weight, bias = fit_linear_stage(z, r, ridge, bool(self.config.linear_center))
        r1 = r - z @ weight - bias
        scale = np.maximum(np.abs(y).max(axis=0), 1.0)
        floor = SIGMA_FLOOR * np.maximum(r.std(axis=0), 1e-6 * scale)
        sigma = np.maximum(r1.std(axis=0), floor)
        with torch.no_grad():
            for buf, value in (
                (self.in_mean, mean),
                (self.in_std, std),
                (self.sigma, sigma),
                (self.lin_weight, weight),
                (self.lin_bias, bias),
            ):
                buf.copy_(torch.as_tensor(value, dtype=torch.float64))
        return z, r1 / sigma

    def heads(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Per member: centre offsets (K, B, n), log-diagonals (K, B, n), factors (K, B, n, n).

        ``z`` is standardised, (B, d + n) (shared by the members) or (K, B, d + n).
        """
        n = self.config.y_dim
        out = self.body(z)
        offset = out[..., :n]
        if self.center_skip is not None:
            offset = offset + self.center_skip(z)
        log_diag = torch.clamp(out[..., n : 2 * n], -LOGDIAG_CLAMP, LOGDIAG_CLAMP)
        factor = out[..., 2 * n :] + self.factor_skip(z)
        return offset, log_diag, factor.reshape(*factor.shape[:-1], n, n)

    def forward(self, x: torch.Tensor, yhat: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Combined centres (B, n), shape matrices C (B, n, n) and ``log det(C^T C)`` (B,).

        Computed in float64 after the float32 members (returned in the dtype of ``x``).
        """
        n = self.config.y_dim
        z64 = (torch.cat([x, yhat], dim=1).to(torch.float64) - self.in_mean) / self.in_std
        lin = z64 @ self.lin_weight + self.lin_bias
        dtype = self.factor_skip.weight.dtype
        offset, log_diag, factor = (t.to(torch.float64) for t in self.heads(z64.to(dtype)))
        mean, cov = moment_match(offset, member_covariances(log_diag, factor))
        chol = torch.linalg.cholesky(cov)
        eye = torch.eye(n, dtype=torch.float64).expand_as(chol)
        inv = torch.linalg.solve_triangular(chol, eye, upper=False)
        center = yhat.to(torch.float64) + lin + self.sigma * mean
        shape = inv / self.sigma
        logdet = (
            -2.0 * torch.log(torch.diagonal(chol, dim1=-2, dim2=-1)).sum(-1)
            - 2.0 * torch.log(self.sigma).sum()
        )
        return center.to(x.dtype), shape.to(x.dtype), logdet.to(x.dtype)
