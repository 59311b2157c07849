"""Calibrating a learned IPC on held-out data with one scale factor (or one per group).

The network's score ``g = ||C (y - c)||`` is computed on ``n`` calibration samples
that were *not* used for training. The calibrated contract is ``E(c, C / s)`` with
``s`` the ``k``-th smallest score, so that ``y`` lies in it exactly when
``g <= s``:

* ``mode="pac"`` (training-conditional): ``k`` from
  :func:`ipcverify.bounds.pac_calibration_index`; with probability at least
  ``1 - delta`` over the calibration set, a fresh sample violates the contract
  with probability at most ``epsilon``.
* ``mode="marginal"`` (split conformal): ``k = ceil((n + 1)(1 - epsilon))``; the
  violation probability, averaged over calibration sets, is at most ``epsilon``.

Both assume the calibration samples and the deployment samples are exchangeable
(for example i.i.d. from one distribution). Proofs: ``proofs/pac_calibration.md``.

Mondrian calibration does the same per group of a discrete column, or per bin of
a continuous column, of ``x`` or ``yhat`` (it must be computable at predict time).
For a continuous column the bin edges are quantiles of a seeded random share of
the calibration set (``edge_fraction``) that is then *not* used for the scores,
so that the bins are fixed independently of the samples they calibrate. In PAC
mode every group is calibrated at ``delta / G`` (Bonferroni over the ``G``
groups), so that with probability at least ``1 - delta`` *every* group's
violation rate is at most ``epsilon``.

The stored scale is the order statistic times ``1 + SCALE_MARGIN``: a slightly
larger set, so that float32 rounding differences between batch sizes cannot
turn a calibration sample on the boundary into a violation.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.bounds import CalibrationMode, calibration_index, min_calibration_size, pac_epsilon
from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError, SampleSizeError
from ipcverify.model import IPCModel, IPCNetwork

__all__ = [
    "SCALE_MARGIN",
    "MAX_GROUPS",
    "ScoreThreshold",
    "GlobalCalibration",
    "GroupScale",
    "MondrianCalibration",
    "Calibration",
    "threshold_scores",
    "calibrate",
    "calibration_from_dict",
    "network_fingerprint",
    "describe_groups",
]

FloatArray = NDArray[np.float64]

#: Relative enlargement of the calibrated scale (float32 rounding guard; conservative).
SCALE_MARGIN = 1e-5
#: Scale used if the order statistic is zero (a perfect score); keeps C / s finite.
MIN_SCALE = 1e-30
#: Most distinct values a discrete group column may have (use ``bins`` beyond that).
MAX_GROUPS = 64
_MODES = ("pac", "marginal")


def _check_eps_delta(epsilon: float, delta: float) -> None:
    for name, v in (("epsilon", epsilon), ("delta", delta)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and 0.0 < v < 1.0):
            raise InvalidInputError(f"{name} must lie strictly between 0 and 1; got {v!r}")


def _check_mode(mode: str) -> None:
    if mode not in _MODES:
        raise InvalidInputError(f"mode must be 'pac' or 'marginal'; got {mode!r}")


@dataclass(frozen=True, kw_only=True)
class ScoreThreshold:
    """The calibrated threshold of one set of scores.

    Attributes
    ----------
    mode : {"pac", "marginal"}
    epsilon, delta : float
        Target violation rate and confidence parameter (``delta`` is recorded but
        plays no role in the marginal guarantee).
    n, k : int
        Calibration samples and the order statistic used (``1 <= k <= n``).
    order_statistic : float
        The ``k``-th smallest score.
    scale : float
        ``order_statistic * (1 + SCALE_MARGIN)`` (at least ``MIN_SCALE``).

    Examples
    --------
    >>> t = threshold_scores(np.arange(1.0, 101.0), epsilon=0.1, delta=0.05, mode="marginal")
    >>> t.k, t.order_statistic
    (91, 91.0)
    """

    mode: CalibrationMode
    epsilon: float
    delta: float
    n: int
    k: int
    order_statistic: float
    scale: float

    def __post_init__(self) -> None:
        _check_mode(self.mode)
        _check_eps_delta(self.epsilon, self.delta)
        if not (isinstance(self.n, int) and isinstance(self.k, int) and 1 <= self.k <= self.n):
            raise InvalidInputError(f"need integers 1 <= k <= n; got k={self.k!r}, n={self.n!r}")
        need = calibration_index(self.n, self.epsilon, self.delta, self.mode)
        if self.k < need:
            raise InvalidInputError(
                f"order statistic k={self.k} is below the k={need} that {self.mode} calibration "
                f"requires for n={self.n}, epsilon={self.epsilon:g}, delta={self.delta:g}; "
                "the record is inconsistent -- recalibrate"
            )
        if not (math.isfinite(self.scale) and self.scale > 0 and self.scale >= self.order_statistic):
            raise InvalidInputError(
                f"scale must be finite, > 0 and >= the order statistic; got scale={self.scale!r}, "
                f"order statistic={self.order_statistic!r}"
            )

    @property
    def certified_epsilon(self) -> float:
        """The violation rate actually certified: ``epsilon`` (marginal) or the tighter PAC value."""
        if self.mode == "marginal":
            return self.epsilon
        return min(self.epsilon, pac_epsilon(self.n, self.k, self.delta))

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""
        return {
            "mode": self.mode,
            "epsilon": self.epsilon,
            "delta": self.delta,
            "n": self.n,
            "k": self.k,
            "order_statistic": self.order_statistic,
            "scale": self.scale,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ScoreThreshold:
        """Inverse of :meth:`to_dict`."""
        return cls(
            mode=str(data["mode"]),  # type: ignore[arg-type]
            epsilon=float(data["epsilon"]),
            delta=float(data["delta"]),
            n=int(data["n"]),
            k=int(data["k"]),
            order_statistic=float(data["order_statistic"]),
            scale=float(data["scale"]),
        )


def threshold_scores(
    scores: ArrayLike, epsilon: float, delta: float, mode: CalibrationMode = "pac"
) -> ScoreThreshold:
    """Calibrate a threshold on exchangeable scores (the core of every calibration).

    Parameters
    ----------
    scores : array_like, shape (n,)
        Non-negative, finite nonconformity scores of held-out samples.
    epsilon, delta : float
        Target violation rate and confidence parameter.
    mode : {"pac", "marginal"}
        Which guarantee (see the module docstring).

    Raises
    ------
    SampleSizeError
        If ``n`` is too small for ``(epsilon, delta)``; the message states the minimum.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> t = threshold_scores(rng.random(1000), epsilon=0.05, delta=0.01)
    >>> t.k, round(t.scale, 3)
    (966, 0.967)
    """
    _check_mode(mode)
    _check_eps_delta(epsilon, delta)
    s = np.asarray(scores, dtype=np.float64).ravel()
    if s.size == 0:
        raise SampleSizeError(
            f"no calibration scores; need at least {min_calibration_size(epsilon, delta, mode)} samples"
        )
    if not np.isfinite(s).all() or (s < 0).any():
        raise InvalidInputError("calibration scores must be finite and >= 0")
    n = int(s.size)
    k = calibration_index(n, epsilon, delta, mode)
    order_stat = float(np.partition(s, k - 1)[k - 1])
    scale = max(order_stat * (1.0 + SCALE_MARGIN), MIN_SCALE)
    return ScoreThreshold(
        mode=mode,
        epsilon=float(epsilon),
        delta=float(delta),
        n=n,
        k=k,
        order_statistic=order_stat,
        scale=scale,
    )


def network_fingerprint(network: IPCNetwork) -> str:
    """SHA-256 of a network's configuration and state dict (ties a calibration to its network).

    Examples
    --------
    >>> from ipcverify.model import ModelConfig
    >>> len(network_fingerprint(IPCNetwork(ModelConfig(x_dim=1, y_dim=1, hidden=(2,)))))
    64
    """
    h = hashlib.sha256(repr(sorted(network.config.to_dict().items())).encode())
    for name, t in sorted(network.state_dict().items()):
        h.update(name.encode())
        arr = t.detach().cpu().contiguous().numpy()
        h.update(str(arr.dtype).encode() + str(arr.shape).encode())
        h.update(arr.tobytes())
    return h.hexdigest()


@dataclass(frozen=True, kw_only=True)
class GlobalCalibration:
    """One scale factor for every input: the calibrated IPC is ``E(c, C / scale)``.

    Attributes
    ----------
    threshold : ScoreThreshold
        Mode, epsilon, delta, n, k and scale.
    data_hash : str
        Content hash of the calibration data.
    network_hash : str
        :func:`network_fingerprint` of the network that was calibrated.

    Examples
    --------
    >>> t = threshold_scores(np.linspace(0.1, 2.0, 200), epsilon=0.1, delta=0.1, mode="marginal")
    >>> cal = GlobalCalibration(threshold=t, data_hash="d", network_hash="h")
    >>> cal.scale_factors(np.zeros((2, 1)), np.zeros((2, 3))).shape
    (2,)
    """

    threshold: ScoreThreshold
    data_hash: str
    network_hash: str
    kind: Literal["global"] = "global"

    def __post_init__(self) -> None:
        if self.kind != "global":
            raise InvalidInputError(f"GlobalCalibration has kind 'global'; got {self.kind!r}")

    @property
    def mode(self) -> CalibrationMode:
        """``"pac"`` or ``"marginal"``."""
        return self.threshold.mode

    @property
    def epsilon(self) -> float:
        """Target violation rate."""
        return self.threshold.epsilon

    @property
    def delta(self) -> float:
        """Confidence parameter."""
        return self.threshold.delta

    @property
    def n(self) -> int:
        """Number of calibration samples used."""
        return self.threshold.n

    def scale_factors(self, x: FloatArray, yhat: FloatArray) -> FloatArray:
        """The scale (same for every sample), shape (B,)."""
        return np.full(len(np.asarray(x)), self.threshold.scale)

    def guarantee(self) -> str:
        """The guarantee in one plain sentence."""
        return _guarantee_sentence(self.threshold, "a new sample")

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form stored in the model file."""
        return {
            "kind": "global",
            **self.threshold.to_dict(),
            "data_hash": self.data_hash,
            "network_hash": self.network_hash,
        }


def _guarantee_sentence(t: ScoreThreshold, who: str) -> str:
    if t.mode == "pac":
        return (
            f"With probability at least {1 - t.delta:.6g} over the draw of the {t.n} calibration samples, "
            f"the probability that the ground truth of {who} lies outside its calibrated ellipsoid is at "
            f"most {t.certified_epsilon:.4g} (target {t.epsilon:g}), provided calibration and deployment "
            "samples are exchangeable (e.g. i.i.d. from one distribution)."
        )
    return (
        f"Averaged over the draw of the {t.n} calibration samples, the probability that the ground truth "
        f"of {who} lies outside its calibrated ellipsoid is at most {t.epsilon:g} (marginal, not "
        "per calibration set), provided calibration and deployment samples are exchangeable."
    )


@dataclass(frozen=True, kw_only=True)
class GroupScale:
    """The threshold of one Mondrian group.

    ``value`` is the group's column value (discrete groups); ``lower``/``upper``
    the bin's edges (continuous column; ``lower <= v < upper``, infinite at the ends).
    """

    label: str
    threshold: ScoreThreshold
    value: float | None = None
    lower: float | None = None
    upper: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (infinite edges stored as ``None``)."""

        def fin(v: float | None) -> float | None:
            return None if v is None or not math.isfinite(v) else float(v)

        return {
            "label": self.label,
            "value": self.value,
            "lower": fin(self.lower),
            "upper": fin(self.upper),
            **self.threshold.to_dict(),
        }


@dataclass(frozen=True, kw_only=True)
class MondrianCalibration:
    """One scale factor per group of a discrete column or per bin of a continuous one.

    Attributes
    ----------
    column : str
        Column name (an ``x`` or ``yhat`` column).
    source : {"x", "yhat"}
        Where the column lives at predict time.
    index : int
        Its position in ``x`` or ``yhat``.
    binning : {"groups", "bins"}
        Discrete values or bins of a continuous column.
    groups : tuple of GroupScale
        Per-group thresholds; for bins, ordered by edge.
    edges : tuple of float
        Interior bin edges (bins only).
    mode, epsilon, delta : see :class:`ScoreThreshold`
        ``delta`` is the overall confidence; in PAC mode every group uses ``delta / G``.
    n_edge : int
        Calibration samples spent on choosing the bin edges (not used for scores).
    data_hash, network_hash : str
        Identity of the calibration data and of the calibrated network.
    """

    column: str
    source: Literal["x", "yhat"]
    index: int
    binning: Literal["groups", "bins"]
    groups: tuple[GroupScale, ...]
    mode: CalibrationMode
    epsilon: float
    delta: float
    data_hash: str
    network_hash: str
    edges: tuple[float, ...] = ()
    n_edge: int = 0
    kind: Literal["mondrian"] = "mondrian"

    def __post_init__(self) -> None:
        _check_mode(self.mode)
        _check_eps_delta(self.epsilon, self.delta)
        if self.kind != "mondrian":
            raise InvalidInputError(f"MondrianCalibration has kind 'mondrian'; got {self.kind!r}")
        if self.source not in ("x", "yhat") or self.index < 0:
            raise InvalidInputError(f"group column must be an x or yhat column; got {self.source!r}")
        if self.binning not in ("groups", "bins"):
            raise InvalidInputError(f"binning must be 'groups' or 'bins'; got {self.binning!r}")
        if not self.groups:
            raise InvalidInputError("a Mondrian calibration needs at least one group")
        gdelta = self.group_delta
        for g in self.groups:
            t = g.threshold
            if (t.mode, t.epsilon) != (self.mode, self.epsilon) or not math.isclose(t.delta, gdelta):
                raise InvalidInputError(
                    f"group {g.label!r}: its (mode, epsilon, delta) disagree with the calibration's "
                    f"({self.mode}, {self.epsilon:g}, {gdelta:g})"
                )
        if self.binning == "bins":
            e = np.asarray(self.edges, dtype=float)
            if len(self.groups) != len(e) + 1 or not (np.diff(e) > 0).all() or not np.isfinite(e).all():
                raise InvalidInputError("bin edges must be finite, increasing, and one fewer than the bins")
        else:
            vals = [g.value for g in self.groups]
            if any(v is None for v in vals) or len(set(vals)) != len(vals):
                raise InvalidInputError("discrete groups need distinct values")

    @property
    def group_delta(self) -> float:
        """Confidence parameter of each group (``delta / G`` in PAC mode)."""
        return self.delta / len(self.groups) if self.mode == "pac" else self.delta

    @property
    def n(self) -> int:
        """Calibration samples used for scores (all groups)."""
        return sum(g.threshold.n for g in self.groups)

    def group_index(self, x: FloatArray, yhat: FloatArray) -> NDArray[np.intp]:
        """Index into :attr:`groups` of every sample (B,).

        Raises
        ------
        InvalidInputError
            If a sample's value of a discrete column was never seen in calibration.
        """
        arr = np.asarray(x if self.source == "x" else yhat, dtype=np.float64)
        if arr.ndim == 1:
            arr = arr[None]
        if arr.shape[1] <= self.index:
            raise InvalidInputError(
                f"Mondrian column {self.column!r} is {self.source}[{self.index}] but {self.source} has "
                f"only {arr.shape[1]} columns"
            )
        v = arr[:, self.index]
        if self.binning == "bins":
            return np.searchsorted(np.asarray(self.edges), v, side="right")
        values = np.array([g.value for g in self.groups], dtype=np.float64)
        order = np.argsort(values)
        pos = np.clip(np.searchsorted(values[order], v), 0, len(values) - 1)
        idx = order[pos]
        unseen = values[idx] != v
        if unseen.any():
            bad = float(v[np.flatnonzero(unseen)[0]])
            raise InvalidInputError(
                f"column {self.column!r} has value {bad:g}, a group never seen in calibration "
                f"(known groups: {', '.join(f'{x:g}' for x in np.sort(values))}); the contract "
                "certifies nothing for it -- recalibrate with data that covers this group"
            )
        return idx

    def scale_factors(self, x: FloatArray, yhat: FloatArray) -> FloatArray:
        """Each sample's group scale, shape (B,)."""
        scales = np.array([g.threshold.scale for g in self.groups])
        return scales[self.group_index(x, yhat)]

    def guarantee(self) -> str:
        """The guarantee in one plain sentence."""
        G = len(self.groups)
        what = f"groups of {self.column}" if self.binning == "groups" else f"bins of {self.column}"
        if self.mode == "pac":
            return (
                f"With probability at least {1 - self.delta:.6g} over the calibration draw, simultaneously "
                f"for each of the {G} {what}, the probability that the ground truth of a new sample in "
                f"that group lies outside its calibrated ellipsoid is at most {self.epsilon:g}, provided "
                "calibration and deployment samples are exchangeable within each group."
            )
        return (
            f"For each of the {G} {what}, averaged over the calibration draw, the probability that the "
            f"ground truth of a new sample in that group lies outside its calibrated ellipsoid is at most "
            f"{self.epsilon:g}, provided calibration and deployment samples are exchangeable."
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form stored in the model file."""
        return {
            "kind": "mondrian",
            "column": self.column,
            "source": self.source,
            "index": self.index,
            "binning": self.binning,
            "edges": [float(e) for e in self.edges],
            "mode": self.mode,
            "epsilon": self.epsilon,
            "delta": self.delta,
            "n_edge": self.n_edge,
            "groups": [g.to_dict() for g in self.groups],
            "data_hash": self.data_hash,
            "network_hash": self.network_hash,
        }


Calibration = GlobalCalibration | MondrianCalibration


def calibration_from_dict(data: Mapping[str, Any]) -> Calibration:
    """Rebuild a calibration from its :meth:`to_dict` form (used by :func:`ipcverify.modelio.load_model`).

    Raises
    ------
    InvalidInputError
        (a ``ValueError``) if the record is inconsistent; ``KeyError`` if a field is missing.

    Examples
    --------
    >>> t = threshold_scores(np.linspace(0.1, 2.0, 200), epsilon=0.1, delta=0.1, mode="marginal")
    >>> cal = GlobalCalibration(threshold=t, data_hash="d", network_hash="h")
    >>> calibration_from_dict(cal.to_dict()) == cal
    True
    """
    kind = data.get("kind")
    if kind == "global":
        return GlobalCalibration(
            threshold=ScoreThreshold.from_dict(data),
            data_hash=str(data["data_hash"]),
            network_hash=str(data["network_hash"]),
        )
    if kind == "mondrian":
        groups = []
        for g in data["groups"]:
            lo = -math.inf if g.get("lower") is None else float(g["lower"])
            hi = math.inf if g.get("upper") is None else float(g["upper"])
            groups.append(
                GroupScale(
                    label=str(g["label"]),
                    threshold=ScoreThreshold.from_dict(g),
                    value=None if g.get("value") is None else float(g["value"]),
                    lower=lo if data["binning"] == "bins" else None,
                    upper=hi if data["binning"] == "bins" else None,
                )
            )
        return MondrianCalibration(
            column=str(data["column"]),
            source=data["source"],
            index=int(data["index"]),
            binning=data["binning"],
            groups=tuple(groups),
            mode=data["mode"],
            epsilon=float(data["epsilon"]),
            delta=float(data["delta"]),
            data_hash=str(data["data_hash"]),
            network_hash=str(data["network_hash"]),
            edges=tuple(float(e) for e in data.get("edges", [])),
            n_edge=int(data.get("n_edge", 0)),
        )
    raise InvalidInputError(f"unknown calibration kind {kind!r} (expected 'global' or 'mondrian')")


def _locate_column(data: PerceptionDataset, name: str) -> tuple[Literal["x", "yhat"], int]:
    if name in data.x_columns:
        return "x", data.x_columns.index(name)
    if name in data.yhat_columns:
        return "yhat", data.yhat_columns.index(name)
    if name in data.y_columns:
        raise InvalidInputError(
            f"group column {name!r} is part of the ground truth y, which is unknown at predict time; "
            "group by an x or yhat column"
        )
    data.column(name)  # raises DataError listing the available columns if unknown
    raise InvalidInputError(
        f"group column {name!r} is an extra column of {data.source}, which the contract cannot see at "
        f"predict time; group by an x column ({', '.join(data.x_columns)}) or a yhat column"
    )


def _mondrian(
    scores: FloatArray,
    values: FloatArray,
    *,
    column: str,
    source: Literal["x", "yhat"],
    index: int,
    bins: int | None,
    epsilon: float,
    delta: float,
    mode: CalibrationMode,
    edge_fraction: float,
    seed: int,
    data_hash: str,
    network_hash: str,
) -> MondrianCalibration:
    n_edge = 0
    if bins is None:
        uniq = np.unique(values)
        if len(uniq) > MAX_GROUPS:
            raise InvalidInputError(
                f"column {column!r} has {len(uniq)} distinct values (more than {MAX_GROUPS}); "
                "it looks continuous -- pass bins=K (CLI: --bins K) to calibrate per quantile bin"
            )
        members = [values == u for u in uniq]
        G = len(uniq)
        specs: list[dict[str, Any]] = [{"label": f"{column}={u:g}", "value": float(u)} for u in uniq]
        edges: tuple[float, ...] = ()
    else:
        if int(bins) != bins or bins < 1:
            raise InvalidInputError(f"bins must be a positive integer; got {bins!r}")
        if not 0.0 < edge_fraction < 1.0:
            raise InvalidInputError(f"edge_fraction must lie in (0, 1); got {edge_fraction!r}")
        perm = np.random.default_rng(seed).permutation(len(values))
        n_edge = max(1, int(round(edge_fraction * len(values))))
        edge_vals, keep = values[perm[:n_edge]], np.sort(perm[n_edge:])
        scores, values = scores[keep], values[keep]
        e = np.unique(np.quantile(edge_vals, np.arange(1, bins) / bins)) if bins > 1 else np.zeros(0)
        edges = tuple(float(v) for v in e)
        idx = np.searchsorted(e, values, side="right")
        G = len(edges) + 1
        members = [idx == j for j in range(G)]
        bounds = [-math.inf, *edges, math.inf]
        specs = [
            {
                "label": f"{bounds[j]:.4g} <= {column} < {bounds[j + 1]:.4g}",
                "lower": bounds[j],
                "upper": bounds[j + 1],
            }
            for j in range(G)
        ]
    group_delta = delta / G if mode == "pac" else delta
    need = min_calibration_size(epsilon, group_delta, mode)
    groups = []
    for spec, mask in zip(specs, members, strict=True):
        n_g = int(mask.sum())
        if n_g < need:
            raise SampleSizeError(
                f"Mondrian group {spec['label']!r} has {n_g} calibration samples but {mode} calibration at "
                f"epsilon={epsilon:g}, delta={group_delta:g} (delta/{G} per group) needs at least {need}; "
                "use more calibration data, fewer bins, or a global calibration"
            )
        groups.append(
            GroupScale(threshold=threshold_scores(scores[mask], epsilon, group_delta, mode), **spec)
        )
    return MondrianCalibration(
        column=column,
        source=source,
        index=index,
        binning="groups" if bins is None else "bins",
        groups=tuple(groups),
        mode=mode,
        epsilon=float(epsilon),
        delta=float(delta),
        data_hash=data_hash,
        network_hash=network_hash,
        edges=edges,
        n_edge=n_edge,
    )


def calibrate(
    model: IPCModel,
    calibration_data: PerceptionDataset,
    epsilon: float,
    delta: float,
    mode: CalibrationMode = "pac",
    *,
    group_column: str | None = None,
    bins: int | None = None,
    recalibrate: bool = False,
    edge_fraction: float = 0.2,
    seed: int = 0,
) -> IPCModel:
    """Calibrate an IPC on held-out data; returns the model with the calibration attached.

    Parameters
    ----------
    model : IPCModel
        A trained model. If it already carries a calibration, ``recalibrate=True``
        is required (the raw network is then calibrated afresh).
    calibration_data : PerceptionDataset
        Samples **not used for training** (nor for choosing the model), exchangeable
        with deployment data.
    epsilon : float
        Target violation probability, e.g. 0.01.
    delta : float
        Confidence parameter of the PAC guarantee, e.g. 0.001 (recorded in marginal mode).
    mode : {"pac", "marginal"}
        Training-conditional (PAC) or marginal (split conformal) guarantee.
    group_column : str, optional
        An ``x`` or ``yhat`` column for Mondrian (per-group) calibration.
    bins : int, optional
        With ``group_column``: calibrate per quantile bin of a continuous column.
        Without it, the column's distinct values are the groups.
    recalibrate : bool
        Allow replacing an existing calibration.
    edge_fraction : float
        Share of the calibration data used only to place the bin edges.
    seed : int
        Seeds the choice of that share.

    Raises
    ------
    SampleSizeError
        If there are too few samples (overall or in a group) for ``(epsilon, delta)``.
    InvalidInputError
        If the model is already calibrated, the dimensions disagree, the data is the
        training data, or the group column cannot be seen at predict time.

    Examples
    --------
    >>> from ipcverify.synthetic import make_lagged_perception
    >>> from ipcverify.model import IPCNetwork, ModelConfig
    >>> net = IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(8,)))
    >>> cal = calibrate(IPCModel(net), make_lagged_perception(1000, seed=1), 0.05, 0.01)
    >>> cal.calibration.threshold.k
    966
    """
    _check_mode(mode)
    _check_eps_delta(epsilon, delta)
    if model.calibration is not None and not recalibrate:
        raise InvalidInputError(
            "the model is already calibrated; calibrating it again on top would compound the scale "
            "factors and void the guarantee -- pass recalibrate=True (CLI: --recalibrate) to "
            "calibrate the raw network afresh"
        )
    cfg = model.config
    if (calibration_data.x_dim, calibration_data.y_dim) != (cfg.x_dim, cfg.y_dim):
        raise InvalidInputError(
            f"{calibration_data.source}: calibration data has x_dim={calibration_data.x_dim}, "
            f"y_dim={calibration_data.y_dim} but the model expects x_dim={cfg.x_dim}, y_dim={cfg.y_dim}"
        )
    data_hash = calibration_data.content_hash()
    if data_hash == model.metadata.get("train_data_hash"):
        raise InvalidInputError(
            f"{calibration_data.source}: this is the model's training data; calibration needs held-out "
            "samples that were not used for training (e.g. the calibration part of a split)"
        )
    if bins is not None and group_column is None:
        raise InvalidInputError("bins needs a group column (CLI: --group-column COL --bins K)")
    scores = model.raw_scores(calibration_data.x, calibration_data.y, calibration_data.yhat)
    net_hash = network_fingerprint(model.network)
    cal: Calibration
    if group_column is None:
        cal = GlobalCalibration(
            threshold=threshold_scores(scores, epsilon, delta, mode),
            data_hash=data_hash,
            network_hash=net_hash,
        )
    else:
        source, index = _locate_column(calibration_data, group_column)
        values = (calibration_data.x if source == "x" else calibration_data.yhat)[:, index]
        cal = _mondrian(
            scores,
            np.asarray(values, dtype=np.float64),
            column=group_column,
            source=source,
            index=index,
            bins=bins,
            epsilon=epsilon,
            delta=delta,
            mode=mode,
            edge_fraction=edge_fraction,
            seed=seed,
            data_hash=data_hash,
            network_hash=net_hash,
        )
    return model.with_calibration(cal)


def describe_groups(cal: Calibration) -> Sequence[dict[str, Any]]:
    """Per-group rows (label, n, k, scale) for reports; one row for a global calibration.

    Examples
    --------
    >>> t = threshold_scores(np.linspace(0.1, 2.0, 200), epsilon=0.1, delta=0.1, mode="marginal")
    >>> describe_groups(GlobalCalibration(threshold=t, data_hash="d", network_hash="h"))[0]["k"]
    181
    """
    if isinstance(cal, GlobalCalibration):
        t = cal.threshold
        return [{"label": "all", "n": t.n, "k": t.k, "scale": t.scale}]
    return [
        {"label": g.label, "n": g.threshold.n, "k": g.threshold.k, "scale": g.threshold.scale}
        for g in cal.groups
    ]
