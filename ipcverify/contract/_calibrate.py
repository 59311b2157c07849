"""The calibrate step of the pipeline: :func:`calibrate` a trained IPC on held-out data.

The network's score ``g = ||C (y - c)||`` is computed on calibration samples that were
*not* used for training; the kind of calibration (:mod:`ipcverify.calibration`: global, or
Mondrian per group of a column) is chosen by the arguments, and the result is attached to
the model. The guarantees are proved in ``proofs/pac_calibration.md``.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from ipcverify.calibration._bounds import CalibrationMode
from ipcverify.calibration._global_scale import GlobalCalibration
from ipcverify.calibration._grouped import GroupedCalibration, GuaranteeKind
from ipcverify.calibration._mondrian import MondrianCalibration
from ipcverify.calibration._protocol import Calibration
from ipcverify.calibration._threshold import check_eps_delta, check_mode
from ipcverify.contract._model import IPCModel
from ipcverify.data._checks import check_informative, warn_correlated_rows, warn_outside_training
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError, SampleSizeError
from ipcverify.guard._domain import DEFAULT_ALPHA, DomainModel


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


def calibrate(
    model: IPCModel,
    calibration_data: PerceptionDataset,
    epsilon: float,
    delta: float,
    mode: CalibrationMode = "pac",
    *,
    mondrian_column: str | None = None,
    bins: int | None = None,
    group_column: str | None = None,
    guarantee: GuaranteeKind = "sample",
    recalibrate: bool = False,
    edge_fraction: float = 0.2,
    seed: int = 0,
    domain_alpha: float | None = DEFAULT_ALPHA,
    domain_group_column: str | None = None,
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
    mondrian_column : str, optional
        An ``x`` or ``yhat`` column for Mondrian (per-group) calibration.
    bins : int, optional
        With ``mondrian_column``: calibrate per quantile bin of a continuous column.
        Without it, the column's distinct values are the groups.
    group_column : str, optional
        A column naming the exchangeable unit of the data -- flights, runs, sequences (any
        column of the file, not needed at predict time). Samples within one group are
        correlated, so the groups, not the rows, are calibrated as exchangeable units
        (:class:`~ipcverify.calibration.GroupedCalibration`, ``proofs/group_calibration.md``).
    guarantee : {"sample", "trajectory"}
        With ``group_column``: bound the expected share of a new group's samples outside their
        sets (``"sample"``), or the probability that a new group leaves its sets anywhere
        (``"trajectory"``).
    recalibrate : bool
        Allow replacing an existing calibration.
    edge_fraction : float
        Share of the calibration data used only to place the bin edges.
    seed : int
        Seeds the choice of that share (and of the domain test's reference subset).
    domain_alpha : float or None
        False-alarm rate of the domain-of-validity test fitted on the calibration inputs
        (:class:`~ipcverify.guard.DomainModel`, attached to the model); None fits none.
    domain_group_column : str, optional
        Fit the domain test with the groups of this column as the exchangeable units
        (leave-one-group-out distances, risk-control threshold: a new group's expected share
        of flagged queries is at most ``domain_alpha``). Defaults to ``group_column``. Without
        it, calibration rows of one flight sit close to each other and a row-level threshold
        flags much of a *new* flight.

    Raises
    ------
    SampleSizeError
        If there are too few samples (overall or in a group) for ``(epsilon, delta)``, or for
        the domain test at ``domain_alpha``; every unmet requirement is named in one message.
    InvalidInputError
        If the model is already calibrated, the dimensions disagree, the data is the
        training data, is made mostly of repeated rows, or the group column cannot be seen at
        predict time.

    Warns
    -----
    DataWarning
        If most calibration inputs lie outside the ranges of the training inputs, if rows repeat,
        or if a column is constant.
    Hint
        If the data have a ``run``, ``flight``, ``sequence`` or ``group`` column and are
        calibrated row by row (neither ``group_column`` nor ``domain_group_column`` given).

    Examples
    --------
    >>> from ipcverify.data._synthetic import make_lagged_perception
    >>> from ipcverify.network._modules import IPCNetwork
    >>> from ipcverify.network._architecture import ModelConfig
    >>> net = IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky"))
    >>> cal = calibrate(IPCModel(net), make_lagged_perception(1000, seed=1), 0.05, 0.01)
    >>> cal.calibration.groups()[0].k, cal.domain.alpha
    (966, 0.01)
    """
    _check_inputs(model, calibration_data, epsilon, delta, mode, recalibrate)
    if bins is not None and mondrian_column is None:
        raise InvalidInputError("bins needs a group column (CLI: --mondrian-column COL --bins K)")
    if mondrian_column is not None and group_column is not None:
        raise InvalidInputError(
            "choose one of a Mondrian column (one scale per group of an x/yhat column) and a group column "
            "(flights or runs as the exchangeable units); they cannot be combined"
        )
    scores = model.raw_scores(calibration_data.x, calibration_data.y, calibration_data.yhat)
    ids = {"data_hash": calibration_data.content_hash(), "network_hash": model.weights.fingerprint()}
    unmet: list[str] = []  # every sample-size requirement is reported at once
    cal: Calibration | None = None
    try:
        if group_column is not None:
            cal = GroupedCalibration.fit(
                scores,
                calibration_data.column(group_column),
                epsilon,
                delta,
                mode,
                guarantee=guarantee,
                column=group_column,
                seed=seed,
                **ids,
            )
        elif mondrian_column is None:
            cal = GlobalCalibration.fit(scores, epsilon, delta, mode, **ids)
        else:
            source, index = _locate_column(calibration_data, mondrian_column)
            values = (calibration_data.x if source == "x" else calibration_data.yhat)[:, index]
            cal = MondrianCalibration.fit(
                scores,
                np.asarray(values, dtype=np.float64),
                column=mondrian_column,
                source=source,
                index=index,
                bins=bins,
                epsilon=epsilon,
                delta=delta,
                mode=mode,
                edge_fraction=edge_fraction,
                seed=seed,
                **ids,
            )
    except SampleSizeError as exc:
        unmet.append(str(exc))
    domain = None
    if domain_alpha is not None:
        domain_groups = group_column if domain_group_column is None else domain_group_column
        try:
            domain = DomainModel.fit(
                calibration_data.x,
                calibration_data.yhat,
                alpha=domain_alpha,
                seed=seed,
                groups=None if domain_groups is None else calibration_data.column(domain_groups),
            )
        except SampleSizeError as exc:
            unmet.append(str(exc))
    if unmet:
        raise SampleSizeError(
            unmet[0]
            if len(unmet) == 1
            else f"{len(unmet)} requirements are not met: "
            + " ".join(f"({i}) {m.rstrip('.')}." for i, m in enumerate(unmet, 1))
        )
    if cal is None:  # unreachable: every branch above assigns or raises
        raise SampleSizeError("no calibration was fitted")
    if group_column is None and domain_group_column is None:
        remedy = "to calibrate with whole groups as the exchangeable units"
        warn_correlated_rows(calibration_data, "calibrating", remedy)
    warn_outside_training(model.metadata, calibration_data)
    return model.with_calibration(cal, domain)


def _check_inputs(
    model: IPCModel,
    calibration_data: PerceptionDataset,
    epsilon: float,
    delta: float,
    mode: str,
    recalibrate: bool,
) -> None:
    """Refuse a calibration that could not carry its guarantee."""
    check_mode(mode)
    check_eps_delta(epsilon, delta)
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
    check_informative(calibration_data, "calibration")
    if calibration_data.content_hash() == model.metadata.get("train_data_hash"):
        raise InvalidInputError(
            f"{calibration_data.source}: this is the model's training data; calibration needs held-out "
            "samples that were not used for training (e.g. the calibration part of a split)"
        )
