"""Float64 NumPy inference for trained IPC networks: the contract's reference evaluation.

Training runs in torch (float32). Once trained, an IPC is *evaluated* everywhere —
prediction, calibration, evaluation, certificates, the landing controller — by this
engine: the same weights (float32 values are exact in float64) applied in float64
NumPy. One evaluation path means the calibrated guarantee is about exactly the sets
the controller uses, and NumPy has far less per-call overhead than torch for the
single queries of a control loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import LOGDIAG_CLAMP, ModelConfig
from ipcverify.network._kind import Engine
from ipcverify.network._weights import NetworkWeights

if TYPE_CHECKING:
    pass

#: Bytes of one layer's activations per chunk of a batch: half a megabyte, so that a layer's input
#: and output stay in a core's L2 cache (1 MB and up on current x86 and ARM server cores).
CACHE_BYTES = 1 << 19


def chunk_rows(width: int) -> int:
    """Rows per chunk of a batch whose widest layer has ``width`` float64 activations per row.

    As many rows as fit :data:`CACHE_BYTES`, rounded down to a multiple of 64 (at least 64):
    512 for the paper's heads (128 units), 192 for the default ensemble (5 members x 64). The
    products of a chunk then run from cache; larger chunks measured up to 25 % slower in the
    second layer of the ensemble (benchmarks/bench_latency.py, ``float64_layers_only``).

    Parameters
    ----------
    width : int
        Activations per row of the widest layer (members x units for an ensemble); below 1
        raises :class:`InvalidInputError`, and very wide layers still get 64 rows.

    Examples
    --------
    >>> chunk_rows(128), chunk_rows(5 * 64), chunk_rows(10_000)
    (512, 192, 64)
    """
    if width < 1:
        raise InvalidInputError(f"a layer needs a positive width; got {width!r}")
    return max(64, CACHE_BYTES // (8 * width) // 64 * 64)


#: Rows evaluated together by :meth:`InferenceEngine.batch` (the paper's heads, 128 hidden units)
CHUNK = chunk_rows(128)

FloatArray = NDArray[np.float64]


def float64_array(t: Any) -> FloatArray:
    """A tensor's or an array's values as a contiguous float64 array (float32 is exact in float64).

    Parameters
    ----------
    t : torch.Tensor or array_like
        A tensor (detached and moved to the CPU first) or anything NumPy converts; a
        contiguous float64 array is returned as is, not copied.

    Examples
    --------
    >>> import torch
    >>> float64_array(torch.tensor([0.1], dtype=torch.float32)).dtype
    dtype('float64')
    >>> float64_array(np.float32([0.1]))[0] == float(np.float32(0.1))
    np.True_
    """
    if hasattr(t, "detach"):  # a torch tensor (torch itself is not imported here)
        t = t.detach().cpu().numpy()
    return np.ascontiguousarray(t, dtype=np.float64)


def activate(h: FloatArray, activation: str) -> FloatArray:
    """A hidden layer's non-linearity (``ModelConfig.activation``), in place where NumPy allows.

    Parameters
    ----------
    h : ndarray
        Pre-activations (float64, any shape); overwritten by ``relu`` and ``tanh``.
    activation : str
        ``"relu"``, ``"tanh"``; anything else is taken as ``"elu"`` (alpha 1) (the config
        has checked the name).

    Examples
    --------
    >>> activate(np.array([-1.0, 2.0]), "relu").tolist()
    [0.0, 2.0]
    """
    if activation == "relu":
        return np.maximum(h, 0.0, out=h)
    if activation == "tanh":
        return np.tanh(h, out=h)
    return np.where(h > 0, h, np.expm1(np.minimum(h, 0.0)))  # elu, alpha = 1


@dataclass(frozen=True, eq=False)
class InferenceEngine(Engine):
    """Float64 forward pass of an :class:`~ipcverify.network.IPCNetwork`.

    Build it with :meth:`from_weights` (or :meth:`from_network`); call :meth:`batch` for (B, ·) arrays,
    :meth:`single` for one query, :meth:`single_values` for one query's values as Python floats
    (lowest latency). It is an :class:`ipcverify.network.Engine`.

    Parameters
    ----------
    config : ModelConfig
        The network's architecture (a ``"cholesky"`` or ``"full"`` head).
    weights, biases : tuple of ndarray
        The MLP's layers, first to last: weights ``(in, out)`` (transposed from torch, so that
        ``out = h @ W + b``) and biases ``(out,)``.
    in_mean, in_scale : ndarray, shape (d + n,)
        Input standardisation: ``z = (concat(x, yhat) - in_mean) * in_scale`` (``in_scale``
        is ``1 / in_std``).
    y_mean : ndarray, shape (n,)
        The training truths' mean: the centre's base when ``config.center`` is not ``"offset"``.
    sigma, inv_sigma : ndarray, shape (n,)
        The per-coordinate output scale and its reciprocal: centre ``base + sigma * o``,
        shape ``L diag(1 / sigma)``.
    tril_rows, tril_cols : ndarray of intp
        Row and column of each packed lower-triangle output (``numpy.tril_indices(n)``).
    diag_pos : ndarray of intp, shape (n,)
        Positions of the diagonal within the packed lower triangle.

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify import example
    >>> from ipcverify.network import ModelConfig
    >>> net = example(config=ModelConfig(x_dim=2, y_dim=3, hidden=(8,), param="cholesky")).model.network
    >>> eng = InferenceEngine.from_network(net)
    >>> c, C = eng.batch(np.zeros((4, 2)), np.zeros((4, 3)))
    >>> c.shape, C.shape
    ((4, 3), (4, 3, 3))
    """

    ONNX = ("ipcverify.network._onnx_mlp", "mlp_nodes")
    GRADIENTS = ("ipcverify.network._lipschitz_mlp", "mlp_gradient_norms")
    BOUND = ("ipcverify.network._lipschitz_mlp", "sound_lipschitz_mlp")

    config: ModelConfig
    weights: tuple[FloatArray, ...]
    biases: tuple[FloatArray, ...]
    in_mean: FloatArray
    in_scale: FloatArray
    y_mean: FloatArray
    sigma: FloatArray
    inv_sigma: FloatArray
    tril_rows: NDArray[np.intp]
    tril_cols: NDArray[np.intp]
    diag_pos: NDArray[np.intp]
    #: flat (row-major) positions of the packed lower triangle and of the diagonal in an n x n matrix
    flat_tril: NDArray[np.intp] = field(init=False, repr=False)
    flat_diag: NDArray[np.intp] = field(init=False, repr=False)
    #: n = 3 with the Cholesky head: (sigma, 1 / sigma, y_mean, clamp) as Python floats for
    #: :meth:`_heads3`; None for the other heads
    heads3: tuple[list[float], list[float], list[float], float] | None = field(init=False, repr=False)
    #: rows :meth:`batch` evaluates together by default (:data:`CHUNK`)
    chunk: int = field(default=CHUNK, init=False, repr=False)

    def __post_init__(self) -> None:
        n = self.config.y_dim
        object.__setattr__(self, "flat_tril", self.tril_rows * n + self.tril_cols)
        object.__setattr__(self, "flat_diag", np.arange(n) * (n + 1))
        fast = n == 3 and self.config.param != "full"
        consts = (self.sigma.tolist(), self.inv_sigma.tolist(), self.y_mean.tolist(), LOGDIAG_CLAMP)
        object.__setattr__(self, "heads3", consts if fast else None)

    @classmethod
    def from_weights(cls, weights: NetworkWeights) -> InferenceEngine:
        """The engine of a network's weights (:class:`~ipcverify.network.NetworkWeights`)."""
        cfg, state = weights.config, weights.state
        linear = [f"body.{2 * i}" for i in range(len(cfg.hidden) + 1)]  # nn.Sequential: Linear, act, ...
        n = cfg.y_dim
        rows, cols = np.tril_indices(n)
        sigma = float64_array(state["sigma"])
        return cls(
            config=cfg,
            weights=tuple(np.ascontiguousarray(float64_array(state[f"{m}.weight"]).T) for m in linear),
            biases=tuple(float64_array(state[f"{m}.bias"]) for m in linear),
            in_mean=float64_array(state["in_mean"]),
            in_scale=1.0 / float64_array(state["in_std"]),
            y_mean=float64_array(state["y_mean"]),
            sigma=sigma,
            inv_sigma=1.0 / sigma,
            tril_rows=rows,
            tril_cols=cols,
            diag_pos=np.flatnonzero(rows == cols),
        )

    def mlp(self, z: FloatArray) -> FloatArray:
        """The network's raw outputs for standardised inputs ``z`` ((B, d + n) or one (d + n,) row)."""
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            z = z @ w
            z += b
            if i < last:
                z = activate(z, self.config.activation)
        return z

    def batch(
        self, x: FloatArray, yhat: FloatArray, chunk: int | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Centres (B, n) and shape matrices (B, n, n) for validated float64 inputs.

        Rows are evaluated ``chunk`` at a time (default :data:`CHUNK`): the hidden layers of a
        chunk stay in the CPU cache, and the results are written straight into the output
        arrays. Every row is computed by the same operations whatever the chunk (only the
        matrix products' summation order may differ, in the last bits).
        """
        n = self.config.y_dim
        size = CHUNK if chunk is None else int(chunk)
        if size < 1:
            raise InvalidInputError(f"chunk must be a positive number of rows; got {chunk!r}")
        rows = len(x)
        centers = np.empty((rows, n))
        shapes = np.zeros((rows, n * n))
        base_all = yhat if self.config.center == "offset" else None
        full = self.config.param == "full"
        flat = self.tril_rows * n + self.tril_cols
        col_scale = self.inv_sigma[self.tril_cols]
        for start in range(0, rows, size):
            sl = slice(start, start + size)
            z = np.concatenate([x[sl], yhat[sl]], axis=1)
            z -= self.in_mean
            z *= self.in_scale
            out = self.mlp(z)
            c = centers[sl]
            np.multiply(self.sigma, out[:, :n], out=c)
            c += self.y_mean if base_all is None else base_all[sl]
            s = out[:, n:]
            if full:
                shapes[sl] = (s.reshape(-1, n, n) * self.inv_sigma).reshape(-1, n * n)
            else:
                diag = s[:, self.diag_pos]
                np.exp(np.clip(diag, -LOGDIAG_CLAMP, LOGDIAG_CLAMP, out=diag), out=diag)
                s[:, self.diag_pos] = diag
                s *= col_scale
                shapes[sl][:, flat] = s
        return centers, shapes.reshape(rows, n, n)

    def single(self, x: FloatArray, yhat: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Centre (n,) and shape matrix (n, n) for one query given as 1-D float64 arrays."""
        c, C = self.batch(x[None, :], yhat[None, :])
        return c[0], C[0]

    def single_values(self, z: FloatArray) -> tuple[list[float], list[float]]:
        """Centre (n floats) and row-major shape matrix (n * n floats) for one input row ``concat(x, yhat)``.

        The operations of :meth:`batch` on one row. For ``n = 3`` with the Cholesky head the
        heads are plain float arithmetic (:meth:`_heads3`); otherwise NumPy on the row.

        Examples
        --------
        >>> from ipcverify import example
        >>> net = example(config=ModelConfig(x_dim=2, y_dim=3, hidden=(8,), param="cholesky")).model.network
        >>> eng = InferenceEngine.from_network(net)
        >>> c, C = eng.single_values(np.array([0.0, 1.0, 0.1, 0.2, 0.3]))
        >>> bool(np.allclose(C, eng.batch(np.array([[0.0, 1.0]]), np.array([[0.1, 0.2, 0.3]]))[1].ravel()))
        True
        """
        d, n = self.config.x_dim, self.config.y_dim
        h = z - self.in_mean
        h *= self.in_scale
        out = self.mlp(h)  # the engine's own MLP evaluation (1-D input: one query)
        consts = self.heads3
        if consts is not None:
            return self._heads3(out.tolist(), z[d:], consts)
        ya = z[d:]
        center = (ya if self.config.center == "offset" else self.y_mean) + self.sigma * out[:n]
        if self.config.param == "full":
            L = out[n:].reshape(n, n)
        else:
            flat_l = np.zeros(n * n)
            flat_l[self.flat_tril] = out[n:]
            diag = out[n:][self.diag_pos]
            flat_l[self.flat_diag] = np.exp(np.minimum(np.maximum(diag, -LOGDIAG_CLAMP), LOGDIAG_CLAMP))
            L = flat_l.reshape(n, n)
        return center.tolist(), (L * self.inv_sigma).ravel().tolist()

    def _heads3(
        self, out: list[float], ya: FloatArray, consts: tuple[list[float], list[float], list[float], float]
    ) -> tuple[list[float], list[float]]:
        """Centre and row-major ``L diag(1/sigma)`` for n = 3, Cholesky head, in plain floats.

        The same operations as :meth:`batch` (``base + sigma o``; ``exp`` of the clamped
        diagonal; ``L_ij / sigma_j``); only ``math.exp`` may differ from NumPy's ``exp`` in the
        last bit.
        """
        o0, o1, o2, l00, l10, l11, l20, l21, l22 = out
        (s0, s1, s2), (i0, i1, i2), y_mean, clamp = consts
        b0, b1, b2 = ya.tolist() if self.config.center == "offset" else y_mean
        center = [b0 + s0 * o0, b1 + s1 * o1, b2 + s2 * o2]
        e00 = math.exp(min(max(l00, -clamp), clamp))
        e11 = math.exp(min(max(l11, -clamp), clamp))
        e22 = math.exp(min(max(l22, -clamp), clamp))
        return center, [e00 * i0, 0.0, 0.0, l10 * i0, e11 * i1, 0.0, l20 * i0, l21 * i1, e22 * i2]

    def prepare(self) -> None:
        """Nothing to compile: the one-query path is NumPy and Python floats."""

    def float64_layers(self, z: FloatArray) -> FloatArray:
        """The MLP alone on standardised rows ``z`` (:meth:`mlp`)."""
        return self.mlp(z)
