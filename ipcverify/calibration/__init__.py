"""Calibrating a learned IPC on held-out data with one scale factor (or one per group).

One module per job: :mod:`~ipcverify.calibration._threshold` (the order statistic of one
set of scores), :mod:`~ipcverify.calibration._protocol` (what every kind provides),
:mod:`~ipcverify.calibration._global_scale`, :mod:`~ipcverify.calibration._mondrian` and
:mod:`~ipcverify.calibration._grouped` (the kinds, each a calibration record and the spec that
fits it: :class:`Global`, :class:`Mondrian`, :class:`Grouped`) and
:mod:`~ipcverify.calibration._kinds` (their registry). The pipeline step that calibrates a
model is :func:`ipcverify.contract.calibrate`, which takes a spec:
``calibrate(model, data, epsilon, delta, Grouped(column="run"))``.

The network's score ``g = ||C (y - c)||`` is computed on ``n`` calibration samples
that were *not* used for training. The calibrated contract is ``E(c, C / s)`` with
``s`` the ``k``-th smallest score, so that ``y`` lies in it exactly when
``g <= s``:

* ``mode="pac"`` (training-conditional): ``k`` from
  :func:`ipcverify.calibration.pac_calibration_index`; with probability at least
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

Grouped calibration (:mod:`~ipcverify.calibration._grouped`) treats groups of correlated
samples (flights, runs; a column of the calibration data only) as the exchangeable units
and gives one scale with a claim about a new run: its expected share of rows outside (the
default), the share of new runs with more than epsilon outside, or every row inside. Proofs:
``proofs/group_calibration.md`` and ``proofs/run_claims.md``.

The stored scale is the order statistic times ``1 + SCALE_MARGIN``: a slightly
larger set, so that float32 rounding differences between batch sizes cannot
turn a calibration sample on the boundary into a violation.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.calibration._bounds import (
        TAIL_MARGIN,
        CalibrationMode,
        clopper_pearson_interval,
        clopper_pearson_lower,
        clopper_pearson_upper,
        marginal_conformal_index,
        min_calibration_size,
        pac_calibration_index,
        pac_epsilon,
        pac_rows_allowing,
        smallest_epsilon,
        smallest_marginal_epsilon,
    )
    from ipcverify.calibration._global_scale import (
        Global,
        GlobalCalibration,
    )
    from ipcverify.calibration._group_counts import (
        GUARANTEES,
        GroupViolations,
        GuaranteeKind,
        group_violation_counts,
    )
    from ipcverify.calibration._grouped import GroupedCalibration
    from ipcverify.calibration._grouped_spec import Grouped
    from ipcverify.calibration._kinds import (
        KINDS,
        METHODS,
        calibration_from_dict,
        register_kind,
    )
    from ipcverify.calibration._method import (
        CalibrationMethod,
        CalibrationRecord,
        CalibrationSample,
        CalibrationSpec,
    )
    from ipcverify.calibration._mondrian import (
        GroupScale,
        Mondrian,
        MondrianCalibration,
    )
    from ipcverify.calibration._mondrian_groups import (
        EDGE_FRACTION,
        MAX_GROUPS,
    )
    from ipcverify.calibration._protocol import (
        GROUP_UNITS,
        AllowedRate,
        Calibration,
        CalibrationSummary,
        GroupClaim,
        GroupInfo,
        GroupUnit,
        TestCounts,
    )
    from ipcverify.calibration._risk_control import (
        risk_control_threshold,
    )
    from ipcverify.calibration._run_plan import (
        ClaimPlan,
        RunPlan,
        plan_runs,
    )
    from ipcverify.calibration._share_bound import (
        run_floor,
        share_lower_bound,
        share_upper_bound,
    )
    from ipcverify.calibration._threshold import (
        MODES,
        SCALE_MARGIN,
        ScoreThreshold,
        threshold_scores,
    )

__all__ = [
    "EDGE_FRACTION",
    "GROUP_UNITS",
    "GUARANTEES",
    "KINDS",
    "MAX_GROUPS",
    "METHODS",
    "MODES",
    "SCALE_MARGIN",
    "TAIL_MARGIN",
    "AllowedRate",
    "Calibration",
    "CalibrationMethod",
    "CalibrationMode",
    "CalibrationRecord",
    "CalibrationSample",
    "CalibrationSpec",
    "CalibrationSummary",
    "ClaimPlan",
    "Global",
    "GlobalCalibration",
    "GroupClaim",
    "GroupInfo",
    "GroupScale",
    "GroupUnit",
    "GroupViolations",
    "Grouped",
    "GroupedCalibration",
    "GuaranteeKind",
    "Mondrian",
    "MondrianCalibration",
    "RunPlan",
    "ScoreThreshold",
    "TestCounts",
    "calibration_from_dict",
    "clopper_pearson_interval",
    "clopper_pearson_lower",
    "clopper_pearson_upper",
    "group_violation_counts",
    "marginal_conformal_index",
    "min_calibration_size",
    "pac_calibration_index",
    "pac_epsilon",
    "pac_rows_allowing",
    "plan_runs",
    "register_kind",
    "risk_control_threshold",
    "run_floor",
    "share_lower_bound",
    "share_upper_bound",
    "smallest_epsilon",
    "smallest_marginal_epsilon",
    "threshold_scores",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
