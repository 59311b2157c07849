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
    from ipcverify.calibration._global_scale import Global
    from ipcverify.calibration._grouped_spec import Grouped
    from ipcverify.calibration._mondrian import Mondrian
    from ipcverify.calibration._run_plan import plan_runs

__all__ = [
    "Global",
    "Grouped",
    "Mondrian",
    "plan_runs",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
