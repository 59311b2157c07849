"""The ``ipcverify demo`` job: synthetic data -> trained IPC -> evaluation."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ipcverify.data import PerceptionDataset, save_dataset
from ipcverify.evaluation import Evaluation, evaluate
from ipcverify.modelio import save_model
from ipcverify.sets import unit_ball_log_volume
from ipcverify.synthetic import make_lagged_perception
from ipcverify.training import TrainConfig, train

__all__ = ["DemoSummary", "run_demo", "global_ellipsoid_log_volume"]


@dataclass(frozen=True)
class DemoSummary:
    """What the demo produced."""

    out_dir: Path
    evaluation: Evaluation
    global_log_volume: float


def global_ellipsoid_log_volume(
    train_data: PerceptionDataset, test_data: PerceptionDataset, violations: int
) -> float:
    """Log-volume of one fixed error ellipsoid (mean and covariance of ``y - yhat`` on the
    training data) grown until it has at most ``violations`` violations on the test data.

    This is the "one ellipsoid for every state" alternative the IPC is compared with in
    the demo; the calibrated version lives in :mod:`ipcverify.baselines`.
    """
    r = train_data.y - train_data.yhat
    mu = r.mean(axis=0)
    cov = np.cov(r, rowvar=False).reshape(r.shape[1], r.shape[1])
    chol = np.linalg.cholesky(cov)
    z = np.linalg.solve(chol, (test_data.y - test_data.yhat - mu).T).T
    d = np.sort(np.linalg.norm(z, axis=1))
    k = max(len(d) - violations - 1, 0)
    radius = d[k]
    n = r.shape[1]
    return float(unit_ball_log_volume(n) + np.log(np.diag(chol)).sum() + n * np.log(radius))


def run_demo(
    out_dir: str | os.PathLike[str], n_train: int = 5000, seed: int = 0, progress: bool = False
) -> DemoSummary:
    """Write synthetic train/test data to ``out_dir``, train an IPC on it, evaluate it.

    Parameters
    ----------
    out_dir : path-like
        Created if missing; receives ``train.csv``, ``test.csv`` and ``model.pt``.
    n_train : int
        Training samples (the test set has 20,000).
    seed : int
        Seed for data and training.

    Examples
    --------
    >>> import tempfile
    >>> s = run_demo(tempfile.mkdtemp(), n_train=300)
    >>> s.evaluation.n
    20000
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    train_data = make_lagged_perception(n_train, seed=seed)
    test_data = make_lagged_perception(20_000, seed=seed + 1_000_003)
    save_dataset(train_data, out / "train.csv")
    save_dataset(test_data, out / "test.csv")
    result = train(train_data, train_config=TrainConfig(seed=seed), progress=progress)
    save_model(result.model, out / "model.pt")
    ev = evaluate(result.model, test_data)
    return DemoSummary(out, ev, global_ellipsoid_log_volume(train_data, test_data, ev.violations))
