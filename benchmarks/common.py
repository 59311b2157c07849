"""Shared helpers of the benchmark suite: machine description, timing statistics, JSON output."""

from __future__ import annotations

import os
import platform
import statistics
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

__all__ = [
    "blas_single_thread",
    "blas_threads",
    "machine_info",
    "save_figure",
    "spread",
    "time_calls",
    "write_json",
]


def blas_single_thread() -> bool:
    """Limit NumPy's BLAS to one thread for the rest of the process (needs threadpoolctl).

    On 2 shared cores OpenBLAS's worker threads make the float64 engine up to ~100x
    slower for batches of 100-1000 rows; the benchmark runs torch, ONNX Runtime and BLAS
    single-threaded and measures the BLAS default separately. Returns False (nothing
    changed) if threadpoolctl is missing.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return False
    threadpool_limits(limits=1, user_api="blas")
    return True


def blas_threads() -> int | None:
    """NumPy's current BLAS thread count (None without threadpoolctl)."""
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return None
    counts = [p["num_threads"] for p in threadpool_info() if p.get("user_api") == "blas"]
    return max(counts) if counts else None


def machine_info() -> dict[str, Any]:
    """CPU count, load average, library versions and torch's thread setting."""
    info: dict[str, Any] = {
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "load_average_at_start": [round(v, 2) for v in os.getloadavg()],
        "python": platform.python_version(),
        "numpy": np.__version__,
        "torch": torch.__version__,
        "torch_threads": torch.get_num_threads(),
        "blas_threads": blas_threads(),
        "note": "2 cores shared with other engineers' jobs while this ran; medians over repeats",
    }
    try:
        import onnxruntime

        info["onnxruntime"] = onnxruntime.__version__
    except ImportError:
        info["onnxruntime"] = None
    try:
        import mapie

        info["mapie"] = mapie.__version__
    except ImportError:
        info["mapie"] = None
    return info


def spread(values: Sequence[float]) -> dict[str, float]:
    """Median, min, max and count of repeated measurements."""
    v = [float(x) for x in values]
    return {"median": statistics.median(v), "min": min(v), "max": max(v), "n": len(v)}


def time_calls(fn: Callable[[], Any], repeats: int, warmup: int = 10) -> np.ndarray:
    """Wall time (s) of ``repeats`` calls of ``fn``, one at a time (after ``warmup`` calls)."""
    for _ in range(warmup):
        fn()
    out = np.empty(repeats)
    clock = time.perf_counter
    for i in range(repeats):
        t0 = clock()
        fn()
        out[i] = clock() - t0
    return out


def save_figure(fig: Any, path: Path) -> None:
    """Lay out a matplotlib figure, write it to ``path`` as a 110-dpi PNG (making its folder) and close it."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_json(path: Path, data: Any) -> None:
    """Write ``data`` as indented JSON (atomically, with ipcverify's one rule for inf and NaN)."""
    from ipcverify.data._files import write_json as write_json_file

    write_json_file(path, data, indent=2)
