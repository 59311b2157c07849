"""Mondrian calibration: one scale factor per group of a discrete column or per bin of a continuous one.

The column must be computable at predict time (an ``x`` or ``yhat`` column). For a
continuous column the bin edges are quantiles of a seeded random share of the calibration
set (``edge_fraction``) that is then *not* used for the scores, so that the bins are fixed
independently of the samples they calibrate. In PAC mode every group is calibrated at
``delta / G`` (Bonferroni over the ``G`` groups), so that with probability at least
``1 - delta`` *every* group's violation rate is at most ``epsilon``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

from ipcverify.calibration._bounds import CalibrationMode, count_text, min_calibration_size
from ipcverify.calibration._method import CalibrationRecord, CalibrationSample, CalibrationSpec
from ipcverify.calibration._mondrian_groups import (
    EDGE_FRACTION,
    check_bins,
    check_edge_fraction,
    discrete_groups,
    locate_column,
    quantile_bins,
)
from ipcverify.calibration._protocol import (
    AllowedRate,
    CalibrationSummary,
    FloatArray,
    GroupInfo,
    RowClaim,
    summarize,
)
from ipcverify.calibration._threshold import (
    ScoreThreshold,
    check_eps_delta,
    check_mode,
    check_seed,
    threshold_scores,
)
from ipcverify.data._dataset import query_rows
from ipcverify.errors import InvalidInputError, SampleSizeError


@dataclass(frozen=True, kw_only=True)
class GroupScale:
    """The threshold of one Mondrian group.

    Attributes
    ----------
    label : str
        Readable name, e.g. ``"run=3"`` or ``"0.5 <= speed < 1.2"``.
    threshold : ScoreThreshold
        The group's calibrated threshold (its own ``n``, ``k`` and scale).
    value : float or None
        The group's column value (discrete groups); None for bins.
    lower, upper : float or None
        The bin's edges (continuous column; ``lower <= v < upper``, ``-inf`` / ``inf`` at the
        ends); None for discrete groups.
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
class MondrianCalibration(RowClaim):
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
    group_scales : tuple of GroupScale
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
    group_scales: tuple[GroupScale, ...]
    mode: CalibrationMode
    epsilon: float
    delta: float
    data_hash: str
    network_hash: str
    edges: tuple[float, ...] = ()
    n_edge: int = 0
    kind: ClassVar[str] = "mondrian"

    def __post_init__(self) -> None:
        check_mode(self.mode)
        check_eps_delta(self.epsilon, self.delta)
        if self.source not in ("x", "yhat") or self.index < 0:
            raise InvalidInputError(f"group column must be an x or yhat column; got {self.source!r}")
        if self.binning not in ("groups", "bins"):
            raise InvalidInputError(f"binning must be 'groups' or 'bins'; got {self.binning!r}")
        if not self.group_scales:
            raise InvalidInputError("a Mondrian calibration needs at least one group")
        gdelta = self.group_delta
        for g in self.group_scales:
            t = g.threshold
            if (t.mode, t.epsilon) != (self.mode, self.epsilon) or not math.isclose(t.delta, gdelta):
                raise InvalidInputError(
                    f"group {g.label!r}: its (mode, epsilon, delta) disagree with the calibration's "
                    f"({self.mode}, {self.epsilon:g}, {gdelta:g})"
                )
        if self.binning == "bins":
            e = np.asarray(self.edges, dtype=float)
            if len(self.group_scales) != len(e) + 1 or not (np.diff(e) > 0).all() or not np.isfinite(e).all():
                raise InvalidInputError("bin edges must be finite, increasing, and one fewer than the bins")
        else:
            vals = [g.value for g in self.group_scales]
            if any(v is None for v in vals) or len(set(vals)) != len(vals):
                raise InvalidInputError("discrete groups need distinct values")

    @property
    def group_delta(self) -> float:
        """Confidence parameter of each group (``delta / G`` in PAC mode)."""
        return self.delta / len(self.group_scales) if self.mode == "pac" else self.delta

    @property
    def n(self) -> int:
        """Calibration samples used for scores (all groups)."""
        return sum(g.threshold.n for g in self.group_scales)

    def group_index(self, x: FloatArray, yhat: FloatArray) -> NDArray[np.intp]:
        """Index into :attr:`groups` of every sample (B,).

        Raises
        ------
        InvalidInputError
            If a sample's value of a discrete column was never seen in calibration.
        """
        arr = query_rows(x if self.source == "x" else yhat)
        if arr.shape[1] <= self.index:
            raise InvalidInputError(
                f"Mondrian column {self.column!r} is {self.source}[{self.index}] but {self.source} has "
                f"only {arr.shape[1]} columns"
            )
        v = arr[:, self.index]
        if self.binning == "bins":
            return np.searchsorted(np.asarray(self.edges), v, side="right")
        values = np.array([g.value for g in self.group_scales], dtype=np.float64)
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

    def scale_for(self, x: FloatArray, yhat: FloatArray) -> FloatArray:
        """Each sample's group scale, shape (B,)."""
        scales = np.array([g.threshold.scale for g in self.group_scales])
        return scales[self.group_index(x, yhat)]

    def groups(self) -> tuple[GroupInfo, ...]:
        """One record per group, in :attr:`group_scales` order."""
        return tuple(
            GroupInfo(label=g.label, n=g.threshold.n, k=g.threshold.k, scale=g.threshold.scale)
            for g in self.group_scales
        )

    def allowed_violation_rate(self) -> AllowedRate:
        """PAC: ``epsilon`` (every group, hence the whole); marginal: no per-draw claim."""
        if self.mode == "pac":
            return AllowedRate(
                rate=self.epsilon,
                reason="with probability 1 - delta every group, hence the whole, violates at most epsilon",
            )
        return AllowedRate(rate=None, reason="marginal Mondrian calibration makes no per-draw claim")

    def summary(self) -> CalibrationSummary:
        """The typed record (per-group ``k``, ``scale`` and records as details)."""
        return summarize(
            self,
            certified_epsilon=self.epsilon,
            grouping=(
                f"{len(self.group_scales)} values of {self.column}"
                if self.binning == "groups"
                else f"{len(self.group_scales)} quantile bins of {self.column}"
            ),
            details={
                "group_delta": self.group_delta,
                "k": [g.threshold.k for g in self.group_scales],
                "scale": [g.threshold.scale for g in self.group_scales],
                "column": self.column,
                "binning": self.binning,
                "n_edge": self.n_edge,
                "groups": [g.to_dict() for g in self.group_scales],
            },
        )

    def guarantee(self) -> str:
        """The guarantee in one plain sentence."""
        G = len(self.group_scales)
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
            "kind": self.kind,
            "column": self.column,
            "source": self.source,
            "index": self.index,
            "binning": self.binning,
            "edges": [float(e) for e in self.edges],
            "mode": self.mode,
            "epsilon": self.epsilon,
            "delta": self.delta,
            "n_edge": self.n_edge,
            "groups": [g.to_dict() for g in self.group_scales],
            "data_hash": self.data_hash,
            "network_hash": self.network_hash,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> MondrianCalibration:
        """Inverse of :meth:`to_dict`."""
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
        return cls(
            column=str(data["column"]),
            source=data["source"],
            index=int(data["index"]),
            binning=data["binning"],
            group_scales=tuple(groups),
            mode=data["mode"],
            epsilon=float(data["epsilon"]),
            delta=float(data["delta"]),
            data_hash=str(data["data_hash"]),
            network_hash=str(data["network_hash"]),
            edges=tuple(float(e) for e in data.get("edges", [])),
            n_edge=int(data.get("n_edge", 0)),
        )

    @classmethod
    def fit(
        cls,
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
        """Calibrate one threshold per group of ``values`` (see the module docstring)."""
        if bins is None:
            specs, members, edges, n_edge = discrete_groups(values, column)
        else:
            specs, members, edges, n_edge, keep = quantile_bins(values, column, bins, edge_fraction, seed)
            scores = scores[keep]
        G = len(specs)
        group_delta = delta / G if mode == "pac" else delta
        need = min_calibration_size(epsilon, group_delta, mode)
        groups = []
        for spec, mask in zip(specs, members, strict=True):
            n_g = int(mask.sum())
            if n_g < need:
                raise SampleSizeError(
                    f"Mondrian group {spec['label']!r} has {n_g} calibration samples but {mode} "
                    f"calibration at epsilon={epsilon:g}, delta={group_delta:g} (delta/{G} per group) "
                    f"needs at least {count_text(need)}; use more calibration data, fewer bins, or a global "
                    "calibration"
                )
            groups.append(
                GroupScale(threshold=threshold_scores(scores[mask], epsilon, group_delta, mode), **spec)
            )
        return cls(
            column=column,
            source=source,
            index=index,
            binning="groups" if bins is None else "bins",
            group_scales=tuple(groups),
            mode=mode,
            epsilon=float(epsilon),
            delta=float(delta),
            data_hash=data_hash,
            network_hash=network_hash,
            edges=edges,
            n_edge=n_edge,
        )


@dataclass(frozen=True, kw_only=True)
class Mondrian(CalibrationSpec):
    """Mondrian calibration, one scale per group of an ``x`` or ``yhat`` column: a spec for ``calibrate()``.

    Parameters
    ----------
    column : str
        An ``x`` or ``yhat`` column (it must be known at predict time).
    bins : int, optional
        Calibrate per quantile bin of a continuous column; without it the column's distinct
        values (at most ``MAX_GROUPS``) are the groups.
    edge_fraction : float
        With ``bins``: the share of the calibration data used only to place the bin edges.
    seed : int
        Seeds the choice of that share.
    mode : {"pac", "marginal"}
        PAC (every group at ``delta / G``) or marginal guarantee.

    Examples
    --------
    >>> Mondrian(column="x_3", bins=4).edge_fraction
    0.2
    >>> Mondrian(column="x_3", bins=0)
    Traceback (most recent call last):
    ...
    ipcverify.errors.InvalidInputError: bins must be a positive integer; got 0
    """

    column: str
    bins: int | None = None
    edge_fraction: float = EDGE_FRACTION
    seed: int = 0
    kind: ClassVar[str] = "mondrian"
    record: ClassVar[CalibrationRecord] = MondrianCalibration

    def __post_init__(self) -> None:
        super().__post_init__()
        if not (isinstance(self.column, str) and self.column):
            raise InvalidInputError(f"a Mondrian calibration needs a column name; got {self.column!r}")
        if self.bins is not None:
            check_bins(self.bins)
        check_edge_fraction(self.edge_fraction)
        check_seed(self.seed)

    def fit(self, sample: CalibrationSample) -> MondrianCalibration:
        """Calibrate one threshold per group of the column's values in the calibration data."""
        data = sample.rows()
        source, index = locate_column(data, self.column)
        values = (data.x if source == "x" else data.yhat)[:, index]
        return MondrianCalibration.fit(
            sample.scores,
            np.asarray(values, dtype=np.float64),
            column=self.column,
            source=source,
            index=index,
            bins=self.bins,
            epsilon=sample.epsilon,
            delta=sample.delta,
            mode=self.mode,
            edge_fraction=self.edge_fraction,
            seed=int(self.seed),
            **sample.ids,
        )
