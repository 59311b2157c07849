"""The domain test's threshold question at forward-pass speed: a k-d tree that stops early, a
float32 product for what the tree does not settle quickly, and the exact test for the rest.

A :class:`~ipcverify.guard.DomainModel` flags a query when its ``k``-th nearest whitened
calibration input is farther than the threshold ``t``. Deployment asks only that question, not
the distance, and for an in-distribution query it has a cheap answer: ``k`` references within
``t`` prove "inside", wherever the nearest one is. :class:`DomainIndex` answers it in three
tiers, each only where it is sure, so that every query gets the answer of the exact test (SciPy's
k-d tree on the same whitened point, ``DomainModel.distance <= t``; ``proofs/domain.md``):

1. **Tree** (:func:`ipcverify.network._kernels.domain_rows`, one compiled call per batch). A k-d tree
   over the references (median splits along the widest side, leaves of :data:`LEAF_SIZE`,
   every node with its bounding box) is searched from the query's own leaf outwards: a
   reference at squared distance at most ``t_in^2`` counts as inside and the search stops at
   the ``k``-th; a node whose box lies beyond ``t_out`` is skipped. ``t_in`` and ``t_out`` are
   ``t`` moved by the relative margin :data:`BAND` = 1e-9, a million times the rounding of a
   float64 distance, so every answer the tree gives is the exact test's. In-distribution
   queries need about one leaf.
2. **Product** (:meth:`DomainIndex.scan`). A query whose search would scan more than
   ``budget`` leaves (far outside, or near the boundary in a sparse region) is tested against
   every reference with one float32 BLAS product per block of rows, ``[w, 1] @ [-2 r_j;
   ||r_j||^2]``, and a rigorous bound on its rounding for any summation order (BLAS may reorder
   and fuse); a pair the bound does not settle is recomputed in float64.
3. **Exact.** A query with a reference inside the margin band goes to SciPy's tree.

:meth:`DomainIndex.kth` computes the distance itself the same way (the float32 product picks
the candidates, float64 decides): the exact ``k``-th neighbour distance at BLAS speed.

Examples
--------
>>> rng = np.random.default_rng(0)
>>> ref = rng.normal(size=(500, 3))
>>> index = DomainIndex.build(ref)
>>> w = rng.normal(size=(4, 3))
>>> exact = np.sort(np.linalg.norm(w[:, None] - ref[None], axis=2), axis=1)[:, 0]
>>> bool(np.allclose(index.kth(w, 1), exact, rtol=1e-14, atol=0.0))
True
>>> index.scan(w, float(exact[0]) * 2.0, 1).tolist()[0]   # well within twice its own distance
1
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ipcverify.errors import InvalidInputError
from ipcverify.guard._kernels import domain_rows, kth_rows, scan_rows

FloatArray = NDArray[np.float64]

#: References per leaf of the k-d tree.
LEAF_SIZE = 16
#: The fast tiers answer only when the distance is at least this far (relative) from the threshold.
BAND = 1e-9
#: Tier 1 answers only up to this many inputs: its float64 rounding, ``(D + 2) u``, stays far inside
#: the band (``proofs/domain.md``); with more, every query goes to tiers 2 and 3.
MAX_INPUTS = 1000
#: Rounding bound of the float32 product, per unit of ``(max ||r_j|| + ||w||)^2``: ``(D + 6) u32``
#: suffices (``proofs/domain.md``), so up to ``D = 161`` inputs; beyond, tier 2 is skipped.
SCAN_BOUND = 1e-5
_U32 = 2.0**-24
#: Whitened queries farther out than this skip the float32 product (it could overflow).
MAX_NORM = 1e15
#: Rows per float32 product are chosen so that the block of products is about this many bytes.
BLOCK_BYTES = 1 << 20


@functools.cache
def _controller() -> Any:
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - a dependency; kept optional for minimal installs
        return None
    return ThreadpoolController()


def one_blas_thread() -> contextlib.AbstractContextManager[Any]:
    """A context in which NumPy's BLAS runs on one thread (threadpoolctl; about 10 µs to enter).

    The domain test's products, and the batch engine's, are many small products of blocks sized
    to the cache: a second BLAS thread only adds its wake-up to each (NumPy's default is one
    thread per core; on 2 shared cores a 10^6-row ``ipcverify predict`` took minutes instead of
    seconds: ``benchmarks/guard_results.json``).

    Examples
    --------
    >>> with one_blas_thread():
    ...     float((np.ones((4, 4)) @ np.ones(4))[0])
    4.0
    """
    controller = _controller()
    if controller is None:  # pragma: no cover
        return contextlib.nullcontext()
    return controller.limit(limits=1, user_api="blas")  # type: ignore[no-any-return]


def levels(threshold: float) -> tuple[float, float]:
    """``(t (1 - BAND))^2`` and ``(t (1 + BAND))^2``: the squared levels the fast tiers decide at.

    Parameters
    ----------
    threshold : float
        The threshold ``t``.

    Examples
    --------
    >>> lo, hi = levels(2.0)
    >>> lo < 4.0 < hi, round(hi - lo, 12)
    (True, 1.6e-08)
    """
    return (threshold * (1.0 - BAND)) ** 2, (threshold * (1.0 + BAND)) ** 2


@dataclass(frozen=True, eq=False)
class DomainIndex:
    """The search structures of one reference set (build it with :meth:`build`).

    Attributes
    ----------
    refs : ndarray, shape (m, D)
        The references in leaf order (``refs = reference[order]``).
    order : ndarray of int, shape (m,)
    nodes : ndarray of int64, shape (N, 5)
        Per node: first and last + 1 reference, left and right child (-1 for a leaf), split
        dimension.
    boxes : ndarray, shape (N, 2 D + 1)
        Per node: its references' smallest and largest coordinates, and the split value (the
        right child's references have coordinates at least that along the split dimension).
    depth : int
        Largest number of edges from the root to a leaf.
    columns : float32 ndarray, shape (D + 1, m)
        ``-2 r_j`` stacked over ``||r_j||^2`` (leaf order), for tier 2.
    max_norm : float
        ``max ||r_j||``, rounded up.
    budget : int
        Leaves the tree may scan for one query before it hands the query to tier 2.
    """

    refs: FloatArray
    order: NDArray[np.intp]
    nodes: NDArray[np.int64]
    boxes: FloatArray
    depth: int
    columns: NDArray[np.float32]
    max_norm: float
    budget: int

    @classmethod
    def build(
        cls, reference: FloatArray, leaf_size: int = LEAF_SIZE, budget: int | None = None
    ) -> DomainIndex:
        """The k-d tree and the float32 columns of ``reference`` (finite, shape (m, D)).

        ``budget`` defaults to the leaves that hold a quarter of the references (at least 8): a
        search that needs more has lost the tree's advantage (a query far in a sparse direction, or
        more inputs than a k-d tree can split usefully), and one float32 product over every
        reference costs about as much as scanning that many leaves. A smaller budget sends more
        queries near the boundary to the product, whose fixed cost per call then dominates
        (measured on the benchmark's workloads: ``benchmarks/bench_latency.py``).
        """
        ref = np.ascontiguousarray(reference, dtype=np.float64)
        if ref.ndim != 2 or len(ref) == 0 or not np.isfinite(ref).all() or leaf_size < 1:
            raise InvalidInputError("domain index: the references must be a finite, non-empty (m, D) array")
        m, dim = ref.shape
        order = np.arange(m)
        spans: list[tuple[int, int]] = [(0, m)]
        children: list[tuple[int, int, int]] = [(-1, -1, 0)]
        split_values: list[float] = [0.0]
        level = [0]
        todo = [0]
        while todo:
            node = todo.pop()
            start, end = spans[node]
            if end - start <= leaf_size:
                continue
            pts = ref[order[start:end]]
            axis = int(np.argmax(pts.max(axis=0) - pts.min(axis=0)))
            mid = (start + end) // 2
            part = np.argpartition(pts[:, axis], mid - start)
            order[start:end] = order[start:end][part]
            left, right = len(spans), len(spans) + 1
            spans += [(start, mid), (mid, end)]
            children += [(-1, -1, 0), (-1, -1, 0)]
            split_values += [0.0, 0.0]
            level += [level[node] + 1] * 2
            children[node] = (left, right, axis)
            split_values[node] = float(ref[order[mid], axis])
            todo += [left, right]
        refs = np.ascontiguousarray(ref[order])
        nodes = np.array([(s, e, *c) for (s, e), c in zip(spans, children, strict=True)], dtype=np.int64)
        boxes = np.empty((len(spans), 2 * dim + 1))
        for i, (s, e) in enumerate(spans):
            boxes[i, :dim] = refs[s:e].min(axis=0)
            boxes[i, dim : 2 * dim] = refs[s:e].max(axis=0)
            boxes[i, 2 * dim] = split_values[i]
        sq = np.einsum("ij,ij->i", refs, refs)
        columns = np.concatenate([-2.0 * refs.T, sq[None, :]], axis=0).astype(np.float32)
        leaves = -(-m // leaf_size)
        return cls(
            refs=refs,
            order=order,
            nodes=nodes,
            boxes=boxes,
            depth=max(level),
            columns=np.ascontiguousarray(columns),
            max_norm=float(np.sqrt(sq.max())) * (1.0 + 1e-12),
            budget=max(8, leaves // 4) if budget is None else int(budget),
        )

    # ------------------------------------------------------------------ tier 1
    def decide(
        self,
        x: FloatArray,
        yhat: FloatArray,
        mean: FloatArray,
        whitening_t: FloatArray,
        threshold: float,
        k: int,
    ) -> NDArray[np.int8]:
        """Tier 1 for raw rows ``(x, yhat)`` (float64, C-contiguous): codes 1 (inside), 0 (outside),
        -1 (a reference inside the margin band) or -2 (over budget, or more than
        :data:`MAX_INPUTS` inputs); non-finite rows are outside.

        The rows are whitened in the compiled call, with the arithmetic of
        :func:`ipcverify.network._kernels.whiten_rows`.
        """
        if whitening_t.shape[1] > MAX_INPUTS:
            return np.full(len(x), -2, dtype=np.int8)
        t2_in, t2_out = levels(threshold)
        return np.asarray(
            domain_rows(
                x,
                yhat,
                mean,
                whitening_t,
                self.refs,
                self.nodes,
                self.boxes,
                t2_in,
                t2_out,
                k,
                self.budget,
                self.depth,
            )  # fmt: skip
        )

    # ------------------------------------------------------------------ tier 2
    def _blocks(
        self, w: FloatArray
    ) -> Iterator[tuple[int, int, NDArray[np.float32], NDArray[np.float32], FloatArray]]:
        """Per block of rows: its bounds, the float32 products ``[w, 1] @ columns``, their rows'
        minima (NaN if any product is) and the rows' slack.

        One block at a time, so that its products are still in the cache when they are read.
        """
        m = self.columns.shape[1]
        dim = w.shape[1]
        rows = max(1, BLOCK_BYTES // (4 * m))
        with np.errstate(over="ignore", invalid="ignore"):  # far-out rows: inf, then excluded below
            norm = np.sqrt(np.einsum("ij,ij->i", w, w))
            slack = SCAN_BOUND * (self.max_norm + norm) ** 2
        if (dim + 6) * _U32 > SCAN_BOUND:  # the bound does not cover so many inputs
            slack[:] = np.nan
        slack[~(norm < MAX_NORM)] = np.nan
        for start in range(0, len(w), rows):
            stop = min(len(w), start + rows)
            w1 = np.ones((stop - start, dim + 1), dtype=np.float32)
            w1[:, :dim] = np.where(np.isnan(slack[start:stop, None]), 0.0, w[start:stop])
            g = w1 @ self.columns
            yield start, stop, g, g.min(axis=1), slack[start:stop]

    def scan(self, w: FloatArray, threshold: float, k: int) -> NDArray[np.int8]:
        """Tier 2 for whitened rows ``w`` (B, D): codes 1, 0 or -1 (undecided: the exact test decides).

        One float32 product per block of rows (about :data:`BLOCK_BYTES` of products, on one BLAS
        thread: :func:`one_blas_thread`), with the
        rounding bound :data:`SCAN_BOUND` ``(max ||r_j|| + ||w||)^2`` for any summation order; the
        pairs it does not settle are recomputed in float64 by :func:`ipcverify.network._kernels.scan_rows`.
        """
        w = np.ascontiguousarray(w, dtype=np.float64)
        codes = np.full(len(w), -1, dtype=np.int8)
        t2_in, t2_out = levels(threshold)
        with one_blas_thread():
            self._scan(w, t2_in, t2_out, k, codes)
        return codes

    def _scan(self, w: FloatArray, t2_in: float, t2_out: float, k: int, codes: NDArray[np.int8]) -> None:
        for start, stop, g, least, slack in self._blocks(w):
            ok = ~np.isnan(slack)
            if ok.all():
                codes[start:stop] = scan_rows(g, least, w[start:stop], self.refs, t2_in, t2_out, k, slack)
            elif ok.any():
                sub = np.flatnonzero(ok)
                codes[start + sub] = scan_rows(np.ascontiguousarray(g[sub]), least[sub], w[start + sub],
                                               self.refs, t2_in, t2_out, k, slack[sub])  # fmt: skip

    def kth(self, w: FloatArray, k: int) -> FloatArray:
        """The ``k``-th nearest reference's distance for whitened rows ``w`` (B, D), NaN where not computed.

        The float32 product picks, per row, the references within twice its rounding bound of the
        ``k``-th smallest value; their squared distances are computed in float64
        (:func:`ipcverify.network._kernels.kth_rows`). NaN for rows the bound does not cover (far out).
        """
        w = np.ascontiguousarray(w, dtype=np.float64)
        out = np.full(len(w), np.nan)
        if k > self.refs.shape[0]:
            raise InvalidInputError(f"domain index: k = {k} exceeds the {self.refs.shape[0]} references")
        with one_blas_thread():
            for start, _, g, least, slack in self._blocks(w):
                ok = np.flatnonzero(~np.isnan(slack))
                if len(ok):
                    rows = g if len(ok) == len(g) else np.ascontiguousarray(g[ok])
                    out[start + ok] = np.sqrt(
                        kth_rows(rows, least[ok], w[start + ok], self.refs, k, slack[ok])
                    )
        return out

    def prune_stats(self) -> dict[str, int]:
        """Sizes of the structure: references, nodes, leaves, depth, budget (for reports)."""
        leaves = int((self.nodes[:, 2] < 0).sum())
        return {"references": len(self.refs), "nodes": len(self.nodes), "leaves": leaves,
                "depth": self.depth, "budget": self.budget}  # fmt: skip
