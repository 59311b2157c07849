"""Which settings of the paper's head give the tightest calibrated IPC? (evidence for the recipe "v1").

Run ``python -m benchmarks.tune_defaults`` from the repository root (about 9 minutes on
2 cores). For each candidate setting -- overrides of the recipe ``"v1"`` (Cholesky head,
hinge) -- and each of three training seeds it trains an IPC on the train split of the
``synthetic`` and ``quad_landing`` benchmark datasets, calibrates it (PAC,
epsilon = 0.01, delta = 0.001) on the calibration split and measures the mean and median
set volume and the coverage on the test split. Writes ``benchmarks/tuning_results.json``;
the conclusions are in ``docs/benchmarks.md``. The committed results were measured when
``synthetic`` was the demo's :func:`ipcverify.data.make_lagged_perception`; the
default recipe ``"tight"`` came later, from ``benchmarks/diagnose_tightness.py``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from benchmarks.common import blas_single_thread, machine_info
from benchmarks.datasets import load_splits
from ipcverify.calibration import Global
from ipcverify.contract import calibrate
from ipcverify.network import ModelConfig
from ipcverify.training import TrainConfig, train

OUT = Path(__file__).with_name("tuning_results.json")
EPSILON, DELTA = 0.01, 0.001

#: Candidate settings (keyword overrides of ModelConfig / TrainConfig).
CANDIDATES: dict[str, dict[str, Any]] = {
    "paper (alpha=0.1, lam=0.01, 20 ep)": {"alpha": 0.1, "lam": 0.01},
    "alpha=0.3": {"alpha": 0.3, "lam": 0.01},
    "alpha=1": {"alpha": 1.0, "lam": 0.01},
    "alpha=1, lam=0.003": {"alpha": 1.0, "lam": 0.003},
    "alpha=1, lam=0.03": {"alpha": 1.0, "lam": 0.03},
    "alpha=1, lam=0.08": {"alpha": 1.0, "lam": 0.08},
    "alpha=1, 40 ep": {"alpha": 1.0, "lam": 0.01, "epochs": 40},
    "alpha=1, batch 32": {"alpha": 1.0, "lam": 0.01, "batch_size": 32},
    "alpha=1, lr 3e-3": {"alpha": 1.0, "lam": 0.01, "lr": 3e-3},
    "alpha=1, lam=0.5": {"alpha": 1.0, "lam": 0.5},
    "alpha=0.1, 100 ep": {"alpha": 0.1, "lam": 0.01, "epochs": 100},
    "lam=0.1": {"alpha": 0.1, "lam": 0.1},
    "centre raw": {"alpha": 0.1, "lam": 0.01, "center": "raw"},
    "param full": {"alpha": 0.1, "lam": 0.01, "param": "full"},
    # training-objective options (TrainConfig.loss / center_warm_start / warmup_epochs)
    "default (hinge, alpha=1)": {},
    "+ centre warm start": {"center_warm_start": True},
    "likelihood": {"loss": "likelihood"},
    "likelihood + centre warm start": {"loss": "likelihood", "center_warm_start": True},
    "likelihood, 40 ep": {"loss": "likelihood", "epochs": 40},
    "likelihood 10 ep, then hinge 10 ep": {"warmup_epochs": 10},
    "likelihood, lr 3e-3": {"loss": "likelihood", "lr": 3e-3},
    "likelihood, 60 ep, batch 32": {"loss": "likelihood", "epochs": 60, "batch_size": 32},
}
_MODEL_KEYS = {"hidden", "param", "center", "activation"}


def run_one(splits: Any, overrides: dict[str, Any], seed: int) -> dict[str, float]:
    """Train, calibrate and measure one setting with one seed."""
    mkw = {k: v for k, v in overrides.items() if k in _MODEL_KEYS}
    tkw = {k: v for k, v in overrides.items() if k not in _MODEL_KEYS}
    mc = ModelConfig.recipe("v1", x_dim=splits.train.x_dim, y_dim=splits.train.y_dim, **mkw)
    t0 = time.perf_counter()
    model = train(splits.train, mc, TrainConfig.recipe("v1", seed=seed, **tkw)).model
    seconds = time.perf_counter() - t0
    cal = calibrate(model, splits.calibration, EPSILON, DELTA, Global(mode="pac"))
    sets = cal.predict_unguarded(splits.test.x, splits.test.yhat)
    vol = np.exp(sets.log_volume())
    raw = model.predict_raw(splits.test.x, splits.test.yhat)
    return {
        "mean_volume": float(vol.mean()),
        "median_volume": float(np.median(vol)),
        "coverage": float(sets.contains(splits.test.y).mean()),
        "raw_coverage": float(raw.contains(splits.test.y).mean()),
        "scale": float(cal.calibration.threshold.scale),  # type: ignore[union-attr]
        "train_seconds": seconds,
    }


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--n", type=int, default=5000, help="samples per split")
    parser.add_argument("--only", nargs="*", default=None, help="candidate names to run")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    blas_single_thread()
    results: dict[str, Any] = {
        "machine": machine_info(),
        "epsilon": EPSILON,
        "delta": DELTA,
        "seeds": args.seeds,
        "n_per_split": args.n,
        "candidates": {},
    }
    names = args.only or list(CANDIDATES)
    if args.only and OUT.is_file():  # add to the earlier results instead of replacing them
        results["candidates"] = json.loads(OUT.read_text()).get("candidates", {})
    for ds in ("synthetic", "quad_landing"):
        splits = load_splits(ds, args.n, args.n, args.n)
        for name in names:
            runs = [run_one(splits, CANDIDATES[name], seed) for seed in range(args.seeds)]
            summary = {
                k: {
                    "median": statistics.median(r[k] for r in runs),
                    "min": min(r[k] for r in runs),
                    "max": max(r[k] for r in runs),
                }
                for k in runs[0]
            }
            results["candidates"].setdefault(name, {"overrides": CANDIDATES[name]})[ds] = summary
            mv = summary["mean_volume"]
            print(
                f"{ds:13s} {name:36s} mean vol {mv['median']:.3g} [{mv['min']:.3g}, {mv['max']:.3g}] "
                f"median vol {summary['median_volume']['median']:.3g} "
                f"coverage {summary['coverage']['median']:.4f}",
                flush=True,
            )
    OUT.write_text(json.dumps(results, indent=2) + "\n")
    return results


if __name__ == "__main__":
    main()
