"""``L_g`` for the default network, the low-rank ensemble: per-sample gradients and a sound bound.

For :class:`~ipcverify.network.LowRankEnsemble` the score is, in standardised output units,
``g = sqrt((t - o)^T Sigma^-1 (t - o))`` with ``t = (y - yhat - lin(z)) / sigma`` and the
moment-matched ``o``, ``Sigma`` of the members (:mod:`ipcverify.network._lowrank`); ``theta`` is every
trainable parameter of every member (MLP body, centre skip path, factor skip path). The
normalisation, the linear centre stage and ``sigma`` are fixed statistics of the training
data (buffers), so ``t`` does not depend on ``theta``.

* :func:`ensemble_gradient_norms` -- ``||grad_theta g(X_i)||`` for every sample: one
  forward and one backward pass per chunk of samples, whose per-layer sensitivities give
  each sample's gradient norm exactly (every weight is used once per sample, so the
  gradient of a layer's weight for sample ``i`` is the outer product of its input and its
  output's sensitivity). The same numbers as ``torch.func``'s ``vmap(grad)`` (checked
  against a plain autograd loop in the tests) without materialising ``p`` numbers per
  sample: about 50 times faster at ``p = 29,475``.
* :func:`sound_lipschitz_lowrank` -- an upper bound on the Lipschitz constant of
  ``theta -> g_theta(X)`` over ``B(theta_hat, r)`` and a box of ``X``. It rests on
  ``Sigma >= diag(mean_k exp(2 h_k)) >= mu I`` and on
  ``sum_k (delta_k^T a)^2 + ||V_k^T a||^2 + a^T diag(exp(2 h_k)) a = K g^2``
  (``a = Sigma^-1 (t - o)``), which bound the gradient with respect to the members'
  outputs by ``sqrt(1/(K mu) + g^2 max(1, 1/(K mu)))``. Derivation:
  ``proofs/lipschitz_lowrank.md``.

:class:`~ipcverify.network.LowRankEngine` answers with these (its ``gradient_norms`` and
``sound_lipschitz``, :class:`ipcverify.network.Engine`); use
:func:`ipcverify.certification.sound_lipschitz` and ``empirical_lipschitz``, which take any model.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping

import numpy as np
import torch
from numpy.typing import NDArray

from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import LOGDIAG_CLAMP
from ipcverify.network._lipschitz_ball import (
    ROUND_UP,
    SVD_MARGIN,
    DataBox,
    LipschitzBound,
    check_radius,
    hidden_norm_bounds,
    jacobian_bound,
    operator_norm,
    require_kind,
)
from ipcverify.network._lowrank import LowRankEnsemble, StackedLinear, member_covariances, moment_match

FloatArray = NDArray[np.float64]
#: Relative slack that covers the rounding of a float64 sum of a few hundred terms.
_SUM_SLACK = 1e-12


def ensemble_scores(
    network: LowRankEnsemble, x: torch.Tensor, y: torch.Tensor, yhat: torch.Tensor
) -> torch.Tensor:
    """``g = ||M^-1 (t - o)||`` (B,) in float64, differentiable in the network's parameters.

    The arithmetic of :meth:`LowRankEnsemble.forward` (members in the parameters' dtype,
    everything after them in float64), with ``C (y - c) = M^-1 (t - o)`` written in
    standardised output units. ``x``, ``y``, ``yhat`` are float64 tensors (B, ·).

    Parameters
    ----------
    network : LowRankEnsemble
        The ensemble; gradients flow to its parameters.
    x : torch.Tensor, shape (B, d)
        States.
    y, yhat : torch.Tensor, shape (B, n)
        Truths and estimates.

    Examples
    --------
    >>> from ipcverify.network import ModelConfig
    >>> net = LowRankEnsemble(ModelConfig(x_dim=2, y_dim=3, hidden=(4,)))
    >>> x, y = torch.zeros(2, 2, dtype=torch.float64), torch.ones(2, 3, dtype=torch.float64)
    >>> g = ensemble_scores(net, x, y, torch.zeros(2, 3, dtype=torch.float64))
    >>> bool(torch.allclose(g, net.score(x, y, torch.zeros_like(y))[0]))
    True
    """
    z = (torch.cat([x, yhat], dim=1) - network.in_mean) / network.in_std
    t = (y - yhat - (z @ network.lin_weight + network.lin_bias)) / network.sigma
    dtype = network.factor_skip.weight.dtype
    offset, log_diag, factor = (a.to(torch.float64) for a in network.heads(z.to(dtype)))
    mean, cov = moment_match(offset, member_covariances(log_diag, factor))
    chol = torch.linalg.cholesky(cov)
    v = torch.linalg.solve_triangular(chol, (t - mean).unsqueeze(-1), upper=False).squeeze(-1)
    return torch.linalg.vector_norm(v, dim=-1)


def _working_copy(
    network: LowRankEnsemble, params: Mapping[str, torch.Tensor] | None, dtype: torch.dtype
) -> LowRankEnsemble:
    """A copy in eval mode whose parameters (not buffers) are ``dtype``, set to ``params`` if given."""
    net = copy.deepcopy(network).eval()
    own = dict(net.named_parameters())
    if params is not None:
        unknown = sorted(set(params) - set(own))
        if unknown:
            raise InvalidInputError(f"unknown parameter name(s) for this network: {', '.join(unknown)}")
    with torch.no_grad():
        for name, p in own.items():
            value = p if params is None or name not in params else torch.as_tensor(params[name])
            if value.shape != p.shape:
                raise InvalidInputError(
                    f"parameter {name} needs shape {tuple(p.shape)}; got {tuple(value.shape)}"
                )
            p.data = value.detach().to(dtype).clone()
    return net


def ensemble_gradient_norms(
    network: LowRankEnsemble,
    x: FloatArray,
    y: FloatArray,
    yhat: FloatArray,
    params: Mapping[str, torch.Tensor] | None = None,
    chunk_size: int = 8192,
    dtype: torch.dtype = torch.float32,
) -> FloatArray:
    """``||grad_theta g(X_i)||`` for every sample (float64 result), ``theta`` = all trainable parameters.

    Parameters
    ----------
    network : LowRankEnsemble
        The ensemble (not modified; a copy is used).
    x, y, yhat : arrays (B, d), (B, n), (B, n)
        The samples.
    params : mapping, optional
        Parameters to evaluate at (names as in ``network.named_parameters()``; default: the
        network's own).
    chunk_size : int
        Samples per forward/backward pass.
    dtype : torch.dtype
        Arithmetic of the members' layers (float32, the network's own, by default); the
        moment matching and the score are float64 either way.

    Examples
    --------
    >>> from ipcverify.network import ModelConfig
    >>> net = LowRankEnsemble(ModelConfig(x_dim=2, y_dim=2, hidden=(4,), members=2))
    >>> ensemble_gradient_norms(net, np.ones((3, 2)), np.ones((3, 2)), np.zeros((3, 2))).shape
    (3,)
    """
    require_kind(network, LowRankEnsemble)
    if chunk_size < 1:
        raise InvalidInputError(f"chunk_size must be a positive number of samples; got {chunk_size!r}")
    net = _working_copy(network, params, dtype)
    linears = [m for m in net.modules() if isinstance(m, StackedLinear)]
    seen: dict[StackedLinear, list[tuple[torch.Tensor, torch.Tensor]]] = {m: [] for m in linears}

    def keep(module: torch.nn.Module, inputs: tuple[torch.Tensor, ...], output: torch.Tensor) -> None:
        seen[module].append((inputs[0], output))  # type: ignore[index]

    handles = [m.register_forward_hook(keep) for m in linears]
    xt, yt, yht = (torch.tensor(np.asarray(a), dtype=torch.float64) for a in (x, y, yhat))
    out = []
    try:
        for i in range(0, len(xt), chunk_size):
            sl = slice(i, i + chunk_size)
            for calls in seen.values():
                calls.clear()
            g = ensemble_scores(net, xt[sl], yt[sl], yht[sl])
            if any(len(calls) != 1 for calls in seen.values()):
                raise InvalidInputError("every layer of the ensemble must be used exactly once per sample")
            pairs = [calls[0] for calls in seen.values()]
            sens = torch.autograd.grad(g.sum(), [o for _, o in pairs])
            sq = torch.zeros(len(g), dtype=torch.float64)
            for (inp, _), delta in zip(pairs, sens, strict=True):
                # weight gradient of sample b, member k: outer(input[k, b], delta[k, b]); bias: delta[k, b]
                inp_sq = (inp.detach().double() ** 2).sum(-1)  # (B,) shared input, or (K, B)
                sq += ((inp_sq + 1.0) * (delta.double() ** 2).sum(-1)).sum(0)
            out.append(torch.sqrt(sq).numpy())
    finally:
        for h in handles:
            h.remove()
    return np.concatenate(out) if out else np.zeros(0)


def score_gradient_bound(mu: float, score: float, members: int) -> float:
    """Bound on ``||d g / d(o_k, h_k, V_k)_k||`` where ``Sigma >= mu I`` and ``g <= score``.

    ``sqrt(1 / (K mu) + score^2 max(1, 1 / (K mu)))``, rounded up: the gradient of the score
    with respect to every member's centre offset, clamped log-diagonal and factor
    (``proofs/lipschitz_lowrank.md``, step 3). ``mu`` must bound ``Sigma``'s smallest
    eigenvalue from below, e.g. ``min_i mean_k exp(2 h_{k,i})``.

    Parameters
    ----------
    mu : float
        A lower bound ``> 0`` on ``Sigma``'s smallest eigenvalue (standardised units).
    score : float
        An upper bound ``>= 0`` on the score ``g`` over the box.
    members : int
        ``K >= 1``, the ensemble's size. Values out of range raise :class:`InvalidInputError`.

    Examples
    --------
    >>> round(score_gradient_bound(1.0, 0.0, 1), 9)  # one member, Sigma >= I, g = 0: |d g / d o| <= 1
    1.0
    """
    if not (mu > 0 and members >= 1 and score >= 0):
        raise InvalidInputError(f"need mu > 0, members >= 1, score >= 0; got {mu!r}, {members!r}, {score!r}")
    inv = 1.0 / (members * mu) * ROUND_UP
    return math.sqrt((inv + score * score * ROUND_UP * max(1.0, inv)) * ROUND_UP) * ROUND_UP


def _target_bound(net: LowRankEnsemble, box: DataBox) -> tuple[FloatArray, FloatArray]:
    """``|z_j| <= Z_j`` and ``|t_i| <= T_i`` over the box (interval arithmetic with rounding slack)."""
    mean, std = net.in_mean.double().numpy(), net.in_std.double().numpy()
    A, b = net.lin_weight.double().numpy(), net.lin_bias.double().numpy()
    sigma = net.sigma.double().numpy()
    u_lo = np.concatenate([box.x_lo, box.yhat_lo])
    u_hi = np.concatenate([box.x_hi, box.yhat_hi])
    z_lo, z_hi = (u_lo - mean) / std, (u_hi - mean) / std  # increasing in u (std > 0)
    z_lo, z_hi = z_lo - _SUM_SLACK * np.abs(z_lo), z_hi + _SUM_SLACK * np.abs(z_hi)
    z_abs = np.maximum(np.abs(z_lo), np.abs(z_hi))
    # lin(z) = z @ A + b lies in [centre - spread, centre + spread] (plus the rounding of both)
    centre = (0.5 * (z_lo + z_hi)) @ A + b
    spread = (0.5 * (z_hi - z_lo)) @ np.abs(A)
    slack = _SUM_SLACK * (np.abs(b) + z_abs @ np.abs(A)) * 4.0
    lin_lo, lin_hi = centre - spread - slack, centre + spread + slack
    r_lo = box.y_lo - box.yhat_hi
    r_hi = box.y_hi - box.yhat_lo
    r_lo = r_lo - _SUM_SLACK * (np.abs(box.y_lo) + np.abs(box.yhat_hi))
    r_hi = r_hi + _SUM_SLACK * (np.abs(box.y_hi) + np.abs(box.yhat_lo))
    t_abs = np.maximum(np.abs(r_lo - lin_hi), np.abs(r_hi - lin_lo)) / sigma * ROUND_UP**2
    return z_abs * ROUND_UP, t_abs


def _member_layers(net: LowRankEnsemble, k: int) -> list[tuple[FloatArray, FloatArray]]:
    return [
        (layer.weight[k].detach().double().numpy(), layer.bias[k, 0].detach().double().numpy())  # type: ignore[index]
        for layer in net.body.layers
    ]


def sound_lipschitz_lowrank(network: LowRankEnsemble, box: DataBox, radius: float) -> LipschitzBound:
    """Upper bound on the Lipschitz constant of ``theta -> g_theta(X)`` for a low-rank ensemble.

    Valid for every ``theta`` (all members' trainable parameters stacked) with
    ``||theta - theta_hat||_2 <= radius`` and every ``X`` in ``box``; the normalisation,
    the linear centre stage and ``sigma`` are held fixed. Derivation:
    ``proofs/lipschitz_lowrank.md``.

    Parameters
    ----------
    network : LowRankEnsemble
        The trained ensemble (another kind raises :class:`InvalidInputError`).
    box : DataBox
        The box of ``X = (x, y, yhat)``, of the network's dimensions.
    radius : float
        Radius of the parameter ball, finite and ``>= 0`` (0: the trained parameters alone).
        A bound that overflows raises :class:`InvalidInputError`.

    Examples
    --------
    >>> from ipcverify.network import ModelConfig
    >>> from ipcverify import example
    >>> ds = example(100, seed=0).data
    >>> net = LowRankEnsemble(ModelConfig(x_dim=6, y_dim=3, hidden=(8,), members=2))
    >>> _ = net.fit_normalisation(ds.x, ds.y, ds.yhat, ridge=1e-3)
    >>> bound = sound_lipschitz_lowrank(net, DataBox.from_dataset(ds), radius=0.1)
    >>> bool(bound.value >= ensemble_gradient_norms(net, ds.x, ds.y, ds.yhat).max())
    True
    """
    require_kind(network, LowRankEnsemble)
    r = check_radius(radius)
    cfg = network.config
    box.check_dims(cfg.x_dim, cfg.y_dim)
    K, n, clamp = cfg.members, cfg.y_dim, LOGDIAG_CLAMP
    z_abs, t_abs = _target_bound(network, box)
    h0 = float(np.linalg.norm(z_abs)) * ROUND_UP
    skip_sq = h0 * h0 + 1.0  # a skip path's input is (z, 1)
    jac, offset, hidden = 0.0, 0.0, np.zeros(len(cfg.hidden) + 1)
    diag_lo = np.empty((K, n))  # lower bounds on every member's clamped log-diagonal
    for k in range(K):
        layers = _member_layers(network, k)
        H = hidden_norm_bounds(layers, h0, r)
        hidden = np.maximum(hidden, H)
        jac = max(jac, math.sqrt(jacobian_bound(layers, H, r) ** 2 + skip_sq) * ROUND_UP)
        w_last, b_last = layers[-1]
        h = H[-1]
        last_sq = h * h + 1.0
        o_bound = operator_norm(w_last[:, :n]) * h + float(np.linalg.norm(b_last[:n]))
        if network.center_skip is not None:
            s_w = network.center_skip.weight[k].detach().double().numpy()
            s_b = network.center_skip.bias[k, 0].detach().double().numpy()
            o_bound += operator_norm(s_w) * h0 + float(np.linalg.norm(s_b))
            last_sq += skip_sq
        offset = max(offset, (o_bound + r * math.sqrt(last_sq)) * ROUND_UP**2)
        spread = np.linalg.norm(w_last[:, n : 2 * n], axis=0) * (1.0 + SVD_MARGIN) * h + r * math.sqrt(
            h * h + 1.0
        )
        b_diag = b_last[n : 2 * n]
        low = b_diag - spread * ROUND_UP - _SUM_SLACK * (np.abs(b_diag) + spread)
        diag_lo[k] = np.maximum(low, -clamp)
    # Sigma >= diag(mu_i) >= mu I: mean over members of exp(2 h), rounded down
    mu_i = np.exp(2.0 * diag_lo).mean(axis=0) * (1.0 - 1e-12)
    mu = float(mu_i.min())
    gamma_sq = (
        min(
            float(np.sum((t_abs + offset) ** 2 / mu_i)),
            (float(np.linalg.norm(t_abs)) + offset) ** 2 / mu,
        )
        * ROUND_UP**4
    )
    out_grad = score_gradient_bound(mu, math.sqrt(gamma_sq) * ROUND_UP, K)
    return LipschitzBound.chain(jac, out_grad, r, hidden, box)
