"""The certificate of a contract: typed records of what :func:`ipcverify.certification.certify` established.

Every part is a frozen dataclass with a ``to_dict()``; :meth:`Certificate.to_dict` is the
layout of ``certificate.json`` (written with the one JSON encoder of
:mod:`ipcverify.data._files`). :mod:`ipcverify.certification._report` renders the same records as HTML.

* :class:`CertificateStatus` -- the verdict, whose text says what to do next;
* :class:`~ipcverify.certification._test_result.TestResult`,
  :class:`~ipcverify.certification._test_result.Consistency`,
  :class:`~ipcverify.certification._test_result.GroupTest` -- what the test data says
  (:mod:`ipcverify.certification._test_result`);
* :class:`ModelIdentity`, :class:`DataIdentity`, :class:`VolumeSummary` -- provenance and size;
  :class:`~ipcverify.certification._test_rows.TestRows` -- the test rows counted, and how they
  were checked against the training and calibration rows;
* :class:`Certificate` -- all of the above plus the calibration summary, Theorem 1, the unit of
  the claim and the executive summary (:class:`~ipcverify.certification.CertificateSummary`);
* :class:`CertifyEvidence`, :class:`CertifyResult` -- the per-sample arrays behind it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ipcverify._package import VERSION
from ipcverify._wording._verdicts import status_verdict
from ipcverify.calibration._protocol import CalibrationSummary, GroupClaim
from ipcverify.certification._evaluation import BinCoverage, WorstBin
from ipcverify.certification._summary import CertificateSummary
from ipcverify.certification._test_result import Consistency, GroupTest, GroupTestResult, TestResult
from ipcverify.certification._test_rows import TestRows
from ipcverify.certification._theorem1 import Theorem1Result
from ipcverify.guard._domain_report import DomainReport

FloatArray = NDArray[np.float64]

#: What every statement of a certificate assumes (a claim about rows).
ASSUMPTION = (
    "calibration, test and deployment samples are exchangeable (e.g. i.i.d. from the deployment "
    "distribution) and were not used for training"
)
#: What a claim about runs assumes.
RUN_ASSUMPTION = (
    "calibration, test and deployment runs are i.i.d. (rows within a run may be correlated), and no "
    "calibration or test row was used for training"
)


class CertificateStatus(Enum):
    """Outcome of :func:`~ipcverify.certification.certify`; the value is its name in words.

    The sentence shown to the user (what the status means, what to do next) is :attr:`text`,
    worded by the wording layer for the audience of the running code.
    """

    CERTIFIED = "certified"
    CONTRADICTED = "contradicted"
    NOT_CALIBRATED = "not calibrated"
    UNCHECKED = "unchecked"
    ROWS_ASSUMED = "rows assumed"
    UNTESTED = "untested"

    @property
    def text(self) -> str:
        """The status's sentence (``certificate.json``'s ``status_text``).

        Examples
        --------
        >>> CertificateStatus.CERTIFIED.text
        'certified: calibrated contract, test data consistent with the calibration'
        """
        return status_verdict(self.name)


@dataclass(frozen=True, kw_only=True)
class ModelIdentity:
    """Which model was certified: file, fingerprints, architecture, parameter count, training.

    ``training`` is how the network was trained (the model file's ``train_config``), and
    ``selection`` how the settings the recipe leaves open were chosen, if a rule chose them
    (:mod:`ipcverify.training._selection`: the paper's recipe's ``alpha``, ``lambda`` and batch size).

    Attributes
    ----------
    path : str or None
        The model file (None: a model in memory).
    file_sha256 : str or None
        SHA-256 of the model file.
    network_sha256 : str
        Fingerprint of the network's weights.
    architecture : mapping
        The network's configuration (``ModelConfig.to_dict()``).
    n_parameters : int
        Number of trained parameters ``p``.
    training, selection : mapping or None
        See above.
    """

    path: str | None
    file_sha256: str | None
    network_sha256: str
    architecture: Mapping[str, Any]
    n_parameters: int
    training: Mapping[str, Any] | None = None
    selection: Mapping[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""
        return {
            "path": self.path,
            "file_sha256": self.file_sha256,
            "network_sha256": self.network_sha256,
            "architecture": dict(self.architecture),
            "n_parameters": self.n_parameters,
            "training": None if self.training is None else dict(self.training),
            "selection": None if self.selection is None else dict(self.selection),
        }


@dataclass(frozen=True, kw_only=True)
class DataIdentity:
    """Which data was used: source, size, content and file hashes.

    ``matches_model_metadata`` (training data only) says whether the content hash is the
    one recorded in the model file at training time (None: nothing recorded).

    Attributes
    ----------
    source : str
        Where the data came from (a path, or ``<memory>``).
    n : int
        Number of samples.
    content_sha256 : str
        SHA-256 of the arrays (:meth:`~ipcverify.data.PerceptionDataset.content_hash`).
    file_sha256 : str or None
        SHA-256 of the file (None: not read from a file).
    matches_model_metadata : bool or None
        Training data only: whether ``content_sha256`` is the hash recorded at training time.
    is_training_data : bool
        Whether this is the training data.
    """

    source: str
    n: int
    content_sha256: str
    file_sha256: str | None
    matches_model_metadata: bool | None = None
    is_training_data: bool = False

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""
        out: dict[str, Any] = {
            "source": self.source,
            "n": self.n,
            "content_sha256": self.content_sha256,
            "file_sha256": self.file_sha256,
        }
        if self.is_training_data:
            out["matches_model_metadata"] = self.matches_model_metadata
        return out


@dataclass(frozen=True, kw_only=True)
class VolumeSummary:
    """The ``volume`` block of ``certificate.json``: log-volumes of the test-set sets.

    Attributes
    ----------
    mean_log, median_log : float
        Mean and median log-volume of the test-set sets.
    unit : str
        The unit of the volumes (``"(units of y)^n"``).
    median_half_width : tuple of float
        Per coordinate of y, the median over the test sets of half the set's axis-aligned extent.
    error_q90 : tuple of float
        Per coordinate of y, the 90th percentile of the estimate's error ``|y - yhat|`` on the
        test data: the scale to read the sets' size against.
    """

    mean_log: float
    median_log: float
    unit: str
    median_half_width: tuple[float, ...] = ()
    error_q90: tuple[float, ...] = ()

    def size_text(self, fmt: str = ".3g", unit: str | None = None) -> str:
        """The sets' half-widths beside the estimate's error, in words ('' without them).

        Parameters
        ----------
        fmt : str
            Format of each number.
        unit : str, optional
            The units of y (``"m"``), written after each list of numbers.

        Examples
        --------
        >>> v = VolumeSummary(mean_log=0.0, median_log=0.0, unit="", median_half_width=(0.2, 0.3),
        ...                   error_q90=(0.02, 0.1))
        >>> v.size_text()
        'median half-width per axis 0.2, 0.3; |y - yhat| 90th percentile 0.02, 0.1 (ratio 10, 3)'
        """
        if not self.median_half_width or len(self.error_q90) != len(self.median_half_width):
            return ""
        u = f" {unit}" if unit else ""
        hw = ", ".join(f"{h:{fmt}}" for h in self.median_half_width) + u
        err = ", ".join(f"{e:{fmt}}" for e in self.error_q90) + u
        ratios = ", ".join(
            f"{h / e:.2g}" if e > 0 else "-"
            for h, e in zip(self.median_half_width, self.error_q90, strict=True)
        )
        return f"median half-width per axis {hw}; |y - yhat| 90th percentile {err} (ratio {ratios})"

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""
        return {
            "mean_log": self.mean_log,
            "median_log": self.median_log,
            "unit": self.unit,
            "median_half_width": list(self.median_half_width),
            "estimate_error_q90": list(self.error_q90),
        }


@dataclass(frozen=True, kw_only=True)
class Certificate:
    """Everything :func:`~ipcverify.certification.certify` established; ``to_dict()`` is ``certificate.json``.

    ``group_claim`` names the groups a claim about groups (flights, runs) counts (None: rows);
    ``summary`` is the executive summary built from the rest (:func:`ipcverify.certification.summarize`).

    Attributes
    ----------
    status : CertificateStatus
        The verdict.
    statement : str
        What is guaranteed, in plain words (:func:`~ipcverify.certification.statement`).
    model : ModelIdentity
        The certified model.
    calibration : CalibrationSummary or None
        The calibration's certificate (None: not calibrated).
    test : TestResult or None
        The test-set bound (None: no test data).
    test_groups : tuple of GroupTestResult
        The test per calibration group (empty for a single group).
    consistency : Consistency
        Whether the test data contradicts the calibration.
    theorem1 : Theorem1Result or None
        Theorem 1 of the paper (None: not computed, see ``theorem1_reason``).
    theorem1_reason : str
        Why Theorem 1 was not computed ("" if it was).
    volume : VolumeSummary or None
        Log-volumes of the test-set sets.
    coverage : BinCoverage or None
        Violation rate per bin of a column (``bin_column``).
    test_data, train_data : DataIdentity or None
        The data files used.
    domain : DomainReport or None
        What the domain-of-validity test found on the test data.
    theorem1_source : str
        Where Theorem 1's training terms came from (the training data, or the statistics stored
        at training time).
    worst_bin : WorstBin or None
        Worst-bin coverage over the state columns and ``||yhat||``.
    group_test : GroupTest or None
        The test counted per group (flights, runs).
    group_claim : GroupClaim or None
        The groups a claim about groups counts (None: rows).
    calibration_group_columns : mapping of str to int
        The same for the calibration data of a row-level calibration, as the model file recorded
        it at calibration; empty without such columns.
    test_group_columns : mapping of str to int
        The test data's columns that look like runs or flights (named like ``run`` or
        ``flight_id``; :func:`ipcverify.data._checks.group_like_counts`) and their numbers of
        groups; empty without such columns.
    summary : CertificateSummary or None
        The executive summary.
    runs : mapping or None
        What the calibration data's runs support, as the model file recorded it at calibration
        (:func:`ipcverify.contract._runs.run_record`: the unit of the claim, the smallest rate the
        runs can certify, the runs the target needs, the within-run dependence); None if the
        calibration data had no runs.
    test_rows : TestRows or None
        The test rows counted (each distinct row once) and how they were checked against the
        training and calibration rows (:mod:`ipcverify.certification._test_rows`); None without
        test data.
    """

    status: CertificateStatus
    statement: str
    model: ModelIdentity
    calibration: CalibrationSummary | None
    test: TestResult | None
    test_groups: tuple[GroupTestResult, ...]
    consistency: Consistency
    theorem1: Theorem1Result | None
    theorem1_reason: str
    volume: VolumeSummary | None
    coverage: BinCoverage | None
    test_data: DataIdentity | None
    train_data: DataIdentity | None
    domain: DomainReport | None = None
    theorem1_source: str = ""
    worst_bin: WorstBin | None = None
    group_test: GroupTest | None = None
    group_claim: GroupClaim | None = None
    test_group_columns: Mapping[str, int] = field(default_factory=dict)
    calibration_group_columns: Mapping[str, int] = field(default_factory=dict)
    summary: CertificateSummary | None = None
    runs: Mapping[str, Any] | None = None
    test_rows: TestRows | None = None

    def to_dict(self) -> dict[str, Any]:
        """The content of ``certificate.json``."""
        if self.theorem1 is None:
            t1: dict[str, Any] = {
                "computed": False,
                "reason": self.theorem1_reason,
                "bound": None,
                "vacuous": None,
                "lipschitz_empirical": None,
                "lipschitz_sound": None,
                "n_needed": None,
            }
        else:
            t1 = {**self.theorem1.to_dict(), "source": self.theorem1_source}
        test = None if self.test is None else self.test.to_dict()
        if test is not None and self.test_groups:
            test["groups"] = [g.to_dict() for g in self.test_groups]
        return {
            "format": "ipcverify-certificate",
            "format_version": 1,
            "ipcverify_version": VERSION,
            "summary": None if self.summary is None else self.summary.to_dict(),
            "status": self.status.name,
            "status_text": self.status.text,
            "statement": self.statement,
            "assumption": ASSUMPTION if self.group_claim is None else RUN_ASSUMPTION,
            "n_parameters": self.model.n_parameters,
            "model": self.model.to_dict(),
            "calibration": None if self.calibration is None else self.calibration.to_dict(),
            "test": test,
            "consistency": self.consistency.to_dict(),
            "theorem1": t1,
            "volume": None if self.volume is None else self.volume.to_dict(),
            "coverage_by_bin": None if self.coverage is None else self.coverage.to_dict(),
            "conditional_coverage": None if self.worst_bin is None else self.worst_bin.to_dict(),
            "domain": None if self.domain is None else self.domain.to_dict(),
            "group_test": None if self.group_test is None else self.group_test.to_dict(),
            "test_group_like_columns": dict(self.test_group_columns),
            "calibration_group_like_columns": dict(self.calibration_group_columns),
            "runs": None if self.runs is None else dict(self.runs),
            "test_rows": None if self.test_rows is None else self.test_rows.to_dict(),
            "data": {
                "test": None if self.test_data is None else self.test_data.to_dict(),
                "train": None if self.train_data is None else self.train_data.to_dict(),
            },
        }

    @property
    def test_bound_note(self) -> str:
        """One sentence when a certified contract's test upper bound exceeds epsilon (else empty)."""
        cal, test = self.calibration, self.test
        if cal is None or test is None or self.status is not CertificateStatus.CERTIFIED:
            return ""
        if test.upper_bound <= cal.epsilon:
            return ""
        return (
            f"The test upper bound ({test.upper_bound:.3g}) is above epsilon ({cal.epsilon:g}) only because "
            f"{test.n:,} test {test.unit} cannot bound the rate more tightly; the guarantee comes from the "
            "calibration, and the test checks that the data do not contradict it (they do not)."
        )


@dataclass(frozen=True, eq=False)
class CertifyEvidence:
    """Per-sample arrays behind a certificate (for the report's plots).

    ``normalized_scores`` is ``g / s`` (a violation iff ``> 1``); ``examples`` holds a
    few test samples' centres, shapes (calibrated) and truths.

    Attributes
    ----------
    normalized_scores, raw_scores, scales : ndarray, shape (N,)
        ``g / s``, the raw score ``g`` and the calibration scale ``s`` of every test sample.
    log_volumes : ndarray, shape (N,)
        Log-volume of each calibrated set.
    violated : ndarray of bool, shape (N,)
        Whether each truth fell outside its set.
    example_index : ndarray of int, shape (E,)
        Test rows of the examples (the smallest, median and largest set, and a violated row).
    example_centers, example_shapes : ndarray, shapes (E, n) and (E, n, n)
        Their calibrated sets ``E(c, C)``.
    example_truths, example_estimates : ndarray, shape (E, n)
        Their truths ``y`` and estimates ``yhat``.
    y_columns : tuple of str
        The data's names of the coordinates of ``y``.
    """

    normalized_scores: FloatArray
    raw_scores: FloatArray
    scales: FloatArray
    log_volumes: FloatArray
    violated: NDArray[np.bool_]
    example_index: NDArray[np.intp]
    example_centers: FloatArray
    example_shapes: FloatArray
    example_truths: FloatArray
    example_estimates: FloatArray
    y_columns: tuple[str, ...] = field(default=())


@dataclass(frozen=True, eq=False)
class CertifyResult:
    """A :class:`Certificate` and the :class:`CertifyEvidence` it rests on (None without test data).

    Attributes
    ----------
    certificate : Certificate
        The verdict and every record it rests on (calibration, test, consistency, domain,
        Theorem 1, summary): what ``certificate.json`` holds.
    evidence : CertifyEvidence or None
        The per-sample arrays behind it (scores, scales, set volumes, violations, example sets),
        which the report plots and ``certificate.json`` does not hold; None without test data.
    """

    certificate: Certificate
    evidence: CertifyEvidence | None
