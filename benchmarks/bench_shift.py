"""Do tighter sets break harder under shift? Violation rates of the old and new default recipes.

Every method is fitted and calibrated (PAC, ``epsilon = 0.01``, ``delta = 0.001``) on
nominal data and then measured where the calibration's exchangeability assumption no
longer holds -- which is exactly where a certificate stops covering anything:

* **synthetic covariate shift**: train and calibrate on the nominal law of
  :func:`~benchmarks.oracle_data.make_hetlag` (seeds 5000 / 5001) and of the held-out
  generator :func:`~benchmarks.oracle_data.make_fresh_lagged` (6000 / 6001); test on
  ``shift`` 0, 0.5 and 1 (deeper / longer ranges and faster motion; seeds 5002 / 6002);
* **the real log** ``data/euroc_mh04_vislam.csv`` (EuRoC MH_04, 20 runs of a VI-SLAM
  estimator; group = method + run): ``random`` -- a random row split 60 / 20 / 20 (the
  exchangeable case); ``run_heldout`` -- 5 folds, each tests on 4 runs, calibrates on 4
  others and trains on the remaining 12; ``time_segment`` -- within every run the first
  60 % of its time trains, 60-80 % calibrates, the last 20 % tests.

Methods: ``ipc`` (the default recipe "tight"), ``ipc_v1`` (the earlier default "v1") and
the ``global_mahalanobis`` ellipsoid as the reference. Per setting: the violation rate
(mean and worst over folds and training seeds), the worst single run (EuRoC) and the
mean volume. ``python -m benchmarks.bench_shift`` writes ``benchmarks/shift_results.json``;
:func:`benchmarks.run.run` includes it.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from benchmarks.common import write_json
from benchmarks.oracle_data import make_fresh_lagged, make_hetlag
from ipcverify.calibration import Global
from ipcverify.certification._baselines import fit_global_mahalanobis
from ipcverify.contract import IPCModel, calibrate
from ipcverify.data import PerceptionDataset
from ipcverify.training import TrainConfig, train

__all__ = ["EUROC", "SHIFTS", "SHIFT_METHODS", "euroc", "euroc_splits", "bench_shift", "main"]

ROOT = Path(__file__).resolve().parent.parent
EUROC = ROOT / "data" / "euroc_mh04_vislam.csv"
SHIFTS: tuple[float, ...] = (0.0, 0.5, 1.0)
SHIFT_METHODS: dict[str, str | None] = {"ipc": "tight", "ipc_v1": "v1", "global_mahalanobis": None}
EPSILON, DELTA = 0.01, 0.001
Fitted = Any  # an object with .predict(x, yhat) -> Ellipsoid


def _fit(
    method: str, tr: PerceptionDataset, cal: PerceptionDataset, seed: int, level: tuple[float, float]
) -> Fitted:
    recipe = SHIFT_METHODS[method]
    epsilon, delta = level
    if recipe is None:
        return fit_global_mahalanobis(tr).calibrate(cal, epsilon, delta, "pac")
    model = train(tr, train_config=TrainConfig.recipe(recipe, seed=seed), recipe=recipe).model
    return calibrate(model, cal, epsilon, delta, Global(mode="pac"), domain=None)


def _measure(fitted: Fitted, te: PerceptionDataset, groups: np.ndarray | None = None) -> dict[str, Any]:
    # the IPC's sets as the network and calibration give them: the domain test is measured apart
    sets = (
        fitted.predict_unguarded(te.x, te.yhat)
        if isinstance(fitted, IPCModel)
        else fitted.predict(te.x, te.yhat)
    )
    violated = ~np.asarray(sets.contains(te.y))
    out: dict[str, Any] = {
        "violation": float(violated.mean()),
        "mean_volume": float(np.exp(sets.log_volume()).mean()),
        "n_test": len(te),
    }
    if groups is not None:
        out["worst_group_violation"] = max(float(violated[groups == g].mean()) for g in np.unique(groups))
    return out


def _summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    v = [r["violation"] for r in runs]
    out = {
        "violation_mean": float(np.mean(v)),
        "violation_max": float(np.max(v)),
        "mean_volume": float(np.median([r["mean_volume"] for r in runs])),
        "runs": runs,
    }
    if "worst_group_violation" in runs[0]:
        out["worst_group_violation"] = float(max(r["worst_group_violation"] for r in runs))
    return out


def _seeds(method: str, seeds: int) -> range:
    return range(1 if SHIFT_METHODS[method] is None else seeds)


Generator = Callable[[int, int, float], PerceptionDataset]
GENERATORS: dict[str, tuple[Generator, tuple[int, int, int]]] = {
    "hetlag": (lambda n, s, sh: make_hetlag(n, s, "gauss", sh)[0], (5000, 5001, 5002)),
    "fresh": (lambda n, s, sh: make_fresh_lagged(n, s, sh)[0], (6000, 6001, 6002)),
}


def synthetic_shift(n: int, seeds: int, level: tuple[float, float] = (EPSILON, DELTA)) -> dict[str, Any]:
    """Fit and calibrate on the nominal law, test on each shift (module docstring)."""
    res: dict[str, Any] = {}
    for name, (gen, (s_tr, s_cal, s_te)) in GENERATORS.items():
        tr, cal = gen(n, s_tr, 0.0), gen(n, s_cal, 0.0)
        tests = {sh: gen(n, s_te, sh) for sh in SHIFTS}
        runs: dict[str, dict[float, list[dict[str, Any]]]] = {}
        for method in SHIFT_METHODS:
            runs[method] = {sh: [] for sh in SHIFTS}
            for seed in _seeds(method, seeds):
                fitted = _fit(method, tr, cal, seed, level)
                for sh, te in tests.items():
                    runs[method][sh].append(_measure(fitted, te))
        for sh in SHIFTS:
            res[f"{name}_shift{sh:g}"] = {m: _summary(runs[m][sh]) for m in SHIFT_METHODS}
    return res


def euroc(path: Path = EUROC) -> tuple[PerceptionDataset, np.ndarray, np.ndarray]:
    """The real log, its groups (method + run) and its times."""
    df = pd.read_csv(path)
    ds = PerceptionDataset(
        x=df[[f"x_{i}" for i in range(5)]].to_numpy(),
        y=df[[f"y_{i}" for i in range(3)]].to_numpy(),
        yhat=df[[f"yhat_{i}" for i in range(3)]].to_numpy(),
        source=str(path),
    )
    return ds, (df["method"] + ":" + df["run"].astype(str)).to_numpy(), df["t"].to_numpy()


Fold = tuple[np.ndarray, np.ndarray, np.ndarray]


def euroc_splits(groups: np.ndarray, t: np.ndarray, seed: int = 0) -> dict[str, list[Fold]]:
    """Row indices (train, calibration, test) of the random, run-held-out and time-segment splits."""
    rng = np.random.default_rng(seed)
    n = len(groups)
    perm = rng.permutation(n)
    a, b = int(0.6 * n), int(0.8 * n)
    out: dict[str, list[Fold]] = {"random": [(perm[:a], perm[a:b], perm[b:])]}
    folds = np.array_split(rng.permutation(np.unique(groups)), 5)
    held: list[Fold] = []
    for k in range(5):
        train_g = np.concatenate([folds[j] for j in range(5) if j not in (k, (k + 1) % 5)])
        held.append(
            (
                np.flatnonzero(np.isin(groups, train_g)),
                np.flatnonzero(np.isin(groups, folds[(k + 1) % 5])),
                np.flatnonzero(np.isin(groups, folds[k])),
            )
        )
    out["run_heldout"] = held
    frac = np.zeros(n)
    for g in np.unique(groups):
        rows = groups == g
        tg = t[rows]
        frac[rows] = (tg - tg.min()) / max(float(tg.max() - tg.min()), 1e-9)
    out["time_segment"] = [
        (
            np.flatnonzero(frac < 0.6),
            np.flatnonzero((frac >= 0.6) & (frac < 0.8)),
            np.flatnonzero(frac >= 0.8),
        )
    ]
    return out


def euroc_shift(
    seeds: int, level: tuple[float, float] = (EPSILON, DELTA), path: Path = EUROC
) -> dict[str, Any]:
    """Every method on the three EuRoC splits (module docstring)."""
    ds, groups, t = euroc(path)
    res: dict[str, Any] = {}
    for name, folds in euroc_splits(groups, t).items():
        res[f"euroc_{name}"] = {}
        for method in SHIFT_METHODS:
            runs = []
            for fold, (i_tr, i_cal, i_te) in enumerate(folds):
                for seed in _seeds(method, seeds):
                    fitted = _fit(method, ds.subset(i_tr), ds.subset(i_cal), seed, level)
                    runs.append(
                        {**_measure(fitted, ds.subset(i_te), groups[i_te]), "fold": fold, "seed": seed}
                    )
            res[f"euroc_{name}"][method] = _summary(runs)
    return res


def bench_shift(
    n: int = 5000, seeds: int = 2, real_log: bool = True, epsilon: float = EPSILON, delta: float = DELTA
) -> dict[str, Any]:
    """Synthetic covariate shift and (``real_log``) the EuRoC splits; see the module docstring."""
    t0 = time.perf_counter()
    level = (epsilon, delta)
    res = {
        "settings": {"epsilon": epsilon, "delta": delta, "mode": "pac", "n": n, "seeds": seeds},
        **synthetic_shift(n, seeds, level),
        **(euroc_shift(seeds, level) if real_log else {}),
    }
    res["runtime_seconds"] = time.perf_counter() - t0
    return res


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=5000)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("shift_results.json"))
    a = ap.parse_args(argv)
    import torch

    torch.set_num_threads(1)
    res = bench_shift(a.n, a.seeds)
    write_json(a.out, res)
    for setting, rows in res.items():
        if isinstance(rows, dict) and "ipc" in rows:
            print(
                f"{setting:22s} "
                + "  ".join(
                    f"{m}: {r['violation_mean']:.4f} (max {r['violation_max']:.4f})" for m, r in rows.items()
                )
            )
    return res


if __name__ == "__main__":
    main()
