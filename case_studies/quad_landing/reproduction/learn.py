"""Learn and calibrate an IPC with the reproduction's recipe, cached on disk.

The recipe (:class:`.reproduction.config.IpcParams`, ``[ipc]`` of ``reproduce.toml``) is a
library recipe on ``(x_C, yhat_C)`` with the paper's hidden layers (64, 128): ipcverify's
default ``tight`` (an ensemble with a low-rank covariance head, trained by likelihood), or the
earlier ``v1`` head with ``v1_head.toml`` (``docs/reproduce.md``; the paper's own network is
:mod:`.paper_ipc`). It is trained
(:func:`ipcverify.training.train`), then calibrated in PAC
mode on a separate calibration set (:func:`ipcverify.contract.calibrate`): with probability at least
``1 - delta`` over the calibration draw, a fresh sample from the calibration
distribution violates the calibrated contract with probability at most ``epsilon``.

Examples
--------
>>> from case_studies.quad_landing.data.datasets import as_dataset, collect_mixed
>>> from case_studies.quad_landing.data.approach import ApproachParams
>>> from case_studies.quad_landing.reproduction.config import IpcParams
>>> ap = ApproachParams.defaults(hover_points=1)
>>> tr = as_dataset(collect_mixed(300, buffer_size=1, seed=0, approach=ap))
>>> cal = as_dataset(collect_mixed(700, buffer_size=1, seed=1, approach=ap))
>>> model = learn_ipc(tr, cal, IpcParams.defaults(epochs=2, epsilon=0.05, delta=0.01))
>>> model.calibration.mode, model.calibration.n
('pac', 700)

The same network calibrated with the calibration flights, not rows, as the exchangeable units
(:func:`flight_level_check`):

>>> check = flight_level_check(model, cal, 0.25)
>>> check.n_flights == len(set(cal.extra["flight"])), check.row_scale > 0
(True, True)
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import torch

from case_studies.quad_landing.reproduction.config import IpcParams
from case_studies.quad_landing.reproduction.record import Record
from ipcverify.calibration import Global, Grouped, plan_runs
from ipcverify.calibration._protocol import CalibrationSummary
from ipcverify.contract import IPCModel, calibrate
from ipcverify.data import PerceptionDataset
from ipcverify.data._files import atomic_write
from ipcverify.errors import Hint, ModelFileError, SampleSizeError
from ipcverify.guard import DomainSpec
from ipcverify.io import load_model, save_model
from ipcverify.network import ModelConfig
from ipcverify.training import train

__all__ = [
    "learn_ipc",
    "cached_ipc",
    "calibration_summary",
    "certified_epsilon",
    "domain_groups",
    "row_level_calibration",
    "flight_level_check",
    "FlightLevelCheck",
]


def learn_ipc(
    train_data: PerceptionDataset,
    calibration_data: PerceptionDataset,
    params: IpcParams,
    *,
    progress: bool = False,
) -> IPCModel:
    """Train on ``train_data``, then PAC-calibrate on ``calibration_data`` (held out).

    Parameters
    ----------
    train_data, calibration_data : PerceptionDataset
        Disjoint data (different seeds, so different paths and flights).
    params : IpcParams
        Network (``hidden``), training (``train``, a :class:`~ipcverify.training.TrainConfig`)
        and calibration (``epsilon``, ``delta``) settings.
    progress : bool
        Show the training progress bar.

    Returns
    -------
    IPCModel
        The calibrated model.
    """
    mc = ModelConfig.recipe(
        params.recipe, x_dim=train_data.x_dim, y_dim=train_data.y_dim, hidden=params.hidden
    )
    # on ipcverify's torch threads for training: one unless OMP_NUM_THREADS says otherwise
    model = train(train_data, mc, params.train, progress=progress).model
    return row_level_calibration(model, calibration_data, params.epsilon, params.delta,
                                 params.coverage_quantile)  # fmt: skip


def row_level_calibration(
    model: IPCModel,
    calibration_data: PerceptionDataset,
    epsilon: float,
    delta: float,
    coverage_quantile: float,
) -> IPCModel:
    """PAC calibration by rows, with the domain of validity fitted by flight where there are enough.

    The reproduction calibrates its 10 Hz samples row by row on purpose, because its certified
    bound on unsafe landings is derived for a row-level calibration, and checks the flights
    separately (:func:`flight_level_check`, the certificates' per-flight test). The library's
    hint that rows of one flight may be correlated (:class:`ipcverify.errors.Hint`) is therefore
    silenced here; its other warnings are not.
    """
    alpha = 1.0 - coverage_quantile
    by = domain_groups(calibration_data, alpha)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", Hint)
        return calibrate(model, calibration_data, epsilon, delta, Global(mode="pac"),
                         domain=DomainSpec(flag_rate=alpha, group_column=by))  # fmt: skip


def domain_groups(calibration_data: PerceptionDataset, alpha: float) -> str | None:
    """``"flight"`` if the domain of validity can be fitted by flight at false-alarm rate ``alpha``.

    The domain of validity (:class:`ipcverify.guard.DomainModel`) flags a query farther from
    the calibration inputs than they lie from each other. Rows of one flight lie close to each
    other, so a row-level threshold flags much of a *new* flight; fitted by flight (each input
    measured against other flights, a risk-control threshold), a new flight's expected share
    flagged is at most ``alpha``. That needs at least ``1 / alpha - 1`` flights; with fewer
    (the ablation's small sets) the row-level test is used. The model's ``domain.method`` and
    ``domain.n_groups`` record which.

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify import PerceptionDataset
    >>> z = np.zeros((200, 1))
    >>> data = PerceptionDataset(z, z, z, extra={"flight": np.arange(200) // 2})
    >>> domain_groups(data, 0.01), domain_groups(data, 0.001)
    ('flight', None)
    """
    flights = calibration_data.extra.get("flight")
    if flights is None or len(set(flights.tolist())) < 1.0 / alpha - 1.0:
        return None
    return "flight"


def certified_epsilon(model: IPCModel) -> float:
    """The violation rate the model's calibration certifies (at its ``1 - delta``)."""
    return float(model.require_calibration().summary().certified_epsilon)


def calibration_summary(model: IPCModel) -> CalibrationSummary:
    """The calibration of a model, with its certified epsilon and guarantee (``to_dict`` for JSON)."""
    return model.require_calibration().summary()


@dataclass(frozen=True, kw_only=True)
class FlightLevelCheck(Record):
    """The network calibrated with its flights as the exchangeable units, beside the row-level scale.

    What :func:`flight_level_check` finds; ``summary.json``'s ``ipc.k<buffer>.flight_level`` is
    :meth:`to_dict`. The ``flight_*`` values are None when there are too few flights for
    ``epsilon``.
    """

    n_flights: int
    n_rows: int
    epsilon: float
    row_scale: float
    row_guarantee: str
    row_scale_mean_violation_fraction: float
    flight_scale: float | None = None
    flight_guarantee: str | None = None
    flight_mean_violation_fraction: Any = None
    run_floor: float | None = None
    run_epsilon: float | None = None
    run_scale: float | None = None
    run_guarantee: str | None = None
    run_mean_share: float | None = None


def flight_level_check(
    model: IPCModel, calibration_data: PerceptionDataset, epsilon: float
) -> FlightLevelCheck:
    """Calibrate the same network with its flights, not its rows, as the exchangeable units.

    The reproduction's calibration treats the 10 Hz samples as exchangeable rows, but the
    samples of one flight are correlated. This recalibrates the raw network by conformal risk
    control over the calibration data's flights (``group_column="flight"``, marginal,
    per-sample guarantee: a new flight's expected share of samples outside their sets is at
    most ``epsilon``; ``proofs/group_calibration.md``) and returns both scale factors. A
    flight-level scale above the row-level one means the flight-level guarantee costs larger
    sets: with ``G`` flights, risk control must leave room for a whole new flight outside its
    sets (the ``+ 1`` in ``(sum_g V_g + 1) / (G + 1) <= epsilon``), so with few flights it is
    strict. ``row_scale_mean_violation_fraction`` is the calibration flights' mean share
    outside at the row-level scale (descriptive, in-sample). ``None`` values mean there are
    too few flights for ``epsilon`` (at least ``1 / epsilon - 1`` are needed).

    Examples
    --------
    The module's example (it needs a learned model and its calibration data) runs it:
    ``flight_level_check(model, cal, 0.25).n_flights`` is the number of calibration flights.
    """
    row = model.require_calibration().summary()
    row_scale = float(row.groups[0].scale)
    flights = calibration_data.extra["flight"]
    check = FlightLevelCheck(
        n_flights=len(set(flights.tolist())),
        n_rows=len(calibration_data),
        epsilon=float(epsilon),
        row_scale=row_scale,
        row_guarantee=row.guarantee,
        row_scale_mean_violation_fraction=_mean_flight_violations(model, calibration_data, row_scale),
    )
    plan = plan_runs(check.n_flights, row.delta)
    target = max(float(epsilon), float(plan.claim("expected-share").smallest or 1.0))
    if target < 1.0:
        pac = calibrate(model, calibration_data, target, row.delta, Grouped(column="flight"), domain=None,
                        recalibrate=True).require_calibration().summary()  # fmt: skip
        check = dataclasses.replace(
            check,
            run_floor=plan.floor,
            run_epsilon=target,
            run_scale=float(pac.groups[0].scale),
            run_guarantee=pac.guarantee,
            run_mean_share=pac.details.get("risk"),
        )
    try:
        by_flight = calibrate(model, calibration_data, epsilon, row.delta,
                              Grouped(column="flight", guarantee="expected-share", mode="marginal"),
                              domain=None, recalibrate=True)  # fmt: skip
    except SampleSizeError:
        return check
    summary = by_flight.require_calibration().summary()
    return dataclasses.replace(
        check,
        flight_scale=float(summary.groups[0].scale),
        flight_guarantee=summary.guarantee,
        flight_mean_violation_fraction=summary.details.get("risk"),
    )


def _mean_flight_violations(model: IPCModel, data: PerceptionDataset, scale: float) -> float:
    """Mean over flights of the share of a flight's samples outside the sets scaled by ``scale``."""
    outside = model.raw_scores(data.x, data.y, data.yhat) > scale
    frame = pd.DataFrame({"flight": data.extra["flight"], "outside": outside})
    return float(frame.groupby("flight")["outside"].mean().mean())


def _key(
    train_data: PerceptionDataset, calibration_data: PerceptionDataset, params: IpcParams
) -> dict[str, Any]:
    return {
        "train": train_data.content_hash(),
        "calibration": calibration_data.content_hash(),
        "params": json.loads(json.dumps(params.to_table(), default=list)),
        "torch": torch.__version__,
        "model_format": 3,  # 2: the model carries its domain-of-validity test; 3: fitted by flight
    }


def cached_ipc(
    path: str | Path,
    train_data: PerceptionDataset,
    calibration_data: PerceptionDataset,
    params: IpcParams,
    *,
    progress: bool = False,
) -> tuple[IPCModel, bool]:
    """:func:`learn_ipc`, reusing ``path`` (a model file) if it was made from the same data and settings.

    Returns
    -------
    model : IPCModel
    cached : bool
        True if the file was reused.
    """
    p = Path(path)
    key_path = p.with_suffix(".key.json")
    key = _key(train_data, calibration_data, params)
    if p.exists() and key_path.exists():
        try:
            if json.loads(key_path.read_text()) == key:
                return load_model(p), True
        except (json.JSONDecodeError, OSError, ModelFileError):
            pass
    model = learn_ipc(train_data, calibration_data, params, progress=progress)
    save_model(model, p)
    text = json.dumps(key, indent=1) + "\n"
    atomic_write(key_path, lambda fh: fh.write(text), "w")
    return model, False
