"""The ``ipcverify demo`` job: synthetic data -> trained IPC -> calibrated IPC -> evaluation."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ipcverify.baselines import fit_global_mahalanobis
from ipcverify.calibration import calibrate
from ipcverify.data import save_dataset
from ipcverify.evaluation import Evaluation, evaluate
from ipcverify.modelio import save_model
from ipcverify.synthetic import make_lagged_perception
from ipcverify.training import TrainConfig, train

__all__ = ["DemoSummary", "run_demo"]

#: Calibration target of the demo: PAC, at most 1 % violations with confidence 99.9 %.
DEMO_EPSILON = 0.01
DEMO_DELTA = 0.001


@dataclass(frozen=True)
class DemoSummary:
    """What the demo produced.

    Attributes
    ----------
    out_dir : Path
        Directory holding ``train.csv``, ``calibration.csv``, ``test.csv``, ``model.pt``
        and ``calibrated.pt``.
    raw : Evaluation
        The trained (uncalibrated) IPC on the test data.
    calibrated : Evaluation
        The calibrated IPC on the test data.
    guarantee : str
        The calibration's guarantee in one sentence.
    global_log_volume : float
        Log-volume of the global Mahalanobis ellipsoid calibrated on the same data at
        the same ``(epsilon, delta)``.
    global_violations : int
        Its violations on the test data.
    """

    out_dir: Path
    raw: Evaluation
    calibrated: Evaluation
    guarantee: str
    global_log_volume: float
    global_violations: int


def run_demo(
    out_dir: str | os.PathLike[str],
    n_train: int = 5000,
    n_calibration: int = 5000,
    seed: int = 0,
    progress: bool = False,
) -> DemoSummary:
    """Generate synthetic data, train an IPC, calibrate it on held-out data, evaluate it.

    The global Mahalanobis ellipsoid (one set shape for every input), fitted on the
    same training data and calibrated on the same calibration data at the same
    ``(epsilon, delta)``, is evaluated alongside for comparison.

    Parameters
    ----------
    out_dir : path-like
        Created if missing; receives the three CSV files and the two model files.
    n_train, n_calibration : int
        Training and calibration samples (the test set has 20,000).
    seed : int
        Seed for data and training.

    Examples
    --------
    >>> import tempfile
    >>> s = run_demo(tempfile.mkdtemp(), n_train=300, n_calibration=1000)
    >>> s.calibrated.n, s.calibrated.calibrated
    (20000, True)
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    train_data = make_lagged_perception(n_train, seed=seed)
    cal_data = make_lagged_perception(n_calibration, seed=seed + 500_009)
    test_data = make_lagged_perception(20_000, seed=seed + 1_000_003)
    for name, ds in (("train", train_data), ("calibration", cal_data), ("test", test_data)):
        save_dataset(ds, out / f"{name}.csv")
    model = train(train_data, train_config=TrainConfig(seed=seed), progress=progress).model
    save_model(model, out / "model.pt")
    calibrated = calibrate(model, cal_data, DEMO_EPSILON, DEMO_DELTA, mode="pac")
    save_model(calibrated, out / "calibrated.pt")
    base = fit_global_mahalanobis(train_data).calibrate(cal_data, DEMO_EPSILON, DEMO_DELTA, mode="pac")
    base_sets = base.predict(test_data.x, test_data.yhat)
    assert calibrated.calibration is not None
    return DemoSummary(
        out_dir=out,
        raw=evaluate(model, test_data),
        calibrated=evaluate(calibrated, test_data),
        guarantee=calibrated.calibration.guarantee(),
        global_log_volume=float(np.median(base_sets.log_volume())),
        global_violations=int((~base_sets.contains(test_data.y)).sum()),
    )
