"""The domain of validity of a calibrated contract: a conformal out-of-distribution test.

Every certificate ipcverify issues assumes that deployment queries are exchangeable with
the calibration samples. :class:`DomainModel` makes that assumption checkable per query:
it is fitted on the calibration inputs ``z = (x, yhat)`` and flags a query whose distance
to the calibration inputs is larger than the calibration inputs' own distances are,
except for a share ``alpha``.

* **Distance.** ``z`` is whitened with the calibration inputs' mean and covariance (an
  eigenvalue floor keeps near-constant directions from dominating), and the score of a
  query is its Euclidean distance to its ``k``-th nearest calibration input.
* **Threshold (conformal, leave-one-out).** Each calibration input's score is its distance
  to its ``k``-th nearest *other* calibration input; the threshold is the
  ``ceil((n + 1)(1 - alpha))``-th smallest of these ``n`` scores.
* **Guarantee.** If a query is exchangeable with the ``n`` calibration inputs, it is
  flagged with probability at most ``alpha`` (proof: ``proofs/domain.md``). A range check
  alone cannot do this: a query can lie inside every column's range and far from all data.

A flagged query is *outside the domain of validity*: the calibration certificate promises
nothing for it. The test says nothing, either way, about queries it does not flag -- no
finite sample can certify that the world did not change; the online monitor
(:mod:`ipcverify.monitor`) watches for that.

Examples
--------
>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> x, yhat = rng.normal(size=(2000, 2)), rng.normal(size=(2000, 3))
>>> dom = DomainModel.fit(x, yhat, alpha=0.01)
>>> dom.contains(x[:5] * 0.5, yhat[:5] * 0.5).tolist()
[True, True, True, True, True]
>>> bool(dom.contains(np.full((1, 2), 8.0), np.zeros((1, 3)))[0])   # far from every sample
False
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats
from scipy.spatial import cKDTree

from ipcverify.bounds import marginal_conformal_index
from ipcverify.calibration.grouped import risk_control_threshold
from ipcverify.data import group_codes
from ipcverify.errors import InvalidInputError, SampleSizeError
from ipcverify.kernels import scan_kth, whiten_one

__all__ = [
    "DEFAULT_ALPHA",
    "DEFAULT_K",
    "MAX_REFERENCE",
    "DomainModel",
    "DomainReport",
    "other_group_distances",
]

FloatArray = NDArray[np.float64]

#: Default false-alarm rate of the domain test (share of in-distribution queries flagged).
DEFAULT_ALPHA = 0.01
#: Default neighbour rank: the distance to the nearest calibration input (chosen on the real log and
#: synthetic shifts: docs/domain.md).
DEFAULT_K = 1
#: Most calibration inputs kept as the reference (a seeded random subset beyond that).
MAX_REFERENCE = 10_000
#: Eigenvalues of the whitening covariance below this share of the largest are raised to it.
EIGEN_FLOOR = 1e-6
#: Level of the one-sided binomial test behind "far more queries outside than false alarms explain".
WELL_ABOVE_LEVEL = 1e-3
METHOD = "conformal k-nearest-neighbour distance on whitened (x, yhat), leave-one-out threshold"
GROUP_METHOD = (
    "conformal k-nearest-neighbour distance on whitened (x, yhat), leave-one-group-out threshold "
    "(conformal risk control over the calibration groups)"
)
#: contains_one answers from a cached or float32 distance only this far (relative) from the threshold.
_ABOVE, _BELOW = 1.0 + 1e-9, 1.0 - 1e-9
_STEP_SLACK = 1.0 + 1e-12  # covers the rounding of a 15-ish-term float64 distance
#: Rounding bound of the float32 scan, per unit of (max ||r|| + ||w||)^2: (D + 6) u32 suffices (_Scan).
_SCAN_BOUND = 1e-5
_U32 = 2.0**-24
_SCAN_MAX_NORM = 1e15  # whitened queries farther out than this go to the tree


@dataclass(frozen=True, eq=False)
class _Scan:
    """All reference points in float32, to bound every squared distance at once.

    ``d_j^2 = ||r_j||^2 - 2 r_j.w + ||w||^2``: the first two terms are one float32 product of
    ``(w, 1)`` with the columns ``(-2 r_j, ||r_j||^2)``. Rounding ``r``, ``||r||^2`` and ``w`` to
    float32 and every operation of the product (``D + 1`` terms, each rounding ``<= u32 = 2^-24``
    relative, ``|r.w| <= ||r|| ||w||``) changes the result by at most ``(D + 5) u32 (R + ||w||)^2``
    with ``R = max ||r_j||``, and the ``k``-th smallest of the values by no more.
    ``_SCAN_BOUND = 1e-5`` covers ``(D + 6) u32`` up to ``D = 161`` inputs (beyond, the scan is
    skipped); the float64 ``R`` is rounded up by a relative ``1e-12``.
    """

    columns: NDArray[np.float32]  # (D + 1, m): -2 r_j stacked over ||r_j||^2
    max_norm: float

    @classmethod
    def of(cls, ref: FloatArray) -> _Scan:
        sq = np.einsum("ij,ij->i", ref, ref)
        cols = np.concatenate([-2.0 * ref.T, sq[None, :]], axis=0)
        return cls(
            np.ascontiguousarray(cols, dtype=np.float32),
            float(np.sqrt(sq.max())) * (1.0 + 1e-12) if len(sq) else 0.0,
        )

    def kth(self, w: FloatArray, k: int) -> tuple[float, float] | None:
        """Lower and upper bounds of the ``k``-th smallest distance ``||r_j - w||`` (None: too far out).

        The products are one call of :func:`ipcverify.kernels.scan_kth`.
        """
        norm = math.hypot(*w.tolist())  # scaled internally: a far-out query cannot overflow here
        if not norm < _SCAN_MAX_NORM or (len(w) + 6) * _U32 > _SCAN_BOUND:
            return None
        ww = norm * norm
        kth = float(scan_kth(w, self.columns, k)) + ww
        if kth != kth:
            return None
        slack = _SCAN_BOUND * (self.max_norm + math.sqrt(ww)) ** 2
        return math.sqrt(max(kth - slack, 0.0)), math.sqrt(kth + slack)


def _stack(x: ArrayLike, yhat: ArrayLike) -> FloatArray:
    xa = np.asarray(x, dtype=np.float64)
    ya = np.asarray(yhat, dtype=np.float64)
    if xa.ndim == 1:
        xa = xa[None]
    if ya.ndim == 1:
        ya = ya[None]
    if xa.ndim != 2 or ya.ndim != 2 or len(xa) != len(ya):
        raise InvalidInputError(
            f"domain test: x and yhat must be (B, d) and (B, n) with the same B; got {xa.shape}, {ya.shape}"
        )
    return np.concatenate([xa, ya], axis=1)


def other_group_distances(tree: cKDTree, points: FloatArray, codes: NDArray[np.intp], k: int) -> FloatArray:
    """Distance from each of the tree's points to its ``k``-th nearest point of another group.

    ``points`` are the tree's data and ``codes`` their groups. Neighbours are fetched in
    growing batches until ``k`` of another group are among them, so small groups cost one
    query and a point deep inside a large group a few more.

    Examples
    --------
    >>> pts = np.array([[0.0], [0.1], [1.0], [3.0]])
    >>> other_group_distances(cKDTree(pts), pts, np.array([0, 0, 1, 1]), 1).tolist()
    [1.0, 0.9, 0.9, 2.9]
    """
    n = len(points)
    out = np.full(n, np.inf)
    todo = np.arange(n)
    m = min(n, k + 1 + int(np.bincount(codes).min()))
    while todo.size:
        dist, idx = tree.query(points[todo], k=m)
        dist, idx = dist.reshape(len(todo), m), idx.reshape(len(todo), m)
        other = codes[idx] != codes[todo][:, None]
        found = np.cumsum(other, axis=1) >= k
        done = found.any(axis=1)
        first = np.argmax(found, axis=1)
        out[todo[done]] = dist[done, first[done]]
        if m == n:  # fewer than k points of other groups: no finite distance
            break
        todo, m = todo[~done], min(n, 2 * m)
    return out


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
    alpha : float
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
    alpha: float
    threshold: float
    n: int
    method: str = METHOD
    n_groups: int | None = None
    _tree: Any = field(default=None, init=False, repr=False)
    _wt: Any = field(default=None, init=False, repr=False)
    _scan: Any = field(default=None, init=False, repr=False)
    _last: Any = field(default=None, init=False, repr=False, compare=False)

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
        if not (0.0 < self.alpha < 1.0) or not (math.isfinite(self.threshold) and self.threshold >= 0):
            raise InvalidInputError("domain model: alpha must lie in (0, 1) and the threshold be finite")
        if self.n_groups is not None and not (2 <= self.n_groups <= self.n):
            raise InvalidInputError(f"domain model: need 2 <= n_groups <= n = {self.n}; got {self.n_groups}")
        for name, value in (("mean", mean), ("whitening", w), ("reference", ref)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "_tree", cKDTree(ref))
        object.__setattr__(self, "_wt", np.ascontiguousarray(w.T))
        object.__setattr__(self, "_scan", _Scan.of(ref))
        object.__setattr__(self, "_last", [None])

    # ------------------------------------------------------------------- fitting
    @classmethod
    def fit(
        cls,
        x: ArrayLike,
        yhat: ArrayLike,
        *,
        alpha: float = DEFAULT_ALPHA,
        k: int = DEFAULT_K,
        max_reference: int = MAX_REFERENCE,
        seed: int = 0,
        groups: ArrayLike | None = None,
    ) -> DomainModel:
        """Fit the test on calibration inputs (leave-one-out conformal threshold at ``alpha``).

        With ``groups`` (one label per input: flight, run, sequence) the inputs of one group are
        correlated and a new group's queries lie farther from the calibration inputs than the
        inputs of a calibration group lie from each other; a row-level threshold then flags far
        more than ``alpha`` of a new group's queries. The score of each calibration input is
        its distance to the ``k``-th nearest input of *another* group, and the threshold is
        set by conformal risk control over the groups
        (:func:`~ipcverify.calibration.grouped.risk_control_threshold`): if the groups are
        exchangeable, the expected share of a new group's queries flagged is at most ``alpha``
        (``proofs/domain.md``).

        Raises
        ------
        SampleSizeError
            If there are too few inputs for ``alpha`` (``n >= (1 - alpha) / alpha`` is needed),
            or with ``groups`` too few groups (``G >= 1 / alpha - 1``).

        Examples
        --------
        >>> rng = np.random.default_rng(1)
        >>> flight = np.repeat(np.arange(150), 20)  # 150 flights, each with its own offset
        >>> z = rng.normal(size=(150, 4))[flight] + 0.1 * rng.normal(size=(3000, 4))
        >>> rows = DomainModel.fit(z[:, :2], z[:, 2:], alpha=0.05)
        >>> by_flight = DomainModel.fit(z[:, :2], z[:, 2:], alpha=0.05, groups=flight)
        >>> new = rng.normal(size=(200, 4))[np.repeat(np.arange(200), 5)] + 0.1 * rng.normal(size=(1000, 4))
        >>> float((~rows.contains(new[:, :2], new[:, 2:])).mean()) > 0.2     # far above alpha
        True
        >>> float((~by_flight.contains(new[:, :2], new[:, 2:])).mean()) < 0.1
        True
        """
        z = _stack(x, yhat)
        if not np.isfinite(z).all():
            raise InvalidInputError("domain test: calibration inputs must be finite")
        if not (isinstance(k, (int, np.integer)) and k >= 1):
            raise InvalidInputError(f"domain test: k must be a positive integer; got {k!r}")
        if not (isinstance(alpha, (int, float)) and 0.0 < alpha < 1.0):
            raise InvalidInputError(f"domain test: alpha must lie strictly between 0 and 1; got {alpha!r}")
        labels = None if groups is None else np.asarray(groups)
        if labels is not None and labels.shape != (len(z),):
            raise InvalidInputError(
                f"domain test: {len(z)} calibration inputs but groups of shape {labels.shape}"
            )
        if len(z) > max_reference:
            keep = np.sort(np.random.default_rng(seed).choice(len(z), max_reference, replace=False))
            z = z[keep]
            labels = None if labels is None else labels[keep]
        n = len(z)
        need = math.ceil((1.0 - alpha) / alpha)
        if n < max(need, k + 1):
            raise SampleSizeError(
                f"the domain test at alpha={alpha:g} needs at least {max(need, k + 1)} calibration inputs; "
                f"got {n} -- use more calibration data or a larger --domain-alpha"
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
                threshold, _ = risk_control_threshold(scores, codes, alpha)
            except SampleSizeError:
                raise SampleSizeError(
                    f"the group-aware domain test at alpha={alpha:g} needs at least "
                    f"{math.ceil(1 / alpha - 1)} groups; got {len(distinct)} -- use more groups "
                    "(flights, runs) or a larger --domain-alpha"
                ) from None
            return cls(mean=mean, whitening=whitening, reference=ref, k=int(k), alpha=float(alpha),
                       threshold=threshold, n=n, method=GROUP_METHOD, n_groups=len(distinct))  # fmt: skip
        dist, _ = tree.query(ref, k=k + 1)  # the first neighbour is the point itself
        loo = np.asarray(dist, dtype=np.float64).reshape(n, k + 1)[:, k]
        rank = marginal_conformal_index(n, alpha)
        threshold = float(np.partition(loo, rank - 1)[rank - 1])
        return cls(mean=mean, whitening=whitening, reference=ref, k=int(k), alpha=float(alpha),
                   threshold=threshold, n=n)  # fmt: skip

    # ------------------------------------------------------------------- queries
    def _whiten(self, z: FloatArray) -> FloatArray:
        if z.shape[1] != len(self.mean):
            raise InvalidInputError(
                f"domain test: queries have {z.shape[1]} columns of (x, yhat) but the domain model was "
                f"fitted on {len(self.mean)}"
            )
        return np.asarray((z - self.mean) @ self.whitening.T)

    def distance(self, x: ArrayLike, yhat: ArrayLike) -> FloatArray:
        """Each query's score: whitened distance to its ``k``-th nearest calibration input (B,).

        Non-finite queries get ``inf``.
        """
        z = _stack(x, yhat)
        ok = np.isfinite(z).all(axis=1)
        out = np.full(len(z), np.inf)
        if ok.any():
            d, _ = self._tree.query(self._whiten(z[ok]), k=[self.k])
            out[ok] = np.asarray(d, dtype=np.float64)[:, 0]
        return out

    def contains(self, x: ArrayLike, yhat: ArrayLike) -> NDArray[np.bool_]:
        """Boolean mask (B,): the query is inside the domain of validity (score <= threshold)."""
        return np.asarray(self.distance(x, yhat) <= self.threshold, dtype=np.bool_)

    def contains_one(self, z: FloatArray) -> bool:
        """One query given as the concatenated 1-D ``(x, yhat)`` (the single-query path).

        The answer of :meth:`contains` for this query alone (the ``k``-th neighbour distance, as
        the tree computes it, is at most the threshold; a larger batch's matrix product may whiten
        a query an ulp differently), reached cheaply in three steps:

        1. the ``k``-th neighbour distance is 1-Lipschitz in the query, so the previous query's
           distance ``d'`` decides when ``|d' - threshold|`` exceeds the step ``||w - w'||`` (a
           control loop's queries move little between frames);
        2. otherwise a float32 scan of all references, ``||r||^2 - 2 r.w + ||w||^2``, decides when
           its rigorous rounding bound (``_Scan``) clears the threshold;
        3. otherwise the tree decides, by the very computation of :meth:`contains`.

        Steps 1 and 2 answer only with a relative margin of ``1e-9`` to the threshold, a million
        times the rounding of the tree's own distance, so the answer is always :meth:`contains`'s.
        """
        if z.shape != self.mean.shape:
            raise InvalidInputError(
                f"domain test: one query is a 1-D (x, yhat) of length {len(self.mean)}; got shape {z.shape}"
            )
        # one cheap sum in Python floats when finite (it cannot raise: a huge finite row sums to
        # inf, and then the exact test decides)
        if not math.isfinite(sum(z.tolist())) and not np.isfinite(z).all():
            return False
        w = whiten_one(z, self.mean, self._wt)
        t = self.threshold
        last = self._last[0]
        if last is not None:  # step 1
            w_prev, d_lo, d_hi = last
            step = math.dist(w.tolist(), w_prev) * _STEP_SLACK
            if d_lo - step > t * _ABOVE:
                return False
            if d_hi + step < t * _BELOW:
                return True
        scan = self._scan.kth(w, self.k)  # step 2: (lower, upper) bounds of the k-th distance, or None
        if scan is not None:
            d_lo, d_hi = scan
            inside = d_hi < t * _BELOW
            if inside or d_lo > t * _ABOVE:
                self._last[0] = (w.tolist(), d_lo, d_hi)
                return inside
        # step 3: exactly the computation of distance() (a bounded tree query can differ by an ulp)
        d, _ = self._tree.query(self._whiten(z[None]), k=[self.k])
        self._last[0] = None
        return bool(float(d[0, 0]) <= t)

    def prepare(self) -> None:
        """Compile (or load from Numba's on-disk cache) the kernels of :meth:`contains_one` now.

        The first :meth:`contains_one` otherwise pays it (seconds on a fresh install). Runs the
        whitening and the scan once at the reference mean; the answer cache of step 1 is left
        untouched.
        """
        # a fresh writable array, as contains_one receives (the kernel is compiled per layout)
        w = whiten_one(np.array(self.mean, dtype=np.float64), self.mean, self._wt)
        self._scan.kth(w, self.k)

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
        return self.summarize(self.distance(x, yhat), violated)

    def summarize(self, distance: FloatArray, violated: NDArray[np.bool_] | None = None) -> DomainReport:
        """:meth:`report` from distances already computed by :meth:`distance`."""
        dist = np.asarray(distance, dtype=np.float64)
        out = ~(dist <= self.threshold)
        v = None if violated is None else np.asarray(violated, dtype=bool)
        return DomainReport(
            method=self.method,
            alpha=self.alpha,
            threshold=self.threshold,
            n_reference=self.n,
            n=len(dist),
            outside=int(out.sum()),
            violations_inside=None if v is None else int((v & ~out).sum()),
            violations_outside=None if v is None else int((v & out).sum()),
        )

    def describe(self) -> DomainReport:
        """The test itself, for a certificate without test queries (``n = 0``)."""
        return DomainReport(
            method=self.method, alpha=self.alpha, threshold=self.threshold, n_reference=self.n, n=0, outside=0
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the model file (the reference as a nested list is avoided: see modelio)."""
        return {
            "method": self.method,
            "k": self.k,
            "alpha": self.alpha,
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
            alpha=float(data["alpha"]),
            threshold=float(data["threshold"]),
            n=int(data["n"]),
            method=str(data.get("method", METHOD)),
            n_groups=None if data.get("n_groups") is None else int(data["n_groups"]),
        )


@dataclass(frozen=True, kw_only=True)
class DomainReport:
    """The ``domain`` block of ``certificate.json``: how many queries of a batch lie outside.

    Examples
    --------
    >>> r = DomainReport(method="knn", alpha=0.01, threshold=2.0, n_reference=100, n=50, outside=5)
    >>> r.outside_fraction, r.well_above_alpha
    (0.1, True)
    """

    method: str
    alpha: float
    threshold: float
    n_reference: int
    n: int
    outside: int
    violations_inside: int | None = None
    violations_outside: int | None = None

    def __post_init__(self) -> None:
        if not (0 <= self.outside <= self.n):
            raise InvalidInputError(f"need 0 <= outside <= n; got {self.outside}, {self.n}")

    def sentence(self) -> str:
        """What the domain test found and what the certificate does (not) promise, in words."""
        if self.n == 0:
            return (
                f"The domain of validity is the region within distance {self.threshold:.3g} (whitened) of "
                f"the {self.n_reference} calibration inputs; queries beyond it are flagged, and "
                f"in-distribution queries are flagged at a rate of at most {self.alpha:g}."
            )
        text = (
            f"{self.outside} of {self.n} queries ({100 * self.outside_fraction:.2f} %) lie outside the "
            f"domain of validity (in-distribution queries are flagged at most {100 * self.alpha:g} % of "
            "the time)"
        )
        if self.outside == 0:
            return text + "."
        text += (
            "; the certificate promises nothing for them: they are unlike every calibration sample, so "
            "the exchangeability it rests on fails there"
        )
        if self.violations_outside is not None and self.violations_inside is not None:
            inside = self.n - self.outside
            rate_in = self.violations_inside / inside if inside else float("nan")
            text += (
                f" (violations: {self.violations_outside} of {self.outside} outside, "
                f"{self.violations_inside} of {inside} inside"
                + (f", {100 * rate_in:.2f} %" if inside else "")
                + ")"
            )
        if self.well_above_alpha:
            text += ". That is far more than false alarms explain: the deployment data have shifted"
        return text + "."

    @property
    def outside_fraction(self) -> float:
        """Share of the queries outside the domain (0 for an empty batch)."""
        return self.outside / self.n if self.n else 0.0

    @property
    def well_above_alpha(self) -> bool:
        """The outside share is above what false alarms explain (one-sided binomial test at 0.001)."""
        if self.n == 0 or self.outside == 0:
            return False
        return bool(stats.binom.sf(self.outside - 1, self.n, self.alpha) < WELL_ABOVE_LEVEL)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (the keys of ``certificate.json["domain"]``)."""
        return {
            "method": self.method,
            "alpha": self.alpha,
            "threshold": self.threshold,
            "n_reference": self.n_reference,
            "n": self.n,
            "outside": self.outside,
            "outside_fraction": self.outside_fraction,
            "well_above_alpha": self.well_above_alpha,
            "violations_inside": self.violations_inside,
            "violations_outside": self.violations_outside,
            "statement": self.sentence(),
        }
