"""Benchmark: training in the paper's configuration (N = 5000, 20 epochs, (64, 128), Adam 1e-3).

Run ``python -m benchmarks.bench_training``. Target (issue 2): <= 10 s on 2 CPU cores;
the ``cholesky`` parameterisation never gives a non-finite loss. Writes
``benchmarks/training_results.json``.
"""

from __future__ import annotations

import json
import statistics
import time
from pathlib import Path

import numpy as np

from benchmarks.common import machine_info
from ipcverify.architecture import ModelConfig
from ipcverify.synthetic import make_lagged_perception
from ipcverify.training import TrainConfig, train

OUT = Path(__file__).with_name("training_results.json")


def main(repeats: int = 3) -> dict[str, object]:
    data = make_lagged_perception(5000, seed=0)
    results: dict[str, object] = {
        "machine": machine_info(),
        "target_seconds": 10.0,
    }
    for param in ("cholesky", "full"):
        times, finite = [], True
        for seed in range(repeats):
            cfg = ModelConfig(x_dim=data.x_dim, y_dim=data.y_dim, param=param)  # type: ignore[arg-type]
            t0 = time.perf_counter()
            res = train(data, cfg, TrainConfig(seed=seed))
            times.append(time.perf_counter() - t0)
            finite &= all(np.isfinite(r["train_loss"]) for r in res.history)
        results[param] = {
            "seconds_median": statistics.median(times),
            "seconds_min": min(times),
            "seconds_max": max(times),
            "repeats": repeats,
            "all_losses_finite": finite,
            "meets_target": statistics.median(times) <= 10.0,
        }
        med = statistics.median(times)
        print(f"{param:9s} median {med:.2f} s (min {min(times):.2f}, max {max(times):.2f}), finite={finite}")
    OUT.write_text(json.dumps(results, indent=2) + "\n")
    return results


if __name__ == "__main__":
    main()
