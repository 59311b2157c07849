"""Shared helpers of the benchmark suite: machine description, timing statistics, JSON output."""

from __future__ import annotations

import json
import os
import platform
import statistics
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

__all__ = ["machine_info", "spread", "time_calls", "write_json"]


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


def write_json(path: Path, data: Any) -> None:
    """Write ``data`` as indented JSON (atomically)."""
    from ipcverify.data import atomic_write

    text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    atomic_write(path, lambda f: f.write(text.encode()))
