"""Float64 NumPy evaluation of a :class:`~ipcverify.lowrank.LowRankEnsemble`: its sets of record.

The same role as :mod:`ipcverify.inference` for the paper's heads: once trained, the
ensemble is evaluated everywhere (prediction, calibration, certificates, the controller's
single queries) by this engine, with the float32 weights taken exactly into float64.

All members are evaluated together: the first layer and the two affine skip paths are
one matrix product of the shared input with the members' stacked weights, the later layers
one batched product each. The moment-matched covariance ``Sigma`` is one product of the
stacked factors; its Cholesky factor and the triangular inverse are written out entry by
entry (:func:`cholesky_lower`, :func:`lower_inverse`), the same arithmetic for one query
or a million, and the same as the ONNX export's graph.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from numpy.typing import NDArray

from ipcverify.architecture import LOGDIAG_CLAMP, ModelConfig
from ipcverify.lowrank import LowRankEnsemble

__all__ = ["LowRankEngine", "cholesky_lower", "lower_inverse"]

FloatArray = NDArray[np.float64]


def _np(t: torch.Tensor) -> FloatArray:
    return np.ascontiguousarray(t.detach().cpu().double().numpy())


def cholesky_lower(S: FloatArray) -> FloatArray:
    """Lower Cholesky factors of SPD matrices ``S`` (..., n, n), entry by entry (Cholesky-Banachiewicz).

    A non-positive pivot (a matrix that is not numerically positive definite) gives NaN
    entries, never an exception: callers treat such a set as degenerate.

    Examples
    --------
    >>> S = np.array([[4.0, 2.0], [2.0, 5.0]])
    >>> cholesky_lower(S).tolist()
    [[2.0, 0.0], [1.0, 2.0]]
    """
    n = S.shape[-1]
    L = np.zeros_like(S)
    for i in range(n):
        for j in range(i + 1):
            s = S[..., i, j] - np.einsum("...k,...k->...", L[..., i, :j], L[..., j, :j])
            if i == j:
                s = np.where(s > 0.0, s, np.nan)
                L[..., i, i] = np.sqrt(s)
            else:
                L[..., i, j] = s / L[..., j, j]
    return L


def lower_inverse(L: FloatArray) -> FloatArray:
    """Inverses of lower-triangular matrices ``L`` (..., n, n) by forward substitution.

    Examples
    --------
    >>> lower_inverse(np.array([[2.0, 0.0], [1.0, 2.0]])).tolist()
    [[0.5, 0.0], [-0.25, 0.5]]
    """
    n = L.shape[-1]
    X = np.zeros_like(L)
    for i in range(n):
        X[..., i, i] = 1.0 / L[..., i, i]
        for j in range(i):
            acc = np.einsum("...k,...k->...", L[..., i, j:i], X[..., j:i, j])
            X[..., i, j] = -acc / L[..., i, i]
    return X


@dataclass(frozen=True, eq=False)
class LowRankEngine:
    """Float64 forward pass of a :class:`~ipcverify.lowrank.LowRankEnsemble` (all members at once).

    Build it with :meth:`from_network`; :meth:`batch` for (B, ·) arrays, :meth:`single`
    for one query.

    Examples
    --------
    >>> net = LowRankEnsemble(ModelConfig(x_dim=2, y_dim=3, hidden=(8,)))
    >>> c, C = LowRankEngine.from_network(net).batch(np.zeros((4, 2)), np.zeros((4, 3)))
    >>> c.shape, C.shape
    ((4, 3), (4, 3, 3))
    """

    config: ModelConfig
    #: first layer with the centre and factor skip paths appended: (K, d + n, h1 + n + n^2)
    first_weight: FloatArray
    first_bias: FloatArray
    #: the later layers, stacked over members: (K, in, out) and (K, 1, out)
    weights: tuple[FloatArray, ...]
    biases: tuple[FloatArray, ...]
    in_mean: FloatArray
    in_scale: FloatArray
    sigma: FloatArray
    inv_sigma: FloatArray
    lin_weight: FloatArray
    lin_bias: FloatArray

    @classmethod
    def from_network(cls, network: LowRankEnsemble) -> LowRankEngine:
        """Extract the stacked weights and the normalisation of a trained ensemble."""
        cfg = network.config
        k, n = cfg.members, cfg.y_dim
        layers = list(network.body.layers)
        d_in = cfg.x_dim + n
        skip_w = np.zeros((k, d_in, n))
        skip_b = np.zeros((k, 1, n))
        if network.center_skip is not None:
            skip_w, skip_b = _np(network.center_skip.weight), _np(network.center_skip.bias)
        parts_w = [_np(layers[0].weight), skip_w, _np(network.factor_skip.weight)]  # type: ignore[arg-type]
        parts_b = [_np(layers[0].bias), skip_b, _np(network.factor_skip.bias)]  # type: ignore[arg-type]
        sigma = _np(network.sigma)
        return cls(
            config=cfg,
            first_weight=np.ascontiguousarray(np.concatenate(parts_w, axis=2)),
            first_bias=np.ascontiguousarray(np.concatenate(parts_b, axis=2)),
            weights=tuple(_np(m.weight) for m in layers[1:]),  # type: ignore[arg-type]
            biases=tuple(_np(m.bias) for m in layers[1:]),  # type: ignore[arg-type]
            in_mean=_np(network.in_mean),
            in_scale=1.0 / _np(network.in_std),
            sigma=sigma,
            inv_sigma=1.0 / sigma,
            lin_weight=_np(network.lin_weight),
            lin_bias=_np(network.lin_bias),
        )

    def _activation(self, h: FloatArray) -> FloatArray:
        act = self.config.activation
        if act == "relu":
            return np.maximum(h, 0.0, out=h)
        if act == "tanh":
            return np.tanh(h, out=h)
        return np.where(h > 0, h, np.expm1(np.minimum(h, 0.0)))  # elu, alpha = 1

    def heads(self, z: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Per member: offsets (K, B, n), log-diagonals (K, B, n), factors (K, B, n, n) for inputs ``z``."""
        n = self.config.y_dim
        width = self.first_weight.shape[2] - n - n * n
        first = z @ self.first_weight  # (B, d + n) @ (K, d + n, ·) -> (K, B, ·)
        first += self.first_bias
        h = first[..., :width]
        skip, fskip = first[..., width : width + n], first[..., width + n :]
        if self.weights:
            h = self._activation(h)
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            h = h @ w
            h += b
            if i < last:
                h = self._activation(h)
        offset = h[..., :n] + skip
        log_diag = np.clip(h[..., n : 2 * n], -LOGDIAG_CLAMP, LOGDIAG_CLAMP)
        factor = (h[..., 2 * n :] + fskip).reshape(*h.shape[:-1], n, n)
        return offset, log_diag, factor

    def combined(self, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Moment-matched offset (B, n) and covariance (B, n, n) in standardised output units."""
        offset, log_diag, factor = self.heads(z)
        k = offset.shape[0]
        mean = offset.mean(axis=0)
        dev = offset - mean
        # Sigma = mean_k (V_k V_k^T + dev_k dev_k^T) + diag(mean_k exp(2 h_k)): one product of the
        # stacked columns [V_k, dev_k] / sqrt(K)
        cols = np.concatenate([factor, dev[..., None]], axis=-1)  # (K, B, n, n + 1)
        cols = np.moveaxis(cols, 0, -2).reshape(*cols.shape[1:-1], -1)  # (B, n, K (n + 1))
        cov = cols @ np.swapaxes(cols, -1, -2)
        cov /= k
        diag = np.exp(2.0 * log_diag).mean(axis=0)
        idx = np.arange(self.config.y_dim)
        cov[..., idx, idx] += diag
        return mean, cov

    def batch(self, x: FloatArray, yhat: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Centres (B, n) and shape matrices (B, n, n) for validated float64 inputs.

        An input so far from the training data that the covariance overflows gives a
        non-finite set, not a floating-point exception: :meth:`ipcverify.model.IPCModel.predict`
        reports it as a degenerate set outside the domain, and the query path answers
        OUTSIDE_DOMAIN.
        """
        z = np.concatenate([x, yhat], axis=1)
        z -= self.in_mean
        z *= self.in_scale
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            mean, cov = self.combined(z)
            center = yhat + z @ self.lin_weight + self.lin_bias + self.sigma * mean
            shape = lower_inverse(cholesky_lower(cov))
            shape *= self.inv_sigma
        return center, shape

    def single(self, x: FloatArray, yhat: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Centre (n,) and shape matrix (n, n) for one query given as 1-D float64 arrays."""
        c, C = self.batch(x[None, :], yhat[None, :])
        return c[0], C[0]
