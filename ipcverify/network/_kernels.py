"""Compiled kernels: the low-rank ensemble's forward pass and sets, and the domain scan.

A controller asks one query per camera frame, and at that size NumPy's per-call overhead
(about a microsecond per operation, a dozen operations per layer stack) costs more than the
arithmetic; a batch spends a third of its time in element-wise passes over the hidden layers
and in NumPy's small-matrix calls per row. These kernels, compiled by Numba on first use (the
query path's ahead of time: :meth:`ipcverify.network.LowRankEngine.prepare` and
:meth:`ipcverify.guard.DomainModel.prepare`), do that work in compiled loops:

* :func:`lowrank_one` -- one query: standardisation, every member's layers, then its set
  (:func:`_set_columns`: the moment-matched covariance, its Cholesky factor and inverse, and
  the centre), each product summed in index order (BLAS may sum in another order: the sets
  agree to the last bits, as the batch's chunks do among themselves);
* :func:`lowrank_sets` -- a batch's sets from its layers' outputs, with the same
  :func:`_set_columns` (queries as columns, so its loops vectorise), so a batch and a single
  query share every operation after the layers but ``exp`` (NumPy's vectorised one for a batch,
  :func:`clamped_exp2`; libm's for one query: they may differ in the last bit);
* :func:`standardise`, :func:`bias_activate` and :func:`bias_skip_add` -- a batch's
  standardisation, and a layer's bias and activation (or bias and skip path) in one pass over
  the BLAS product, the same numbers as NumPy's separate passes;
* :func:`rcond_lower_3` -- the cheap lower bound of the reciprocal condition number with which
  :mod:`ipcverify.network._nonsingular` validates a batch's shape matrices;
* :func:`compiled` -- the decorator of every kernel here and in :mod:`ipcverify.guard._kernels`
  (the domain test's compiled code).

The kernels are compiled without ``fastmath`` (IEEE semantics: no reassociation, NaN kept) and
with NumPy's error model (a division by zero gives inf or NaN, never an exception), so a
degenerate set comes out as NaN entries just as from the batch path.

Examples
--------
>>> import numpy as np
>>> clamped_exp2(np.array([0.0, 0.5]), 1.0).tolist() == [1.0, float(np.exp(1.0))]
True
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: the hidden non-linearities of ``ModelConfig.activation``, as the kernels' integer codes
ACTIVATION_CODES = {"relu": 0, "tanh": 1, "elu": 2}


def compiled(function: Callable[..., Any]) -> Any:
    """``numba.njit`` (NumPy's error model, GIL released), cached on disk where a cache directory is writable.

    Numba refuses ``cache=True`` when neither the package's ``__pycache__`` nor a user cache
    directory is writable (a read-only install); the kernel is then compiled in each process.

    Parameters
    ----------
    function : callable
        A Python function Numba can compile in nopython mode; compiled lazily, on its first call.
    """
    try:
        return njit(function, cache=True, error_model="numpy", nogil=True)
    except RuntimeError:
        return njit(function, cache=False, error_model="numpy", nogil=True)


_compiled = compiled


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
    order. The set is :func:`_set_columns`'s: a non-positive pivot gives NaN entries, an
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
    exps = np.empty((members, n, 1))
    for m in range(members):
        for a in range(n):
            v = h[m, nu + a]
            v = -clamp if v < -clamp else (clamp if v > clamp else v)  # NaN kept, as clamped_exp2 keeps it
            exps[m, a, 0] = math.exp(2.0 * v)
    res = np.empty(n + n * n)
    work = np.empty((n + 3 * n * n + 1, 1))
    _set_columns(
        h.reshape((members, out_w, 1)), exps, base.reshape((n, 1)), sigma, inv_sigma,
        res[:n].reshape((1, n)), res[n:].reshape((1, n * n)), work,
    )  # fmt: skip
    return res


@_compiled
def _set_columns(
    out: FloatArray,
    exps: FloatArray,
    base: FloatArray,
    sigma: FloatArray,
    inv_sigma: FloatArray,
    centers: FloatArray,
    shapes: FloatArray,
    work: FloatArray,
) -> None:  # pragma: no cover - compiled
    """Column ``r`` of every member's ``[U | h]`` (K, n (n + 1) + n, R) -> set ``r``, written in place.

    The moment-matched offset ``mean_k o_k`` and covariance ``mean_k U_k' U_k'^T +
    diag(mean_k exps_k)`` (``U_k'`` with its offset column centred; ``exps`` (K, n, R) is
    ``exp(2 h)`` of the clamped log-diagonal ``h``, see :func:`clamped_exp2`), its
    Cholesky-Banachiewicz factor ``L``, the inverse of ``L`` by forward substitution with its
    columns divided by ``sigma``: ``shapes`` (R, n * n, row-major); ``centers = base + sigma *
    mean`` (R, n) with ``base`` (n, R). ``work`` is scratch of ``(n + 3 n^2 + 1, R)`` floats.
    Each set's operations are those of one query, in the same order, whatever ``R``: the loops
    run over the columns innermost, so that the compiler can vectorise them. A non-positive
    pivot gives NaN entries, an overflow inf: never an exception.
    """
    members = out.shape[0]
    rows = out.shape[2]
    n = base.shape[0]
    mean, cov, low, inv, ex = 0, n, n + n * n, n + 2 * n * n, n + 3 * n * n  # rows of work
    for a in range(n):
        for r in range(rows):
            work[mean + a, r] = 0.0
        for m in range(members):
            for r in range(rows):
                work[mean + a, r] += out[m, a * (n + 1) + n, r]
        for r in range(rows):
            work[mean + a, r] /= members
    for a in range(n):
        for b in range(a + 1):
            row = cov + a * n + b
            for r in range(rows):
                work[row, r] = 0.0
            for m in range(members):
                for c in range(n):
                    for r in range(rows):
                        work[row, r] += out[m, a * (n + 1) + c, r] * out[m, b * (n + 1) + c, r]
                for r in range(rows):
                    work[row, r] += (out[m, a * (n + 1) + n, r] - work[mean + a, r]) * (
                        out[m, b * (n + 1) + n, r] - work[mean + b, r]
                    )
            for r in range(rows):
                work[row, r] /= members
    for a in range(n):
        for r in range(rows):
            work[ex, r] = 0.0
        for m in range(members):
            for r in range(rows):
                work[ex, r] += exps[m, a, r]
        for r in range(rows):
            work[cov + a * n + a, r] += work[ex, r] / members
    for i in range(n):
        for j in range(i + 1):
            for r in range(rows):
                dot = 0.0
                for p in range(j):
                    dot += work[low + i * n + p, r] * work[low + j * n + p, r]
                s = work[cov + i * n + j, r] - dot
                if i == j:
                    work[low + i * n + i, r] = math.sqrt(s) if s > 0.0 else math.nan
                else:
                    work[low + i * n + j, r] = s / work[low + j * n + j, r]
    for j in range(n):
        for r in range(rows):
            work[inv + j * n + j, r] = 1.0 / work[low + j * n + j, r]
        for i in range(j + 1, n):
            for r in range(rows):
                dot = 0.0
                for p in range(j, i):
                    dot += work[low + i * n + p, r] * work[inv + p * n + j, r]
                work[inv + i * n + j, r] = -dot / work[low + i * n + i, r]
    for r in range(rows):
        for i in range(n):
            for j in range(n):
                shapes[r, i * n + j] = work[inv + i * n + j, r] * inv_sigma[j] if j <= i else 0.0
        for a in range(n):
            centers[r, a] = base[a, r] + sigma[a] * work[mean + a, r]


@_compiled
def standardise(
    x: FloatArray, yhat: FloatArray, mean: FloatArray, scale: FloatArray
) -> FloatArray:  # pragma: no cover - compiled
    """``(concat(x, yhat) - mean) * scale`` (R, d + n) in one pass, as the one-query kernel computes it."""
    rows, d = x.shape
    n = yhat.shape[1]
    z = np.empty((rows, d + n))
    for r in range(rows):
        for i in range(d):
            z[r, i] = (x[r, i] - mean[i]) * scale[i]
        for a in range(n):
            z[r, d + a] = (yhat[r, a] - mean[d + a]) * scale[d + a]
    return z


def clamped_exp2(log_diag: FloatArray, clamp: float) -> FloatArray:
    """``exp(2 clip(h, -clamp, clamp))`` elementwise, as a new array (NaN kept).

    In NumPy, whose vectorised ``exp`` is several times faster than a compiled loop of libm's:
    the batch path's exponentials. The one-query kernel computes the same numbers with libm
    (the two may differ in the last bit).

    Parameters
    ----------
    log_diag : ndarray
        The log-diagonal outputs ``h`` (float64, any shape; not modified).
    clamp : float
        The bound of the clip (``LOGDIAG_CLAMP``).

    Examples
    --------
    >>> clamped_exp2(np.array([0.0, 1.0, 50.0]), 2.0).round(3).tolist()  # exp(0), exp(2), exp(4)
    [1.0, 7.389, 54.598]
    """
    out = np.maximum(log_diag, -clamp)  # np.clip's semantics without its Python-level overhead
    np.minimum(out, clamp, out=out)
    out *= 2.0
    return np.exp(out, out=out)


@_compiled
def lowrank_sets(
    out: FloatArray,
    exps: FloatArray,
    lin: FloatArray,
    yhat: FloatArray,
    lin_bias: FloatArray,
    sigma: FloatArray,
    inv_sigma: FloatArray,
    centers: FloatArray,
    shapes: FloatArray,
) -> None:  # pragma: no cover - compiled
    """Every set of a batch from every member's ``[U | h]`` (K, ·, R), written in place.

    ``exps`` (K, n, R) is :func:`clamped_exp2` of the log-diagonal rows of ``out``, ``lin``
    (n, R) the linear stage's product, ``yhat`` (R, n) the estimates; ``centers``
    (R, n) and ``shapes`` (R, n * n) receive the sets: :func:`_set_columns` with ``base =
    (yhat + lin) + lin_bias``, the one-query kernel's arithmetic column by column.
    """
    n, rows = lin.shape
    base = np.empty((n, rows))
    for a in range(n):
        for r in range(rows):
            base[a, r] = (yhat[r, a] + lin[a, r]) + lin_bias[a]
    work = np.empty((n + 3 * n * n + 1, rows))
    _set_columns(out, exps, base, sigma, inv_sigma, centers, shapes, work)


@_compiled
def bias_activate(h: FloatArray, bias: FloatArray, code: int) -> None:  # pragma: no cover - compiled
    """In place, one pass: ``h = activation(h + bias)`` for ``h`` (W, R) and ``bias`` (W,).

    ``code`` is one of :data:`ACTIVATION_CODES`, or ``-1`` for the bias alone. The same numbers
    as NumPy's ``h += bias[:, None]`` and then the activation, in half the memory traffic.
    """
    w, rows = h.shape
    for j in range(w):
        b = bias[j]
        if code < 0:
            for r in range(rows):
                h[j, r] += b
        elif code == 0:
            for r in range(rows):
                v = h[j, r] + b
                h[j, r] = 0.0 if v < 0.0 else v  # NaN kept, as np.maximum keeps it
        else:
            for r in range(rows):
                h[j, r] = _activate(h[j, r] + b, code)


@_compiled
def bias_skip_add(h: FloatArray, bias: FloatArray, skip: FloatArray) -> None:  # pragma: no cover - compiled
    """In place, one pass: ``h = (h + bias) + skip`` for ``h`` and ``skip`` (W, R), ``bias`` (W,)."""
    w, rows = h.shape
    for j in range(w):
        b = bias[j]
        for r in range(rows):
            h[j, r] = (h[j, r] + b) + skip[j, r]


@_compiled
def rcond_lower_3(
    s: FloatArray, rel: float, tiny: float, normal: float
) -> FloatArray:  # pragma: no cover - compiled
    """Per 3x3 matrix of ``s`` (B, 3, 3): ``|det C|`` lowered by its rounding bound over
    ``||C||_F ||adj C||_F``, times ``1 - 1e-12``; 0 where ``det``, ``||C||_F^2`` or
    ``||adj C||_F^2`` is not a normal number (or NaN). ``rel`` is the relative rounding bound of
    the determinant (times the permanent of ``|C|``), ``tiny`` the absolute one (times the largest
    ``|C_0j|``). See :func:`ipcverify.network.nonsingular` for why it is a lower bound of
    ``sigma_min / sigma_max``.
    """
    res = np.empty(s.shape[0])
    for r in range(s.shape[0]):
        a, b, c = s[r, 0, 0], s[r, 0, 1], s[r, 0, 2]
        d, e, f = s[r, 1, 0], s[r, 1, 1], s[r, 1, 2]
        g, h, i = s[r, 2, 0], s[r, 2, 1], s[r, 2, 2]
        k00, k01, k02 = e * i - f * h, f * g - d * i, d * h - e * g
        k10, k11, k12 = c * h - b * i, a * i - c * g, b * g - a * h
        k20, k21, k22 = b * f - c * e, c * d - a * f, a * e - b * d
        det = abs(a * k00 + b * k01 + c * k02)
        aa, ab, ac = abs(a), abs(b), abs(c)
        perm = aa * (abs(e * i) + abs(f * h))
        perm += ab * (abs(f * g) + abs(d * i))
        perm += ac * (abs(d * h) + abs(e * g))
        big = aa if aa > ab else ab
        big = big if big > ac else ac
        det -= rel * perm + tiny * big
        adj2 = k00 * k00 + k01 * k01 + k02 * k02 + k10 * k10 + k11 * k11 + k12 * k12
        adj2 += k20 * k20 + k21 * k21 + k22 * k22
        c2 = 0.0
        for p in range(3):
            for q in range(3):
                c2 += s[r, p, q] * s[r, p, q]
        shown = det >= normal and c2 >= normal and adj2 >= normal and c2 < math.inf and adj2 < math.inf
        res[r] = det / (math.sqrt(c2) * math.sqrt(adj2)) * (1.0 - 1e-12) if shown else 0.0
    return res
