"""Certify an IPC: what is guaranteed, what the test data says, and what Theorem 1 says.

:func:`certify` gathers three independent pieces of evidence about a model:

1. The **calibration certificate** (if the model is calibrated): the guarantee of
   :mod:`ipcverify.calibration`, e.g. "with probability >= 1 - delta over the
   calibration draw, P(y outside the set) <= epsilon".
2. The **test-set bound**: ``k`` violations among ``n`` fresh test samples give a
   one-sided Clopper--Pearson upper bound on the violation rate at confidence
   ``1 - delta`` -- valid by itself when the test samples are i.i.d. from the
   deployment distribution and were not used to train, select or calibrate the model.
   Test rows that are training or calibration rows (by the row fingerprints the model file
   records, whatever their order, subset or repeats) are refused, and a repeated test row is
   counted once (:func:`~ipcverify.certification._test_rows.fresh_test_rows`).
   If the test data contradicts the calibration claim (its lower bound exceeds what
   the calibration allows), the status says so.
   With a group column (flights, runs; ``group_column=``, or the column of a flight-level
   calibration), the test is also counted per group
   (:func:`ipcverify.certification.group_test_step`): valid when the test groups are i.i.d.,
   whatever the correlation of the rows within a group, which the row-level bound assumes away.
3. **Theorem 1** of the paper, with both Lipschitz constants; computed only when the
   training data is given, reported as vacuous when it is.

It is a short pipeline of named steps (:mod:`ipcverify.certification._certify_steps`:
:func:`check_inputs`, :func:`score_test_set`, :func:`test_results`, :func:`theorem1_step`,
:func:`statement`, ...); the result types
live in :mod:`ipcverify.certification._certificate`. :func:`write_certificate` writes ``certificate.json``
(atomically) and the self-contained ``report.html`` (:mod:`ipcverify.certification._report`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ipcverify._wording._spelling import option
from ipcverify.certification._certificate import (
    Certificate,
    CertifyEvidence,
    CertifyResult,
    DataIdentity,
    ModelIdentity,
    VolumeSummary,
)
from ipcverify.certification._certify_steps import (
    TestScores,
    certificate_status,
    check_inputs,
    score_test_set,
    statement,
    test_results,
    theorem1_step,
)
from ipcverify.certification._evaluation import BinCoverage, WorstBin, coverage_by_bin, worst_bin_coverage
from ipcverify.certification._group_check import group_test_step
from ipcverify.certification._report import render_report
from ipcverify.certification._summarize import check_labels, output_labels, summarize
from ipcverify.certification._test_result import Consistency, GroupTest, GroupTestResult, TestResult
from ipcverify.certification._test_rows import fresh_test_rows
from ipcverify.contract._guarded import CALIBRATION_GROUPS_KEY, mark_row_level, mark_runs
from ipcverify.contract._model import IPCModel
from ipcverify.contract._runs import RUNS_KEY
from ipcverify.data._checks import group_like_counts
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._files import atomic_write, file_sha256, write_json
from ipcverify.errors import InvalidInputError
from ipcverify.guard._domain_report import DomainReport
from ipcverify.io._modelio import load_data_for_model, load_model
from ipcverify.network._lipschitz_ball import DEFAULT_RADIUS

FloatArray = NDArray[np.float64]
PathLike = str | os.PathLike[str]

#: Number of example ellipsoids kept for the report's projections.
N_EXAMPLES = 4


def _identity(data: PerceptionDataset, path: PathLike | None, model: IPCModel | None = None) -> DataIdentity:
    content = data.content_hash()
    recorded = None if model is None else model.metadata.get("train_data_hash")
    return DataIdentity(
        source=data.source,
        n=len(data),
        content_sha256=content,
        file_sha256=None if path is None else file_sha256(path),
        matches_model_metadata=None if recorded is None else recorded == content,
        is_training_data=model is not None,
    )


def _model_identity(model: IPCModel, path: PathLike | None) -> ModelIdentity:
    return ModelIdentity(
        path=None if path is None else str(path),
        file_sha256=None if path is None else file_sha256(path),
        network_sha256=model.weights.fingerprint(),
        architecture=model.config.to_dict(),
        n_parameters=model.n_parameters,
        training=model.metadata.get("train_config"),
        selection=model.metadata.get("selection"),
    )


def _examples(log_volumes: FloatArray, violated: NDArray[np.bool_]) -> NDArray[np.intp]:
    order = np.argsort(log_volumes, kind="stable")
    picks = [int(order[0]), int(order[len(order) // 2]), int(order[-1])]
    bad = np.flatnonzero(violated)
    picks.append(int(bad[0]) if len(bad) else int(order[(3 * len(order)) // 4]))
    seen: list[int] = []
    for p in picks:
        if p not in seen:
            seen.append(p)
    return np.asarray(seen[:N_EXAMPLES], dtype=np.intp)


def _evidence(scores: TestScores, test_data: PerceptionDataset) -> CertifyEvidence:
    idx = _examples(scores.log_volume, scores.violated)
    ex = scores.sets[idx]
    return CertifyEvidence(
        normalized_scores=scores.normalized,
        raw_scores=scores.raw,
        scales=scores.scales,
        log_volumes=scores.log_volume,
        violated=scores.violated,
        example_index=idx,
        example_centers=ex.centers,
        example_shapes=ex.shapes,
        example_truths=test_data.y[idx],
        example_estimates=test_data.yhat[idx],
        y_columns=test_data.y_columns,
    )


def certify(
    model: IPCModel,
    test_data: PerceptionDataset | None = None,
    *,
    train_data: PerceptionDataset | None = None,
    delta: float | None = None,
    bin_column: str | None = None,
    bins: int = 10,
    group_column: str | None = None,
    lipschitz_radius: float = DEFAULT_RADIUS,
) -> CertifyResult:
    """Certify a (preferably calibrated) IPC on fresh test data.

    It takes the statistical inputs only. How the report names ``y`` (units, labels) and which
    files the certificate records belong to the report: :func:`write_certificate`.

    Parameters
    ----------
    model : IPCModel
        The model; its calibration (if any) is what gets certified.
    test_data : PerceptionDataset, optional
        Fresh samples, used neither for training nor for calibration (a row of either is
        refused; a repeated row is counted once: the certificate's ``test_rows``). Without them the
        certificate holds what the model file holds: the calibration certificate, the
        domain of validity and Theorem 1 from the statistics stored at training.
    train_data : PerceptionDataset, optional
        The training set, for Theorem 1 (its empirical term, ``L_g`` and ``N``). Without
        it Theorem 1 uses the statistics stored at training, or is reported as not computed.
    delta : float, optional
        Confidence parameter of the test bound and Theorem 1; default: the
        calibration's ``delta``, or :data:`DEFAULT_DELTA` without calibration.
    bin_column : str, optional
        Column for conditional coverage (default: the first ``x`` column).
    bins : int
        Number of quantile bins of that column.
    group_column : str, optional
        A column of the test data naming each row's group (flight, run): adds the test counted
        per group (:func:`ipcverify.certification.group_test_step`), valid for correlated rows.
        Default: the column of a flight-level calibration, if the test data has it.
    lipschitz_radius : float
        Parameter-ball radius of the sound Lipschitz bound (Theorem 1).

    Raises
    ------
    InvalidInputError
        If dimensions disagree, some test rows are calibration or training rows (or, for a
        model file without row fingerprints, the test data is an exact copy of either), most
        test rows repeat another, the calibration belongs to a different network, the group
        column is missing from the test data, has one group only, or is given without test
        data.

    Examples
    --------
    >>> from ipcverify import example
    >>> from ipcverify.network import ModelConfig
    >>> from ipcverify import calibrate
    >>> m = example(config=ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")).model
    >>> m = calibrate(m, example(2000, seed=1).data, epsilon=0.05, delta=0.01)
    >>> res = certify(m, example(2000, seed=2).data)
    >>> res.certificate.status.name, res.certificate.test.n
    ('CERTIFIED', 2000)
    """
    delta = check_inputs(model, test_data, train_data, delta)
    given, rows = test_data, None  # the test data as given, and what its rows are
    if test_data is not None:  # refuse training or calibration rows; count each distinct row once
        test_data, rows = fresh_test_rows(model, test_data, train_data)
    claim = None if model.calibration is None else model.calibration.group_claim()
    if test_data is not None and claim is not None and group_column is not None:
        test_data, group_column = _runs_named(test_data, claim.column, group_column)
    y_labels = output_labels(model, test_data)
    if group_column is not None and test_data is None:
        raise InvalidInputError(
            f"group column {group_column!r} needs test data to count per group ({option('test_data')})"
        )
    cal = model.calibration
    tested = (
        _tested(model, test_data, delta, bin_column, bins, group_column) if test_data is not None else None
    )
    test = None if tested is None else tested.test
    group_test = None if tested is None else tested.group_test
    consistency = (
        Consistency(checked=False, reason="no test data")
        if test is None
        else Consistency.check(None if cal is None else cal.allowed_violation_rate(), test)
    )
    calibration_groups = dict(model.metadata.get(CALIBRATION_GROUPS_KEY) or {}) if cal else {}
    test_groups = {} if test_data is None else group_like_counts(test_data)
    # a row-level claim on rows that come in runs rests on independent rows: only a check by runs counts
    in_doubt = cal is not None and cal.group_claim() is None and bool(calibration_groups or test_groups)
    checks: tuple[Consistency, ...] = (
        (consistency,) if group_test is None else (consistency, group_test.consistency)
    )
    if in_doubt:
        checks = () if group_test is None else (group_test.consistency,)
    status = certificate_status(cal, checks, tested is not None, rows_in_doubt=in_doubt)
    t1, t1_reason, t1_source = theorem1_step(model, train_data, delta, lipschitz_radius)
    cert = Certificate(
        status=status,
        statement=statement(cal, test, status, group_test),
        model=_model_identity(model, None),
        calibration=None if cal is None else cal.summary(),
        test=test,
        test_groups=() if tested is None else tested.groups,
        consistency=consistency,
        theorem1=t1,
        theorem1_reason=t1_reason,
        theorem1_source=t1_source,
        volume=None if tested is None else tested.volume,
        coverage=None if tested is None else tested.coverage,
        worst_bin=None if tested is None else tested.worst_bin,
        domain=_domain(model, test_data, None if tested is None else tested.scores.violated),
        group_test=group_test,
        test_data=None if given is None else _identity(given, None),
        train_data=None if train_data is None else _identity(train_data, None, model),
        group_claim=None if cal is None else cal.group_claim(),
        test_group_columns=test_groups,
        calibration_group_columns=calibration_groups,
        runs=model.metadata.get(RUNS_KEY) if cal else None,
        test_rows=rows,
    )
    rows_outside = (
        None if tested is None else (int(tested.scores.violated.sum()), len(tested.scores.violated))
    )
    summary = summarize(cert, labels=y_labels, rows_outside=rows_outside)
    cert = replace(cert, summary=summary)
    return CertifyResult(
        cert, None if tested is None or test_data is None else _evidence(tested.scores, test_data)
    )


def _runs_named(
    test_data: PerceptionDataset, claim_column: str, column: str
) -> tuple[PerceptionDataset, str]:
    """Test data whose runs ``column`` names, for a claim about runs named ``claim_column`` at calibration."""
    if claim_column in test_data.extra or column not in test_data.extra:
        return test_data, column
    extra = {**test_data.extra, claim_column: test_data.extra[column]}
    return replace(test_data, extra=extra), claim_column


@dataclass(frozen=True, eq=False)
class _Tested:
    scores: TestScores
    test: TestResult
    groups: tuple[GroupTestResult, ...]
    volume: VolumeSummary
    coverage: BinCoverage
    worst_bin: WorstBin
    group_test: GroupTest | None


def _tested(
    model: IPCModel,
    test_data: PerceptionDataset,
    delta: float,
    bin_column: str | None,
    bins: int,
    group_column: str | None,
) -> _Tested:
    """Steps 2-3 on the test data: scores, test bounds (per row and per group), volumes, coverage."""
    scores = score_test_set(model, test_data)
    test, groups = test_results(model.calibration, test_data, scores.violated, delta)
    group_test = group_test_step(model.calibration, test_data, scores.violated, delta, group_column)
    column = bin_column or test_data.x_columns[0]
    values = test_data.column(column)  # numbers (quantile bins) or text (one bin per flight or run)
    return _Tested(
        scores=scores,
        test=test,
        groups=groups,
        volume=VolumeSummary(
            mean_log=float(np.mean(scores.log_volume)),
            median_log=float(np.median(scores.log_volume)),
            unit=f"log of volume in the units of y (dimension {model.config.y_dim})",
            median_half_width=tuple(float(h) for h in np.median(scores.sets.half_widths(), axis=0)),
            error_q90=tuple(float(e) for e in np.quantile(np.abs(test_data.y - test_data.yhat), 0.9, axis=0)),
        ),
        coverage=coverage_by_bin(values, scores.violated, column, bins),
        worst_bin=worst_bin_coverage(test_data.x, test_data.yhat, scores.violated, test_data.x_columns, bins),
        group_test=group_test,
    )


def _domain(
    model: IPCModel, test_data: PerceptionDataset | None, violated: NDArray[np.bool_] | None
) -> DomainReport | None:
    """The domain-of-validity block: the test's own description, and the test queries outside it."""
    if model.domain is None:
        return None
    if test_data is None:
        return model.domain.describe()
    report = mark_row_level(model, model.domain.report(test_data.x, test_data.yhat, violated))
    return mark_runs(model, report, test_data, ~model.domain.contains(test_data.x, test_data.yhat))


def write_certificate(
    result: CertifyResult,
    out_dir: PathLike,
    *,
    units: str | None = None,
    labels: Sequence[str] | None = None,
) -> tuple[Path, Path]:
    """Write ``certificate.json`` and ``report.html`` into ``out_dir`` (atomically); return their paths.

    Parameters
    ----------
    result : CertifyResult
        What :func:`certify` returned.
    out_dir : path-like
        The directory (created if missing).
    units : str, optional
        The units of ``y`` (e.g. ``"m"``), for the summary and every plot axis along ``y``;
        default: none named (the page says "units of the data").
    labels : sequence of str, optional
        One label per coordinate of ``y`` (e.g. ``("forward", "left", "up")``); default: the
        data's column names.

    Raises
    ------
    InvalidInputError
        If the labels do not name every coordinate of ``y`` or the units are empty.

    Examples
    --------
    >>> import tempfile
    >>> from ipcverify import calibrate, certify, example
    >>> m = calibrate(example().model, example(2000, seed=1).data, epsilon=0.05, delta=0.01)
    >>> res = certify(m, example(2000, seed=2).data)
    >>> with tempfile.TemporaryDirectory() as out:
    ...     json_path, html_path = write_certificate(res, out, units="m", labels=("x", "y", "z"))
    ...     (json_path.name, html_path.name)
    ('certificate.json', 'report.html')
    """
    result = labelled(result, units=units, labels=labels)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cert_path, report_path = out / "certificate.json", out / "report.html"
    write_json(cert_path, result.certificate)
    html = render_report(result)
    atomic_write(report_path, lambda f: f.write(html), mode="w")
    return cert_path, report_path


def labelled(
    result: CertifyResult, *, units: str | None = None, labels: Sequence[str] | None = None
) -> CertifyResult:
    """``result`` with its summary naming the units and coordinates of ``y`` (nothing is re-decided)."""
    cert = result.certificate
    if cert.summary is None or (units is None and labels is None):
        return result
    if units is not None and not units.strip():
        raise InvalidInputError(
            f"the units of y must not be empty; name them (e.g. {option('units', 'm')}) or leave them out"
        )
    names = cert.summary.labels if labels is None else check_labels(labels, len(cert.summary.labels))
    violated = None if result.evidence is None else result.evidence.violated
    summary = summarize(
        cert,
        created_utc=cert.summary.date_utc,
        units=None if units is None else units.strip(),
        labels=names,
        rows_outside=None if violated is None else (int(violated.sum()), len(violated)),
    )
    return replace(result, certificate=replace(cert, summary=summary))


def with_files(
    result: CertifyResult, model_path: PathLike, test_path: PathLike | None, train_path: PathLike | None
) -> CertifyResult:
    """``result`` with the SHA-256 of the files it was certified from (and its summary redone)."""
    cert = result.certificate
    cert = replace(
        cert,
        model=replace(cert.model, path=str(model_path), file_sha256=file_sha256(model_path)),
        test_data=None
        if cert.test_data is None or test_path is None
        else replace(cert.test_data, file_sha256=file_sha256(test_path)),
        train_data=None
        if cert.train_data is None or train_path is None
        else replace(cert.train_data, file_sha256=file_sha256(train_path)),
    )
    if cert.summary is not None:
        violated = None if result.evidence is None else result.evidence.violated
        cert = replace(cert, summary=summarize(
            cert, created_utc=cert.summary.date_utc, units=cert.summary.units, labels=cert.summary.labels,
            rows_outside=None if violated is None else (int(violated.sum()), len(violated)),
        ))  # fmt: skip
    return replace(result, certificate=cert)


def certify_files(
    model_path: PathLike,
    test_path: PathLike | None,
    out_dir: PathLike,
    *,
    train_path: PathLike | None = None,
    delta: float | None = None,
    bin_column: str | None = None,
    bins: int = 10,
    group_column: str | None = None,
    lipschitz_radius: float = DEFAULT_RADIUS,
    units: str | None = None,
    labels: Sequence[str] | None = None,
) -> CertifyResult:
    """Load a model file and data files, :func:`certify`, and :func:`write_certificate` (the CLI's call).

    Parameters
    ----------
    model_path : path-like
        The model file.
    test_path : path-like or None
        The test data file (None: no test).
    out_dir : path-like
        Directory for ``certificate.json`` and ``report.html``.
    train_path : path-like, optional
        The training data file, for Theorem 1.
    delta, bin_column, bins, group_column, lipschitz_radius
        As for :func:`certify`.
    units, labels
        As for :func:`write_certificate`.
    """
    model = load_model(model_path)
    test_data = None if test_path is None else load_data_for_model(test_path, model)
    train_data = None if train_path is None else load_data_for_model(train_path, model)
    result = certify(
        model,
        test_data,
        train_data=train_data,
        delta=delta,
        bin_column=bin_column,
        bins=bins,
        group_column=group_column,
        lipschitz_radius=lipschitz_radius,
    )
    result = labelled(with_files(result, model_path, test_path, train_path), units=units, labels=labels)
    write_certificate(result, out_dir)
    return result
