"""Certify an IPC: what is guaranteed, what the test data says, and what Theorem 1 says.

:func:`certify` gathers three independent pieces of evidence about a model:

1. The **calibration certificate** (if the model is calibrated): the guarantee of
   :mod:`ipcverify.calibration`, e.g. "with probability >= 1 - delta over the
   calibration draw, P(y outside the set) <= epsilon".
2. The **test-set bound**: ``k`` violations among ``n`` fresh test samples give a
   one-sided Clopper--Pearson upper bound on the violation rate at confidence
   ``1 - delta`` -- valid by itself when the test samples are i.i.d. from the
   deployment distribution and were not used to train, select or calibrate the model.
   If the test data contradicts the calibration claim (its lower bound exceeds what
   the calibration allows), the status says so.
3. **Theorem 1** of the paper, with both Lipschitz constants; computed only when the
   training data is given, reported as vacuous when it is.

:func:`write_certificate` writes ``certificate.json`` (atomically) and the
self-contained ``report.html`` (:mod:`ipcverify.report`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any, TypedDict

import numpy as np
from numpy.typing import NDArray
from scipy import stats

import ipcverify
from ipcverify.bounds import clopper_pearson_interval, clopper_pearson_lower, clopper_pearson_upper
from ipcverify.calibration import GlobalCalibration, MondrianCalibration, network_fingerprint
from ipcverify.data import PerceptionDataset, load_dataset
from ipcverify.errors import InvalidInputError
from ipcverify.evaluation import BinCoverage, coverage_by_bin
from ipcverify.files import atomic_write, file_sha256, write_json
from ipcverify.lipschitz import DEFAULT_RADIUS
from ipcverify.model import IPCModel
from ipcverify.modelio import load_model
from ipcverify.theorem1 import Theorem1Result, theorem1

__all__ = [
    "DEFAULT_DELTA",
    "CertificateStatus",
    "TestBound",
    "Certificate",
    "VolumeSummary",
    "CertifyEvidence",
    "CertifyResult",
    "certify",
    "write_certificate",
    "certify_files",
    "load_data_for_model",
]

FloatArray = NDArray[np.float64]

#: Confidence parameter of the test-set bound when the model carries no calibration.
DEFAULT_DELTA = 0.001
#: Number of example ellipsoids kept for the report's projections.
N_EXAMPLES = 4


class CertificateStatus(Enum):
    """Outcome of :func:`certify`; the value is the text shown to the user."""

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


@dataclass(frozen=True, kw_only=True)
class TestBound:
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
    """

    __test__ = False  # not a pytest test class

    n: int
    violations: int
    delta: float
    upper_bound: float
    lower_bound: float
    interval: tuple[float, float]

    def __post_init__(self) -> None:
        if not (0 <= self.violations <= self.n and self.n >= 1):
            raise InvalidInputError(f"need 0 <= violations <= n, n >= 1; got {self.violations}, {self.n}")
        if not (self.lower_bound <= self.violations / self.n <= self.upper_bound):
            raise InvalidInputError("test bounds must bracket the empirical rate")

    @classmethod
    def from_counts(cls, violations: int, n: int, delta: float) -> TestBound:
        """Compute the bounds from counts.

        Examples
        --------
        >>> t = TestBound.from_counts(3, 1000, 0.001)
        >>> round(t.upper_bound, 4)
        0.013
        """
        return cls(
            n=int(n),
            violations=int(violations),
            delta=float(delta),
            upper_bound=clopper_pearson_upper(violations, n, delta),
            lower_bound=clopper_pearson_lower(violations, n, delta),
            interval=clopper_pearson_interval(violations, n, delta),
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
            "bound": "one-sided Clopper-Pearson upper bound at confidence 1 - delta",
        }


class VolumeSummary(TypedDict):
    """The ``volume`` block of ``certificate.json``: log-volumes of the test-set sets."""

    mean_log: float
    median_log: float
    unit: str


@dataclass(frozen=True, kw_only=True)
class Certificate:
    """Everything :func:`certify` established, in JSON-ready parts.

    See :meth:`to_dict` for the file layout of ``certificate.json``.
    """

    status: CertificateStatus
    statement: str
    model: dict[str, Any]
    calibration: dict[str, Any] | None
    test: TestBound
    test_groups: tuple[dict[str, Any], ...]
    consistency: dict[str, Any]
    theorem1: Theorem1Result | None
    theorem1_reason: str
    volume: VolumeSummary
    coverage: BinCoverage
    data: dict[str, Any]

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
            t1 = self.theorem1.to_dict()
        test = self.test.to_dict()
        if self.test_groups:
            test["groups"] = list(self.test_groups)
        return {
            "format": "ipcverify-certificate",
            "format_version": 1,
            "ipcverify_version": ipcverify.__version__,
            "status": self.status.name,
            "status_text": self.status.value,
            "statement": self.statement,
            "assumption": (
                "calibration, test and deployment samples are exchangeable (e.g. i.i.d. from the deployment "
                "distribution) and were not used for training"
            ),
            "n_parameters": self.model["n_parameters"],
            "model": self.model,
            "calibration": self.calibration,
            "test": test,
            "consistency": self.consistency,
            "theorem1": t1,
            "volume": self.volume,
            "coverage_by_bin": self.coverage.to_dict(),
            "data": self.data,
        }


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
    """A :class:`Certificate` and the :class:`CertifyEvidence` it rests on."""

    certificate: Certificate
    evidence: CertifyEvidence


def _check_dims(model: IPCModel, data: PerceptionDataset, role: str) -> None:
    cfg = model.config
    if (data.x_dim, data.y_dim) != (cfg.x_dim, cfg.y_dim):
        raise InvalidInputError(
            f"{data.source}: {role} data has x_dim={data.x_dim}, y_dim={data.y_dim} but the model expects "
            f"x_dim={cfg.x_dim}, y_dim={cfg.y_dim}"
        )


def _identity(data: PerceptionDataset, path: str | os.PathLike[str] | None) -> dict[str, Any]:
    return {
        "source": data.source,
        "n": len(data),
        "content_sha256": data.content_hash(),
        "file_sha256": None if path is None else file_sha256(path),
    }


def _consistency(cal: GlobalCalibration | MondrianCalibration | None, test: TestBound) -> dict[str, Any]:
    """Does the test data contradict the calibration claim? (false-alarm probability <= 2 delta)."""
    if cal is None:
        return {"checked": False, "reason": "no calibration"}
    if isinstance(cal, GlobalCalibration):
        t = cal.threshold
        if t.mode == "pac":
            allowed = t.certified_epsilon
            why = "the PAC calibration allows a violation rate up to this value (w.p. 1 - delta)"
        else:
            # the violation rate of a marginal calibration is Beta(n - k + 1, k) (continuous scores)
            allowed = float(stats.beta.ppf(1.0 - t.delta, t.n - t.k + 1, t.k))
            why = "1 - delta quantile of the marginal calibration's Beta(n - k + 1, k) violation rate"
    elif cal.mode == "pac":
        allowed = cal.epsilon
        why = "with probability 1 - delta every group, hence the whole, violates at most epsilon"
    else:
        return {"checked": False, "reason": "marginal Mondrian calibration makes no per-draw claim"}
    ok = test.lower_bound <= allowed
    return {
        "checked": True,
        "consistent": bool(ok),
        "allowed_rate": allowed,
        "test_lower_bound": test.lower_bound,
        "rule": f"contradiction if the test lower bound exceeds the allowed rate ({why})",
    }


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


def certify(
    model: IPCModel,
    test_data: PerceptionDataset,
    *,
    train_data: PerceptionDataset | None = None,
    delta: float | None = None,
    bin_column: str | None = None,
    bins: int = 10,
    lipschitz_radius: float = DEFAULT_RADIUS,
    model_path: str | os.PathLike[str] | None = None,
    test_path: str | os.PathLike[str] | None = None,
    train_path: str | os.PathLike[str] | None = None,
) -> CertifyResult:
    """Certify a (preferably calibrated) IPC on fresh test data.

    Parameters
    ----------
    model : IPCModel
        The model; its calibration (if any) is what gets certified.
    test_data : PerceptionDataset
        Fresh samples, used neither for training nor for calibration.
    train_data : PerceptionDataset, optional
        The training set, for Theorem 1 (its empirical term, ``L_g`` and ``N``).
        Without it Theorem 1 is reported as not computed.
    delta : float, optional
        Confidence parameter of the test bound and Theorem 1; default: the
        calibration's ``delta``, or :data:`DEFAULT_DELTA` without calibration.
    bin_column : str, optional
        Column for conditional coverage (default: the first ``x`` column).
    bins : int
        Number of quantile bins of that column.
    lipschitz_radius : float
        Parameter-ball radius of the sound Lipschitz bound (Theorem 1).
    model_path, test_path, train_path : path-like, optional
        Files to fingerprint (SHA-256) in the certificate.

    Raises
    ------
    InvalidInputError
        If dimensions disagree, the test data is the calibration or training data,
        or the calibration belongs to a different network.

    Examples
    --------
    >>> from ipcverify.synthetic import make_lagged_perception
    >>> from ipcverify.model import IPCNetwork, ModelConfig
    >>> from ipcverify.calibration import calibrate
    >>> m = IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(8,))))
    >>> m = calibrate(m, make_lagged_perception(2000, seed=1), epsilon=0.05, delta=0.01)
    >>> res = certify(m, make_lagged_perception(2000, seed=2))
    >>> res.certificate.status.name, res.certificate.test.n
    ('CERTIFIED', 2000)
    """
    _check_dims(model, test_data, "test")
    cal = model.calibration
    if cal is not None and not isinstance(cal, (GlobalCalibration, MondrianCalibration)):
        raise InvalidInputError(f"cannot certify an unknown calibration type {type(cal).__name__}")
    test_hash = test_data.content_hash()
    net_hash = network_fingerprint(model.network)
    if cal is not None:
        if cal.network_hash != net_hash:
            raise InvalidInputError(
                "the model's calibration was computed for a different network (fingerprint mismatch); "
                "recalibrate this network"
            )
        if cal.data_hash == test_hash:
            raise InvalidInputError(
                f"{test_data.source}: the test data is the calibration data; certify on fresh samples"
            )
    if test_hash == model.metadata.get("train_data_hash"):
        raise InvalidInputError(f"{test_data.source}: the test data is the training data; use fresh samples")
    if delta is None:
        delta = cal.delta if cal is not None else DEFAULT_DELTA
    if not (isinstance(delta, (int, float)) and 0 < delta < 1):
        raise InvalidInputError(f"delta must lie strictly between 0 and 1; got {delta!r}")
    delta = float(delta)

    centers, shapes = model.raw_arrays(test_data.x, test_data.yhat)
    d = test_data.y - centers
    raw = np.linalg.norm(np.einsum("bij,bj->bi", shapes, d), axis=1)
    scales = (
        np.ones(len(raw))
        if cal is None
        else np.asarray(cal.scale_factors(test_data.x, test_data.yhat), dtype=float)
    )
    sets = model.predict(test_data.x, test_data.yhat)
    violated = ~sets.contains(test_data.y)
    normalized = sets.g(test_data.y)
    log_vol = sets.log_volume()
    test = TestBound.from_counts(int(violated.sum()), len(test_data), delta)

    groups: list[dict[str, Any]] = []
    if isinstance(cal, MondrianCalibration):
        gi = cal.group_index(test_data.x, test_data.yhat)
        for j, g in enumerate(cal.groups):
            m = gi == j
            if m.any():
                tb = TestBound.from_counts(int(violated[m].sum()), int(m.sum()), delta)
                groups.append({"label": g.label, **tb.to_dict()})
            else:
                groups.append({"label": g.label, "n": 0, "violations": 0, "upper_bound": None})

    consistency = _consistency(cal, test)
    if cal is None:
        status = CertificateStatus.NOT_CALIBRATED
    elif not consistency["checked"]:
        status = CertificateStatus.UNCHECKED
    else:
        status = CertificateStatus.CERTIFIED if consistency["consistent"] else CertificateStatus.CONTRADICTED

    t1: Theorem1Result | None = None
    reason = ""
    if train_data is None:
        reason = "not computed: training data not given (pass --train-data)"
    else:
        _check_dims(model, train_data, "training")
        t1 = theorem1(model, train_data, delta, radius=lipschitz_radius)

    column = bin_column or test_data.x_columns[0]
    coverage = coverage_by_bin(np.asarray(test_data.column(column), dtype=float), violated, column, bins)

    test_sentence = (
        f"Independently, the ground truth fell outside its set for {test.violations} of {test.n} fresh "
        f"test samples, so with "
        f"confidence {1 - delta:.6g} the violation rate of this contract is at most {test.upper_bound:.4g} "
        "(Clopper-Pearson; valid if the test samples are i.i.d. from deployment and unused in training "
        "and calibration)."
    )
    if cal is None:
        statement = "No calibration certificate: the model was not calibrated. " + test_sentence
    else:
        statement = cal.guarantee() + " " + test_sentence
        if status is CertificateStatus.CONTRADICTED:
            statement = "WARNING: the test data contradicts the calibration. " + statement

    train_info = None
    if train_data is not None:
        train_info = _identity(train_data, train_path)
        recorded = model.metadata.get("train_data_hash")
        train_info["matches_model_metadata"] = (
            None if recorded is None else recorded == train_info["content_sha256"]
        )
    cert = Certificate(
        status=status,
        statement=statement,
        model={
            "path": None if model_path is None else str(model_path),
            "file_sha256": None if model_path is None else file_sha256(model_path),
            "network_sha256": net_hash,
            "architecture": model.config.to_dict(),
            "n_parameters": model.n_parameters,
        },
        calibration=None if cal is None else _calibration_summary(cal),
        test=test,
        test_groups=tuple(groups),
        consistency=consistency,
        theorem1=t1,
        theorem1_reason=reason,
        volume={
            "mean_log": float(np.mean(log_vol)),
            "median_log": float(np.median(log_vol)),
            "unit": f"log of volume in the units of y (dimension {model.config.y_dim})",
        },
        coverage=coverage,
        data={"test": _identity(test_data, test_path), "train": train_info},
    )
    idx = _examples(log_vol, violated)
    ex = sets[idx]
    evidence = CertifyEvidence(
        normalized_scores=normalized,
        raw_scores=raw,
        scales=scales,
        log_volumes=log_vol,
        violated=violated,
        example_index=idx,
        example_centers=ex.centers,
        example_shapes=ex.shapes,
        example_truths=test_data.y[idx],
        example_estimates=test_data.yhat[idx],
        y_columns=test_data.y_columns,
    )
    return CertifyResult(cert, evidence)


def _calibration_summary(cal: GlobalCalibration | MondrianCalibration) -> dict[str, Any]:
    if isinstance(cal, GlobalCalibration):
        t = cal.threshold
        return {
            "kind": "global",
            "mode": t.mode,
            "epsilon": t.epsilon,
            "delta": t.delta,
            "n": t.n,
            "k": t.k,
            "scale": t.scale,
            "order_statistic": t.order_statistic,
            "certified_epsilon": t.certified_epsilon,
            "data_sha256": cal.data_hash,
            "guarantee": cal.guarantee(),
        }
    return {
        "kind": "mondrian",
        "mode": cal.mode,
        "epsilon": cal.epsilon,
        "delta": cal.delta,
        "group_delta": cal.group_delta,
        "n": cal.n,
        "k": [g.threshold.k for g in cal.groups],
        "scale": [g.threshold.scale for g in cal.groups],
        "column": cal.column,
        "binning": cal.binning,
        "n_edge": cal.n_edge,
        "groups": [g.to_dict() for g in cal.groups],
        "data_sha256": cal.data_hash,
        "guarantee": cal.guarantee(),
    }


def write_certificate(result: CertifyResult, out_dir: str | os.PathLike[str]) -> tuple[Path, Path]:
    """Write ``certificate.json`` and ``report.html`` into ``out_dir`` (atomically); return their paths."""
    from ipcverify.report import render_report

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cert_path, report_path = out / "certificate.json", out / "report.html"
    write_json(cert_path, result.certificate)
    html = render_report(result)
    atomic_write(report_path, lambda f: f.write(html), mode="w")
    return cert_path, report_path


def load_data_for_model(path: str | os.PathLike[str], model: IPCModel) -> PerceptionDataset:
    """Load a data file with the column names the model was trained on (tables; NPZ has no names).

    Examples
    --------
    >>> import tempfile, os
    >>> from ipcverify.synthetic import make_lagged_perception
    >>> from ipcverify.data import save_dataset
    >>> from ipcverify.model import IPCNetwork, ModelConfig
    >>> p = os.path.join(tempfile.mkdtemp(), "d.csv")
    >>> save_dataset(make_lagged_perception(5, seed=0), p)
    >>> len(load_data_for_model(p, IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3)))))
    5
    """
    if Path(path).suffix.lower() == ".npz":
        return load_dataset(path)
    meta = model.metadata
    return load_dataset(
        path, meta.get("x_columns") or None, meta.get("y_columns") or None, meta.get("yhat_columns") or None
    )


def certify_files(
    model_path: str | os.PathLike[str],
    test_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    train_path: str | os.PathLike[str] | None = None,
    delta: float | None = None,
    bin_column: str | None = None,
    bins: int = 10,
    lipschitz_radius: float = DEFAULT_RADIUS,
) -> CertifyResult:
    """Load a model file and data files, :func:`certify`, and :func:`write_certificate` (the CLI's call)."""
    model = load_model(model_path)
    test_data = load_data_for_model(test_path, model)
    train_data = None if train_path is None else load_data_for_model(train_path, model)
    result = certify(
        model,
        test_data,
        train_data=train_data,
        delta=delta,
        bin_column=bin_column,
        bins=bins,
        lipschitz_radius=lipschitz_radius,
        model_path=model_path,
        test_path=test_path,
        train_path=train_path,
    )
    write_certificate(result, out_dir)
    return result
