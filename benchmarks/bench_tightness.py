"""Tightness: set volume at matched certified coverage, and coverage on held-out data.

Every method is fitted on the same training split, calibrated on the same calibration
split with the same ``(epsilon, delta, mode)`` through ipcverify's order statistic
(:func:`ipcverify.calibration.threshold_scores`, PAC by default), then measured on the
same test split:

* ``ipc`` -- ipcverify's IPC with its default settings, calibrated.
* ``global_mahalanobis`` -- one residual-covariance ellipsoid for every input
  (:class:`ipcverify.baselines.GlobalMahalanobis`; Johnstone & Cox 2021, Messoudi et al. 2022).
* ``bonferroni_box`` -- per-axis intervals at ``epsilon / n``
  (:class:`ipcverify.baselines.BonferroniBox`; what puncc and MAPIE users build).
* ``mapie_multivariate`` -- MAPIE 1.6's ``MultivariateResidualNormalisedScore``
  (:mod:`benchmarks.peers`), if ``mapie==1.6.0`` is installed.
* ``raw_ipc`` -- **uncalibrated**: the paper's IPC as published, i.e. trained with the
  paper's objective settings (alpha = 0.1, lambda = 0.01, 20 epochs, (64, 128), Adam 1e-3)
  and used without calibration; its coverage is whatever the network gives.
* ``raw_ipc_paper_head`` -- **uncalibrated**, and also with the paper's output head
  (centre predicted outright, nine free shape entries: ``center="raw"``, ``param="full"``).

Volumes are in the units of y cubed (m^3 for both datasets). Training is repeated over
seeds (the learned methods); the baselines are deterministic.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from benchmarks.common import spread
from benchmarks.datasets import Splits
from benchmarks.peers import MAPIE_VERSION, fit_mapie_multivariate, mapie_available
from ipcverify.architecture import ModelConfig
from ipcverify.baselines import fit_bonferroni_box, fit_global_mahalanobis
from ipcverify.bounds import CalibrationMode
from ipcverify.calibrate import calibrate
from ipcverify.model import IPCModel
from ipcverify.training import TrainConfig, train

__all__ = ["METHODS", "PAPER_TRAIN", "measure", "bench_tightness"]

#: Methods in report order.
METHODS: tuple[str, ...] = (
    "ipc",
    "global_mahalanobis",
    "bonferroni_box",
    "mapie_multivariate",
    "raw_ipc",
    "raw_ipc_paper_head",
)
#: The paper's training settings (Sun, Yang and Mitra: hinge margin and weight as first released).
PAPER_TRAIN: dict[str, Any] = {"alpha": 0.1, "lam": 0.01, "epochs": 20, "lr": 1e-3, "batch_size": 64}


def measure(sets: Any, y: np.ndarray) -> dict[str, float]:
    """Mean and median volume, mean log-volume and coverage of a batch of sets."""
    logv = np.asarray(sets.log_volume(), dtype=np.float64)
    vol = np.exp(logv)
    return {
        "mean_volume": float(vol.mean()),
        "median_volume": float(np.median(vol)),
        "mean_log_volume": float(logv.mean()),
        "coverage": float(np.mean(sets.contains(y))),
    }


def _timed(fn: Callable[[], Any]) -> tuple[Any, float]:
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def _summarise(runs: list[dict[str, float]], extra: dict[str, Any]) -> dict[str, Any]:
    keys = [k for k in runs[0] if isinstance(runs[0][k], float)]
    out: dict[str, Any] = {k: statistics.median(r[k] for r in runs) for k in keys}
    out["spread"] = {k: spread([r[k] for r in runs]) for k in keys}
    out.update(extra)
    return out


def bench_tightness(
    splits: Splits,
    epsilon: float = 0.01,
    delta: float = 0.001,
    mode: CalibrationMode = "pac",
    seeds: int = 3,
    mapie_epochs: int = 20,
    mapie_seeds: int | None = None,
) -> tuple[dict[str, Any], IPCModel]:
    """Fit, calibrate and measure every method on one dataset.

    Returns
    -------
    results : dict
        ``{method: {mean_volume, median_volume, coverage, mean_log_volume, spread, ...}}``.
    ipc : IPCModel
        The calibrated IPC of the first seed (for the latency and cost benchmarks).
    """
    tr, cal, te = splits.train, splits.calibration, splits.test
    x_dim, y_dim = tr.x_dim, tr.y_dim
    common = {"epsilon": epsilon, "delta": delta, "mode": mode, "calibration_n": len(cal), "test_n": len(te)}
    res: dict[str, Any] = {}
    runs: dict[str, list[dict[str, float]]] = {m: [] for m in METHODS}
    first_ipc: IPCModel | None = None
    for seed in range(seeds):
        model, t_train = _timed(lambda seed=seed: train(tr, train_config=TrainConfig(seed=seed)).model)
        calibrated, t_cal = _timed(lambda model=model: calibrate(model, cal, epsilon, delta, mode))
        first_ipc = first_ipc or calibrated
        runs["ipc"].append(
            {
                **measure(calibrated.predict(te.x, te.yhat), te.y),
                "train_seconds": t_train,
                "calibrate_seconds": t_cal,
            }
        )
        paper = train(tr, train_config=TrainConfig(seed=seed, **PAPER_TRAIN)).model
        runs["raw_ipc"].append(measure(paper.predict_raw(te.x, te.yhat), te.y))
        head = ModelConfig(x_dim=x_dim, y_dim=y_dim, center="raw", param="full")
        paper_head = train(tr, head, TrainConfig(seed=seed, **PAPER_TRAIN)).model
        runs["raw_ipc_paper_head"].append(measure(paper_head.predict_raw(te.x, te.yhat), te.y))
    assert first_ipc is not None
    defaults = TrainConfig()
    res["ipc"] = _summarise(
        runs["ipc"],
        {
            **common,
            "calibrated": True,
            "settings": {"alpha": defaults.alpha, "lam": defaults.lam, "epochs": defaults.epochs},
        },
    )
    for name, fit in (("global_mahalanobis", fit_global_mahalanobis), ("bonferroni_box", fit_bonferroni_box)):
        base = fit(tr).calibrate(cal, epsilon, delta, mode)
        res[name] = _summarise([measure(base.predict(te.x, te.yhat), te.y)], {**common, "calibrated": True})
    if mapie_available() is None:
        res["mapie_multivariate"] = {
            "skipped": f"mapie=={MAPIE_VERSION} is not installed (pip install -e '.[bench]')",
        }
    else:
        for seed in range(seeds if mapie_seeds is None else mapie_seeds):
            fitted, t_fit = _timed(lambda seed=seed: fit_mapie_multivariate(tr, mapie_epochs, seed=seed))
            peer = fitted.calibrate(cal, epsilon, delta, mode)
            runs["mapie_multivariate"].append(
                {**measure(peer.predict(te.x, te.yhat), te.y), "train_seconds": t_fit}
            )
        res["mapie_multivariate"] = _summarise(
            runs["mapie_multivariate"],
            {
                **common,
                "calibrated": True,
                "epochs": mapie_epochs,
                "calibration": "MAPIE's score; radius from ipcverify's order statistic (benchmarks/peers.py)",
            },
        )
    for name in ("raw_ipc", "raw_ipc_paper_head"):
        res[name] = _summarise(
            runs[name],
            {
                "calibrated": False,
                "note": "UNCALIBRATED: coverage not matched, no certificate",
                "settings": PAPER_TRAIN,
            },
        )
    gm = res["global_mahalanobis"]["mean_volume"]
    for r in res.values():
        if "mean_volume" in r:
            r["mean_volume_ratio_to_global_mahalanobis"] = r["mean_volume"] / gm
    return res, first_ipc
