"""Calibrating a learned IPC on held-out data with one scale factor (or one per group).

One module per job: :mod:`~ipcverify.calibration.threshold` (the order statistic of one
set of scores), :mod:`~ipcverify.calibration.protocol` (what every kind provides),
:mod:`~ipcverify.calibration.global_scale` and :mod:`~ipcverify.calibration.mondrian` (the
kinds) and :mod:`~ipcverify.calibration.kinds` (their registry). The pipeline step that
calibrates a model is :func:`ipcverify.calibrate.calibrate`.

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

Grouped calibration (:mod:`~ipcverify.calibration.grouped`) treats groups of correlated
samples (flights, runs; a column of the calibration data only) as the exchangeable units
and gives one scale with a trajectory-level guarantee (every sample of a new flight inside)
or a per-sample one valid under group exchangeability. Proofs:
``proofs/group_calibration.md``.

The stored scale is the order statistic times ``1 + SCALE_MARGIN``: a slightly
larger set, so that float32 rounding differences between batch sizes cannot
turn a calibration sample on the boundary into a violation.
"""

from __future__ import annotations

from ipcverify.calibration.global_scale import GlobalCalibration
from ipcverify.calibration.grouped import (
    GUARANTEES,
    GroupedCalibration,
    GroupViolations,
    group_violation_counts,
    risk_control_threshold,
)
from ipcverify.calibration.kinds import KINDS, calibration_from_dict
from ipcverify.calibration.mondrian import MAX_GROUPS, GroupScale, MondrianCalibration
from ipcverify.calibration.protocol import AllowedRate, Calibration, CalibrationSummary, GroupInfo
from ipcverify.calibration.threshold import SCALE_MARGIN, ScoreThreshold, threshold_scores

__all__ = [
    "GUARANTEES",
    "KINDS",
    "MAX_GROUPS",
    "SCALE_MARGIN",
    "AllowedRate",
    "Calibration",
    "CalibrationSummary",
    "GlobalCalibration",
    "GroupInfo",
    "GroupViolations",
    "GroupedCalibration",
    "GroupScale",
    "MondrianCalibration",
    "ScoreThreshold",
    "calibration_from_dict",
    "group_violation_counts",
    "risk_control_threshold",
    "threshold_scores",
]
