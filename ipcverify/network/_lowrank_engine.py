"""Float64 NumPy evaluation of a :class:`~ipcverify.network.LowRankEnsemble`: its sets of record.

The same role as :mod:`ipcverify.network._engine` for the paper's heads: once trained, the
ensemble is evaluated everywhere (prediction, calibration, certificates, the controller's
single queries) by this engine, with the float32 weights taken exactly into float64.

All members are evaluated together, with the queries as columns: the first layer of every
member, the two affine skip paths and the linear stage are one matrix product of the
standardised inputs, the later layers one batched product each, and the biases and
activations one compiled pass each (:mod:`ipcverify.network._kernels`). The moment-matched covariance
``Sigma``, its Cholesky factor and the triangular inverse are then computed by the compiled
:func:`ipcverify.network.lowrank_sets`, with the arithmetic of one query
(:func:`ipcverify.network.lowrank_one`) column by column. :func:`cholesky_lower` and
:func:`lower_inverse` write the same factorisation for whole arrays in NumPy; the ONNX
export's graph follows them, so all agree to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import LOGDIAG_CLAMP, ModelConfig
from ipcverify.network._engine import chunk_rows, float64_array
from ipcverify.network._kernels import (
    ACTIVATION_CODES,
    bias_activate,
    bias_skip_add,
    clamped_exp2,
    lowrank_one,
    lowrank_sets,
    standardise,
)
from ipcverify.network._kind import Engine
from ipcverify.network._weights import NetworkWeights

if TYPE_CHECKING:
    pass

FloatArray = NDArray[np.float64]


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


def _u_layout(n: int) -> NDArray[np.intp]:
    """Column order turning a member's ``[o (n) | vec(V) (n^2)]`` into ``U = [V | o]``.

    ``U`` is n x (n + 1), stored by rows.
    """
    order = []
    for i in range(n):
        order += [n + i * n + j for j in range(n)] + [i]
    return np.asarray(order, dtype=np.intp)


@dataclass(frozen=True, eq=False)
class LowRankEngine(Engine):
    """Float64 forward pass of a :class:`~ipcverify.network.LowRankEnsemble` (all members at once).

    Build it with :meth:`from_weights` (or :meth:`from_network`); :meth:`batch` for (B, ·)
    arrays, :meth:`single` for one query (it is an :class:`ipcverify.network.Engine`). The
    weights are stored so that every member's outputs come out as
    ``[U | h]``: ``U = [V | o]`` (n x (n + 1), row-major) and the log-diagonal ``h``; the
    moment-matched covariance is then ``mean_k U_k' U_k'^T + diag(mean_k exp(2 h_k))`` with
    ``U_k'`` the member's ``U`` with its centre offset replaced by the deviation from the
    members' mean.

    Parameters
    ----------
    config : ModelConfig
        The ensemble's architecture (``param="lowrank"``, ``K = members``).
    first_weight, first_bias : ndarray
        The first layer with the skip paths appended, in the layout of ``U``: ``(K, d + n, h1 +
        n (n + 1))`` and ``(K, 1, ·)``.
    weights, biases : tuple of ndarray
        The later layers stacked over members, ``(K, in, out)`` and ``(K, 1, out)``; the last
        one's columns in ``[U | h]`` order.
    in_mean, in_scale : ndarray, shape (d + n,)
        Input standardisation ``z = (concat(x, yhat) - in_mean) * in_scale``.
    sigma, inv_sigma : ndarray, shape (n,)
        The per-coordinate output scale and its reciprocal.
    lin_weight, lin_bias : ndarray
        The linear centre stage ``z @ lin_weight + lin_bias``: ``(d + n, n)`` and ``(n,)``
        (zero weight when ``config.linear_center`` is off).

    Examples
    --------
    >>> from ipcverify import example
    >>> net = example(config=ModelConfig(x_dim=2, y_dim=3, hidden=(8,))).model.network  # a low-rank ensemble
    >>> c, C = LowRankEngine.from_network(net).batch(np.zeros((4, 2)), np.zeros((4, 3)))
    >>> c.shape, C.shape
    ((4, 3), (4, 3, 3))
    """

    ONNX = ("ipcverify.network._onnx_lowrank", "lowrank_nodes")
    GRADIENTS = ("ipcverify.network._lipschitz_lowrank", "ensemble_gradient_norms")
    BOUND = ("ipcverify.network._lipschitz_lowrank", "sound_lipschitz_lowrank")

    config: ModelConfig
    #: first layer, then the skip paths in the layout of U: (K, d + n, h1 + n (n + 1)) and (K, 1, ·)
    first_weight: FloatArray
    first_bias: FloatArray
    #: the later layers, stacked over members: (K, in, out) and (K, 1, out); the last in [U | h] order
    weights: tuple[FloatArray, ...]
    biases: tuple[FloatArray, ...]
    in_mean: FloatArray
    in_scale: FloatArray
    sigma: FloatArray
    inv_sigma: FloatArray
    lin_weight: FloatArray
    lin_bias: FloatArray
    #: one query's first product (see :meth:`single_values`): (d + n, K * h1 + K * (nu + n) + n):
    #: every member's hidden units, then every member's skip paths padded with zeros to the width
    #: of ``[U | h]``, then the linear stage
    single_weight: FloatArray = field(init=False, repr=False)
    #: its bias, same columns (zero for the linear stage, whose bias is added with ``yhat``)
    single_bias: FloatArray = field(init=False, repr=False)
    #: the arguments of :func:`ipcverify.network.lowrank_one` after the query's own
    single_arguments: tuple[Any, ...] = field(init=False, repr=False)
    #: the batch's products, rows as columns: ``single_weight`` transposed, and the later layers
    #: (K, out, in) with their biases flattened (K * out,)
    first_t: FloatArray = field(init=False, repr=False)
    weights_t: tuple[FloatArray, ...] = field(init=False, repr=False)
    biases_t: tuple[FloatArray, ...] = field(init=False, repr=False)
    #: rows per chunk of :meth:`batch`: :func:`ipcverify.network.chunk_rows` of the widest layer
    chunk: int = field(init=False, repr=False)

    def __post_init__(self) -> None:
        k, n, h1 = self.config.members, self.config.y_dim, self.config.hidden[0]
        w0, b0 = self.first_weight, self.first_bias
        pad = np.zeros((k, w0.shape[1], n))

        def flat(w: FloatArray) -> FloatArray:
            """(K, rows, cols) -> (rows, K * cols): every member's columns side by side."""
            return w.transpose(1, 0, 2).reshape(w.shape[1], -1)

        # every member's hidden units, then every member's skip paths, then lin: one block each
        hidden_w, skip_w = w0[:, :, :h1], np.concatenate([w0[:, :, h1:], pad], axis=2)
        hidden_b, skip_b = b0[:, :, :h1], np.concatenate([b0[:, :, h1:], pad[:, :1]], axis=2)
        single_w = np.concatenate([flat(hidden_w), flat(skip_w), self.lin_weight], axis=1)
        single_b = np.concatenate([flat(hidden_b)[0], flat(skip_b)[0], np.zeros(n)])
        derived: dict[str, Any] = {
            "single_weight": np.ascontiguousarray(single_w),
            "single_bias": single_b,
            "first_t": np.ascontiguousarray(single_w.T),
            "weights_t": tuple(np.ascontiguousarray(w.transpose(0, 2, 1)) for w in self.weights),
            "biases_t": tuple(np.ascontiguousarray(b.reshape(-1)) for b in self.biases),
            "chunk": chunk_rows(k * max(self.config.hidden)),
        }
        for name, value in derived.items():
            object.__setattr__(self, name, value)
        object.__setattr__(
            self,
            "single_arguments",
            (
                np.ascontiguousarray(self.in_mean, dtype=np.float64),
                np.ascontiguousarray(self.in_scale, dtype=np.float64),
                self.single_weight,
                self.single_bias,
                tuple(np.ascontiguousarray(w, dtype=np.float64) for w in self.weights),
                tuple(np.ascontiguousarray(b, dtype=np.float64) for b in self.biases),
                np.ascontiguousarray(self.lin_bias, dtype=np.float64).reshape(-1),
                np.ascontiguousarray(self.sigma, dtype=np.float64),
                np.ascontiguousarray(self.inv_sigma, dtype=np.float64),
                k,
                h1,
                float(LOGDIAG_CLAMP),
                ACTIVATION_CODES[self.config.activation],
            ),
        )

    @classmethod
    def from_weights(cls, weights: NetworkWeights) -> LowRankEngine:
        """The stacked weights (in the ``[U | h]`` layout) and the normalisation of an ensemble's weights."""
        cfg, state = weights.config, weights.state
        k, n = cfg.members, cfg.y_dim
        d_in = cfg.x_dim + n
        skip_w, skip_b = np.zeros((k, d_in, n)), np.zeros((k, 1, n))
        if cfg.linear_center:
            skip_w, skip_b = (
                float64_array(state["center_skip.weight"]),
                float64_array(state["center_skip.bias"]),
            )
        u = _u_layout(n)
        # skip paths [centre (n) | factor (n^2)] -> U layout
        sw = np.concatenate([skip_w, float64_array(state["factor_skip.weight"])], axis=2)[..., u]
        sb = np.concatenate([skip_b, float64_array(state["factor_skip.bias"])], axis=2)[..., u]
        # last layer [o (n) | h (n) | V (n^2)] -> [U | h]
        order = np.concatenate(
            [np.concatenate([np.arange(n), np.arange(2 * n, 2 * n + n * n)])[u], n + np.arange(n)]
        )
        layers = range(1, len(cfg.hidden) + 1)
        weights_ = [float64_array(state[f"body.layers.{i}.weight"]) for i in layers]
        biases = [float64_array(state[f"body.layers.{i}.bias"]) for i in layers]
        weights_[-1], biases[-1] = weights_[-1][..., order], biases[-1][..., order]
        sigma = float64_array(state["sigma"])
        first_w, first_b = (
            float64_array(state["body.layers.0.weight"]),
            float64_array(state["body.layers.0.bias"]),
        )
        return cls(
            config=cfg,
            first_weight=np.ascontiguousarray(np.concatenate([first_w, sw], axis=2)),
            first_bias=np.ascontiguousarray(np.concatenate([first_b, sb], axis=2)),
            weights=tuple(np.ascontiguousarray(w) for w in weights_),
            biases=tuple(np.ascontiguousarray(b) for b in biases),
            in_mean=float64_array(state["in_mean"]),
            in_scale=1.0 / float64_array(state["in_std"]),
            sigma=sigma,
            inv_sigma=1.0 / sigma,
            lin_weight=float64_array(state["lin_weight"]),
            lin_bias=float64_array(state["lin_bias"]),
        )

    def _moments(self, out: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Moment-matched offset (B, n) and covariance (B, n, n) from every member's ``[U | h]`` (K, ·, B)."""
        n, k = self.config.y_dim, self.config.members
        nu = n * (n + 1)
        U = out[:, :nu].transpose(0, 2, 1).reshape(k, -1, n, n + 1).copy()
        mean = U[..., n].sum(axis=0) / k
        U[..., n] -= mean
        cols = U.transpose(1, 2, 0, 3).reshape(-1, n, k * (n + 1))  # (B, n, K (n + 1))
        cov = cols @ cols.transpose(0, 2, 1)
        cov /= k
        log_var = np.minimum(np.maximum(out[:, nu:].transpose(0, 2, 1), -LOGDIAG_CLAMP), LOGDIAG_CLAMP)
        log_var *= 2.0
        cov.reshape(-1, n * n)[:, :: n + 1] += np.exp(log_var).sum(axis=0) / k
        return mean, cov

    def layers(self, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Every member's ``[U | h]`` (K, n (n + 1) + n, B) and the linear stage (n, B), rows as columns.

        ``z`` is the standardised input (B, d + n). The network's layers, skip paths and
        linear stage alone: the float64 work every set needs before its moments. Each product
        is one BLAS call with the queries as columns, so that every later pass (the biases,
        the activations, :func:`ipcverify.network.lowrank_sets`) runs along contiguous rows.
        """
        code = ACTIVATION_CODES[self.config.activation]
        k, n = self.config.members, self.config.y_dim
        hidden = k * self.config.hidden[0]
        out_w = n * (n + 1) + n
        first = self.first_t @ z.T  # (K h1 + K (nu + n) + n, B): the single query's first product
        bias_activate(first[:hidden], self.single_bias[:hidden], code)
        bias_activate(first[hidden:], self.single_bias[hidden:], -1)
        rows = z.shape[0]
        h = first[:hidden].reshape(k, -1, rows)
        last = len(self.weights_t) - 1
        for i, (w, b) in enumerate(zip(self.weights_t, self.biases_t, strict=True)):
            h = w @ h  # (K, out, in) @ (K, in, B)
            flat = h.reshape(-1, rows)
            if i < last:
                bias_activate(flat, b, code)
            else:  # adding the skip's padding 0.0 to h changes nothing
                bias_skip_add(flat, b, first[hidden : hidden + k * out_w])
        return h, first[hidden + k * out_w :]

    def combined(self, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Moment-matched offset (B, n) and covariance (B, n, n) in standardised output units.

        In NumPy, independently of the compiled :func:`ipcverify.network.lowrank_sets` that
        :meth:`batch` uses (the tests check one against the other, and both against the
        mixture's moments computed by hand).
        """
        return self._moments(self.layers(z)[0])

    def batch(
        self, x: FloatArray, yhat: FloatArray, chunk: int | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Centres (B, n) and shape matrices (B, n, n) for validated float64 inputs.

        Rows are evaluated ``chunk`` at a time (default :attr:`chunk`, which keeps the members'
        hidden layers in the CPU cache); every row gets the same operations whatever the chunk.
        An input so far from the training data that the covariance overflows gives a
        non-finite set, not a floating-point exception:
        :meth:`ipcverify.contract.IPCModel.predict` reports it as a degenerate set outside the
        domain, and the query path answers OUTSIDE_DOMAIN.
        """
        size = self.chunk if chunk is None else int(chunk)
        if size < 1:
            raise InvalidInputError(f"chunk must be a positive number of rows; got {chunk!r}")
        n = self.config.y_dim
        nu = n * (n + 1)
        centers, shapes = np.empty((len(x), n)), np.empty((len(x), n, n))
        for start in range(0, len(x), size):
            sl = slice(start, start + size)
            z = standardise(x[sl], yhat[sl], self.in_mean, self.in_scale)
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                out, lin = self.layers(z)
                lowrank_sets(
                    out, clamped_exp2(out[:, nu:], LOGDIAG_CLAMP), lin, np.ascontiguousarray(yhat[sl]),
                    self.lin_bias.reshape(-1), self.sigma, self.inv_sigma, centers[sl],
                    shapes[sl].reshape(-1, n * n),
                )  # fmt: skip
        return centers, shapes

    def single(self, x: FloatArray, yhat: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Centre (n,) and shape matrix (n, n) for one query given as 1-D float64 arrays.

        The same arithmetic as :meth:`batch` (up to the summation order of the matrix
        products, and libm's ``exp`` for NumPy's) with less per-call overhead; see
        :meth:`single_values`.
        """
        d, n = self.config.x_dim, self.config.y_dim
        if np.shape(x) != (d,) or np.shape(yhat) != (n,):
            raise InvalidInputError(
                f"one query needs x of shape ({d},) and yhat of shape ({n},); got {np.shape(x)} "
                f"and {np.shape(yhat)}"
            )
        z = np.concatenate((x, yhat))
        both = lowrank_one(z, *self.single_arguments)
        return both[:n], both[n:].reshape(n, n)

    def single_values(self, z: FloatArray) -> tuple[list[float], list[float]]:
        """Centre (n floats) and row-major shape matrix (n * n floats) for one query, as Python floats.

        ``z`` is the query's raw input row ``concat(x, yhat)`` (1-D float64, C-contiguous and
        writable, as :func:`numpy.concatenate` returns it: another layout compiles the kernel
        again; not modified). One call of the compiled kernel
        :func:`ipcverify.network.lowrank_one`: the operations of :meth:`batch` (the first
        layer, the skip paths and ``lin`` as one product with :attr:`single_weight`; means
        summed over members in order; ``exp`` of twice the clamped log-diagonal;
        Cholesky-Banachiewicz; forward substitution; ``yhat + lin(z) + sigma * mean``), each
        product summed in index order where BLAS may choose another: the same sets up to the
        last bits.
        """
        n = self.config.y_dim
        self._check_one(z)
        res = lowrank_one(z, *self.single_arguments).tolist()
        return res[:n], res[n:]

    def prepare(self) -> None:
        """Compile (or load from Numba's on-disk cache) the one-query kernel for this network now.

        The first :meth:`single` otherwise pays it: seconds on a fresh install, about a
        millisecond from the cache. :class:`ipcverify.decision.IPCQuery` calls it once, so a control
        loop's first frame costs what the others do. Evaluates one query at the input mean and
        discards it.
        """
        d = self.config.x_dim
        z = np.array(self.in_mean, dtype=np.float64).reshape(-1)
        self.single(z[:d], z[d:])

    def float64_layers(self, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The network's layers alone on standardised rows ``z`` (:meth:`layers`)."""
        return self.layers(z)

    def _check_one(self, z: FloatArray) -> None:
        """The compiled kernel reads without bounds checks: one query's input row is checked here."""
        d, n = self.config.x_dim, self.config.y_dim
        if z.shape != (d + n,):
            raise InvalidInputError(
                f"one query's input row concat(x, yhat) needs shape ({d + n},) (x of length {d}, "
                f"yhat of length {n}); got shape {z.shape}"
            )
