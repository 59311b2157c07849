"""Deployment: a contract's sets written to a file, and logs replayed through the online monitor.

The sets themselves come from :meth:`IPCModel.predict <ipcverify.IPCModel.predict>`
(:mod:`ipcverify.contract._guarded`). :func:`write_predictions` writes them to NPZ;
:func:`monitor_log` replays a labelled log, in order, through the anytime-valid monitor.

Examples
--------
>>> import numpy as np
>>> from ipcverify import example
>>> from ipcverify.network import ModelConfig
>>> m = example(config=ModelConfig(x_dim=2, y_dim=3, hidden=(8,), param="cholesky")).model
>>> p = m.predict(np.zeros((4, 2)), np.zeros((4, 3)))
>>> p.centers.shape, p.in_domain.tolist()   # no domain model: every query counts as inside
((4, 3), [True, True, True, True])
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ipcverify._wording._spelling import option
from ipcverify.calibration._group_counts import allowed_outside
from ipcverify.contract._guarded import Predictions, predict_sets
from ipcverify.contract._model import IPCModel
from ipcverify.data._dataset import PerceptionDataset, PerceptionInputs
from ipcverify.data._files import atomic_write
from ipcverify.data._split import group_codes
from ipcverify.errors import InvalidInputError
from ipcverify.guard._clustering import ViolationRuns
from ipcverify.guard._monitor import MonitorResult, ViolationMonitor

FloatArray = NDArray[np.float64]


def write_predictions(predictions: Predictions, path: str | os.PathLike[str]) -> None:
    """Write ``center``, ``shape``, ``in_domain``, ``domain_distance`` and ``singular`` to an NPZ (atomic).

    Parameters
    ----------
    predictions : Predictions
        What :func:`predict_sets` returned.
    path : path-like
        The NPZ file.
    """
    p = predictions
    atomic_write(
        path,
        lambda f: np.savez(
            f,
            center=p.centers,
            shape=p.shapes,
            in_domain=p.in_domain,
            domain_distance=p.distance,
            singular=p.singular,
        ),
    )


@dataclass(frozen=True, eq=False)
class LogMonitoring:
    """A labelled deployment log replayed through the online monitor (:mod:`ipcverify.guard._monitor`).

    Attributes
    ----------
    result : MonitorResult
        The monitor's trajectory (e-values, alarm, in-domain fraction).
    violated : ndarray (B,)
        Per observation: the truth fell outside its calibrated set (rows, bool); per group, the
        group's statistic in ``[0, 1]`` (any violation, or the share of its rows outside).
    in_domain : bool ndarray (B,)
        Per observation: the query was in the domain (per group: most of its queries were).
    epsilon, delta : float
        The tested rate (the calibration's allowed rate) and the false-alarm bound.
    calibration_delta : float
        The calibration's own confidence parameter: given a calibration whose claim holds
        (probability at least ``1 - calibration_delta``), a false alarm has probability at
        most ``delta``.
    unit : str
        What one observation is: ``"rows"``, or the groups and their statistic.
    labels : tuple of str
        The group of each observation, in the order the groups ended (empty for rows).
    n_rows : int
        Rows of the log.
    row_in_domain_fraction : float
        Share of the log's rows inside the domain of validity.
    runs : ViolationRuns or None
        For a log monitored row by row: whether its violations come in runs (then an alarm says
        that correlated rows can raise it; :mod:`ipcverify.guard._clustering`). None per group.
    null : str
        The hypothesis the violation test rejects when it alarms, in words.
    domain_rate : float or None
        Per group, with a domain test fitted by groups: the out-of-domain test's null rate (a new
        group's expected share of queries outside the domain is at most this); None otherwise.
    """

    result: MonitorResult
    violated: NDArray[Any]
    in_domain: NDArray[np.bool_]
    epsilon: float
    delta: float
    calibration_delta: float
    unit: str = "rows"
    labels: tuple[str, ...] = ()
    n_rows: int = 0
    row_in_domain_fraction: float = 1.0
    runs: ViolationRuns | None = None
    null: str = ""
    domain_rate: float | None = None

    @property
    def alarm_index(self) -> int | None:
        """Observation (row, or group in ``labels``) at which the certificate was refuted, or None."""
        return self.result.alarm_index

    @property
    def domain_alarm_index(self) -> int | None:
        """Group (in ``labels``) at which the out-of-domain rate was refuted, or None (or no such test)."""
        return self.result.final.domain_alarm_index

    def _where(self, i: int) -> str:
        if not self.labels:
            return f"row {i} (0-based)"
        return f"group {self.labels[i]!r} (observation {i} of {self.unit}, 0-based)"

    def sentence(self) -> str:
        """The outcome in words."""
        share = f"{100 * self.row_in_domain_fraction:.1f} % of the queries were inside the domain of validity"
        what = (
            f"{self.n_rows} rows"
            if not self.labels
            else f"{len(self.labels)} {self.unit} ({self.n_rows} rows)"
        )
        domain = self._domain_sentence()
        null = self.null or f"a violation rate of at most {self.epsilon:.4g}"
        if self.alarm_index is None:
            quiet = (
                f"the log is consistent with {null} (anytime-valid test, false-alarm probability at most "
                f"{self.delta:g}); {share}."
            )
            if self.domain_alarm_index is not None:  # the domain alarm leads, the violation test follows
                return f"{domain.strip()} No violation alarm over {what}: {quiet}"
            return f"No alarm over {what}: {quiet}{domain}"
        text = (
            f"ALARM at {self._where(self.alarm_index)}: the violations up to there refute "
            f"{null} (false-alarm probability at most "
            f"{self.delta:g}, given a calibration whose claim holds, which it does with probability at least "
            f"{1 - self.calibration_delta:g})"
        )
        if self.runs is not None and self.runs.clustered:
            text += f"; but {self.runs.sentence()}"
        return f"{text}; {share}.{domain}"

    def _domain_sentence(self) -> str:
        if self.domain_rate is None:
            return ""
        i = self.domain_alarm_index
        if i is None:
            return (
                " The out-of-domain test raised no alarm (a new group's expected share of queries outside "
                "the "
                f"domain of validity at most {self.domain_rate:g})."
            )
        return (
            f" DOMAIN ALARM at {self._where(i)}: the groups' shares of queries outside the domain of "
            "validity "
            f"refute an expected share of at most {self.domain_rate:g} (the domain test's false-alarm rate)."
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain data for ``monitor.json`` (``unit``, ``observations`` and ``groups`` added for groups)."""
        total = float(np.sum(self.violated))
        return {
            "rows": self.n_rows,
            "unit": self.unit,
            "observations": len(self.violated),
            "groups": list(self.labels),
            "violations": int(total) if total.is_integer() else total,
            "epsilon": self.epsilon,
            "delta": self.delta,
            "calibration_delta": self.calibration_delta,
            "alarm": self.alarm_index is not None,
            "alarm_index": self.alarm_index,
            "null": self.null,
            "domain_rate": self.domain_rate,
            "domain_alarm": self.domain_alarm_index is not None,
            "domain_alarm_index": self.domain_alarm_index,
            "in_domain_fraction": self.row_in_domain_fraction,
            "violation_runs": None if self.runs is None else self.runs.to_dict(),
            "statement": self.sentence(),
            "monitor": self.result.to_dict(),
        }


@dataclass(frozen=True, eq=False)
class _GroupObservations:
    """One observation per group, in the order the groups end (an observation exists only then)."""

    statistic: FloatArray
    mostly_inside: NDArray[np.bool_]
    outside_share: FloatArray
    labels: tuple[str, ...]


def _per_group(
    data: PerceptionDataset,
    column: str,
    statistic: str,
    violated: NDArray[np.bool_],
    in_domain: NDArray[np.bool_],
    share_limit: float | None,
) -> _GroupObservations:
    """Each group's statistic (any violation, its share outside, or that share above the limit)."""
    codes, distinct = group_codes(data.column(column), f"{data.source}: group column {column!r}")
    G = len(distinct)
    last = np.full(G, -1)
    np.maximum.at(last, codes, np.arange(len(codes)))
    order = np.argsort(last, kind="stable")
    size = np.bincount(codes, minlength=G)
    bad = np.bincount(codes, weights=violated.astype(np.float64), minlength=G)
    inside = np.bincount(codes, weights=in_domain.astype(np.float64), minlength=G)
    if statistic == "trajectory":
        stat = (bad > 0).astype(np.float64)
    elif statistic == "share-of-runs" and share_limit is not None:
        stat = np.array(
            [b > allowed_outside(share_limit, int(m)) for b, m in zip(bad, size, strict=True)], float
        )
    else:
        stat = bad / size
    return _GroupObservations(
        statistic=stat[order],
        mostly_inside=(2 * inside > size)[order],
        outside_share=(1.0 - inside / size)[order],
        labels=tuple(str(v) for v in distinct[order]),
    )


#: The null hypothesis of the monitor's violation test, by the statistic of one observation.
_NULLS = {
    "rows": "each row violating with probability at most {rate:.4g} given the rows before it",
    "trajectory": "each new group leaving its sets somewhere with probability at most {rate:.4g} given the "
    "groups before it",
    "share": "each new group's expected share of rows outside at most {rate:.4g} given the groups before it",
    "sample": "each new group's expected share of rows outside at most {rate:.4g} given the groups before it",
    "share-of-runs": "each new group having more than {limit:g} of its rows outside with probability at "
    "most {rate:.4g} given the groups before it",
}


def monitor_log(
    model: IPCModel, data: PerceptionDataset, *, delta: float | None = None, group_column: str | None = None
) -> LogMonitoring:
    """Replay a labelled log, in order, through :class:`~ipcverify.guard.ViolationMonitor`.

    The tested rate is the calibration's allowed rate (:meth:`Calibration.allowed_violation_rate`,
    or its epsilon when it makes no per-draw claim). A row-level calibration is monitored row by
    row (every row an observation, in the domain or not, since the claim covers every
    exchangeable query); its null, stated where it alarms, is that every row violates with at most
    that probability given the rows before it, which correlated rows can break. A run-level
    calibration (its claim is about groups) is monitored with one observation per group of its
    column, taken when the group's last row arrives: whether the group left its sets anywhere
    (``guarantee="trajectory"``), the share of its rows outside their sets (``"expected-share"``,
    whose expectation is what the claim bounds), or whether that share exceeds the claim's
    (``"share-of-runs"``); the null is then the claim itself, and bursts of violations within a
    run raise no alarm. With a domain test fitted by groups, a second e-process tests the groups'
    shares of queries outside the domain against its false-alarm rate. ``group_column`` names the
    log's runs when its column is not the calibration's; for a row-level calibration it monitors
    one observation per group of it (the share of its rows outside), which stays valid when the
    rows of a group are correlated but the groups are independent. Proofs: ``proofs/monitor.md``
    and ``proofs/run_claims.md``.

    Parameters
    ----------
    model : IPCModel
        A calibrated model.
    data : PerceptionDataset
        The labelled log, in time order.
    delta : float, optional
        The monitor's false-alarm probability (default: the calibration's delta).
    group_column : str, optional
        See above.

    Raises
    ------
    InvalidInputError
        If the model is not calibrated, or the runs' column (the claim's, or ``group_column``) is
        not in the log.
    """
    cal = model.require_calibration()
    allowed = cal.allowed_violation_rate()
    epsilon = allowed.rate if allowed.rate is not None else cal.epsilon
    delta = cal.delta if delta is None else float(delta)
    claim = cal.group_claim()
    column = group_column if group_column is not None else None if claim is None else claim.column
    if claim is not None and column not in data.extra:
        raise InvalidInputError(
            f"{data.source}: the calibration's claim is about runs (its calibration data named them "
            f"{claim.column!r}), and the log has no column {column!r}; name the column of the log's runs "
            f"({option('group_column', 'COL')})"
        )
    statistic = claim.unit if claim is not None else "share"
    limit = None if claim is None else claim.share_limit
    if column is not None:
        data.column(column)  # a missing column is refused before any work, naming the available ones
    pred = predict_sets(model, PerceptionInputs(data.x, data.yhat, data.source))
    d = data.y - pred.centers
    g = np.linalg.norm(np.einsum("bij,bj->bi", pred.shapes, d), axis=1)
    violated = np.asarray(~(g <= 1.0), dtype=np.bool_)
    row_share = float(pred.in_domain.mean())
    if column is None:
        monitor = ViolationMonitor(epsilon, delta, in_domain_only=False)
        return LogMonitoring(
            result=monitor.run(violated, pred.in_domain),
            violated=violated,
            in_domain=pred.in_domain,
            epsilon=epsilon,
            delta=delta,
            calibration_delta=cal.delta,
            n_rows=len(violated),
            row_in_domain_fraction=row_share,
            runs=ViolationRuns.of(violated),
            null=_NULLS["rows"].format(rate=epsilon),
        )
    obs = _per_group(data, column, statistic, violated, pred.in_domain, limit)
    # a domain test fitted by groups bounds a new group's expected share of queries outside: test it per group
    dom = model.domain
    domain_rate = dom.flag_rate if dom is not None and dom.n_groups is not None else None
    monitor = ViolationMonitor(epsilon, delta, in_domain_only=False, domain_rate=domain_rate)
    what = {
        "trajectory": "any violation",
        "share-of-runs": f"more than {limit:g} of its rows outside" if limit is not None else "",
    }.get(statistic, "share of rows outside")
    return LogMonitoring(
        result=monitor.run(obs.statistic, obs.mostly_inside, obs.outside_share),
        violated=obs.statistic,
        in_domain=obs.mostly_inside,
        epsilon=epsilon,
        delta=delta,
        calibration_delta=cal.delta,
        unit=f"groups of {column} ({what})",
        labels=obs.labels,
        n_rows=len(violated),
        row_in_domain_fraction=row_share,
        null=_NULLS[statistic].format(rate=epsilon, limit=limit or 0.0),
        domain_rate=domain_rate,
    )
