"""Benchmark: Theorem 1 for the default recipe, and what its statistics add to ``train()``.

Run ``python -m benchmarks.bench_theorem1``. For the default recipe ("tight": an ensemble of
5 low-rank-head MLPs (64, 64), p = 29,475 parameters for x_dim = 6 and y_dim = 3) trained
on two logs -- the demo's data (:func:`ipcverify.data.make_lagged_perception`, 5,000
rows, seed 0) and the real EuRoC log (``data/euroc_mh04_vislam.csv``, all 5,249 rows,
x = ``x_0..x_4``) -- it records:

* Theorem 1 (delta = 0.001, the training alpha = 1.0, radius 0.1): ``p``, ``N``, the
  empirical term, the sound and empirical ``L_g``, both bounds and the ``N`` each needs;
* the time ``train()`` spends on :class:`ipcverify.certification.TrainingStatistics` (scores,
  per-sample gradients, box, hash: wall and CPU seconds, median of 3) next to the whole
  ``train()``, and the time of the sound bound;
* the per-sample gradient norms by ``torch.func``'s ``vmap(grad)`` (what the paper's heads
  use) against :func:`ipcverify.network.ensemble_gradient_norms`: their largest
  relative difference and both times.

Writes ``benchmarks/theorem1_results.json``.
"""

from __future__ import annotations

import copy
import time
from pathlib import Path
from typing import Any, cast

import numpy as np
import torch
from torch.func import functional_call, grad, vmap

from benchmarks.common import machine_info, spread, write_json
from ipcverify.certification._lipschitz import sound_lipschitz
from ipcverify.certification._theorem1 import TrainingStatistics, theorem1
from ipcverify.data import PerceptionDataset, load_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.network._lipschitz_lowrank import ensemble_scores
from ipcverify.network._lowrank import LowRankEnsemble
from ipcverify.training import train

ROOT = Path(__file__).resolve().parent.parent
OUT = Path(__file__).with_name("theorem1_results.json")
EUROC = ROOT / "data" / "euroc_mh04_vislam.csv"
DELTA = 0.001


def _timed(fn: Any) -> tuple[Any, float, float]:
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w0, time.process_time() - c0


def vmap_grad_norms(network: LowRankEnsemble, data: PerceptionDataset, chunk: int = 1000) -> np.ndarray:
    """The same per-sample norms by torch.func (vmap of grad over ``ensemble_scores``), float32 members."""
    net = copy.deepcopy(network).eval()
    params = {k: v.detach() for k, v in net.named_parameters()}
    buffers = dict(net.named_buffers())

    class _Score(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.net = net

        def forward(self, x: torch.Tensor, y: torch.Tensor, yhat: torch.Tensor) -> torch.Tensor:
            return ensemble_scores(self.net, x[None], y[None], yhat[None])[0]

    score = _Score()
    prefixed = {f"net.{k}": v for k, v in params.items()}
    bufs = {f"net.{k}": v for k, v in buffers.items()}

    def g(p: dict[str, torch.Tensor], x: torch.Tensor, y: torch.Tensor, yh: torch.Tensor) -> torch.Tensor:
        return functional_call(score, (p, bufs), (x, y, yh))  # type: ignore[no-any-return]

    gfun = vmap(grad(g), in_dims=(None, 0, 0, 0))
    xt, yt, yht = (torch.tensor(a) for a in (data.x, data.y, data.yhat))
    out = []
    with torch.no_grad():
        for i in range(0, len(xt), chunk):
            sl = slice(i, i + chunk)
            grads = gfun(prefixed, xt[sl], yt[sl], yht[sl])
            sq = sum((v.flatten(1).double() ** 2).sum(1) for v in grads.values())
            out.append(torch.sqrt(sq).numpy())
    return np.concatenate(out)


def bench_one(name: str, data: PerceptionDataset, repeats: int = 3) -> dict[str, Any]:
    """Train the default recipe on ``data`` and measure Theorem 1 and its costs."""
    model, train_wall, train_cpu = _timed(lambda: train(data).model)
    alpha = float(model.metadata["train_config"]["alpha"])
    stats_wall, stats_cpu = [], []
    for _ in range(repeats):
        _, w, c = _timed(lambda: TrainingStatistics.compute(model, data, alpha))
        stats_wall.append(w)
        stats_cpu.append(c)
    bound, sound_wall, _ = _timed(lambda: sound_lipschitz(model, data))
    res = theorem1(model, TrainingStatistics.from_dict(model.metadata["training_statistics"]), DELTA)
    # the default recipe's network is the ensemble: its engine's gradient norms
    # (ensemble_gradient_norms, its default chunks and float32 members) refuse any other network
    net = cast(LowRankEnsemble, model.network)
    fast, fast_wall, fast_cpu = _timed(
        lambda: model.engine.gradient_norms(net, data.x, data.y, data.yhat, None, 8192, torch.float32)
    )
    ref, ref_wall, ref_cpu = _timed(lambda: vmap_grad_norms(net, data))
    t1 = res.to_dict()
    return {
        "data": name,
        "n_train": len(data),
        "n_parameters": model.n_parameters,
        "theorem1": {
            k: t1[k]
            for k in (
                "alpha",
                "delta",
                "lipschitz_radius",
                "empirical_term",
                "confidence_term",
                "lipschitz_sound",
                "lipschitz_empirical",
                "complexity_term_sound",
                "complexity_term_empirical",
                "bound",
                "vacuous",
                "n_needed",
                "bound_with_empirical_lipschitz",
                "vacuous_with_empirical_lipschitz",
                "n_needed_with_empirical_lipschitz",
            )
        },
        "sound_bound_parts": {
            "jacobian_bound": bound.jacobian_bound,
            "output_gradient_bound": bound.output_gradient_bound,
            "hidden_norm_bounds": list(bound.hidden_norm_bounds),
        },
        "seconds": {
            "train_total_wall": train_wall,
            "train_total_cpu": train_cpu,
            "training_statistics_wall": spread(stats_wall),
            "training_statistics_cpu": spread(stats_cpu),
            "sound_bound_wall": sound_wall,
            "gradient_norms_one_backward_wall": fast_wall,
            "gradient_norms_one_backward_cpu": fast_cpu,
            "gradient_norms_vmap_grad_wall": ref_wall,
            "gradient_norms_vmap_grad_cpu": ref_cpu,
        },
        "gradient_norms_max_relative_difference": float(np.max(np.abs(fast - ref) / ref)),
    }


def main() -> dict[str, Any]:
    """Run both logs and write ``benchmarks/theorem1_results.json``."""
    torch.manual_seed(0)
    euroc = load_dataset(EUROC, x_columns=[f"x_{i}" for i in range(5)])
    results: dict[str, Any] = {
        "machine": machine_info(),
        "recipe": "tight (default)",
        "runs": [
            bench_one("demo: make_lagged_perception(5000, seed=0)", make_lagged_perception(5000, seed=0)),
            bench_one(f"EuRoC MH_04 VI-SLAM log, all {len(euroc)} rows", euroc),
        ],
    }
    write_json(OUT, results)
    for run in results["runs"]:
        t1, s = run["theorem1"], run["seconds"]
        print(
            f"{run['data']}: p = {run['n_parameters']:,}, N = {run['n_train']:,}, L_g sound "
            f"{t1['lipschitz_sound']:.3g}, empirical {t1['lipschitz_empirical']:.3g}; "
            f"bound {t1['bound']:.3g} "
            f"(n_needed {t1['n_needed']:.3g}), with empirical L_g {t1['bound_with_empirical_lipschitz']:.3g} "
            f"(n_needed {t1['n_needed_with_empirical_lipschitz']:.3g}); statistics "
            f"{s['training_statistics_wall']['median']:.2f} s wall of train() {s['train_total_wall']:.1f} s"
        )
    return results


if __name__ == "__main__":
    main()
