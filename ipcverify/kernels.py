"""Compiled kernels: the low-rank ensemble's forward pass and sets, and the domain scan.

A controller asks one query per camera frame, and at that size NumPy's per-call overhead
(about a microsecond per operation, a dozen operations per layer stack) costs more than the
arithmetic; a batch spends a third of its time in element-wise passes over the hidden layers
and in NumPy's small-matrix calls per row. These kernels, compiled by Numba on first use (the
query path's ahead of time: :meth:`ipcverify.lowrank_engine.LowRankEngine.prepare` and
:meth:`ipcverify.domain.DomainModel.prepare`), do that work in compiled loops:

* :func:`lowrank_one` -- one query: standardisation, every member's layers, then its set
  (:func:`_set_of_row`: the moment-matched covariance, its Cholesky factor and inverse, and
  the centre), each product summed in index order (BLAS may sum in another order: the sets
  agree to the last bits, as the batch's chunks do among themselves);
* :func:`lowrank_sets` -- a batch's sets from its layers' outputs, row by row with the same
  :func:`_set_of_row`, so a batch and a single query share every operation after the layers;
* :func:`bias_activate` and :func:`bias_skip_add` -- a batch layer's bias and activation
  (or bias and skip path) in one pass over the BLAS product, the same numbers as NumPy's
  separate passes;
* :func:`whiten_one` and :func:`scan_kth` -- the whitening of a query and the float32 scan of
  all reference points of :class:`ipcverify.domain.DomainModel`, whose rounding bound
  (``proofs/domain.md``) holds for any summation order.

The kernels are compiled without ``fastmath`` (IEEE semantics: no reassociation, NaN kept) and
with NumPy's error model (a division by zero gives inf or NaN, never an exception), so a
degenerate set comes out as NaN entries just as from the batch path.

Examples
--------
>>> import numpy as np
>>> cols = np.array([[-2.0, 0.0], [0.0, -2.0], [1.0, 1.0]], dtype=np.float32)  # refs (1,0), (0,1)
>>> w = whiten_one(np.array([1.0, 0.0]), np.zeros(2), np.eye(2))
>>> float(scan_kth(w, cols, 1) + w @ w), float(scan_kth(w, cols, 2) + w @ w)  # squared distances
(0.0, 2.0)
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = [
    "ACTIVATION_CODES",
    "bias_activate",
    "bias_skip_add",
    "lowrank_one",
    "lowrank_sets",
    "scan_kth",
    "whiten_one",
]

FloatArray = NDArray[np.float64]

#: the hidden non-linearities of ``ModelConfig.activation``, as the kernels' integer codes
ACTIVATION_CODES = {"relu": 0, "tanh": 1, "elu": 2}


def _compiled(function: Callable[..., Any]) -> Any:
    """``numba.njit`` (NumPy's error model, GIL released), cached on disk where a cache directory is writable.

    Numba refuses ``cache=True`` when neither the package's ``__pycache__`` nor a user cache
    directory is writable (a read-only install); the kernel is then compiled in each process.
    """
    try:
        return njit(function, cache=True, error_model="numpy", nogil=True)
    except RuntimeError:
        return njit(function, cache=False, error_model="numpy", nogil=True)


@_compiled
def _activate(v: float, code: int) -> float:  # pragma: no cover - compiled
    if code == 0:
        return 0.0 if v < 0.0 else v  # NaN kept, as np.maximum keeps it
    if code == 1:
        return math.tanh(v)
    return v if v > 0.0 else math.expm1(0.0 if v >= 0.0 else v)  # NaN kept, as np.minimum keeps it


@_compiled
def _layer(
    h: FloatArray, weight: FloatArray, bias: FloatArray, code: int, last: bool
) -> FloatArray:  # pragma: no cover
    """Every member's ``h @ W + b`` (then the activation unless ``last``): (K, in) -> (K, out)."""
    k, n_in, n_out = weight.shape
    out = np.zeros((k, n_out))
    for m in range(k):
        for i in range(n_in):
            a = h[m, i]
            for j in range(n_out):
                out[m, j] += a * weight[m, i, j]
        for j in range(n_out):
            v = out[m, j] + bias[m, 0, j]
            out[m, j] = v if last else _activate(v, code)
    return out


@_compiled
def lowrank_one(  # pragma: no cover - compiled
    z: FloatArray,
    in_mean: FloatArray,
    in_scale: FloatArray,
    first_weight: FloatArray,
    first_bias: FloatArray,
    weights: tuple[FloatArray, ...],
    biases: tuple[FloatArray, ...],
    lin_bias: FloatArray,
    sigma: FloatArray,
    inv_sigma: FloatArray,
    members: int,
    hidden: int,
    clamp: float,
    code: int,
) -> FloatArray:
    """One query's centre and shape matrix, ``n + n * n`` floats (the shape row-major).

    ``z`` is the raw input row ``concat(x, yhat)`` (its last ``n`` entries are ``yhat``; one
    argument, so the compiled specialisation does not depend on how a caller sliced ``yhat``);
    ``first_weight`` and ``first_bias`` are the
    engine's ``single_weight`` and ``single_bias`` (every member's hidden units, then every
    member's skip paths in the width of ``[U | h]``, then the linear centre stage);
    ``weights`` and ``biases`` the later layers stacked over members, the last in ``[U | h]``
    order. The set is :func:`_set_of_row`'s: a non-positive pivot gives NaN entries, an
    overflow inf, never an exception.
    """
    n = sigma.shape[0]
    d = z.shape[0]
    width = first_weight.shape[1]
    zs = np.empty(d)
    for i in range(d):
        zs[i] = (z[i] - in_mean[i]) * in_scale[i]
    first = np.zeros(width)
    for i in range(d):
        a = zs[i]
        for j in range(width):
            first[j] += a * first_weight[i, j]
    for j in range(width):
        first[j] += first_bias[j]
    h = np.empty((members, hidden))
    for m in range(members):
        for j in range(hidden):
            h[m, j] = _activate(first[m * hidden + j], code)
    last = len(weights) - 1
    for idx in range(len(weights)):
        h = _layer(h, weights[idx], biases[idx], code, idx == last)
    nu = n * (n + 1)
    skip0 = members * hidden
    out_w = nu + n
    for m in range(members):
        for j in range(out_w):
            h[m, j] += first[skip0 + m * out_w + j]
    lin0 = width - n
    base = np.empty(n)
    for a in range(n):
        base[a] = z[d - n + a] + first[lin0 + a] + lin_bias[a]
    res = np.empty(n + n * n)
    work = np.empty(n + 2 * n * n)
    _set_of_row(h.reshape(members, 1, out_w), 0, base, sigma, inv_sigma, clamp, res[:n], res[n:], work)
    return res


@_compiled
def _set_of_row(
    out: FloatArray,
    r: int,
    base: FloatArray,
    sigma: FloatArray,
    inv_sigma: FloatArray,
    clamp: float,
    center: FloatArray,
    shape: FloatArray,
    work: FloatArray,
) -> None:  # pragma: no cover - compiled
    """Row ``r`` of every member's ``[U | h]`` (K, B, n (n + 1) + n) -> its set, written in place.

    The moment-matched offset ``mean_k o_k`` and covariance ``mean_k U_k' U_k'^T +
    diag(mean_k exp(2 h_k))`` (``U_k'`` with its offset column centred, ``h`` clamped), its
    Cholesky-Banachiewicz factor ``L``, the inverse of ``L`` by forward substitution with its
    columns divided by ``sigma``: ``shape`` (n * n, row-major); ``center = base + sigma * mean``.
    ``work`` is scratch of ``n + 2 n^2`` floats (no allocation per row). A non-positive pivot
    gives NaN entries, an overflow inf: never an exception.
    """
    members = out.shape[0]
    n = base.shape[0]
    nu = n * (n + 1)
    mean, cov, low = 0, n, n + n * n  # offsets into work
    for a in range(n):
        s = 0.0
        for m in range(members):
            s += out[m, r, a * (n + 1) + n]
        work[mean + a] = s / members
    for a in range(n):
        for b in range(a + 1):
            s = 0.0
            for m in range(members):
                for c in range(n):
                    s += out[m, r, a * (n + 1) + c] * out[m, r, b * (n + 1) + c]
                s += (out[m, r, a * (n + 1) + n] - work[mean + a]) * (
                    out[m, r, b * (n + 1) + n] - work[mean + b]
                )
            work[cov + a * n + b] = s / members
    for a in range(n):
        e = 0.0
        for m in range(members):
            v = out[m, r, nu + a]
            v = -clamp if v < -clamp else (clamp if v > clamp else v)
            e += math.exp(2.0 * v)
        work[cov + a * n + a] += e / members
    for i in range(n):
        for j in range(i + 1):
            dot = 0.0
            for p in range(j):
                dot += work[low + i * n + p] * work[low + j * n + p]
            s = work[cov + i * n + j] - dot
            if i == j:
                work[low + i * n + i] = math.sqrt(s) if s > 0.0 else math.nan
            else:
                work[low + i * n + j] = s / work[low + j * n + j]
    for i in range(n * n):
        shape[i] = 0.0
    for j in range(n):
        shape[j * n + j] = 1.0 / work[low + j * n + j]
        for i in range(j + 1, n):
            dot = 0.0
            for p in range(j, i):
                dot += work[low + i * n + p] * shape[p * n + j]
            shape[i * n + j] = -dot / work[low + i * n + i]
    for i in range(n):
        for j in range(i + 1):
            shape[i * n + j] *= inv_sigma[j]
    for a in range(n):
        center[a] = base[a] + sigma[a] * work[mean + a]


@_compiled
def lowrank_sets(
    out: FloatArray,
    base: FloatArray,
    sigma: FloatArray,
    inv_sigma: FloatArray,
    clamp: float,
    centers: FloatArray,
    shapes: FloatArray,
) -> None:  # pragma: no cover - compiled
    """Every row's set from every member's ``[U | h]`` (K, B, ·): ``centers`` (B, n) and ``shapes``
    (B, n * n), written in place; ``base`` (B, n) is ``yhat + lin(z)``. The one-query kernel's
    arithmetic (:func:`_set_of_row`), row by row."""
    n = base.shape[1]
    work = np.empty(n + 2 * n * n)
    for r in range(out.shape[1]):
        _set_of_row(out, r, base[r], sigma, inv_sigma, clamp, centers[r], shapes[r], work)


@_compiled
def bias_activate(h: FloatArray, bias: FloatArray, code: int) -> None:  # pragma: no cover - compiled
    """In place, one pass: ``h = activation(h + bias)`` for ``h`` (K, B, W) and ``bias`` (K, 1, W).

    The same numbers as NumPy's ``h += bias`` and then the activation, in half the memory traffic.
    """
    k, rows, w = h.shape
    for m in range(k):
        for r in range(rows):
            for j in range(w):
                h[m, r, j] = _activate(h[m, r, j] + bias[m, 0, j], code)


@_compiled
def bias_skip_add(h: FloatArray, bias: FloatArray, skip: FloatArray) -> None:  # pragma: no cover - compiled
    """In place, one pass: ``h = (h + bias) + skip`` for ``h`` and ``skip`` (K, B, W), ``bias`` (K, 1, W)."""
    k, rows, w = h.shape
    for m in range(k):
        for r in range(rows):
            for j in range(w):
                h[m, r, j] = (h[m, r, j] + bias[m, 0, j]) + skip[m, r, j]


@_compiled
def whiten_one(z: FloatArray, mean: FloatArray, whitening_t: FloatArray) -> FloatArray:  # pragma: no cover
    """``(z - mean) @ whitening_t`` for one query, each product summed in index order."""
    d = z.shape[0]
    dw = whitening_t.shape[1]
    w = np.zeros(dw)
    for i in range(d):
        a = z[i] - mean[i]
        for j in range(dw):
            w[j] += a * whitening_t[i, j]
    return w


@_compiled
def scan_kth(w: FloatArray, columns: NDArray[np.float32], k: int) -> np.float32:  # pragma: no cover
    """The ``k``-th smallest of the float32 products ``(w, 1) . column_j`` (NaN if any is NaN).

    ``columns`` (float32, ``(D + 1, m)``) stacks ``-2 r_j`` over ``||r_j||^2``, so adding
    ``||w||^2`` gives the squared distance to the ``k``-th nearest reference, up to the rounding
    that ``ipcverify.domain`` bounds (for any summation order of the product).
    """
    dw = w.shape[0]
    w1 = np.empty(dw + 1, np.float32)
    for j in range(dw):
        w1[j] = w[j]
    w1[dw] = 1.0
    d2 = np.dot(w1, columns)
    m = d2.shape[0]
    if k > 1:
        if np.isnan(d2).any():
            return np.float32(np.nan)
        return np.partition(d2, k - 1)[k - 1]
    lanes = 16  # a running minimum per lane, so that the loop vectorises
    best = np.full(lanes, np.float32(np.inf))
    nan = False
    for s in range(0, m - lanes + 1, lanes):
        for j in range(lanes):
            v = d2[s + j]
            nan |= v != v
            best[j] = v if v < best[j] else best[j]
    r = best.min()
    for j in range(m - m % lanes, m):
        v = d2[j]
        nan |= v != v
        r = v if v < r else r
    return np.float32(np.nan) if nan else r
