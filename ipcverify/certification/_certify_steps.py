"""The named steps of :func:`~ipcverify.certification.certify`, each a function of its inputs.

1. :func:`check_inputs` refuses data the certificate could not rest on;
2. :func:`score_test_set` scores every test sample (:class:`TestScores`);
3. :func:`test_results` counts the violations in the unit of the calibration's claim;
4. :func:`theorem1_step` computes Theorem 1, or says why not;
5. :func:`statement` says what holds, in plain words, and :func:`certificate_status` gives the verdict.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ipcverify._wording._spelling import option
from ipcverify.calibration._protocol import Calibration, row_counts
from ipcverify.certification._certificate import CertificateStatus
from ipcverify.certification._test_result import Consistency, GroupTest, GroupTestResult, TestResult
from ipcverify.certification._theorem1 import Theorem1Result, TrainingStatistics, theorem1
from ipcverify.contract._model import IPCModel
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.sets._ellipsoid import Ellipsoid

FloatArray = NDArray[np.float64]

#: Confidence parameter of the test-set bound when the model carries no calibration.
DEFAULT_DELTA = 0.001


def no_statistics() -> str:
    """Why Theorem 1 is not computed for a model file without training statistics and no training data."""
    return (
        "not computed: training data not given, and the model records no training statistics (a model "
        "not built by ipcverify.training.train, or a default-recipe model file written before Theorem 1 "
        f"covered the default recipe); pass the training data ({option('train_data')}), or retrain the "
        "model"
    )


def _check_dims(model: IPCModel, data: PerceptionDataset, role: str) -> None:
    cfg = model.config
    if (data.x_dim, data.y_dim) != (cfg.x_dim, cfg.y_dim):
        raise InvalidInputError(
            f"{data.source}: {role} data has x_dim={data.x_dim}, y_dim={data.y_dim} but the model expects "
            f"x_dim={cfg.x_dim}, y_dim={cfg.y_dim}"
        )


def check_inputs(
    model: IPCModel,
    test_data: PerceptionDataset | None,
    train_data: PerceptionDataset | None,
    delta: float | None,
) -> float:
    """Step 1: refuse data the certificate could not rest on; return the confidence ``delta``.

    Parameters
    ----------
    model : IPCModel
        The model to certify.
    test_data, train_data : PerceptionDataset or None
        The test data and the training data (for Theorem 1).
    delta : float or None
        The confidence parameter; None: the calibration's, else :data:`DEFAULT_DELTA`.

    Raises
    ------
    InvalidInputError
        If dimensions disagree, the test data is the calibration or training data, the
        training data is not the data the model file records it was trained on, the
        calibration belongs to a different network, or ``delta`` is not in ``(0, 1)``.
    """
    if train_data is not None:
        _check_dims(model, train_data, "training")
        recorded = model.metadata.get("train_data_hash")
        if recorded is not None and recorded != train_data.content_hash():
            raise InvalidInputError(
                f"{train_data.source}: this is not the data the model was trained on (its content SHA-256 "
                "differs from the one the model file recorded at training), and Theorem 1 is a statement "
                f"about the training set itself; pass the training file, or leave {option('train_data')} "
                "out to use "
                "the statistics the model file stored at training"
            )
    cal = model.calibration
    if cal is not None and cal.network_hash != model.weights.fingerprint():
        raise InvalidInputError(
            "the model's calibration was computed for a different network (fingerprint mismatch); "
            "recalibrate this network"
        )
    if test_data is not None:
        _check_test_data(model, test_data)
    if delta is None:
        delta = cal.delta if cal is not None else DEFAULT_DELTA
    if not (isinstance(delta, (int, float)) and 0 < delta < 1):
        raise InvalidInputError(f"delta must lie strictly between 0 and 1; got {delta!r}")
    return float(delta)


def _check_test_data(model: IPCModel, test_data: PerceptionDataset) -> None:
    _check_dims(model, test_data, "test")
    cal = model.calibration
    test_hash = test_data.content_hash()
    if cal is not None:
        if cal.data_hash == test_hash:
            raise InvalidInputError(
                f"{test_data.source}: the test data is the calibration data; certify on fresh samples"
            )
    if test_hash == model.metadata.get("train_data_hash"):
        raise InvalidInputError(f"{test_data.source}: the test data is the training data; use fresh samples")


@dataclass(frozen=True, eq=False)
class TestScores:
    """The contract's sets on the test data and what they say about each sample.

    Attributes
    ----------
    sets : Ellipsoid
        The calibrated sets of the test samples.
    raw, scales, normalized : ndarray, shape (N,)
        The raw score ``g``, the calibration scale ``s`` and ``g / s``.
    violated : ndarray of bool, shape (N,)
        Whether each truth fell outside its set.
    log_volume : ndarray, shape (N,)
        Log-volume of each set.
    """

    __test__ = False  # not a pytest test class

    sets: Ellipsoid
    raw: FloatArray
    scales: FloatArray
    normalized: FloatArray
    violated: NDArray[np.bool_]
    log_volume: FloatArray


def score_test_set(model: IPCModel, test_data: PerceptionDataset) -> TestScores:
    """Step 2: raw scores, calibration scales, calibrated sets and violations of every test sample.

    Parameters
    ----------
    model : IPCModel
        The model.
    test_data : PerceptionDataset
        The test data.
    """
    centers, shapes = model.raw_arrays(test_data.x, test_data.yhat)
    raw = np.linalg.norm(np.einsum("bij,bj->bi", shapes, test_data.y - centers), axis=1)
    cal = model.calibration
    scales = np.ones(len(raw)) if cal is None else np.asarray(cal.scale_for(test_data.x, test_data.yhat))
    sets = model.predict_unguarded(test_data.x, test_data.yhat)
    return TestScores(
        sets=sets,
        raw=raw,
        scales=scales,
        normalized=sets.g(test_data.y),
        violated=~sets.contains(test_data.y),
        log_volume=sets.log_volume(),
    )


def test_results(
    cal: Calibration | None, test_data: PerceptionDataset, violated: NDArray[np.bool_], delta: float
) -> tuple[TestResult, tuple[GroupTestResult, ...]]:
    """Step 3: the test bound overall (counted in the unit of the calibration's claim) and, for a
    calibration with several groups, per group.

    Parameters
    ----------
    cal : Calibration or None
        The model's calibration.
    test_data : PerceptionDataset
        The test data.
    violated : ndarray of bool, shape (N,)
        Whether each test truth fell outside its set.
    delta : float
        Confidence parameter of the bounds.
    """
    counts = row_counts(violated) if cal is None else cal.test_counts(violated, test_data)
    if counts.shares is not None:  # a claim about the expected share of a run's rows: bound the mean share
        test = TestResult.from_shares(counts.shares, delta, counts.unit)
    else:
        test = TestResult.from_counts(counts.violations, counts.n, delta, counts.unit)
    if cal is None or len(cal.groups()) == 1:
        return test, ()
    gi = cal.group_index(test_data.x, test_data.yhat)
    groups = []
    for j, g in enumerate(cal.groups()):
        m = gi == j
        res = TestResult.from_counts(int(violated[m].sum()), int(m.sum()), delta) if m.any() else None
        groups.append(GroupTestResult(label=g.label, result=res))
    return test, tuple(groups)


def certificate_status(
    cal: Calibration | None, checks: tuple[Consistency, ...], tested: bool, rows_in_doubt: bool = False
) -> CertificateStatus:
    """The verdict: no calibration or untested; CONTRADICTED if a check fails; UNCHECKED if none ran.

    A row-level claim on rows that come in runs (``rows_in_doubt``) is never CERTIFIED: its
    calibration counted correlated rows as independent samples, so it is ROWS_ASSUMED unless a
    check (with runs as the units: the caller passes only those) contradicts it.
    """
    if cal is None:
        return CertificateStatus.NOT_CALIBRATED
    if not tested:
        return CertificateStatus.UNTESTED
    done = [c for c in checks if c.checked]
    if any(not c.consistent for c in done):
        return CertificateStatus.CONTRADICTED
    if rows_in_doubt:
        return CertificateStatus.ROWS_ASSUMED
    return CertificateStatus.CERTIFIED if done else CertificateStatus.UNCHECKED


def theorem1_step(
    model: IPCModel, train_data: PerceptionDataset | None, delta: float, radius: float
) -> tuple[Theorem1Result | None, str, str]:
    """Step 4: Theorem 1 and where its training terms came from, or the reason it was not computed.

    From the training data if given, else from the statistics :func:`ipcverify.training.train`
    stored in the model file (for every recipe). A model file without them (a default-recipe
    model written before they were stored for it) gets a reason instead: the PAC certificate
    does not depend on Theorem 1.

    Parameters
    ----------
    model : IPCModel
        The model.
    train_data : PerceptionDataset or None
        The training data.
    delta : float
        Confidence parameter of Theorem 1.
    radius : float
        Radius of the parameter ball of the sound Lipschitz bound.
    """
    if train_data is not None:
        return theorem1(model, train_data, delta, radius=radius), "", "training data"
    stored = model.metadata.get("training_statistics")
    if stored is None:
        return None, no_statistics(), ""
    stats = TrainingStatistics.from_dict(stored)
    return theorem1(model, stats, delta, radius=radius), "", "statistics stored at training time"


def statement(
    cal: Calibration | None,
    test: TestResult | None,
    status: CertificateStatus,
    group_test: GroupTest | None = None,
) -> str:
    """Step 5: the certificate's statement in plain words (with the group-level test, if any).

    Parameters
    ----------
    cal : Calibration or None
        The model's calibration.
    test : TestResult or None
        The test-set bound.
    status : CertificateStatus
        The verdict.
    group_test : GroupTest, optional
        The test counted per group.
    """
    text = _statement(cal, test, status)
    if group_test is None:
        return text
    if test is not None and test.unit == "samples":
        text += " The row-level bound assumes independent rows; rows of one group are correlated."
    return text + " " + group_test.sentence()


def _statement(cal: Calibration | None, test: TestResult | None, status: CertificateStatus) -> str:
    if test is None:
        if cal is None:
            return "No calibration certificate and no test data: nothing is guaranteed about this model."
        return cal.guarantee() + " No test data was given: nothing here checks the calibration independently."
    if test.statistic == "mean":
        test_sentence = (
            f"Independently, over {test.n} fresh test {test.unit} the mean share of rows whose ground truth "
            f"fell outside its set was {100 * test.empirical_rate:.3g} %, so with confidence "
            f"{1 - test.delta:.6g} "
            f"the expected share of a new one's rows outside is at most {test.bound_text()} (betting bound; "
            f"valid if the test {test.unit} are i.i.d. from deployment and unused in training and "
            "calibration)."
        )
    else:
        test_sentence = (
            f"Independently, the ground truth fell outside its set for {test.violations} of {test.n} fresh "
            f"test {test.unit}, so with "
            f"confidence {1 - test.delta:.6g} the violation rate of this contract is at most "
            f"{test.bound_text()} (Clopper-Pearson; valid if the test {test.unit} are i.i.d. from "
            "deployment and unused in training and calibration)."
        )
    if cal is None:
        return "No calibration certificate: the model was not calibrated. " + test_sentence
    text = cal.guarantee() + " " + test_sentence
    if status is CertificateStatus.CONTRADICTED:
        text = "WARNING: the test data contradicts the calibration. " + text
    return text
