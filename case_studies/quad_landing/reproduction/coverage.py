"""Do the closed loop's queries look like the calibration data? The model's own domain test on them.

:func:`coverage_check` runs the IPC's domain-of-validity test (:class:`ipcverify.guard.DomainModel`)
on every query a campaign made and on held-out test samples, and returns a
:class:`CoverageCheck`: the flag rate per group of queries with its Clopper--Pearson interval,
whether a shift is detected, the distances (for the coverage figure) and per-feature ranges
(informational). ``summary.json``'s ``landing.coverage`` is its :meth:`CoverageCheck.to_dict`
without the distances.

Examples
--------
>>> g = CoverageGroup(n=10, exceed=1, rate=0.1, interval=(0.0, 0.4), lower=0.005, median_distance=1.0)
>>> g.to_dict()["interval"]
[0.0, 0.4]
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.landing.runs import LandingRun
from case_studies.quad_landing.reproduction.record import Record
from ipcverify.calibration._bounds import clopper_pearson_interval, clopper_pearson_lower
from ipcverify.contract import IPCModel
from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError

__all__ = ["HeldOutFlags", "CoverageGroup", "CoverageCheck", "coverage_check"]


@dataclass(frozen=True)
class HeldOutFlags(Record):
    """The domain test on held-out samples drawn like the calibration data: how many it flags."""

    n: int
    median_distance: float
    outside: int


@dataclass(frozen=True, kw_only=True)
class CoverageGroup(Record):
    """One group of closed-loop queries: ``exceed`` of ``n`` outside the domain, with the rate's interval."""

    n: int
    exceed: int
    rate: float
    interval: tuple[float, float]
    lower: float
    median_distance: float


@dataclass(frozen=True, kw_only=True)
class CoverageCheck:
    """What :func:`coverage_check` found (see there).

    ``groups`` is empty and ``shift_detected``, ``distances`` and ``feature_range`` are None
    when the runs made no query. ``distances`` holds the raw distances (``queries``, ``test``)
    the coverage figure draws; ``feature_range`` the informational per-feature ranges
    (JSON-bound plain data).
    """

    method: str
    quantile: float
    threshold: float
    test: HeldOutFlags
    null_rate: float
    confidence: float
    groups: Mapping[str, CoverageGroup]
    shift_detected: bool | None
    distances: Mapping[str, list[float]] | None = None
    feature_range: Mapping[str, Any] | None = None

    def to_dict(self, *, distances: bool = True) -> dict[str, Any]:
        """As in ``summary.json`` (``landing.coverage`` leaves the ``distances`` out)."""
        out: dict[str, Any] = {
            "method": self.method,
            "quantile": self.quantile,
            "threshold": self.threshold,
            "test": self.test.to_dict(),
            "null_rate": self.null_rate,
            "confidence": self.confidence,
        }
        groups = {name: g.to_dict() for name, g in self.groups.items()}
        if self.distances is None:
            out.update(shift_detected=self.shift_detected, groups=groups)
            return out
        out.update(groups=groups, shift_detected=self.shift_detected)
        if distances:
            out["distances"] = dict(self.distances)
        out["feature_range"] = None if self.feature_range is None else dict(self.feature_range)
        return out


def coverage_check(
    model: IPCModel,
    calibration_data: PerceptionDataset,
    test_data: PerceptionDataset,
    runs: Sequence[LandingRun],
    *,
    delta: float = 0.05,
) -> CoverageCheck:
    """Do the closed loop's queries look like the calibration data? The model's own domain test.

    The same machinery every deployment path uses (:class:`ipcverify.guard.DomainModel`,
    fitted by :func:`ipcverify.contract.calibrate` on the calibration inputs): a query is
    outside the domain of validity when its whitened distance to the calibration inputs
    exceeds the test's threshold; an exchangeable query is flagged with probability at most
    ``alpha`` (``proofs/domain.md``).

    Parameters
    ----------
    model : IPCModel
        The IPC used in the runs, with its domain model.
    calibration_data : PerceptionDataset
        The data the calibration was computed on (for the per-feature range figures).
    test_data : PerceptionDataset
        Held-out samples drawn like the calibration data: their flag rate checks the test.
    runs : sequence of LandingRun
        Runs flown with the model; every query with a detection is checked.
    delta : float
        Confidence parameter of the intervals and of the flag.

    Returns
    -------
    CoverageCheck
        ``threshold``, ``null_rate`` (= ``alpha``), the held-out ``test`` flags, per group
        (``all``, ``first``, ``later`` queries) the number of queries, the ones outside the domain
        and their rate with a Clopper--Pearson interval, ``shift_detected`` (the one-sided lower
        bound of some group's rate exceeds ``alpha``), the distances and per-feature range figures.
    """
    domain = model.domain
    if domain is None:
        raise InvalidInputError("the model has no domain-of-validity test; recalibrate it with calibrate()")
    test_d = domain.distance(test_data.x, test_data.yhat)
    held_out = HeldOutFlags(
        n=int(test_d.size),
        median_distance=float(np.median(test_d)),
        outside=int((test_d > domain.threshold).sum()),
    )
    common: dict[str, Any] = {
        "method": domain.method,
        "quantile": 1.0 - domain.flag_rate,
        "threshold": domain.threshold,
        "test": held_out,
        "null_rate": domain.flag_rate,
        "confidence": 1 - delta,
    }
    qs = [(i, q) for r in runs for i, q in enumerate(r.queries) if q.detected and q.x_c is not None]
    if not qs:
        return CoverageCheck(**common, groups={}, shift_detected=None)
    x = np.array([q.x_c for _, q in qs])
    yh = np.array([q.yhat_c for _, q in qs])
    d = domain.distance(x, yh)
    first = np.array([i == 0 for i, _ in qs])
    groups: dict[str, CoverageGroup] = {}
    for name, mask in (("all", np.ones(len(qs), bool)), ("first", first), ("later", ~first)):
        n = int(mask.sum())
        if not n:
            continue
        k = int((d[mask] > domain.threshold).sum())
        groups[name] = CoverageGroup(
            n=n,
            exceed=k,
            rate=k / n,
            interval=clopper_pearson_interval(k, n, delta),
            lower=clopper_pearson_lower(k, n, delta),
            median_distance=float(np.median(d[mask])),
        )
    return CoverageCheck(
        **common,
        groups=groups,
        shift_detected=bool(any(g.lower > domain.flag_rate for g in groups.values())),
        distances={"queries": d.tolist(), "test": np.sort(test_d).tolist()},
        feature_range=_feature_ranges(calibration_data, test_data, x, yh),
    )


def _feature_ranges(
    calibration_data: PerceptionDataset, test_data: PerceptionDataset, x: FloatArray, yh: FloatArray
) -> dict[str, Any]:
    """Per-feature 0.5-99.5 % ranges: informational only (a query can be inside every range and far
    from all data, or outside one range and still near the data); the domain test decides."""
    cal = np.concatenate([calibration_data.x, calibration_data.yhat], axis=1)
    lo, hi = np.quantile(cal, 0.005, axis=0), np.quantile(cal, 0.995, axis=0)
    names = [*calibration_data.x_columns, *calibration_data.yhat_columns]
    q = np.concatenate([x, yh], axis=1)
    t = np.concatenate([test_data.x, test_data.yhat], axis=1)
    return {
        "range": "0.5-99.5 % of the calibration data, per feature (informational; the domain test decides)",
        "queries_outside_any": float(np.mean(np.any((q < lo) | (q > hi), axis=1))),
        "test_outside_any": float(np.mean(np.any((t < lo) | (t > hi), axis=1))),
        "queries_outside_by_feature": {
            n: float(np.mean((q[:, i] < lo[i]) | (q[:, i] > hi[i]))) for i, n in enumerate(names)
        },
    }
