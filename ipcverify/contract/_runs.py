"""Which unit a calibration's claim is about when the data come in runs, and what the runs support.

A robot log is a few runs (flights, drives), and the rows of one run are correlated. When the
calibration data name their runs, :func:`choose_method` makes the claim about runs
(:class:`~ipcverify.calibration.Grouped`, expected share) unless the caller chose a kind
explicitly; a row-level claim on such data is then an explicit choice, recorded as an assumption.
:func:`run_record` measures what the runs support -- the smallest rate they can certify, the runs
the target needs (:func:`~ipcverify.calibration._run_plan.plan_runs`) and the within-run
dependence at the calibrated scale (:func:`~ipcverify.calibration._dependence.measure_dependence`)
-- and is stored in the model's metadata under :data:`RUNS_KEY`, where certificates read it.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ipcverify._wording._spelling import option
from ipcverify.calibration._dependence import measure_dependence
from ipcverify.calibration._global_scale import Global
from ipcverify.calibration._grouped_spec import Grouped
from ipcverify.calibration._method import CalibrationMethod
from ipcverify.calibration._protocol import Calibration
from ipcverify.calibration._run_plan import plan_runs
from ipcverify.data._checks import group_like_counts
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import Hint, InvalidInputError

#: Model metadata: what the calibration data's runs support (:func:`run_record`).
RUNS_KEY = "calibration_runs"


class AmbiguousRunsError(InvalidInputError):
    """The calibration data have several columns that could name runs, and no kind was chosen."""


def choose_method(
    data: PerceptionDataset, method: CalibrationMethod | None
) -> tuple[CalibrationMethod, bool]:
    """The calibration kind: ``method`` if given, else one chosen from the data; and whether it was chosen.

    With no ``method``: data with one column that names runs (``run``, ``flight``, ``segment``, ...:
    :func:`~ipcverify.data._checks.group_like_counts`) are calibrated by those runs
    (``Grouped(column=...)``, expected share); data with none row by row (``Global()``).

    Parameters
    ----------
    data : PerceptionDataset
        The calibration data.
    method : CalibrationMethod or None
        The caller's choice (None: choose).

    Raises
    ------
    AmbiguousRunsError
        If no method is given and several columns could name the runs.

    Examples
    --------
    >>> z = np.zeros((6, 1))
    >>> choose_method(PerceptionDataset(z, z, z, extra={"flight": np.arange(6) // 2}), None)
    (Grouped(mode='pac', column='flight', guarantee='expected-share', gamma=None, seed=0), True)
    >>> choose_method(PerceptionDataset(z, z, z), None)
    (Global(mode='pac'), True)
    """
    if method is not None:
        return method, False
    runs = group_like_counts(data)
    if not runs:
        return Global(), True
    if len(runs) > 1:
        listed = ", ".join(f"{c!r} ({g} groups)" for c, g in runs.items())
        raise AmbiguousRunsError(
            f"{data.source}: several columns could name the runs ({listed}); say which one's groups are "
            f"independent runs ({option('grouped', 'COL')}), or make a row-level claim explicitly with "
            f"{option('unit_row')}"
        )
    return Grouped(column=next(iter(runs))), True


def run_column(data: PerceptionDataset, method: CalibrationMethod) -> str | None:
    """The column whose runs the calibration data come in: the method's unit column, else a run-like one."""
    if method.unit_column is not None:
        return method.unit_column
    runs = group_like_counts(data)
    return next(iter(runs), None)


def run_record(
    cal: Calibration,
    data: PerceptionDataset,
    normalized: NDArray[np.float64],
    method: CalibrationMethod,
    chosen: bool,
    domain_by_rows: bool = False,
) -> dict[str, Any] | None:
    """What the calibration data's runs support, for the model's metadata (None: the data have no runs).

    Parameters
    ----------
    cal : Calibration
        The fitted calibration.
    data : PerceptionDataset
        The calibration data.
    normalized : ndarray, shape (N,)
        Each calibration row's score over its calibrated scale (above 1: outside its set).
    method : CalibrationMethod
        The spec that fitted ``cal``.
    chosen : bool
        Whether ipcverify chose the method (False: the caller did).
    domain_by_rows : bool
        Whether the domain test was fitted row by row (the hint of a row-level claim then says
        how to fit it by runs).

    Returns
    -------
    dict or None
        ``{column, n_runs, unit, row_claim_chosen, plan, dependence}``: the unit of the claim
        (``"run"`` or ``"row"``), whether a row-level claim on run data was the caller's explicit
        choice, the :class:`~ipcverify.calibration._run_plan.RunPlan` at the calibration's
        ``(epsilon, delta)`` and the :class:`~ipcverify.calibration._dependence.RunDependence` at
        the calibrated scale.
    """
    column = run_column(data, method)
    if column is None:
        return None
    dependence = measure_dependence(normalized, data.column(column), 1.0, column)
    unit = "run" if method.unit_column is not None else "row"
    gamma = getattr(cal, "gamma", None)
    plan = plan_runs(dependence.n_runs, cal.delta, epsilon=cal.epsilon, gamma=gamma)
    if unit == "row":
        warnings.warn(
            Hint(
                f"{data.source}: a row-level claim on data with runs of {column!r}"
                + (" (chosen explicitly)" if not chosen else "")
                + f" assumes independent rows: {dependence.sentence()}; a claim about runs "
                f"({option('unit_run', column)}) would hold without that assumption; "
                + plan.sentence()
                + (
                    " The domain test, fitted row by row, flags the rows of a new run too often: fit it by "
                    f"runs ({option('domain_group_column', column)})."
                    if domain_by_rows
                    else ""
                )
            ),
            stacklevel=3,
        )
    return {
        "column": column,
        "n_runs": dependence.n_runs,
        "unit": unit,
        "row_claim_chosen": unit == "row" and not chosen,
        "plan": plan.to_dict(),
        "dependence": dependence.to_dict(),
    }
