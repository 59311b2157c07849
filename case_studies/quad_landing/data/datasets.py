"""The reproduction's datasets: exploration paths plus approach flights, cached on disk.

Every dataset of the reproduction (training, calibration and test, at one buffer size)
is a mix: ``1 - fraction`` of its samples come from the exploration paths of
:func:`.collect.collect`, ``fraction`` from the approach flights of
:func:`.approach.collect_approach`; an extra column ``source`` says which (0 paths,
1 approach). Both parts depend only on ``(seed, index)`` of each path or flight, so the
test sets of different buffer sizes are flown on the same paths and flights.

No dataset holds a measurement taken with the pad's edges within ``aligned_margin_deg``
of the image axes, where OpenCV's AprilTag corner refinement reads the range up to about
2 % short (``docs/case_study.md``): the approach flights never fly such headings, and the
exploration paths' rows there (about 3 % of them, the headings spin) are dropped
(:func:`alignment_deg`). The landing runs never measure there either, so calibration and
deployment agree on this.

Both parts take a measurement every ``sample_every`` camera frames (default 6, i.e. 10 Hz,
sparser than :func:`.collect.collect`'s 30 Hz): perception errors come in bursts of 0.1–0.25 s
(rotation transients), and sparser samples spread a dataset over more paths and flights,
so its samples are closer to the independent draws the calibration and the
Clopper–Pearson bounds assume.

:func:`cached_mixed` writes ``NAME.parquet`` with a ``NAME.key.json`` sidecar recording
every setting that went into it, and reuses the file when the settings match.

Examples
--------
>>> from case_studies.quad_landing.data.approach import ApproachParams
>>> data = collect_mixed(40, buffer_size=1, seed=0, approach=ApproachParams.defaults(hover_points=1))
>>> len(data), sorted(set(data["source"]))
(40, [0, 1])
>>> as_dataset(data).x_dim
12
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from case_studies.quad_landing.data.approach import ApproachParams, collect_approach
from case_studies.quad_landing.data.collect import collect
from case_studies.quad_landing.data.columns import X_COLUMNS, Y_COLUMNS, YHAT_COLUMNS
from case_studies.quad_landing.sim.config import SimConfig, load_config
from ipcverify.data import PerceptionDataset
from ipcverify.files import atomic_write

__all__ = [
    "collect_mixed",
    "as_dataset",
    "cached_mixed",
    "is_cached",
    "alignment_deg",
    "SOURCE_PATHS",
    "SOURCE_APPROACH",
]

#: Values of the ``source`` column.
SOURCE_PATHS, SOURCE_APPROACH = 0, 1
_KEY_VERSION = 3


def alignment_deg(yaw: ArrayLike, pad_yaw: float) -> NDArray[np.float64]:
    """Angle (degrees, 0..45) between the pad's edges and the image axes for a level camera.

    The downward camera's image axes turn with the vehicle's heading, so this is the
    distance of ``yaw - pad_yaw`` from the nearest multiple of 90 degrees.

    Examples
    --------
    >>> alignment_deg([0.3, 0.3 + np.pi / 2 + 0.01, 1.0], 0.3).round(2).tolist()
    [0.0, 0.57, 40.11]
    """
    d = np.asarray(yaw, dtype=np.float64) - pad_yaw
    return np.rad2deg(np.abs((d + np.pi / 4) % (np.pi / 2) - np.pi / 4))


def _paths_off_axes(
    n: int,
    *,
    buffer_size: int,
    seed: int,
    margin: float,
    config: SimConfig,
    progress: Callable[[int], None] | None,
) -> pd.DataFrame:
    """The first ``n`` exploration rows whose alignment is at least ``margin`` degrees."""
    m = n if margin <= 0 else int(np.ceil(n / (1.0 - 4 * 2 * margin / 360.0) * 1.02)) + 20
    reported = [0]

    def tick(k: int) -> None:  # raw rows, capped at n (the bar is a guide, not a count)
        step = min(k, n - reported[0])
        if progress is not None and step > 0:
            progress(step)
            reported[0] += step

    while True:
        rows, _ = collect(m, buffer_size=buffer_size, seed=seed, config=config, progress=tick)
        keep = rows[alignment_deg(rows["xw_8"].to_numpy(), config.pad.yaw) >= margin]
        if len(keep) >= n:
            return keep.iloc[:n].reset_index(drop=True)
        m = int(m * 1.2) + 50


def collect_mixed(
    n: int,
    *,
    buffer_size: int,
    seed: int,
    approach: ApproachParams,
    config: SimConfig | None = None,
    progress: Callable[[int], None] | None = None,
) -> pd.DataFrame:
    """``n`` samples: ``round(fraction n)`` from approach flights, the rest from exploration paths.

    Parameters
    ----------
    n : int
        Samples with a detection.
    buffer_size : int
        Camera buffer size ``k``.
    seed : int
        Seeds both parts.
    approach : ApproachParams
        The approach flights and the mixing fraction.
    config : SimConfig, optional
        The simulator (defaults if None).
    progress : callable, optional
        Called with the number of new samples as they are added.

    Returns
    -------
    pandas.DataFrame
        :data:`.columns.DATASET_COLUMNS` plus ``source``.
    """
    cfg = load_config() if config is None else config
    cfg = cfg.replace(collect={"sample_every": approach.sample_every})
    n_app = int(round(approach.fraction * n))
    parts = []
    if n - n_app:
        paths = _paths_off_axes(
            n - n_app,
            buffer_size=buffer_size,
            seed=seed,
            margin=approach.aligned_margin_deg,
            config=cfg,
            progress=progress,
        )
        paths["source"] = SOURCE_PATHS
        parts.append(paths)
    if n_app:
        flights, _ = collect_approach(
            n_app, buffer_size=buffer_size, seed=seed, params=approach, config=cfg, progress=progress
        )
        flights["source"] = SOURCE_APPROACH
        parts.append(flights)
    return pd.concat(parts, ignore_index=True)


def as_dataset(data: pd.DataFrame, source: str = "<memory>") -> PerceptionDataset:
    """The ``x_C``, ``y_C``, ``yhat_C`` columns as a :class:`~ipcverify.data.PerceptionDataset`.

    The other columns (world frame, path, time, source) are kept as extra columns.
    """
    used = set(X_COLUMNS) | set(Y_COLUMNS) | set(YHAT_COLUMNS)
    return PerceptionDataset(
        data[list(X_COLUMNS)].to_numpy(float),
        data[list(Y_COLUMNS)].to_numpy(float),
        data[list(YHAT_COLUMNS)].to_numpy(float),
        source=source,
        x_columns=X_COLUMNS,
        y_columns=Y_COLUMNS,
        yhat_columns=YHAT_COLUMNS,
        extra={c: data[c].to_numpy() for c in data.columns if c not in used},
    )


def _key(n: int, buffer_size: int, seed: int, approach: ApproachParams, config: SimConfig) -> dict[str, Any]:
    sim = config.as_dict()
    del sim["collect"]["buffer_size"]  # the collect command's default; the dataset's is buffer_size
    return {
        "version": _KEY_VERSION,
        "n": int(n),
        "buffer_size": int(buffer_size),
        "seed": int(seed),
        "approach": approach.to_table(),
        "sim": sim,
    }


def _normalise(obj: Any) -> Any:
    return json.loads(json.dumps(obj, default=list))


def is_cached(
    path: str | Path, n: int, *, buffer_size: int, seed: int, approach: ApproachParams, config: SimConfig
) -> bool:
    """Whether ``path`` holds the dataset these settings would collect (see :func:`cached_mixed`)."""
    p = Path(path)
    key_path = p.with_suffix(".key.json")
    if not (p.exists() and key_path.exists()):
        return False
    try:
        return bool(
            json.loads(key_path.read_text()) == _normalise(_key(n, buffer_size, seed, approach, config))
        )
    except (json.JSONDecodeError, OSError):
        return False


def cached_mixed(
    path: str | Path,
    n: int,
    *,
    buffer_size: int,
    seed: int,
    approach: ApproachParams,
    config: SimConfig,
    progress: Callable[[int], None] | None = None,
) -> tuple[pd.DataFrame, bool]:
    """Load ``path`` (a ``.parquet``) if it was made with these settings, else collect and write it.

    Returns
    -------
    data : pandas.DataFrame
    cached : bool
        True if the file was reused.
    """
    p = Path(path)
    if is_cached(p, n, buffer_size=buffer_size, seed=seed, approach=approach, config=config):
        return pd.read_parquet(p), True
    data = collect_mixed(
        n, buffer_size=buffer_size, seed=seed, approach=approach, config=config, progress=progress
    )
    atomic_write(p, lambda fh: data.to_parquet(fh, index=False))
    text = json.dumps(_normalise(_key(n, buffer_size, seed, approach, config)), indent=1) + "\n"
    atomic_write(p.with_suffix(".key.json"), lambda fh: fh.write(text), "w")
    return data, False
