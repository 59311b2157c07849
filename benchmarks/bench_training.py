"""Benchmark: training cost of the default recipe at N = 5,000 (target: <= 10 s on 2 cores).

``python -m benchmarks.bench_training`` trains the default recipe ``"tight"`` (5 members,
all in one process) and, for comparison, the earlier default ``"v1"``, three times each
on the 5,000-sample training splits of the ``synthetic`` and ``quad_landing`` benchmark
datasets, with torch limited to one thread (the second core stays free). It records wall
and CPU seconds, the epochs run and whether every loss stayed finite, and the load
average (the machine is shared), in ``benchmarks/training_results.json``. A benchmark,
not a timed test.
"""

from __future__ import annotations

import os
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from benchmarks.common import blas_single_thread, machine_info, write_json
from benchmarks.datasets import load_splits
from ipcverify.training import TrainConfig, train

__all__ = ["TARGET_SECONDS", "main"]

OUT = Path(__file__).with_name("training_results.json")
#: The issue's budget for the default recipe at N = 5,000 on 2 cores.
TARGET_SECONDS = 10.0


def main(repeats: int = 3, datasets: tuple[str, ...] = ("synthetic", "quad_landing")) -> dict[str, Any]:
    torch.set_num_threads(1)
    blas_single_thread()
    results: dict[str, Any] = {
        "machine": machine_info(),
        "target_seconds": TARGET_SECONDS,
        "torch_threads": 1,
    }
    for name in datasets:
        data = load_splits(name, 5000, 10, 10).train
        for recipe in ("tight", "v1"):
            wall, cpu, epochs, finite = [], [], [], True
            for seed in range(repeats):
                t0, c0 = time.perf_counter(), time.process_time()
                res = train(data, train_config=TrainConfig.recipe(recipe, seed=seed), recipe=recipe)
                wall.append(time.perf_counter() - t0)
                cpu.append(time.process_time() - c0)
                epochs.append(len(res.history))
                finite &= all(np.isfinite(r["train_loss"]) for r in res.history)
            med = statistics.median(wall)
            results[f"{name}/{recipe}"] = {
                "wall_seconds_median": med,
                "wall_seconds_min": min(wall),
                "wall_seconds_max": max(wall),
                "cpu_seconds_median": statistics.median(cpu),
                "epochs": epochs,
                "repeats": repeats,
                "all_losses_finite": finite,
                "meets_target": med <= TARGET_SECONDS,
                "load_average_after": [round(v, 2) for v in os.getloadavg()],
            }
            print(
                f"{name:13s} {recipe:6s} wall median {med:.2f} s (min {min(wall):.2f}, max {max(wall):.2f}), "
                f"CPU {statistics.median(cpu):.2f} s, epochs {epochs}, finite={finite}"
            )
    write_json(OUT, results)
    return results


if __name__ == "__main__":
    main()
