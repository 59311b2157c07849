"""What the camera-timing model did in a reproduction, and how Table I was tested, as records.

* :func:`camera_timing_summary` — ``summary.json``'s ``camera_timing``: the ``[camera_timing]``
  parameters used, the mean reader iteration they give on the Pi, and per buffer size the
  age of the test images (how much older the image is than the state it is paired with)
  and the perception error, from Table I's pilot test sets;
* :func:`table1_protocol` — ``summary.json``'s ``table1_protocol``: the test flights (the pilot
  model), their speeds against the training data's.

Examples
--------
>>> import pandas as pd
>>> df = pd.DataFrame({"age": [0.01, 0.02, 0.03], "yhat_0": [0, 0, 0], "yhat_1": [0, 0, 0],
...                    "yhat_2": [1.0, 1.0, 1.0], "y_0": [0, 0, 0], "y_1": [0, 0, 0],
...                    "y_2": [1.01, 1.02, 1.03]})
>>> s = image_stats(df)
>>> round(s.age_ms.median, 6), round(s.error_mm.median, 6)
(20.0, 20.0)
>>> list(s.to_dict())
['n', 'age_ms', 'error_mm']
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from case_studies.quad_landing.reproduction.config import ReproduceConfig
from case_studies.quad_landing.reproduction.record import Record
from case_studies.quad_landing.sim.config import SimConfig

__all__ = [
    "Quantiles",
    "ImageStats",
    "CameraTimingSummary",
    "Table1Protocol",
    "image_stats",
    "camera_timing_summary",
    "table1_protocol",
]


@dataclass(frozen=True)
class Quantiles(Record):
    """5 %, 50 % and 95 % quantiles and the mean of a sample."""

    p05: float
    median: float
    p95: float
    mean: float


@dataclass(frozen=True)
class ImageStats(Record):
    """Age (ms) and ``|yhat_C - y_C|`` (mm) of a dataset's ``n`` images."""

    n: int
    age_ms: Quantiles
    error_mm: Quantiles


@dataclass(frozen=True)
class CameraTimingSummary(Record):
    """``summary.json``'s ``camera_timing`` (see the module docstring); ``parameters`` is the TOML table."""

    parameters: Mapping[str, Any]
    reader_mean_ms: float
    camera_period_ms: float
    per_buffer: Mapping[str, ImageStats]
    training: ImageStats


@dataclass(frozen=True)
class Table1Protocol(Record):
    """``summary.json``'s ``table1_protocol``: how Table I was tested, and the flights' speeds (m/s).

    ``pilot`` is ``[pilot]`` as its TOML table; ``speed_m_s`` the median, 90th percentile and
    maximum speed of the pilot test flights and of the training flights.
    """

    training: str
    test: str
    pilot: Mapping[str, Any]
    speed_m_s: Mapping[str, Mapping[str, float]]


def _quantiles(values: np.ndarray) -> Quantiles:
    q = np.percentile(values, [5, 50, 95])
    return Quantiles(float(q[0]), float(q[1]), float(q[2]), float(values.mean()))


def image_stats(frame: pd.DataFrame) -> ImageStats:
    """Age (ms) and ``|yhat_C - y_C|`` (mm) of a dataset's images: 5 %, 50 %, 95 % and mean."""
    err = frame[["yhat_0", "yhat_1", "yhat_2"]].to_numpy() - frame[["y_0", "y_1", "y_2"]].to_numpy()
    return ImageStats(
        n=len(frame),
        age_ms=_quantiles(1e3 * frame["age"].to_numpy(float)),
        error_mm=_quantiles(1e3 * np.linalg.norm(err, axis=1)),
    )


def _speed(frame: pd.DataFrame) -> dict[str, float]:
    v = np.linalg.norm(frame[["xw_3", "xw_4", "xw_5"]].to_numpy(float), axis=1)
    return {"median": float(np.median(v)), "p90": float(np.percentile(v, 90)), "max": float(v.max())}


def camera_timing_summary(
    sim: SimConfig, frames: Mapping[str, pd.DataFrame], buffers: Sequence[int]
) -> CameraTimingSummary:
    """``summary.json``'s ``camera_timing`` (see the module docstring)."""
    timing = sim.camera_timing
    return CameraTimingSummary(
        parameters=timing.to_table(),
        reader_mean_ms=timing.reader_time_ms(),
        camera_period_ms=1e3 / sim.camera.fps,
        per_buffer={str(b): image_stats(frames[f"pilot_k{b}"]) for b in buffers},
        training=image_stats(frames["train_k1"]),
    )


def table1_protocol(cfg: ReproduceConfig, frames: Mapping[str, pd.DataFrame]) -> Table1Protocol:
    """``summary.json``'s ``table1_protocol``: how Table I was tested, the flights' speeds."""
    return Table1Protocol(
        training=(
            f"IPC (recipe {cfg.ipc.recipe}, hidden layers {', '.join(map(str, cfg.ipc.hidden))}) trained on "
            f"{cfg.sizes.n_train} and PAC-calibrated (epsilon = {cfg.ipc.epsilon:g}) on "
            f"{cfg.sizes.n_calibration} samples at buffer size 1 (exploration paths and approach flights)"
        ),
        test=(
            f"{cfg.sizes.n_pilot} measurements per buffer size from pilot test flights (smooth hand-flown "
            "motion around the pad), the same flights for every buffer size"
        ),
        pilot=cfg.pilot.to_table(),
        speed_m_s={"pilot": _speed(frames["pilot_k1"]), "training": _speed(frames["train_k1"])},
    )
