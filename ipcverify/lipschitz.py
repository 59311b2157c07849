"""The Lipschitz constant ``L_g`` of ``g_theta(X) = ||C_theta(x, yhat)(y - c_theta(x, yhat))||`` in ``theta``.

Theorem 1 of the paper needs ``L_g``. Two numbers are computed, and labelled:

* :func:`empirical_lipschitz` -- the largest per-sample gradient norm
  ``||grad_theta g(X_i)||`` over a dataset at the trained ``theta``. It is a
  **lower estimate** of the Lipschitz constant (a maximum over finitely many
  points at one ``theta``), so a Theorem 1 bound computed with it is optimistic,
  not a guarantee.
* :func:`sound_lipschitz` -- an **upper bound** on the Lipschitz constant of
  ``theta -> g_theta(X)`` over the Euclidean parameter ball ``B(theta_hat, r)``
  (``r`` fixed in advance: :data:`DEFAULT_RADIUS`), for every ``X`` in a box
  (by default the bounding box of the data). It propagates norm bounds layer by
  layer and multiplies the result by ``1 + FLOAT_MARGIN`` to cover rounding in
  the float64 arithmetic. The derivation is ``proofs/lipschitz.md``.

Only the network's trainable parameters (the MLP ``body``) count as ``theta``;
the normalisation buffers are fixed statistics of the training data.

Both are derived for one MLP with the paper's heads (``"cholesky"``, ``"full"``). For the
default recipe's network -- the low-rank head (a Cholesky factor of a sum), the linear
centre stage and the ensemble's moment matching -- no bound is derived yet:
:func:`theorem1_unavailable` says so, and these functions refuse such models.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn
from torch.func import functional_call, grad, vmap

from ipcverify.architecture import LOGDIAG_CLAMP
from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.model import IPCModel, IPCNetwork

__all__ = [
    "DEFAULT_RADIUS",
    "FLOAT_MARGIN",
    "DataBox",
    "LipschitzEstimate",
    "LipschitzBound",
    "per_sample_gradient_norms",
    "empirical_lipschitz",
    "sound_lipschitz",
    "theorem1_unavailable",
    "Theorem1UnavailableError",
]

FloatArray = NDArray[np.float64]

#: Radius of the parameter ball of the sound bound. Fixed here, never tuned on data.
DEFAULT_RADIUS = 0.1
#: Relative safety margin on the sound bound (float64 rounding in norms and SVDs).
FLOAT_MARGIN = 1e-6
_SVD_MARGIN = 1e-9


class Theorem1UnavailableError(InvalidInputError):
    """Theorem 1 (its Lipschitz constant) is not derived for the model's architecture."""


def theorem1_unavailable(model: IPCModel) -> str | None:
    """Why the Lipschitz constants (hence Theorem 1) cannot be computed for ``model``; None if they can.

    Examples
    --------
    >>> from ipcverify.model import build_network
    >>> from ipcverify.architecture import ModelConfig
    >>> theorem1_unavailable(IPCModel(build_network(ModelConfig.recipe("v1", x_dim=2, y_dim=3)))) is None
    True
    >>> default = IPCModel(build_network(ModelConfig(x_dim=2, y_dim=3)))
    >>> print(theorem1_unavailable(default))  # doctest: +ELLIPSIS
    not available for this architecture: ...
    """
    if isinstance(model.network, IPCNetwork):
        return None
    cfg = model.config
    parts = ["the low-rank covariance head"]
    if cfg.linear_center:
        parts.append("a linear centre stage")
    if cfg.members > 1:
        parts.append(f"an ensemble of {cfg.members} networks")
    return (
        "not available for this architecture: the sound Lipschitz bound of Theorem 1 (proofs/lipschitz.md) "
        "is derived for one network with the paper's 'cholesky' or 'full' head, and this model has "
        f"{', '.join(parts)}, for which no bound is derived. The PAC calibration certificate does not depend "
        "on it; train with --recipe v1 to get Theorem 1"
    )


def _require_supported(model: IPCModel) -> IPCNetwork:
    reason = theorem1_unavailable(model)
    if reason is not None or not isinstance(model.network, IPCNetwork):
        raise Theorem1UnavailableError(reason or "unsupported network")
    return model.network


@dataclass(frozen=True)
class DataBox:
    """An axis-aligned box for ``X = (x, y, yhat)``: per-coordinate lower and upper bounds.

    Examples
    --------
    >>> from ipcverify.synthetic import make_lagged_perception
    >>> box = DataBox.from_dataset(make_lagged_perception(50, seed=0))
    >>> box.x_lo.shape, box.y_hi.shape
    ((6,), (3,))
    """

    x_lo: FloatArray
    x_hi: FloatArray
    y_lo: FloatArray
    y_hi: FloatArray
    yhat_lo: FloatArray
    yhat_hi: FloatArray

    def __post_init__(self) -> None:
        for name in ("x", "y", "yhat"):
            lo = np.array(getattr(self, f"{name}_lo"), dtype=np.float64).ravel()
            hi = np.array(getattr(self, f"{name}_hi"), dtype=np.float64).ravel()
            if lo.shape != hi.shape or not (np.isfinite(lo).all() and np.isfinite(hi).all()):
                raise InvalidInputError(f"box bounds of {name} must be finite arrays of equal shape")
            if (lo > hi).any():
                raise InvalidInputError(f"box of {name}: a lower bound exceeds its upper bound")
            lo.setflags(write=False)
            hi.setflags(write=False)
            object.__setattr__(self, f"{name}_lo", lo)
            object.__setattr__(self, f"{name}_hi", hi)
        if self.y_lo.shape != self.yhat_lo.shape:
            raise InvalidInputError("y and yhat boxes must have the same dimension")

    @classmethod
    def from_dataset(cls, data: PerceptionDataset) -> DataBox:
        """The bounding box of a dataset's ``x``, ``y`` and ``yhat``."""
        return cls(
            data.x.min(0), data.x.max(0), data.y.min(0), data.y.max(0), data.yhat.min(0), data.yhat.max(0)
        )

    def to_dict(self) -> dict[str, list[float]]:
        """Plain-data form."""
        return {k: getattr(self, k).tolist() for k in ("x_lo", "x_hi", "y_lo", "y_hi", "yhat_lo", "yhat_hi")}


@dataclass(frozen=True)
class LipschitzEstimate:
    """A **lower estimate** of ``L_g``: the largest per-sample gradient norm at ``theta_hat``."""

    value: float
    n_samples: int
    argmax: int
    kind: str = "empirical (lower estimate: max gradient norm over the data at the trained parameters)"

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""
        return {"value": self.value, "n_samples": self.n_samples, "argmax": self.argmax, "kind": self.kind}


@dataclass(frozen=True)
class LipschitzBound:
    """An **upper bound** on ``L_g`` over ``B(theta_hat, radius)`` and a box of ``X``.

    Attributes
    ----------
    value : float
        The bound (already multiplied by ``1 + FLOAT_MARGIN``).
    radius : float
        Radius of the parameter ball.
    jacobian_bound : float
        Bound on the operator norm of ``d(network output) / d theta``.
    output_gradient_bound : float
        Bound on the operator norm of ``d(C (y - c)) / d(network output)``.
    hidden_norm_bounds : tuple of float
        Bounds on the Euclidean norm of each layer's input (normalised input first).
    """

    value: float
    radius: float
    jacobian_bound: float
    output_gradient_bound: float
    hidden_norm_bounds: tuple[float, ...]
    box: DataBox = field(repr=False)
    kind: str = "sound (upper bound over the parameter ball and the data box)"

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""
        return {
            "value": self.value,
            "radius": self.radius,
            "jacobian_bound": self.jacobian_bound,
            "output_gradient_bound": self.output_gradient_bound,
            "hidden_norm_bounds": list(self.hidden_norm_bounds),
            "kind": self.kind,
        }


def _score_function(net: IPCNetwork) -> Any:
    buffers = dict(net.named_buffers())

    def g_single(
        params: dict[str, torch.Tensor], x: torch.Tensor, y: torch.Tensor, yhat: torch.Tensor
    ) -> torch.Tensor:
        center, C, _ = functional_call(net, (params, buffers), (x[None], yhat[None]))
        v = C[0] @ (y - center[0])
        return torch.sqrt((v * v).sum())

    return g_single


def per_sample_gradient_norms(
    network: IPCNetwork,
    x: FloatArray,
    y: FloatArray,
    yhat: FloatArray,
    params: dict[str, torch.Tensor] | None = None,
    chunk_size: int = 4096,
    dtype: torch.dtype = torch.float64,
) -> FloatArray:
    """``||grad_theta g(X_i)||`` for every sample, in float64 (``torch.func``: vmap of grad).

    Parameters
    ----------
    network : IPCNetwork
        The network (not modified; a float64 copy is used).
    x, y, yhat : arrays (B, d), (B, n), (B, n)
        The samples.
    params : dict, optional
        Parameters to evaluate at (names as in ``network.named_parameters()``);
        default: the network's own.
    chunk_size : int
        Samples per vectorised batch (memory ~ chunk_size * p * 8 bytes).
    dtype : torch.dtype
        Arithmetic of the computation (float64 by default; float32 is about twice as fast).

    Examples
    --------
    >>> from ipcverify.architecture import ModelConfig
    >>> net = IPCNetwork(ModelConfig(x_dim=2, y_dim=2, hidden=(4,), param="cholesky"))
    >>> per_sample_gradient_norms(net, np.ones((3, 2)), np.ones((3, 2)), np.zeros((3, 2))).shape
    (3,)
    """
    net = copy.deepcopy(network).to(dtype).eval()
    if params is None:
        params = {k: v.detach() for k, v in net.named_parameters()}
    else:
        params = {k: torch.as_tensor(v, dtype=dtype) for k, v in params.items()}
    gfun = vmap(grad(_score_function(net)), in_dims=(None, 0, 0, 0))
    out = []
    xt, yt, yht = (torch.tensor(np.asarray(a), dtype=dtype) for a in (x, y, yhat))
    with torch.no_grad():
        for i in range(0, len(xt), chunk_size):
            sl = slice(i, i + chunk_size)
            grads = gfun(params, xt[sl], yt[sl], yht[sl])
            norms = torch.stack([torch.linalg.vector_norm(g.flatten(1), dim=1) for g in grads.values()], 1)
            out.append(torch.linalg.vector_norm(norms.double(), dim=1).numpy())
    return np.concatenate(out) if out else np.zeros(0)


def empirical_lipschitz(
    model: IPCModel, data: PerceptionDataset, chunk_size: int = 4096, dtype: torch.dtype = torch.float32
) -> LipschitzEstimate:
    """Largest ``||grad_theta g||`` over ``data`` at the trained parameters (a lower estimate of ``L_g``).

    Computed in float32 by default (the network's own precision; relative error ~1e-6,
    immaterial for an estimate); pass ``dtype=torch.float64`` for more digits.

    Examples
    --------
    >>> from ipcverify.synthetic import make_lagged_perception
    >>> from ipcverify.model import IPCNetwork
    >>> from ipcverify.architecture import ModelConfig
    >>> m = IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")))
    >>> est = empirical_lipschitz(m, make_lagged_perception(100, seed=0))
    >>> est.value > 0, est.n_samples
    (True, 100)
    """
    norms = per_sample_gradient_norms(
        _require_supported(model), data.x, data.y, data.yhat, chunk_size=chunk_size, dtype=dtype
    )
    if not np.isfinite(norms).all():
        raise InvalidInputError("a per-sample gradient is not finite; the network output overflowed")
    i = int(np.argmax(norms))
    return LipschitzEstimate(value=float(norms[i]), n_samples=len(norms), argmax=i)


def _opnorm(w: FloatArray) -> float:
    if w.size == 0:
        return 0.0
    return float(np.linalg.norm(w, 2)) * (1.0 + _SVD_MARGIN) + 1e-300


def _linear_layers(net: IPCNetwork) -> list[tuple[FloatArray, FloatArray]]:
    layers = []
    for mod in net.body:
        if isinstance(mod, nn.Linear):
            layers.append((mod.weight.detach().double().numpy(), mod.bias.detach().double().numpy()))
        elif not isinstance(mod, (nn.ReLU, nn.Tanh, nn.ELU)):
            raise InvalidInputError(f"sound Lipschitz bound: unsupported layer {type(mod).__name__}")
        elif isinstance(mod, nn.ELU) and mod.alpha != 1.0:
            raise InvalidInputError("sound Lipschitz bound: ELU needs alpha = 1 (1-Lipschitz)")
    return layers


def sound_lipschitz(
    model: IPCModel, box: DataBox | PerceptionDataset, radius: float = DEFAULT_RADIUS
) -> LipschitzBound:
    """Upper bound on the Lipschitz constant of ``theta -> g_theta(X)`` over a ball and a box.

    Valid for every ``theta`` with ``||theta - theta_hat||_2 <= radius`` (all trainable
    parameters stacked) and every ``X = (x, y, yhat)`` in ``box``. See
    ``proofs/lipschitz.md`` for the derivation.

    Parameters
    ----------
    model : IPCModel
        The trained model (its calibration is irrelevant: ``g`` is the raw score).
    box : DataBox or PerceptionDataset
        The box of ``X`` (a dataset is replaced by its bounding box).
    radius : float
        Radius ``r >= 0`` of the parameter ball; fix it before looking at the data.

    Examples
    --------
    >>> from ipcverify.synthetic import make_lagged_perception
    >>> from ipcverify.model import IPCNetwork
    >>> from ipcverify.architecture import ModelConfig
    >>> m = IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")))
    >>> ds = make_lagged_perception(100, seed=0)
    >>> sound_lipschitz(m, ds).value >= empirical_lipschitz(m, ds).value
    True
    """
    if not (math.isfinite(radius) and radius >= 0):
        raise InvalidInputError(f"radius must be finite and >= 0; got {radius!r}")
    if isinstance(box, PerceptionDataset):
        box = DataBox.from_dataset(box)
    net = _require_supported(model)
    cfg = net.config
    if box.x_lo.shape != (cfg.x_dim,) or box.y_lo.shape != (cfg.y_dim,):
        raise InvalidInputError(
            f"box has x_dim={box.x_lo.size}, y_dim={box.y_lo.size}; the model expects "
            f"x_dim={cfg.x_dim}, y_dim={cfg.y_dim}"
        )
    n = cfg.y_dim
    in_mean = net.in_mean.double().numpy()
    in_std = net.in_std.double().numpy()
    sigma = net.sigma.double().numpy()
    y_mean = net.y_mean.double().numpy()
    up = 1.0 + 1e-12  # per-operation rounding guard in the interval arithmetic below

    # 1. normalised input z = (u - mean) / std, u = (x, yhat) in the box
    u_lo = np.concatenate([box.x_lo, box.yhat_lo])
    u_hi = np.concatenate([box.x_hi, box.yhat_hi])
    z_abs = np.maximum(np.abs(u_lo - in_mean), np.abs(u_hi - in_mean)) / in_std * up
    H = [float(np.linalg.norm(z_abs)) * up]

    # 2. hidden layers: ||h_l|| <= ||W|| ||h|| + ||b|| + r sqrt(||h||^2 + 1)   (|phi(t)| <= |t|)
    layers = _linear_layers(net)
    ops = [_opnorm(W) for W, _ in layers]
    for (_, b), op in zip(layers[:-1], ops[:-1], strict=True):
        h = H[-1]
        H.append((op * h + float(np.linalg.norm(b)) + radius * math.sqrt(h * h + 1.0)) * up)

    # 3. output bounds: centre part o (rows :n) as a whole, each shape output separately
    W_L, b_L = layers[-1]
    h = H[-1]
    pert = radius * math.sqrt(h * h + 1.0)
    o_bound = (_opnorm(W_L[:n]) * h + float(np.linalg.norm(b_L[:n])) + pert) * up
    s_bound = (np.linalg.norm(W_L[n:], axis=1) * (1.0 + _SVD_MARGIN) * h + np.abs(b_L[n:]) + pert) * up

    # 4. d = r - o with r = (y - base) / sigma over the box
    if cfg.center == "offset":
        r_lo, r_hi = box.y_lo - box.yhat_hi, box.y_hi - box.yhat_lo
    else:
        r_lo, r_hi = box.y_lo - y_mean, box.y_hi - y_mean
    r_abs = np.maximum(np.abs(r_lo), np.abs(r_hi)) / sigma * up
    d_bound = (float(np.linalg.norm(r_abs)) + o_bound) * up

    # 5. ||d v / d out||_F with v = L(s) d
    if cfg.param == "full":
        L_fro_sq = float(np.sum(s_bound**2))
        ds_fro_sq = n * d_bound**2
    else:
        rows, cols = np.tril_indices(n)
        diag = rows == cols
        D = np.exp(np.minimum(s_bound[diag], LOGDIAG_CLAMP)) * up
        L_fro_sq = float(np.sum(D**2) + np.sum(s_bound[~diag] ** 2))
        ds_fro_sq = ((n - 1) + float(np.max(D)) ** 2) * d_bound**2
    out_grad = math.sqrt(L_fro_sq + ds_fro_sq) * up

    # 6. Jacobian of the output w.r.t. all parameters: sum_l P_l^2 (||h_{l-1}||^2 + 1)
    n_layers = len(layers)
    P = [1.0] * n_layers
    for i in range(n_layers - 2, -1, -1):
        P[i] = P[i + 1] * (ops[i + 1] + radius) * up
    jac = math.sqrt(sum(P[i] ** 2 * (H[i] ** 2 + 1.0) for i in range(n_layers))) * up

    value = out_grad * jac * (1.0 + FLOAT_MARGIN)
    if not math.isfinite(value):
        raise InvalidInputError("the sound Lipschitz bound overflowed; the box or the weights are too large")
    return LipschitzBound(
        value=value,
        radius=float(radius),
        jacobian_bound=jac,
        output_gradient_bound=out_grad,
        hidden_norm_bounds=tuple(H),
        box=box,
    )
