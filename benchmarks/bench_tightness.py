"""Tightness: set volume at matched certified coverage, against the peers and the oracle.

Every calibrated method is fitted on the same training split, calibrated on the same
calibration split with the same ``(epsilon, delta, mode)`` through ipcverify's order
statistic (:func:`ipcverify.calibration.threshold_scores`, PAC by default), then measured
on the same test split:

* ``ipc`` -- ipcverify's IPC with its default recipe (``"tight"``), calibrated.
* ``ipc_v1`` -- the recipe ``"v1"``: ipcverify's default before ``"tight"`` (Cholesky head,
  hinge alpha = 1, 20 epochs), calibrated.
* ``ipc_paper`` -- the recipe ``"paper"`` (the paper's head and loss), calibrated.
* ``global_mahalanobis`` -- one residual-covariance ellipsoid for every input
  (:class:`ipcverify.certification.GlobalMahalanobis`; Johnstone & Cox 2021, Messoudi et al. 2022).
* ``bonferroni_box`` -- per-axis intervals at ``epsilon / n``
  (:class:`ipcverify.certification.BonferroniBox`; what puncc and MAPIE users build).
* ``mapie_multivariate`` -- MAPIE 1.6's ``MultivariateResidualNormalisedScore``
  (:mod:`benchmarks.peers`), if ``mapie==1.6.0`` is installed.
* ``oracle`` -- on data with a known conditional law (:mod:`benchmarks.oracle_data`): the
  true conditional ellipsoids, radius from the **same PAC order statistic** on the
  calibration split (the oracle's own scores). ``oracle_exact`` -- the same sets at
  exactly conditional coverage ``1 - epsilon`` (closed-form volume; no calibration, so no
  finite-sample margin: the PAC order statistic costs even the oracle a factor).
  ``mean_volume_ratio_to_oracle_same_coverage`` (ellipsoidal methods, first training seed)
  compares with the oracle at the coverage the method actually reaches
  (:func:`benchmarks.diagnose_tightness.diagnose`): set size at equal coverage.
* ``raw_ipc`` -- **uncalibrated**: the paper's IPC as published (Cholesky head, alpha = 0.1,
  lambda = 0.01, 20 epochs, Adam 1e-3) used without calibration; ``raw_ipc_paper_head`` --
  **uncalibrated**, also with the paper's head (the ``ipc_paper`` network, raw).

Per method: mean and median volume (units of y cubed), coverage, worst-bin coverage over
10 quantile bins of every state column and of ``||yhat||``
(:func:`ipcverify.certification.worst_bin_coverage`), training seconds, and the mean-volume
ratios to the global ellipsoid, MAPIE and the oracle (PAC and exact). On oracle data the
ellipsoidal methods of the first seed are diagnosed (:func:`benchmarks.diagnose_tightness.diagnose`).
Learned methods are repeated over training seeds (medians and spread); the baselines are
deterministic.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from benchmarks.common import spread
from benchmarks.datasets import Splits
from benchmarks.diagnose_tightness import diagnose
from benchmarks.peers import MAPIE_VERSION, fit_mapie_multivariate, mapie_available
from ipcverify.calibration import Global
from ipcverify.calibration._bounds import CalibrationMode
from ipcverify.calibration._threshold import threshold_scores
from ipcverify.certification._baselines import fit_bonferroni_box, fit_global_mahalanobis
from ipcverify.certification._evaluation import worst_bin_coverage
from ipcverify.contract import IPCModel, calibrate
from ipcverify.data import PerceptionDataset
from ipcverify.network import ModelConfig
from ipcverify.sets import Ellipsoid
from ipcverify.training import TrainConfig, train
from ipcverify.training._selection import HingeSelection

__all__ = ["METHODS", "ORACLE_METHODS", "RECIPE_METHODS", "measure", "bench_tightness", "worst_bin_allowance"]

#: Methods in report order (the oracle rows only on data with a known law).
METHODS: tuple[str, ...] = (
    "ipc",
    "ipc_v1",
    "ipc_paper",
    "global_mahalanobis",
    "bonferroni_box",
    "mapie_multivariate",
    "oracle",
    "oracle_exact",
    "raw_ipc",
    "raw_ipc_paper_head",
)
ORACLE_METHODS: tuple[str, ...] = ("oracle", "oracle_exact")
#: The calibrated IPC rows and the recipe each one trains.
RECIPE_METHODS: dict[str, str] = {"ipc": "tight", "ipc_v1": "v1", "ipc_paper": "paper"}
#: Bins of the worst-bin coverage.
BINS = 10


def worst_bin_allowance(epsilon: float, n_test: int, bins: int = BINS) -> float:
    """Two binomial standard deviations of one bin's coverage at ``1 - epsilon`` ("binomial noise").

    Examples
    --------
    >>> round(worst_bin_allowance(0.01, 5000), 4)
    0.0089
    """
    return 2.0 * float(np.sqrt(epsilon * (1.0 - epsilon) / (n_test / bins)))


def measure(sets: Any, test: PerceptionDataset) -> dict[str, Any]:
    """Mean / median volume, mean log-volume, coverage and worst-bin coverage of a batch of sets."""
    logv = np.asarray(sets.log_volume(), dtype=np.float64)
    vol = np.exp(logv)
    covered = np.asarray(sets.contains(test.y))
    worst = worst_bin_coverage(test.x, test.yhat, ~covered, test.x_columns, BINS)
    return {
        "mean_volume": float(vol.mean()),
        "median_volume": float(np.median(vol)),
        "mean_log_volume": float(logv.mean()),
        "coverage": float(covered.mean()),
        "worst_bin_coverage": float(worst.coverage),
        "worst_bin_column": worst.column,
    }


def _timed(fn: Callable[[], Any]) -> tuple[Any, float]:
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def _summarise(runs: list[dict[str, Any]], extra: dict[str, Any]) -> dict[str, Any]:
    keys = [k for k in runs[0] if isinstance(runs[0][k], float)]
    out: dict[str, Any] = {k: statistics.median(r[k] for r in runs) for k in keys}
    out["spread"] = {k: spread([r[k] for r in runs]) for k in keys}
    out["worst_bin_columns"] = [r["worst_bin_column"] for r in runs]
    for r in runs:
        if "diagnosis" in r:
            out["diagnosis"] = r["diagnosis"]
    out.update(extra)
    return out


def _diagnosis(sets: Ellipsoid, splits: Splits, k: int, n: int, epsilon: float) -> dict[str, Any]:
    if splits.test_oracle is None:
        return {}
    return {"diagnosis": diagnose(sets, splits.test_oracle, 1.0 - epsilon, pac_k=k, pac_n=n).to_dict()}


def _recipe_runs(
    splits: Splits, seeds: int, epsilon: float, delta: float, mode: CalibrationMode
) -> tuple[dict[str, list[dict[str, Any]]], IPCModel]:
    """The calibrated IPC of each recipe and the two uncalibrated paper rows, over training seeds."""
    tr, cal, te = splits.train, splits.calibration, splits.test
    runs: dict[str, list[dict[str, Any]]] = {
        m: [] for m in (*RECIPE_METHODS, "raw_ipc", "raw_ipc_paper_head")
    }
    first: IPCModel | None = None
    for seed in range(seeds):
        for method, recipe in RECIPE_METHODS.items():
            tc = TrainConfig.recipe(recipe, seed=seed)
            # the paper's recipe chooses its unstated alpha, lambda and batch size on training rows
            rule = HingeSelection() if recipe == "paper" else None
            model, t_train = _timed(
                lambda tc=tc, recipe=recipe, rule=rule: (
                    train(tr, train_config=tc, recipe=recipe, select=rule).model
                )
            )
            calibrated, t_cal = _timed(
                lambda model=model: calibrate(model, cal, epsilon, delta, Global(mode=mode), domain=None)
            )
            first = first or calibrated
            sets = calibrated.predict_unguarded(te.x, te.yhat)
            rec = {**measure(sets, te), "train_seconds": t_train, "calibrate_seconds": t_cal}
            if seed == 0 and method != "ipc_paper":
                group = calibrated.require_calibration().groups()[0]
                rec.update(_diagnosis(sets, splits, group.k, group.n, epsilon))
            runs[method].append(rec)
            if method == "ipc_paper":
                runs["raw_ipc_paper_head"].append(measure(model.predict_raw(te.x, te.yhat), te))
        head = ModelConfig.recipe("v1", x_dim=tr.x_dim, y_dim=tr.y_dim)
        # the paper's hinge training (alpha = 0.1, lambda = 0.01) on the v1 head, as before the selection rule
        paper = train(tr, head, TrainConfig.recipe("paper", seed=seed, start_at_estimate=False)).model
        runs["raw_ipc"].append(measure(paper.predict_raw(te.x, te.yhat), te))
    if first is None:
        raise ValueError("seeds must be >= 1")
    return runs, first


def _oracle_rows(splits: Splits, epsilon: float, delta: float, mode: CalibrationMode) -> dict[str, Any]:
    cal_o, te_o, te = splits.calibration_oracle, splits.test_oracle, splits.test
    if cal_o is None or te_o is None:
        return {}
    t = threshold_scores(cal_o.scores(splits.calibration.y), epsilon, delta, mode)
    pac = te_o.sets(t.scale)
    exact = te_o.sets(te_o.radius(1.0 - epsilon))
    note = f"the true conditional law ({te_o.law}); "
    return {
        "oracle": _summarise(
            [{**measure(pac, te), **_diagnosis(pac, splits, t.k, t.n, epsilon)}],
            {"calibrated": True, "note": note + "radius from the same PAC order statistic"},
        ),
        "oracle_exact": _summarise(
            [measure(exact, te)],
            {"calibrated": False, "note": note + "exact conditional coverage 1 - epsilon at every input"},
        ),
    }


def bench_tightness(
    splits: Splits,
    epsilon: float = 0.01,
    delta: float = 0.001,
    mode: CalibrationMode = "pac",
    seeds: int = 3,
    mapie_epochs: int = 60,
    mapie_seeds: int | None = None,
) -> tuple[dict[str, Any], IPCModel]:
    """Fit, calibrate and measure every method on one dataset.

    Returns
    -------
    results : dict
        ``{method: {mean_volume, median_volume, coverage, worst_bin_coverage, spread, ...}}``.
    ipc : IPCModel
        The calibrated default IPC of the first seed (for the latency and cost benchmarks).
    """
    tr, cal, te = splits.train, splits.calibration, splits.test
    common = {"epsilon": epsilon, "delta": delta, "mode": mode, "calibration_n": len(cal), "test_n": len(te)}
    runs, first_ipc = _recipe_runs(splits, seeds, epsilon, delta, mode)
    res: dict[str, Any] = {}
    for method, recipe in RECIPE_METHODS.items():
        tc = TrainConfig.recipe(recipe)
        settings = {"recipe": recipe, "loss": tc.loss, "epochs": tc.epochs, "alpha": tc.alpha, "lam": tc.lam}
        res[method] = _summarise(runs[method], {**common, "calibrated": True, "settings": settings})
    gm = fit_global_mahalanobis(tr).calibrate(cal, epsilon, delta, mode)
    gm_sets = gm.predict(te.x, te.yhat)
    gm_rec = measure(gm_sets, te)
    if gm.threshold is not None:
        gm_rec.update(_diagnosis(gm_sets, splits, gm.threshold.k, gm.threshold.n, epsilon))
    res["global_mahalanobis"] = _summarise([gm_rec], {**common, "calibrated": True})
    box = fit_bonferroni_box(tr).calibrate(cal, epsilon, delta, mode)
    res["bonferroni_box"] = _summarise(
        [measure(box.predict(te.x, te.yhat), te)], {**common, "calibrated": True}
    )
    if mapie_available() is None:
        res["mapie_multivariate"] = {
            "skipped": f"mapie=={MAPIE_VERSION} is not installed (pip install -e '.[bench]')",
        }
    else:
        mruns = []
        for seed in range(seeds if mapie_seeds is None else mapie_seeds):
            fitted, t_fit = _timed(lambda seed=seed: fit_mapie_multivariate(tr, mapie_epochs, seed=seed))
            peer = fitted.calibrate(cal, epsilon, delta, mode)
            sets = peer.predict(te.x, te.yhat)
            rec = {**measure(sets, te), "train_seconds": t_fit}
            if seed == 0 and peer.threshold is not None:
                rec.update(_diagnosis(sets, splits, peer.threshold.k, peer.threshold.n, epsilon))
            mruns.append(rec)
        res["mapie_multivariate"] = _summarise(
            mruns,
            {
                **common,
                "calibrated": True,
                "epochs": mapie_epochs,
                "calibration": "MAPIE's score; radius from ipcverify's order statistic (benchmarks/peers.py)",
            },
        )
    res.update(_oracle_rows(splits, epsilon, delta, mode))
    paper = {
        "recipe": "paper (raw_ipc: Cholesky head)",
        **{k: getattr(TrainConfig.recipe("paper"), k) for k in ("alpha", "lam", "epochs")},
    }
    for name in ("raw_ipc", "raw_ipc_paper_head"):
        res[name] = _summarise(
            runs[name],
            {
                "calibrated": False,
                "note": "UNCALIBRATED: coverage not matched, no certificate",
                "settings": paper,
            },
        )
    _ratios(res)
    return res, first_ipc


def _ratios(res: dict[str, Any]) -> None:
    """Mean-volume ratios of every row to the references that exist on this dataset."""
    refs = {
        "global_mahalanobis": "mean_volume_ratio_to_global_mahalanobis",
        "mapie_multivariate": "mean_volume_ratio_to_mapie",
        "oracle": "mean_volume_ratio_to_oracle",
        "oracle_exact": "mean_volume_ratio_to_oracle_exact",
    }
    for ref, key in refs.items():
        base = res.get(ref, {}).get("mean_volume")
        if base is None:
            continue
        for r in res.values():
            if "mean_volume" in r:
                r[key] = r["mean_volume"] / base
    for r in res.values():  # at the method's own coverage: from the diagnosis of its first seed
        same = r.get("diagnosis", {}).get("volume_ratio_to_oracle_same_coverage")
        if same is not None:
            r["mean_volume_ratio_to_oracle_same_coverage"] = same
