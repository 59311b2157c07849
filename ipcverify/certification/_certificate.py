"""The certificate of a contract: typed records of what :func:`ipcverify.certification.certify` established.

Every part is a frozen dataclass with a ``to_dict()``; :meth:`Certificate.to_dict` is the
layout of ``certificate.json`` (written with the one JSON encoder of
:mod:`ipcverify.data._files`). :mod:`ipcverify.certification._report` renders the same records as HTML.

* :class:`CertificateStatus` -- the verdict, whose text says what to do next;
* :class:`TestResult` -- violations on fresh test data and exact binomial bounds;
* :class:`Consistency` -- does the test data contradict the calibration's claim?
* :class:`GroupTest` -- the test counted per group (flight, run): valid for correlated rows;
* :class:`ModelIdentity`, :class:`DataIdentity`, :class:`VolumeSummary` -- provenance and size;
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
from ipcverify.calibration._bounds import (
    clopper_pearson_interval,
    clopper_pearson_lower,
    clopper_pearson_upper,
)
from ipcverify.calibration._protocol import (
    GROUP_UNITS,
    AllowedRate,
    CalibrationSummary,
    GroupClaim,
    GroupUnit,
)
from ipcverify.certification._evaluation import BinCoverage, WorstBin
from ipcverify.certification._summary import CertificateSummary
from ipcverify.certification._theorem1 import Theorem1Result
from ipcverify.errors import InvalidInputError
from ipcverify.guard._domain import DomainReport

__all__ = [
    "ASSUMPTION",
    "CertificateStatus",
    "TestResult",
    "GroupTestResult",
    "Consistency",
    "GroupTest",
    "ModelIdentity",
    "DataIdentity",
    "VolumeSummary",
    "Certificate",
    "CertifyEvidence",
    "CertifyResult",
]

FloatArray = NDArray[np.float64]

#: What every statement of a certificate assumes.
ASSUMPTION = (
    "calibration, test and deployment samples are exchangeable (e.g. i.i.d. from the deployment "
    "distribution) and were not used for training"
)


class CertificateStatus(Enum):
    """Outcome of :func:`~ipcverify.certification.certify`; the value is the text shown to the user."""

    CERTIFIED = "certified: calibrated contract, test data consistent with the calibration"
    CONTRADICTED = (
        "contradicted: the test data violates the calibration's claim -- check that calibration and "
        "test data come from the deployment distribution; recalibrate on representative data"
    )
    NOT_CALIBRATED = (
        "no calibration certificate: only the test-set bound holds -- run `ipcverify calibrate` on "
        "held-out data to obtain one"
    )
    UNCHECKED = "certified by calibration; consistency with the test data not checkable in this mode"
    UNTESTED = (
        "certified by calibration; no test data was given, so nothing checked it independently -- "
        "pass --data with fresh held-out samples to add the test"
    )


@dataclass(frozen=True, kw_only=True)
class TestResult:
    """Violations of the contract on a test set and their exact binomial bounds.

    Attributes
    ----------
    n, violations : int
        Test samples and samples whose truth lies outside its set.
    delta : float
        Confidence parameter of the bounds.
    upper_bound : float
        One-sided Clopper--Pearson upper bound at ``1 - delta``.
    lower_bound : float
        One-sided lower bound at ``1 - delta`` (used for the consistency check).
    interval : tuple of float
        Two-sided interval at ``1 - delta``.
    unit : str
        What was counted: ``"samples"``, or groups (flights, runs) for a calibration whose
        claim is about groups (their rows are correlated, so rows are not the unit).

    Examples
    --------
    >>> t = TestResult.from_counts(3, 1000, 0.001)
    >>> round(t.upper_bound, 4)
    0.013
    """

    __test__ = False  # not a pytest test class

    n: int
    violations: int
    delta: float
    upper_bound: float
    lower_bound: float
    interval: tuple[float, float]
    unit: str = "samples"

    def __post_init__(self) -> None:
        if not (0 <= self.violations <= self.n and self.n >= 1):
            raise InvalidInputError(f"need 0 <= violations <= n, n >= 1; got {self.violations}, {self.n}")
        if not (self.lower_bound <= self.violations / self.n <= self.upper_bound):
            raise InvalidInputError("test bounds must bracket the empirical rate")

    @classmethod
    def from_counts(cls, violations: int, n: int, delta: float, unit: str = "samples") -> TestResult:
        """Compute the bounds from counts."""
        return cls(
            n=int(n),
            violations=int(violations),
            delta=float(delta),
            upper_bound=clopper_pearson_upper(violations, n, delta),
            lower_bound=clopper_pearson_lower(violations, n, delta),
            interval=clopper_pearson_interval(violations, n, delta),
            unit=unit,
        )

    @property
    def empirical_rate(self) -> float:
        """``violations / n``."""
        return self.violations / self.n

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""
        return {
            "n": self.n,
            "violations": self.violations,
            "empirical_rate": self.empirical_rate,
            "upper_bound": self.upper_bound,
            "lower_bound": self.lower_bound,
            "interval": list(self.interval),
            "delta": self.delta,
            "unit": self.unit,
            "bound": "one-sided Clopper-Pearson upper bound at confidence 1 - delta",
        }


@dataclass(frozen=True, kw_only=True)
class GroupTestResult:
    """The test result of one calibration group (``result`` is None if no test sample fell in it).

    Examples
    --------
    >>> GroupTestResult(label="x_0=1", result=None).to_dict()["n"]
    0
    """

    label: str
    result: TestResult | None

    def to_dict(self) -> dict[str, Any]:
        """``{label, **result}``, or ``{label, n: 0, violations: 0, upper_bound: None}``."""
        if self.result is None:
            return {"label": self.label, "n": 0, "violations": 0, "upper_bound": None}
        return {"label": self.label, **self.result.to_dict()}


@dataclass(frozen=True, kw_only=True)
class Consistency:
    """Does the test data contradict the calibration's claim? (false-alarm probability <= 2 delta).

    Built by :meth:`check`: the claim is contradicted when the test set's one-sided lower
    bound exceeds the rate the calibration allows.

    Examples
    --------
    >>> t = TestResult.from_counts(50, 1000, 0.001)
    >>> Consistency.check(AllowedRate(rate=0.01, reason="pac"), t).consistent
    False
    """

    checked: bool
    consistent: bool | None = None
    allowed_rate: float | None = None
    test_lower_bound: float | None = None
    rule: str = ""
    reason: str = ""

    @classmethod
    def check(cls, allowed: AllowedRate | None, test: TestResult) -> Consistency:
        """Compare the test lower bound with the allowed rate (if the calibration claims one)."""
        if allowed is None:
            return cls(checked=False, reason="no calibration")
        if allowed.rate is None:
            return cls(checked=False, reason=allowed.reason)
        return cls(
            checked=True,
            consistent=bool(test.lower_bound <= allowed.rate),
            allowed_rate=allowed.rate,
            test_lower_bound=test.lower_bound,
            rule=f"contradiction if the test lower bound exceeds the allowed rate ({allowed.reason})",
        )

    def to_dict(self) -> dict[str, Any]:
        """``{checked, reason}`` or ``{checked, consistent, allowed_rate, test_lower_bound, rule}``."""
        if not self.checked:
            return {"checked": False, "reason": self.reason}
        return {
            "checked": True,
            "consistent": self.consistent,
            "allowed_rate": self.allowed_rate,
            "test_lower_bound": self.test_lower_bound,
            "rule": self.rule,
        }


@dataclass(frozen=True, kw_only=True)
class GroupTest:
    """The test counted per group (flight, run): one Bernoulli per test group, valid for correlated rows.

    A row-level Clopper--Pearson bound assumes independent rows; rows of one flight are
    correlated, so it can be far too narrow. Counting one statistic per group
    (:func:`~ipcverify.calibration.group_violation_counts`) gives ``n_groups`` i.i.d.
    Bernoulli draws when the test groups are i.i.d., whatever the dependence within a group
    (``proofs/group_calibration.md`` section 6). Built by
    :func:`ipcverify.certification._certify.group_test_step`.

    Attributes
    ----------
    column : str
        The test data's group column.
    n_groups, n_rows : int
        Test groups and test rows.
    seed : int
        Seeds the choice of one sample per group (``sample``).
    trajectory : TestResult
        Groups with any violation: bounds on the probability that a new group leaves its sets
        somewhere.
    sample : TestResult
        Groups whose one randomly chosen sample violates: bounds on the expected share of a new
        group's samples outside their sets (a random sample of a random group).
    compared_unit : {"trajectory", "sample"} or None
        The count checked against the calibration's allowed rate (None: not checked).
    consistency : Consistency
        That check (the same rule as the row-level one).

    Examples
    --------
    >>> t = TestResult.from_counts(1, 30, 0.01, "groups of run (any violation)")
    >>> s = TestResult.from_counts(0, 30, 0.01, "groups of run (one random sample each)")
    >>> g = GroupTest(column="run", n_groups=30, n_rows=600, seed=0, trajectory=t, sample=s,
    ...               compared_unit=None, consistency=Consistency(checked=False, reason="no calibration"))
    >>> g.to_dict()["trajectory"]["violations"], round(g.to_dict()["sample"]["upper_bound"], 3)
    (1, 0.142)
    """

    __test__ = False  # not a pytest test class

    column: str
    n_groups: int
    n_rows: int
    seed: int
    trajectory: TestResult
    sample: TestResult
    compared_unit: GroupUnit | None
    consistency: Consistency

    def __post_init__(self) -> None:
        if not (2 <= self.n_groups <= self.n_rows) or self.trajectory.n != self.n_groups != self.sample.n:
            raise InvalidInputError(
                f"a group test needs 2 <= n_groups <= n_rows and both counts over n_groups; got "
                f"n_groups={self.n_groups}, n_rows={self.n_rows}"
            )
        if self.sample.violations > self.trajectory.violations:
            raise InvalidInputError(
                "a group whose random sample violates has a violation: sample <= trajectory"
            )
        if self.compared_unit is not None and self.compared_unit not in GROUP_UNITS:
            raise InvalidInputError(
                f"compared_unit must be one of {GROUP_UNITS} or None; got {self.compared_unit!r}"
            )

    @property
    def compared(self) -> TestResult | None:
        """The count checked against the calibration (None if none was)."""
        if self.compared_unit is None:
            return None
        return self.trajectory if self.compared_unit == "trajectory" else self.sample

    def sentence(self) -> str:
        """What the group counts say, in one or two sentences."""
        t, s = self.trajectory, self.sample
        conf = f"{1 - t.delta:.6g}"
        text = (
            f"Counted per group of {self.column!r} ({self.n_groups} test groups, {self.n_rows} rows; "
            "valid if the test groups are i.i.d., whatever the correlation within a group): with confidence "
            f"{conf}, a random sample of a new group violates with probability at most {s.upper_bound:.4g} "
            f"({s.violations} of {s.n} randomly chosen samples outside), and a new group leaves its sets "
            f"somewhere with probability at most {t.upper_bound:.4g} ({t.violations} of {t.n} groups)."
        )
        c = self.consistency
        if c.checked and not c.consistent:
            text += (
                f" The group-level {self.compared_unit} count CONTRADICTS the calibration: its lower bound "
                f"{c.test_lower_bound:.4g} exceeds the allowed rate {c.allowed_rate:.4g}."
            )
        return text

    def to_dict(self) -> dict[str, Any]:
        """``{column, n_groups, n_rows, seed, trajectory, sample, compared_unit, consistency, statement}``."""
        return {
            "column": self.column,
            "n_groups": self.n_groups,
            "n_rows": self.n_rows,
            "seed": self.seed,
            "trajectory": self.trajectory.to_dict(),
            "sample": self.sample.to_dict(),
            "compared_unit": self.compared_unit,
            "consistency": self.consistency.to_dict(),
            "statement": self.sentence(),
            "assumption": "test groups i.i.d. from deployment; rows within a group may be correlated",
        }


@dataclass(frozen=True, kw_only=True)
class ModelIdentity:
    """Which model was certified: file, fingerprints, architecture, parameter count, training.

    ``training`` is how the network was trained (the model file's ``train_config``), and
    ``selection`` how the settings the recipe leaves open were chosen, if a rule chose them
    (:mod:`ipcverify.training._selection`: the paper's recipe's ``alpha``, ``lambda`` and batch size).
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
    """The ``volume`` block of ``certificate.json``: log-volumes of the test-set sets."""

    mean_log: float
    median_log: float
    unit: str

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""
        return {"mean_log": self.mean_log, "median_log": self.median_log, "unit": self.unit}


@dataclass(frozen=True, kw_only=True)
class Certificate:
    """Everything :func:`~ipcverify.certification.certify` established; ``to_dict()`` is ``certificate.json``.

    ``group_claim`` names the groups a claim about groups (flights, runs) counts (None: rows);
    ``summary`` is the executive summary built from the rest (:func:`ipcverify.certification.summarize`).
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
    summary: CertificateSummary | None = None

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
            "status_text": self.status.value,
            "statement": self.statement,
            "assumption": ASSUMPTION,
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
    """A :class:`Certificate` and the :class:`CertifyEvidence` it rests on (None without test data)."""

    certificate: Certificate
    evidence: CertifyEvidence | None
