"""The calibrate step of the pipeline: :func:`calibrate` a trained IPC on held-out data.

The network's score ``g = ||C (y - c)||`` is computed on calibration samples that were
*not* used for training; the kind of calibration is a spec object
(:mod:`ipcverify.calibration`: :class:`~ipcverify.calibration.Global`,
:class:`~ipcverify.calibration.Mondrian` per group of a column,
:class:`~ipcverify.calibration.Grouped` with flights as the units, or any registered kind)
that fits itself, and the domain-of-validity test is fitted as its
:class:`~ipcverify.guard.DomainSpec` says; both are attached to the model. The guarantees are
proved in ``proofs/pac_calibration.md``.
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray

from ipcverify._wording._spelling import Remedy, option
from ipcverify.calibration._bounds import pac_rows_allowing
from ipcverify.calibration._kinds import check_registered
from ipcverify.calibration._method import CalibrationMethod, CalibrationSample
from ipcverify.calibration._protocol import Calibration
from ipcverify.calibration._threshold import check_eps_delta
from ipcverify.contract._guarded import CALIBRATION_GROUPS_KEY
from ipcverify.contract._model import IPCModel
from ipcverify.contract._runs import RUNS_KEY, choose_method, run_record
from ipcverify.data._checks import check_informative, group_like_counts, warn_outside_training
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._fingerprints import count_recorded, recorded_rows, row_fingerprints, with_recorded_rows
from ipcverify.errors import Hint, InvalidInputError, SampleSizeError
from ipcverify.guard._domain import DomainModel
from ipcverify.guard._domain_spec import DomainSpec

#: The default domain test: flag rate ``DEFAULT_FLAG_RATE`` of :mod:`ipcverify.guard._domain` (or the
#: smallest the runs allow), with the calibration's units.
DEFAULT_DOMAIN = DomainSpec()


def calibrate(
    model: IPCModel,
    calibration_data: PerceptionDataset,
    epsilon: float,
    delta: float,
    method: CalibrationMethod | None = None,
    *,
    domain: DomainSpec | None = DEFAULT_DOMAIN,
    recalibrate: bool = False,
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
    method : CalibrationMethod, optional
        The kind of calibration and its options, a registered spec (it fits itself):
        ``Global(mode="pac")`` (one scale, rows as the units, PAC or ``mode="marginal"``),
        ``Mondrian(column=..., bins=..., edge_fraction=..., seed=..., mode=...)`` (one scale per
        group of an ``x`` or ``yhat`` column) or ``Grouped(column=..., guarantee=..., gamma=...,
        mode=...)`` (flights or runs as the exchangeable units,
        :class:`~ipcverify.calibration.GroupedCalibration`, ``proofs/run_claims.md``). Default:
        by runs when the data have one column that names them (``run``, ``flight``, ...:
        ``Grouped(column=...)``, expected share), else ``Global()``. A row-level claim on data
        with runs is then an explicit choice, recorded in the model as an assumption with the
        data's effective number of independent rows.
    domain : DomainSpec or None
        How to fit the domain-of-validity test on the calibration inputs
        (:class:`~ipcverify.guard.DomainModel`, attached to the model): its false-alarm rate
        ``flag_rate`` and the column whose groups are its units (default: the method's, e.g. a
        ``Grouped`` calibration's column); None fits none.
    recalibrate : bool
        Allow replacing an existing calibration.

    Raises
    ------
    SampleSizeError
        If there are too few samples (overall or in a group) for ``(epsilon, delta)``, or for
        the domain test at its ``flag_rate``; every unmet requirement is named in one message.
    InvalidInputError
        If the model is already calibrated, the dimensions disagree, some calibration rows are
        training rows (whatever their order or repeats: by the row fingerprints the model file
        records, :mod:`ipcverify.data._fingerprints`), the data is made mostly of repeated rows,
        the group column cannot be seen at predict time, ``method`` is not a registered
        calibration spec, or no method is given and several columns could name the runs.

    Warns
    -----
    DataWarning
        If most calibration inputs lie outside the ranges of the training inputs, if rows repeat
        (which breaks the exchangeability the guarantee rests on), or if a column is constant.
    Hint
        When the model file records no fingerprints of its training rows (only an exact copy of
        the training file is then recognised); when ipcverify chose to calibrate by runs; when a
        row-level claim is made on data with runs (with their effective number of independent
        rows); when the domain test takes the smallest false-alarm rate the runs allow.

    Examples
    --------
    >>> from ipcverify.calibration import Grouped
    >>> from ipcverify import example
    >>> from ipcverify.network import ModelConfig
    >>> net = example(config=ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")).model.network
    >>> cal = calibrate(IPCModel(net), example(1000, seed=1).data, 0.05, 0.01)
    >>> cal.calibration.groups()[0].k, cal.domain.flag_rate
    (966, 0.01)
    >>> import numpy as np
    >>> from ipcverify.data import PerceptionDataset
    >>> d = example(1000, seed=2).data
    >>> flights = PerceptionDataset(d.x, d.y, d.yhat, extra={"flight": np.arange(1000) // 10})  # 100 flights
    >>> by_flight = calibrate(IPCModel(net), flights, 0.1, 0.05, Grouped(column="flight"),
    ...                       domain=DomainSpec(flag_rate=0.05))
    >>> by_flight.calibration.n_groups, by_flight.domain.n_groups  # the domain test's units too
    (100, 100)
    >>> import warnings
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")
    ...     auto = calibrate(IPCModel(net), flights, 0.1, 0.05)    # the data name their runs
    >>> auto.calibration.guarantee_kind, auto.metadata["calibration_runs"]["unit"]
    ('expected-share', 'run')
    """
    if domain is not None and not isinstance(domain, DomainSpec):
        raise InvalidInputError(
            "domain must be a DomainSpec (ipcverify.guard), e.g. DomainSpec(flag_rate=0.01), or None; "
            f"got {domain!r}"
        )
    method, chosen = choose_method(calibration_data, method)
    _check_inputs(model, calibration_data, epsilon, delta, method, domain, recalibrate)
    rows = _fresh_rows(model, calibration_data)
    sample = CalibrationSample(
        scores=model.raw_scores(calibration_data.x, calibration_data.y, calibration_data.yhat),
        data=calibration_data,
        epsilon=epsilon,
        delta=delta,
        data_hash=calibration_data.content_hash(),
        network_hash=model.weights.fingerprint(),
    )
    unmet: list[tuple[str, tuple[Remedy, ...]]] = []  # every unmet sample-size requirement, at once
    cal: Calibration | None = None
    with warnings.catch_warnings(record=True) as caught:  # a hint is shown only if no error follows
        warnings.simplefilter("always")
        cal, dom = _fit(method, domain, sample, calibration_data, chosen, unmet)
    if unmet:
        raise SampleSizeError(
            unmet[0][0]
            if len(unmet) == 1
            else f"{len(unmet)} requirements are not met: "
            + " ".join(f"({i}) {m.rstrip('.')}." for i, (m, _) in enumerate(unmet, 1)),
            remedies=unmet[0][1] if len(unmet) == 1 else (),  # one requirement: its own remedies
        )
    if cal is None:  # unreachable: the fit above assigns or raises
        raise SampleSizeError("no calibration was fitted")
    if chosen and method.unit_column is not None:
        warnings.warn(
            Hint(
                f"{calibration_data.source}: its rows come in runs of {method.unit_column!r}, so the claim "
                "is "
                "about runs (the expected share of a new run's rows outside their sets); for a row-level "
                f"claim, which assumes independent rows, choose {option('unit_row')}"
            ),
            stacklevel=2,
        )
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if method.unit_column is None and cal.mode == "pac":
        warn_largest_score(cal, calibration_data.source)
    warn_outside_training(model.metadata, calibration_data)
    # what the certificate's "independent rows" check needs to know of a row-level calibration, and
    # what the runs of the calibration data support
    metadata = {k: v for k, v in model.metadata.items() if k not in (CALIBRATION_GROUPS_KEY, RUNS_KEY)}
    metadata = with_recorded_rows(metadata, "calibration", rows)  # certify refuses test rows among them
    if method.unit_column is None and (counts := group_like_counts(calibration_data)):
        metadata[CALIBRATION_GROUPS_KEY] = counts
    normalized = sample.scores / cal.scale_for(calibration_data.x, calibration_data.yhat)
    by_rows = domain is not None and domain.units(method.unit_column) is None
    if (record := run_record(cal, calibration_data, normalized, method, chosen, by_rows)) is not None:
        metadata[RUNS_KEY] = record
    return IPCModel(model.source, cal, metadata, dom)


def _fit(
    method: CalibrationMethod,
    domain: DomainSpec | None,
    sample: CalibrationSample,
    data: PerceptionDataset,
    chosen: bool,
    unmet: list[tuple[str, tuple[Remedy, ...]]],
) -> tuple[Calibration | None, DomainModel | None]:
    """Fit the calibration and the domain test; every unmet sample-size requirement goes to ``unmet``."""
    cal: Calibration | None = None
    try:
        cal = method.fit(sample)
    except SampleSizeError as exc:
        row_claim = f" or make a row-level claim explicitly with {option('unit_row')}"
        said = str(exc).rstrip(".") + (row_claim if chosen and method.unit_column is not None else "")
        unmet.append((said, exc.remedies))
    dom: DomainModel | None = None
    if domain is not None:
        try:
            dom = domain.fit(data, method.unit_column)
        except SampleSizeError as exc:
            unmet.append((str(exc), exc.remedies))
    return cal, dom


def warn_largest_score(cal: Calibration, source: str) -> None:
    """A :class:`~ipcverify.errors.Hint` for each group whose PAC scale is its largest calibration score.

    Below :func:`~ipcverify.calibration._bounds.pac_rows_allowing` ``(1, ...)`` samples, a PAC
    calibration lets none of them lie outside its set: the one most unusual sample sets the
    size of every set of its group. The hint says how many samples would allow one.

    Parameters
    ----------
    cal : Calibration
        A row-level PAC calibration (its groups' ``k`` are ranks of scores).
    source : str
        The calibration data's name, for the message.

    Examples
    --------
    >>> import warnings
    >>> from ipcverify import example
    >>> ex = example(50)
    >>> with warnings.catch_warnings(record=True) as w:
    ...     warnings.simplefilter("always")
    ...     warn_largest_score(calibrate(ex.model, ex.data, 0.1, 0.01, domain=None).calibration, "cal.csv")
    >>> print(str(w[-1].message)[:77])
    cal.csv: the calibrated scale is the largest of the 50 calibration scores: at
    """
    for g in cal.groups():
        if g.k != g.n:
            continue
        where = "" if g.label == "all" else f" of group {g.label}"
        need = pac_rows_allowing(1, cal.epsilon, cal.delta)
        warnings.warn(
            Hint(
                f"{source}: the calibrated scale{where} is the largest of the {g.n} calibration scores: at "
                f"epsilon={cal.epsilon:g}, delta={cal.delta:g}, {g.n} samples allow none of them outside its "
                f"set, so the single most unusual sample sets the size of every set; {need} samples would "
                "allow one, and more samples give a tighter scale"
            ),
            stacklevel=3,
        )


def _check_inputs(
    model: IPCModel,
    calibration_data: PerceptionDataset,
    epsilon: float,
    delta: float,
    method: CalibrationMethod,
    domain: DomainSpec | None,
    recalibrate: bool,
) -> None:
    """Refuse a calibration that could not carry its guarantee."""
    check_registered(method)
    check_eps_delta(epsilon, delta)
    if model.calibration is not None and not recalibrate:
        raise InvalidInputError(
            "the model is already calibrated; calibrating it again on top would compound the scale "
            f"factors and void the guarantee -- pass {option('recalibrate')} to "
            "calibrate the raw network afresh",
            remedies=(Remedy("recalibrate", True),),
        )
    cfg = model.config
    if (calibration_data.x_dim, calibration_data.y_dim) != (cfg.x_dim, cfg.y_dim):
        raise InvalidInputError(
            f"{calibration_data.source}: calibration data has x_dim={calibration_data.x_dim}, "
            f"y_dim={calibration_data.y_dim} but the model expects x_dim={cfg.x_dim}, y_dim={cfg.y_dim}"
        )
    check_informative(calibration_data, "calibration")


def _fresh_rows(model: IPCModel, data: PerceptionDataset) -> NDArray[np.uint64]:
    """The calibration rows' fingerprints; refuse rows that are training rows (in any order, subset, repeats).

    With the training rows' fingerprints recorded in the model, every row is looked up; a model
    trained by an ipcverify that did not record them is checked only against an exact copy of the
    training file (its content hash), with a :class:`~ipcverify.errors.Hint` that says so.
    """
    rows = row_fingerprints(data)
    recorded = recorded_rows(model.metadata, "training")
    held_out = (
        "calibration needs held-out samples that were not used for training (e.g. the calibration part of "
        "a split)"
    )
    if recorded is not None:
        reused = count_recorded(rows, recorded)
        if reused:
            raise InvalidInputError(
                f"{data.source}: {reused:,} of {len(rows):,} calibration rows are rows of the model's "
                f"training data (by the fingerprints of the {len(recorded):,} training rows the model file "
                "records); "
                f"{held_out} -- remove those rows"
            )
    elif (train_hash := model.metadata.get("train_data_hash")) is not None:
        if data.content_hash() == train_hash:
            raise InvalidInputError(f"{data.source}: this is the model's training data; {held_out}")
        warnings.warn(
            Hint(
                f"{data.source}: the model file records no fingerprints of its training rows (an ipcverify "
                "before row fingerprints trained it), so only an exact copy of the training file is "
                "recognised, not a shuffled, partial or repeated one: make sure no calibration row was a "
                "training row, or retrain with this ipcverify"
            ),
            stacklevel=3,
        )
    return rows
