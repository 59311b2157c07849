"""Compiled kernels of the domain test (:mod:`ipcverify.guard._domain`, :mod:`ipcverify.guard._index`).

Compiled by Numba as :mod:`ipcverify.network._kernels` compiles (:func:`ipcverify.network.compiled`: no
``fastmath``, NumPy's error model, cached on disk):

* :func:`whiten_one` and :func:`whiten_rows` -- ``(z - mean) @ W^T``, each entry summed in index
  order, so that a query gets the same bits alone, in any batch and inside the search kernels;
* :func:`domain_rows` and :func:`domain_one` -- a k-d tree search that stops at the ``k``-th
  reference within the threshold (:func:`_decide`), for a batch and for one query (which first
  asks what the previous query left: its witness, or a Lipschitz bound);
* :func:`scan_rows` and :func:`kth_rows` -- the threshold test and the ``k``-th neighbour
  distance from a float32 BLAS product ``[w, 1] @ [-2 r_j; ||r_j||^2]``, with every pair its
  rounding bound does not settle recomputed in float64.

The rounding arguments are in ``proofs/domain.md``.

Examples
--------
>>> import numpy as np
>>> refs = np.array([[1.0, 0.0], [0.0, 1.0]])
>>> w = whiten_rows(np.array([[1.0], [3.0]]), np.array([[0.0], [0.0]]), np.zeros(2), np.eye(2))
>>> bool((w == [whiten_one(np.array([1.0, 0.0]), np.zeros(2), np.eye(2)), [3.0, 0.0]]).all())
True
>>> g = (np.hstack([w, np.ones((2, 1))]) @ np.vstack([-2.0 * refs.T, [[1.0, 1.0]]])).astype(np.float32)
>>> kth_rows(g, g.min(axis=1), w, refs, 2, np.full(2, 1e-5)).tolist()  # squared distance, 2nd nearest
[2.0, 10.0]
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ipcverify.network._kernels import compiled

FloatArray = NDArray[np.float64]


@compiled
def _whiten_into(
    x: FloatArray, y: FloatArray, mean: FloatArray, whitening_t: FloatArray, w: FloatArray
) -> None:
    """``w = (concat(x, y) - mean) @ whitening_t``, each entry summed in index order (in place)."""
    d = x.shape[0]
    dw = whitening_t.shape[1]
    for j in range(dw):
        w[j] = 0.0
    for i in range(d):
        a = x[i] - mean[i]
        for j in range(dw):
            w[j] += a * whitening_t[i, j]
    for i in range(y.shape[0]):
        a = y[i] - mean[d + i]
        for j in range(dw):
            w[j] += a * whitening_t[d + i, j]


@compiled
def whiten_one(z: FloatArray, mean: FloatArray, whitening_t: FloatArray) -> FloatArray:  # pragma: no cover
    """``(z - mean) @ whitening_t`` for one query, each product summed in index order."""
    w = np.empty(whitening_t.shape[1])
    _whiten_into(z, z[:0], mean, whitening_t, w)
    return w


#: Rows whitened together by :func:`_whiten_block` (queries as columns, so that the loop vectorises).
_BLOCK = 64


@compiled
def _whiten_block(
    x: FloatArray, yhat: FloatArray, start: int, mean: FloatArray, whitening_t: FloatArray, w: FloatArray
) -> int:  # pragma: no cover - compiled
    """Rows ``start ...`` (at most ``_BLOCK``) whitened into ``w`` (``_BLOCK``, D); returns how many.

    Each entry gets :func:`_whiten_into`'s operations in its order (a sum from 0.0 over the
    inputs in index order), computed for the block's rows side by side.
    """
    rows = min(_BLOCK, x.shape[0] - start)
    d, n, dw = x.shape[1], yhat.shape[1], whitening_t.shape[1]
    acc = np.zeros((dw, _BLOCK))
    a = np.empty(_BLOCK)
    for i in range(d + n):
        for r in range(rows):
            a[r] = (x[start + r, i] - mean[i]) if i < d else (yhat[start + r, i - d] - mean[i])
        for j in range(dw):
            c = whitening_t[i, j]
            for r in range(rows):
                acc[j, r] += a[r] * c
    for r in range(rows):
        for j in range(dw):
            w[r, j] = acc[j, r]
    return rows


@compiled
def whiten_rows(
    x: FloatArray, yhat: FloatArray, mean: FloatArray, whitening_t: FloatArray
) -> FloatArray:  # pragma: no cover
    """Each row's ``(concat(x, yhat) - mean) @ whitening_t``: :func:`whiten_one`'s numbers, row by row."""
    out = np.empty((x.shape[0], whitening_t.shape[1]))
    w = np.empty((_BLOCK, whitening_t.shape[1]))
    for start in range(0, x.shape[0], _BLOCK):
        rows = _whiten_block(x, yhat, start, mean, whitening_t, w)
        out[start : start + rows] = w[:rows]
    return out


@compiled
def _gap2(w: FloatArray, boxes: FloatArray, node: int) -> float:  # pragma: no cover - compiled
    """Squared distance from ``w`` to the bounding box of ``node`` (``boxes[node] = (lo, hi, split)``)."""
    dim = w.shape[0]
    s = 0.0
    for d in range(dim):
        g = max(boxes[node, d] - w[d], w[d] - boxes[node, dim + d], 0.0)
        s += g * g
    return s


@compiled
def _dist2(w: FloatArray, refs: FloatArray, j: int) -> float:  # pragma: no cover - compiled
    """``sum_d (w_d - r_jd)^2`` in index order."""
    s = 0.0
    for d in range(w.shape[0]):
        v = w[d] - refs[j, d]
        s += v * v
    return s


@compiled
def _decide(
    w: FloatArray, refs: FloatArray, nodes: NDArray[np.int64], boxes: FloatArray,
    t2_in: float, t2_out: float, k: int, budget: int, stack: NDArray[np.int64],
) -> tuple[int, float]:  # fmt: skip  # pragma: no cover - compiled
    """Is the ``k``-th nearest reference of ``w`` within the threshold? A k-d tree search that stops early.

    ``nodes`` rows are ``(start, end, left, right, split dimension)`` over ``refs`` (sorted by
    leaf), ``boxes`` rows the nodes' bounding boxes ``(lo, hi)`` and split value. A reference
    counts as inside when its squared distance is at most ``t2_in``, as possibly inside when at
    most ``t2_out``; a node whose box lies farther than ``t2_out`` is skipped. Returns ``(1,
    j)``: ``k`` references inside, the last one ``refs[j]``; ``(0, low)``: fewer than ``k``
    references even possibly inside, and every other reference at squared distance ``>= low``
    (as computed); ``(-1, 0)``: undecided (references between the two levels); ``(-2, 0)``:
    more than ``budget`` leaves would be scanned.
    """
    dim = w.shape[0]
    for d in range(dim):
        if not math.isfinite(w[d]):
            return 0, math.inf
    inside = 0
    maybe = 0
    leaves = 0
    low = math.inf
    top = 1
    stack[0] = 0
    while top > 0:
        top -= 1
        node = stack[top]
        g = _gap2(w, boxes, node)
        if g > t2_out:
            low = min(low, g)
            continue
        left = nodes[node, 2]
        while left >= 0:  # down to the leaf on w's side, the other children kept for later
            if w[nodes[node, 4]] < boxes[node, 2 * dim]:
                stack[top] = nodes[node, 3]
                node = left
            else:
                stack[top] = left
                node = nodes[node, 3]
            top += 1
            left = nodes[node, 2]
        if leaves == budget:
            return -2, 0.0
        leaves += 1
        for j in range(nodes[node, 0], nodes[node, 1]):
            s = _dist2(w, refs, j)
            if s <= t2_in:
                inside += 1
                if inside >= k:
                    return 1, float(j)
            elif s <= t2_out:
                maybe += 1
            else:
                low = min(low, s)
    return (-1, 0.0) if inside + maybe >= k else (0, low)


@compiled
def domain_rows(
    x: FloatArray, yhat: FloatArray, mean: FloatArray, whitening_t: FloatArray, refs: FloatArray,
    nodes: NDArray[np.int64], boxes: FloatArray, t2_in: float, t2_out: float, k: int, budget: int,
    depth: int,
) -> NDArray[np.int8]:  # fmt: skip  # pragma: no cover - compiled
    """Per row: whiten as :func:`whiten_rows`, then :func:`_decide`'s code (1, 0, -1 or -2).

    With ``k = 1`` a row first tries the reference that proved the previous row inside (as
    :func:`domain_one` does for one query): rows of a log in time order move little, and a
    reference within ``t2_in`` proves "inside" whichever it is.
    """
    codes = np.empty(x.shape[0], np.int8)
    w = np.empty((_BLOCK, whitening_t.shape[1]))
    stack = np.empty(depth + 2, np.int64)
    witness = -1  # the reference that proved the previous row inside (k = 1): rows of a log move little
    for start in range(0, x.shape[0], _BLOCK):
        rows = _whiten_block(x, yhat, start, mean, whitening_t, w)
        for r in range(rows):
            if witness >= 0 and _dist2(w[r], refs, witness) <= t2_in:
                codes[start + r] = 1
                continue
            code, value = _decide(w[r], refs, nodes, boxes, t2_in, t2_out, k, budget, stack)
            codes[start + r] = code
            witness = int(value) if code == 1 and k == 1 else witness
    return codes


#: Slots of :func:`domain_one`'s ``state``: what the previous query left, the levels and settings,
#: then the previous and the current whitened point (D floats each).
_KIND, _VALUE, _T2_IN, _T2_OUT, _K, _BUDGET, _POINTS = 0, 1, 2, 3, 4, 5, 6


@compiled
def domain_one(
    z: FloatArray, affine: FloatArray, refs: FloatArray, nodes: NDArray[np.int64], boxes: FloatArray,
    state: FloatArray, stack: NDArray[np.int64],
) -> int:  # fmt: skip  # pragma: no cover - compiled
    """One query ``z``: :func:`domain_rows`'s code, answered from the previous query where that is sound.

    ``affine`` stacks the mean over the transposed whitening (``(D + 1, D)``; the whitening of
    :func:`whiten_one`); ``state`` (``6 + 2 D`` floats, one call's arguments kept few: each costs
    the caller time) holds ``t2_in``, ``t2_out``, ``k`` and the search budget, and what the
    previous decided query left: ``state[0] = 1`` and its witness ``refs[state[1]]`` (``k = 1``),
    checked first; or ``state[0] = 2``, a lower bound ``state[1]`` of its ``k``-th neighbour
    distance and its whitened point: the distance is 1-Lipschitz, so a query within
    ``state[1] - sqrt(t2_out)`` of that point is outside too. ``state[0] = 0``: nothing kept.
    """
    dim = affine.shape[1]
    t2_in, t2_out = state[_T2_IN], state[_T2_OUT]
    k, budget = int(state[_K]), int(state[_BUDGET])
    prev = state[_POINTS : _POINTS + dim]
    w = state[_POINTS + dim : _POINTS + 2 * dim]
    _whiten_into(z, z[:0], affine[0], affine[1:], w)
    kind = state[_KIND]
    if kind == 1.0:
        if _dist2(w, refs, int(state[_VALUE])) <= t2_in:
            return 1
    elif kind == 2.0:
        step = 0.0
        for d in range(dim):
            v = w[d] - prev[d]
            step += v * v
        if state[_VALUE] - math.sqrt(step) * (1.0 + 1e-12) > math.sqrt(t2_out):
            return 0
    code, value = _decide(w, refs, nodes, boxes, t2_in, t2_out, k, budget, stack)
    state[_KIND] = 0.0
    if code == 1 and k == 1:
        state[_KIND], state[_VALUE] = 1.0, value
    elif code == 0 and value < math.inf:
        state[_KIND], state[_VALUE] = 2.0, math.sqrt(value) * (1.0 - 1e-12)
        prev[:] = w
    return code


@compiled
def scan_rows(
    g: NDArray[np.float32], least: NDArray[np.float32], w: FloatArray, refs: FloatArray, t2_in: float,
    t2_out: float, k: int, slack: FloatArray,
) -> NDArray[np.int8]:  # fmt: skip  # pragma: no cover - compiled
    """:func:`_decide`'s codes (1, 0 or -1) from a float32 product ``g = [w, 1] @ columns``.

    ``g[i, j] + ||w_i||^2`` is the squared distance from ``w_i`` to ``refs[j]`` up to
    ``slack[i]`` (the caller's rounding bound); a pair the bound does not settle, or whose value
    is NaN, is recomputed in float64 as :func:`_decide` computes it. ``least[i]`` is the smallest
    ``g[i, j]`` (NaN if any is NaN: NumPy's ``min``): a row whose smallest value is surely beyond
    the threshold is outside at once.
    """
    rows, m = g.shape
    codes = np.empty(rows, np.int8)
    for i in range(rows):
        ww = 0.0
        for d in range(w.shape[1]):
            ww += w[i, d] * w[i, d]
        out_cut, in_cut = t2_out + slack[i], t2_in - slack[i]
        if least[i] + ww > out_cut:  # every reference surely beyond the threshold (False if NaN)
            codes[i] = 0
            continue
        inside = 0
        maybe = 0
        for j in range(m):
            v = g[i, j] + ww
            if v > out_cut:
                continue
            if v <= in_cut:
                inside += 1
            else:
                s = _dist2(w[i], refs, j)
                if s <= t2_in:
                    inside += 1
                elif s <= t2_out:
                    maybe += 1
            if inside >= k:
                break
        codes[i] = 1 if inside >= k else (0 if inside + maybe < k else -1)
    return codes


@compiled
def _insert(best: FloatArray, v: float) -> None:  # pragma: no cover - compiled
    """Insert ``v`` into the ascending ``best`` if it is smaller than its last entry (the largest drops)."""
    p = best.shape[0] - 1
    if not v < best[p]:
        return
    while p > 0 and best[p - 1] > v:
        best[p] = best[p - 1]
        p -= 1
    best[p] = v


@compiled
def kth_rows(
    g: NDArray[np.float32],
    least: NDArray[np.float32],
    w: FloatArray,
    refs: FloatArray,
    k: int,
    slack: FloatArray,
) -> FloatArray:  # pragma: no cover - compiled
    """Each row's ``k``-th smallest of ``sum_d (w_id - r_jd)^2`` (float64, index order) over all ``j``.

    The float32 product ``g`` (as in :func:`scan_rows`, with ``least`` its rows' minima) picks
    the candidates: every ``j`` whose value is within ``2 slack[i]`` of the ``k``-th smallest
    value; only those are computed in float64. NaN for a row with a NaN value (the caller decides
    it otherwise).
    """
    rows, m = g.shape
    out = np.empty(rows)
    best = np.empty(k)
    for i in range(rows):
        ww = 0.0
        for d in range(w.shape[1]):
            ww += w[i, d] * w[i, d]
        if k == 1:
            nan = least[i] != least[i]
            best[0] = least[i] + ww
        else:
            best[:] = math.inf
            nan = False
            for j in range(m):  # the k smallest values, sorted
                v = g[i, j] + ww
                nan |= v != v
                _insert(best, v)
        if nan:
            out[i] = math.nan
            continue
        # candidates: g + ww <= best + 2 slack, as a float32 level a little beyond (a superset)
        cut = best[k - 1] + 2.0 * slack[i] - ww
        level = np.float32(cut + 1e-6 * (abs(cut) + ww) + 1e-300)
        best[:] = math.inf
        row = g[i]
        full = m - m % 64
        for s in range(0, full, 64):  # a vectorised count per block of 64, then the block's candidates
            hits = np.int32(0)
            for j in range(64):
                hits += np.int32(row[s + j] <= level)
            if hits:
                for j in range(s, s + 64):
                    if row[j] <= level:
                        _insert(best, _dist2(w[i], refs, j))
        for j in range(full, m):
            if row[j] <= level:
                _insert(best, _dist2(w[i], refs, j))
        out[i] = best[k - 1]
    return out
