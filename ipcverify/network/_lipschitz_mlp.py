"""``L_g`` for the paper's heads (:class:`~ipcverify.network.IPCNetwork`): gradient norms and a sound bound.

The score is ``g_theta(X) = ||C_theta(x, yhat)(y - c_theta(x, yhat))||``; ``theta`` is every
trainable parameter of the MLP, the normalisation buffers are fixed statistics of the training
data.

* :func:`mlp_gradient_norms` -- ``||grad_theta g(X_i)||`` for every sample, by ``torch.func``
  (vmap of grad).
* :func:`sound_lipschitz_mlp` -- an upper bound on the Lipschitz constant of
  ``theta -> g_theta(X)`` over ``B(theta_hat, r)`` and a box of ``X``: norm bounds propagated
  layer by layer (:mod:`ipcverify.network._lipschitz_ball`), times ``1 + FLOAT_MARGIN``.
  Derivation: ``proofs/lipschitz.md``.

The dense engine (:class:`~ipcverify.network.InferenceEngine`) answers with these; use
:func:`ipcverify.certification.sound_lipschitz` and
:func:`~ipcverify.certification.empirical_lipschitz`, which take any model.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn
from torch.func import functional_call, grad, vmap

from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import LOGDIAG_CLAMP
from ipcverify.network._lipschitz_ball import (
    SVD_MARGIN,
    DataBox,
    LipschitzBound,
    hidden_norm_bounds,
    jacobian_bound,
    operator_norm,
    require_kind,
)
from ipcverify.network._modules import IPCNetwork

FloatArray = NDArray[np.float64]


def _score_function(net: IPCNetwork) -> Any:
    buffers = dict(net.named_buffers())

    def g_single(
        params: dict[str, torch.Tensor], x: torch.Tensor, y: torch.Tensor, yhat: torch.Tensor
    ) -> torch.Tensor:
        center, C, _ = functional_call(net, (params, buffers), (x[None], yhat[None]))
        v = C[0] @ (y - center[0])
        return torch.sqrt((v * v).sum())

    return g_single


def mlp_gradient_norms(
    network: IPCNetwork,
    x: FloatArray,
    y: FloatArray,
    yhat: FloatArray,
    params: Mapping[str, torch.Tensor] | None = None,
    chunk_size: int = 4096,
    dtype: torch.dtype = torch.float64,
) -> FloatArray:
    """``||grad_theta g(X_i)||`` for every sample (float64 result), by ``torch.func``'s vmap of grad.

    ``network`` is not modified (a copy in ``dtype`` is used); ``params`` (names as in
    ``network.named_parameters()``) default to the network's own; ``chunk_size`` samples are
    vectorised together (memory ~ chunk_size * p * 8 bytes).

    Examples
    --------
    >>> from ipcverify import example
    >>> from ipcverify.network import ModelConfig
    >>> net = example(config=ModelConfig(x_dim=2, y_dim=2, hidden=(4,), param="cholesky")).model.network
    >>> mlp_gradient_norms(net, np.ones((3, 2)), np.ones((3, 2)), np.zeros((3, 2))).shape
    (3,)
    """
    require_kind(network, IPCNetwork)
    net = copy.deepcopy(network).to(dtype).eval()
    if params is None:
        own = {k: v.detach() for k, v in net.named_parameters()}
    else:
        own = {k: torch.as_tensor(v, dtype=dtype) for k, v in params.items()}
    gfun = vmap(grad(_score_function(net)), in_dims=(None, 0, 0, 0))
    out = []
    xt, yt, yht = (torch.tensor(np.asarray(a), dtype=dtype) for a in (x, y, yhat))
    with torch.no_grad():
        for i in range(0, len(xt), chunk_size):
            sl = slice(i, i + chunk_size)
            grads = gfun(own, xt[sl], yt[sl], yht[sl])
            norms = torch.stack([torch.linalg.vector_norm(g.flatten(1), dim=1) for g in grads.values()], 1)
            out.append(torch.linalg.vector_norm(norms.double(), dim=1).numpy())
    return np.concatenate(out) if out else np.zeros(0)


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


def sound_lipschitz_mlp(net: IPCNetwork, box: DataBox, radius: float) -> LipschitzBound:
    """Upper bound on the Lipschitz constant of ``theta -> g_theta(X)`` for the paper's heads.

    Valid for every ``theta`` with ``||theta - theta_hat||_2 <= radius`` (all trainable
    parameters stacked) and every ``X = (x, y, yhat)`` in ``box``; ``radius`` is checked by the
    caller. Derivation: ``proofs/lipschitz.md``.

    Examples
    --------
    >>> from ipcverify.network import ModelConfig
    >>> from ipcverify import example
    >>> net = example(config=ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")).model.network
    >>> ds = example(100, seed=0).data
    >>> bound = sound_lipschitz_mlp(net, DataBox.from_dataset(ds), 0.1)
    >>> bool(bound.value >= mlp_gradient_norms(net, ds.x, ds.y, ds.yhat).max())
    True
    """
    require_kind(net, IPCNetwork)
    cfg = net.config
    box.check_dims(cfg.x_dim, cfg.y_dim)
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
    H = hidden_norm_bounds(layers, H[0], radius)

    # 3. output bounds: centre part o (rows :n) as a whole, each shape output separately
    W_L, b_L = layers[-1]
    h = H[-1]
    pert = radius * math.sqrt(h * h + 1.0)
    o_bound = (operator_norm(W_L[:n]) * h + float(np.linalg.norm(b_L[:n])) + pert) * up
    s_bound = (np.linalg.norm(W_L[n:], axis=1) * (1.0 + SVD_MARGIN) * h + np.abs(b_L[n:]) + pert) * up

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
    jac = jacobian_bound(layers, H, radius)

    return LipschitzBound.chain(jac, out_grad, radius, H, box)
