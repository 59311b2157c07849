"""The domain of validity of a calibrated contract: a conformal out-of-distribution test.

Every certificate ipcverify issues assumes that deployment queries are exchangeable with
the calibration samples. :class:`DomainModel` makes that assumption checkable per query:
it is fitted on the calibration inputs ``z = (x, yhat)`` and flags a query whose distance
to the calibration inputs is larger than the calibration inputs' own distances are,
except for a share ``flag_rate``.

* **Distance.** ``z`` is whitened with the calibration inputs' mean and covariance (an
  eigenvalue floor keeps near-constant directions from dominating), and the score of a
  query is its Euclidean distance to its ``k``-th nearest calibration input.
* **Threshold (conformal, leave-one-out).** On the ``n`` *distinct* calibration inputs, each one's
  score is its distance to its ``k``-th nearest other; the threshold is the
  ``ceil((n + 1)(1 - flag_rate))``-th smallest of these scores, and never 0 (:func:`_positive`).
* **Guarantee.** If a query is exchangeable with the ``n`` calibration inputs, it is
  flagged with probability at most ``flag_rate`` (proof: ``proofs/domain.md``). A range check
  alone cannot do this: a query can lie inside every column's range and far from all data.
* **Evaluation.** :meth:`DomainModel.contains` answers "score <= threshold" without computing
  the score: a k-d tree search that stops at the ``k``-th reference within the threshold, a
  float32 BLAS product with a rigorous rounding bound, the exact test only within a relative
  ``1e-9`` of the threshold (:mod:`ipcverify.guard._index`) -- the exact test's answer for
  every query, at about a leaf of the tree per in-distribution query.

A flagged query is *outside the domain of validity*: the calibration certificate promises nothing
for it. The test says nothing about queries it does not flag -- no finite sample can certify that
the world did not change; the online monitor (:mod:`ipcverify.guard._monitor`) watches for that.
:class:`DomainReport` (:mod:`ipcverify.guard._domain_report`) counts the queries of a batch outside
the domain, :func:`~ipcverify.guard._neighbours.other_group_distances` the leave-one-group-out scores.

Examples
--------
>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> x, yhat = rng.normal(size=(2000, 2)), rng.normal(size=(2000, 3))
>>> dom = DomainModel.fit(x, yhat, flag_rate=0.01)
>>> dom.contains(x[:5] * 0.5, yhat[:5] * 0.5).tolist()
[True, True, True, True, True]
>>> bool(dom.contains(np.full((1, 2), 8.0), np.zeros((1, 3)))[0])   # far from every sample
False
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from ipcverify._wording._spelling import Remedy, flag_rate_floor, option
from ipcverify.calibration._bounds import (
    marginal_conformal_index,
    min_calibration_size,
    smallest_marginal_epsilon,
)
from ipcverify.calibration._risk_control import risk_control_threshold
from ipcverify.data._dataset import query_rows
from ipcverify.data._fingerprints import first_distinct_rows
from ipcverify.data._split import group_codes
from ipcverify.errors import DataError, InvalidInputError, SampleSizeError
from ipcverify.guard._domain_report import DomainReport
from ipcverify.guard._index import BAND, MAX_INPUTS, DomainIndex, levels
from ipcverify.guard._kernels import domain_one, whiten_one, whiten_rows
from ipcverify.guard._neighbours import other_group_distances

FloatArray = NDArray[np.float64]

#: Default flag rate of the domain test (the share of in-distribution queries it flags).
DEFAULT_FLAG_RATE = 0.01
#: Default neighbour rank: the distance to the nearest calibration input (chosen on the real log and
#: synthetic shifts: docs/domain.md).
DEFAULT_K = 1
#: Most calibration inputs kept as the reference (a seeded random subset beyond that).
MAX_REFERENCE = 10_000
#: Eigenvalues of the whitening covariance below this share of the largest are raised to it.
EIGEN_FLOOR = 1e-6
METHOD = "conformal k-nearest-neighbour distance on whitened (x, yhat), leave-one-out threshold"
GROUP_METHOD = (
    "conformal k-nearest-neighbour distance on whitened (x, yhat), leave-one-group-out threshold "
    "(conformal risk control over the calibration groups)"
)


def _stack(x: ArrayLike, yhat: ArrayLike) -> FloatArray:
    xa, ya = query_rows(x), query_rows(yhat)
    if xa.ndim != 2 or ya.ndim != 2 or len(xa) != len(ya):
        raise InvalidInputError(
            f"domain test: x and yhat must be (B, d) and (B, n) with the same B; got {xa.shape}, {ya.shape}"
        )
    return np.concatenate([xa, ya], axis=1)


def _positive(threshold: float, scores: FloatArray) -> float:
    """The threshold, or if it is 0 the smallest positive score (it flags less: ``proofs/domain.md``)."""
    if threshold <= 0 and not (scores > 0).any():
        raise DataError("domain test: the whitened calibration inputs lie at distance 0 from each other in "
                        "float64, so no radius can be set; calibrate on data whose inputs vary")  # fmt: skip
    return threshold if threshold > 0 else float(scores[scores > 0].min())


@dataclass(frozen=True, eq=False)
class DomainModel:
    """A fitted domain-of-validity test (build it with :meth:`fit`).

    Attributes
    ----------
    mean : ndarray, shape (D,)
        Mean of the calibration inputs ``z = (x, yhat)``.
    whitening : ndarray, shape (D, D)
        ``W`` with ``W^T W = Sigma^{-1}`` (floored): distances are ``||W (z - z')||``.
    reference : ndarray, shape (m, D)
        The whitened calibration inputs.
    k : int
        Neighbour rank of the score.
    flag_rate : float
        False-alarm rate the threshold was set for.
    threshold : float
        Queries with a score above it are outside the domain.
    n : int
        Calibration inputs used (``m``).
    method : str
        The test in words.
    n_groups : int or None
        With a group-aware threshold (:meth:`fit` with ``groups``): the number of calibration
        groups; None for the row-level threshold.
    """

    mean: FloatArray
    whitening: FloatArray
    reference: FloatArray
    k: int
    flag_rate: float
    threshold: float
    n: int
    method: str = METHOD
    n_groups: int | None = None
    _tree: Any = field(default=None, init=False, repr=False)
    _wt: Any = field(default=None, init=False, repr=False)
    _search: Any = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        mean = np.array(self.mean, dtype=np.float64)
        w = np.array(self.whitening, dtype=np.float64)
        ref = np.ascontiguousarray(self.reference, dtype=np.float64)
        D = mean.shape[0] if mean.ndim == 1 else -1
        if mean.ndim != 1 or w.shape != (D, D) or ref.ndim != 2 or ref.shape[1] != D:
            raise InvalidInputError(
                f"domain model: inconsistent shapes mean {mean.shape}, whitening {w.shape}, "
                f"reference {ref.shape}"
            )
        if not (np.isfinite(mean).all() and np.isfinite(w).all() and np.isfinite(ref).all()):
            raise InvalidInputError("domain model: non-finite entries")
        if not (1 <= self.k < len(ref)) or self.n != len(ref):
            raise InvalidInputError(f"domain model: need 1 <= k < n = {len(ref)}; got k={self.k}")
        if not (0.0 < self.flag_rate < 1.0) or not (math.isfinite(self.threshold) and self.threshold >= 0):
            raise InvalidInputError("domain model: flag_rate must lie in (0, 1) and the threshold be finite")
        if self.n_groups is not None and not (2 <= self.n_groups <= self.n):
            raise InvalidInputError(f"domain model: need 2 <= n_groups <= n = {self.n}; got {self.n_groups}")
        for name, value in (("mean", mean), ("whitening", w), ("reference", ref)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "_tree", cKDTree(ref))
        object.__setattr__(self, "_wt", np.ascontiguousarray(w.T))
        # built on first use: the index; per thread, domain_one's arguments after the query (its
        # state and search stack are the thread's own: the kernel runs without the GIL)
        object.__setattr__(self, "_search", [None, threading.local()])

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without the search structures (rebuilt on first use; thread-local state cannot be)."""
        state = dict(self.__dict__)
        state["_search"] = None
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        object.__setattr__(self, "_search", [None, threading.local()])

    # ------------------------------------------------------------------- fitting
    @classmethod
    def fit(
        cls,
        x: ArrayLike,
        yhat: ArrayLike,
        *,
        flag_rate: float = DEFAULT_FLAG_RATE,
        k: int = DEFAULT_K,
        max_reference: int = MAX_REFERENCE,
        seed: int = 0,
        groups: ArrayLike | None = None,
    ) -> DomainModel:
        """Fit the test on calibration inputs (leave-one-out conformal threshold at ``flag_rate``).

        With ``groups`` (one label per input: flight, run, sequence) the inputs of one group are
        correlated and a new group's queries lie farther from the calibration inputs than the
        inputs of a calibration group lie from each other; a row-level threshold then flags far
        more than ``flag_rate`` of a new group's queries. The score of each calibration input is
        its distance to the ``k``-th nearest input of *another* group, and the threshold is
        set by conformal risk control over the groups
        (:func:`~ipcverify.calibration.risk_control_threshold`): if the groups are
        exchangeable, the expected share of a new group's queries flagged is at most ``flag_rate``
        (``proofs/domain.md``).

        Raises
        ------
        SampleSizeError
            If there are too few inputs for ``flag_rate`` (``n >= (1 - flag_rate) / flag_rate`` is needed),
            or with ``groups`` too few groups (``G >= 1 / flag_rate - 1``).

        Examples
        --------
        >>> rng = np.random.default_rng(1)
        >>> flight = np.repeat(np.arange(150), 20)  # 150 flights, each with its own offset
        >>> z = rng.normal(size=(150, 4))[flight] + 0.1 * rng.normal(size=(3000, 4))
        >>> rows = DomainModel.fit(z[:, :2], z[:, 2:], flag_rate=0.05)
        >>> by_flight = DomainModel.fit(z[:, :2], z[:, 2:], flag_rate=0.05, groups=flight)
        >>> new = rng.normal(size=(200, 4))[np.repeat(np.arange(200), 5)] + 0.1 * rng.normal(size=(1000, 4))
        >>> float((~rows.contains(new[:, :2], new[:, 2:])).mean()) > 0.2     # far above flag_rate
        True
        >>> float((~by_flight.contains(new[:, :2], new[:, 2:])).mean()) < 0.1
        True
        """
        z = _stack(x, yhat)
        if not np.isfinite(z).all():
            raise InvalidInputError("domain test: calibration inputs must be finite")
        if not (isinstance(k, (int, np.integer)) and k >= 1):
            raise InvalidInputError(f"domain test: k must be a positive integer; got {k!r}")
        if not (isinstance(flag_rate, (int, float)) and 0.0 < flag_rate < 1.0):
            raise InvalidInputError(
                f"domain test: {option('flag_rate')} must lie strictly between 0 and 1; got {flag_rate!r}"
            )
        labels = None if groups is None else np.asarray(groups)
        if labels is not None and labels.shape != (len(z),):
            raise InvalidInputError(
                f"domain test: {len(z)} calibration inputs but groups of shape {labels.shape}"
            )
        keep = first_distinct_rows(z)  # a repeated input is one point (of its first group)
        if len(keep) > max_reference:
            keep = keep[np.sort(np.random.default_rng(seed).choice(len(keep), max_reference, replace=False))]
        z, labels = z[keep], None if labels is None else labels[keep]
        n = len(z)
        need = min_calibration_size(flag_rate, 0.5, "marginal")  # ceil((1 - flag_rate) / flag_rate), exactly
        if n < max(need, k + 1):
            smallest = smallest_marginal_epsilon(n)
            raise SampleSizeError(
                f"the domain test at flag rate {flag_rate:g} needs at least {max(need, k + 1)} calibration "
                f"inputs; got {n} -- use more calibration data or a larger {option('flag_rate')}"
                + ("" if n < k + 1 else f" ({flag_rate_floor(n, 'inputs', smallest)})"),
                remedies=() if n < k + 1 else (Remedy("flag_rate", smallest),),
            )
        mean = z.mean(axis=0)
        cov = np.atleast_2d(np.cov(z, rowvar=False))
        vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
        top = max(float(vals[-1]), 1e-300)
        vals = np.maximum(vals, EIGEN_FLOOR * top)
        whitening = (vecs / np.sqrt(vals)).T  # rows: scaled principal directions
        ref = (z - mean) @ whitening.T
        tree = cKDTree(ref)
        if labels is not None:
            codes, distinct = group_codes(labels, "domain test groups")
            scores = other_group_distances(tree, ref, codes, k)
            try:
                threshold, _ = risk_control_threshold(scores, codes, flag_rate)
            except SampleSizeError:
                smallest = smallest_marginal_epsilon(len(distinct))
                raise SampleSizeError(
                    f"the group-aware domain test at flag rate {flag_rate:g} needs at least "
                    f"{math.ceil(1 / flag_rate - 1)} groups; got {len(distinct)} -- use more groups "
                    f"(flights, runs) or a larger {option('flag_rate')} "
                    f"({flag_rate_floor(len(distinct), 'groups', smallest)})",
                    remedies=(Remedy("flag_rate", smallest),),
                ) from None
            return cls(mean=mean, whitening=whitening, reference=ref, k=int(k), flag_rate=float(flag_rate),
                       threshold=_positive(threshold, scores), n=n, method=GROUP_METHOD,
                       n_groups=len(distinct))  # fmt: skip
        dist, _ = tree.query(ref, k=k + 1)  # the first neighbour is the point itself
        loo = np.asarray(dist, dtype=np.float64).reshape(n, k + 1)[:, k]
        rank = marginal_conformal_index(n, flag_rate)
        threshold = _positive(float(np.partition(loo, rank - 1)[rank - 1]), loo)
        return cls(mean=mean, whitening=whitening, reference=ref, k=int(k), flag_rate=float(flag_rate),
                   threshold=threshold, n=n)  # fmt: skip

    # ------------------------------------------------------------------- queries
    def index(self) -> DomainIndex:
        """The search structure of the fast test (:mod:`ipcverify.guard._index`), built on first use."""
        search = self._search
        if search[0] is None:
            search[0] = DomainIndex.build(self.reference)
        return search[0]  # type: ignore[no-any-return]

    def _one_args(self) -> tuple[Any, ...]:
        """This thread's arguments of :func:`~ipcverify.guard.domain_one` after the query."""
        local = self._search[1]
        args = getattr(local, "args", None)
        if args is None:
            index = self.index()
            # the layout of domain_kernels.domain_one's state: kind, value, t2_in, t2_out, k, budget,
            # then the previous and the current whitened point
            state = np.zeros(6 + 2 * len(self.mean))
            # no search budget for one query: scanning every leaf in the compiled call (tens of µs at
            # worst) costs less than the float32 product's Python path for one row
            state[2:6] = (*levels(self.threshold), self.k, len(index.nodes))
            affine = np.vstack([self.mean, self._wt])
            args = (affine, index.refs, index.nodes, index.boxes, state, np.zeros(index.depth + 2, np.int64))
            local.args = args
        return args  # type: ignore[no-any-return]

    def _rows(self, x: ArrayLike, yhat: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """``x`` and ``yhat`` as C-contiguous float64 (B, d) and (B, n), checked against the model."""
        xa = np.ascontiguousarray(x, dtype=np.float64)
        ya = np.ascontiguousarray(yhat, dtype=np.float64)
        xa, ya = (xa[None] if xa.ndim == 1 else xa), (ya[None] if ya.ndim == 1 else ya)
        if xa.ndim != 2 or ya.ndim != 2 or len(xa) != len(ya):
            raise InvalidInputError(
                f"domain test: x and yhat must be (B, d) and (B, n) with the same B; got {xa.shape}, "
                f"{ya.shape}"
            )
        if xa.shape[1] + ya.shape[1] != len(self.mean):
            raise InvalidInputError(
                f"domain test: queries have {xa.shape[1] + ya.shape[1]} columns of (x, yhat) but the domain "
                f"model was fitted on {len(self.mean)}"
            )
        return xa, ya

    def whiten(self, x: ArrayLike, yhat: ArrayLike) -> FloatArray:
        """The whitened queries ``W (z - mean)`` (B, D), as every test of this model computes them.

        Each entry is summed in index order (:func:`ipcverify.network._kernels.whiten_rows`), so a query gets
        the same bits alone or in any batch, and in :meth:`contains_one`.
        """
        xa, ya = self._rows(x, yhat)
        return np.asarray(whiten_rows(xa, ya, self.mean, self._wt))

    def _exact(self, w: FloatArray) -> FloatArray:
        """SciPy's k-d tree on whitened rows: the exact test's k-th neighbour distance (inf if not finite)."""
        out = np.full(len(w), np.inf)
        ok = np.isfinite(w).all(axis=1)
        if ok.any():
            out[ok] = np.asarray(self._tree.query(w[ok], k=[self.k])[0], dtype=np.float64)[:, 0]
        return out

    def distance(self, x: ArrayLike, yhat: ArrayLike) -> FloatArray:
        """Each query's score: whitened distance to its ``k``-th nearest calibration input (B,).

        Computed in float64 from the candidates a float32 product picks
        (:meth:`DomainIndex.kth <ipcverify.guard.DomainIndex.kth>`; the exact test's value to
        the last bits), and by the exact test itself (SciPy's k-d tree) for a query the product
        cannot bound or whose distance lies within a relative ``1e-9`` of the threshold, so that
        ``distance <= threshold`` is exactly :meth:`contains`. Non-finite queries get ``inf``.
        """
        w = self.whiten(x, yhat)
        out = np.full(len(w), np.inf)
        ok = np.flatnonzero(np.isfinite(w).all(axis=1))
        if len(ok):
            d = self.index().kth(w[ok], self.k)
            t = self.threshold
            unsure = np.isnan(d)
            unsure[~unsure] = np.abs(d[~unsure] - t) <= BAND * t
            redo = np.flatnonzero(unsure)
            if len(redo):
                d[redo] = self._exact(w[ok[redo]])
            out[ok] = d
        return out

    def contains(self, x: ArrayLike, yhat: ArrayLike) -> NDArray[np.bool_]:
        """Boolean mask (B,): the query is inside the domain of validity (score <= threshold).

        Exactly the exact test's answer (SciPy's k-d tree on the whitened query), reached in
        three tiers (:mod:`ipcverify.guard._index`): a compiled k-d tree search that stops at the
        ``k``-th reference within the threshold, a float32 BLAS product with a rigorous rounding
        bound for queries the search would take long over, and the exact test for a query with a
        reference within a relative ``1e-9`` of the threshold (``proofs/domain.md``). Non-finite
        queries are outside.
        """
        xa, ya = self._rows(x, yhat)
        index = self.index()
        codes = index.decide(xa, ya, self.mean, self._wt, self.threshold, self.k)
        over = np.flatnonzero(codes == -2)
        if len(over):
            w = whiten_rows(xa[over], ya[over], self.mean, self._wt)
            codes[over] = index.scan(w, self.threshold, self.k)
        band = np.flatnonzero(codes == -1)
        if len(band):
            w = whiten_rows(xa[band], ya[band], self.mean, self._wt)
            codes[band] = self._exact(w) <= self.threshold
        return np.asarray(codes == 1, dtype=np.bool_)

    def contains_one(self, z: FloatArray) -> bool:
        """One query given as the concatenated 1-D ``(x, yhat)`` (the single-query path).

        The answer of :meth:`contains` for this query (the same whitened bits, the same test), in
        one compiled call (:func:`ipcverify.guard.domain_one`: the search without a
        budget, since one query's float32 product would cost more in Python than the scan of
        every leaf) unless the query is within the 1e-9 band and needs the exact test. The call
        first asks the previous query: the reference that proved it inside (``k = 1``), or, after
        an outside answer, the 1-Lipschitz bound of the distance (a control loop's queries move
        little between frames).
        """
        if z.shape != self.mean.shape:
            raise InvalidInputError(
                f"domain test: one query is a 1-D (x, yhat) of length {len(self.mean)}; got shape {z.shape}"
            )
        code = domain_one(z, *self._one_args()) if len(z) <= MAX_INPUTS else -2
        if code >= 0:
            return bool(code == 1)
        w = whiten_one(np.asarray(z, dtype=np.float64), self.mean, self._wt)[None]
        code = int(self.index().scan(w, self.threshold, self.k)[0]) if code == -2 else code
        return bool(code == 1 or (code == -1 and self._exact(w)[0] <= self.threshold))

    def forget(self) -> None:
        """Drop what :meth:`contains_one` kept of this thread's previous query (answers do not change)."""
        self._one_args()[-2][0] = 0.0  # state[0]: nothing kept

    def prepare(self) -> None:
        """Build the index and compile (or load from Numba's cache) :meth:`contains_one`'s kernels now."""
        # a fresh writable array, as contains_one receives (the kernel is compiled per layout)
        self.contains_one(np.array(self.mean, dtype=np.float64))
        self.forget()

    # ------------------------------------------------------------- reporting
    def report(
        self, x: ArrayLike, yhat: ArrayLike, violated: NDArray[np.bool_] | None = None
    ) -> DomainReport:
        """How many of a batch of queries lie outside the domain (and, with labels, how they fared).

        Parameters
        ----------
        x, yhat : array_like
            The queries.
        violated : bool array, optional
            Whether each query's truth fell outside its set; counts the violations inside and
            outside the domain.
        """
        return self.summarize_outside(~self.contains(x, yhat), violated)

    def summarize(self, distance: FloatArray, violated: NDArray[np.bool_] | None = None) -> DomainReport:
        """:meth:`report` from distances already computed by :meth:`distance`."""
        return self.summarize_outside(~(np.asarray(distance, dtype=np.float64) <= self.threshold), violated)

    def summarize_outside(
        self, outside: NDArray[np.bool_], violated: NDArray[np.bool_] | None = None
    ) -> DomainReport:
        """:meth:`report` from the flags already computed (``outside = ~contains``)."""
        out = np.asarray(outside, dtype=bool)
        v = None if violated is None else np.asarray(violated, dtype=bool)
        return DomainReport(
            method=self.method,
            flag_rate=self.flag_rate,
            threshold=self.threshold,
            n_reference=self.n,
            n=len(out),
            outside=int(out.sum()),
            violations_inside=None if v is None else int((v & ~out).sum()),
            violations_outside=None if v is None else int((v & out).sum()),
        )

    def describe(self) -> DomainReport:
        """The test itself, for a certificate without test queries (``n = 0``)."""
        return DomainReport(
            method=self.method,
            flag_rate=self.flag_rate,
            threshold=self.threshold,
            n_reference=self.n,
            n=0,
            outside=0,
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the model file (the reference as a nested list is avoided: see modelio)."""
        return {
            "method": self.method,
            "k": self.k,
            "flag_rate": self.flag_rate,
            "threshold": self.threshold,
            "n": self.n,
            "mean": self.mean.tolist(),
            "whitening": self.whitening.tolist(),
            "reference": self.reference,
            "n_groups": self.n_groups,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> DomainModel:
        """Inverse of :meth:`to_dict` (``reference`` may be an array or a tensor's numpy view)."""
        return cls(
            mean=np.asarray(data["mean"], dtype=np.float64),
            whitening=np.asarray(data["whitening"], dtype=np.float64),
            reference=np.asarray(data["reference"], dtype=np.float64),
            k=int(data["k"]),
            flag_rate=float(data["flag_rate" if "flag_rate" in data else "alpha"]),  # "alpha": earlier files
            threshold=float(data["threshold"]),
            n=int(data["n"]),
            method=str(data.get("method", METHOD)),
            n_groups=None if data.get("n_groups") is None else int(data["n_groups"]),
        )
