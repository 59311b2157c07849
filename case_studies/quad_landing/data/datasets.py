"""The reproduction's datasets: exploration paths, approach flights and pilot test flights, cached.

Every training, calibration and held-out test set of the reproduction is a mix:
``1 - fraction`` of its samples come from the exploration paths of :func:`.collect.collect`,
``fraction`` from the approach flights of :func:`.approach.collect_approach`. Table I is
tested on pilot flights like the paper's manual ones (:mod:`.pilot`). An extra column
``source`` says which (0 paths, 1 approach, 2 pilot). Every path and flight depends only
on its ``(seed, index)``, so the datasets of different buffer sizes, and of different
camera variants (the ablation), are flown on the same paths and flights. Those flights
do not depend on the camera, so each is flown once and measured with every camera that
needs it (:mod:`.recording`, :func:`collect_mixed_many`, :func:`collect_pilot_many`).

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

:func:`cached_many` (and :func:`cached_mixed` for one dataset) writes ``NAME.parquet`` with a
``NAME.key.json`` sidecar recording every setting that went into it, and reuses the file
when the settings match.

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
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from case_studies.quad_landing.data.approach import ApproachParams, record_approach
from case_studies.quad_landing.data.collect import dataset_from_records, record_path
from case_studies.quad_landing.data.columns import X_COLUMNS, Y_COLUMNS, YHAT_COLUMNS
from case_studies.quad_landing.data.pilot import PilotParams, record_pilot
from case_studies.quad_landing.data.recording import FlightRecording, PathRecord, measure_recording
from case_studies.quad_landing.settings import TomlSection
from case_studies.quad_landing.sim.camera import (
    BufferSize,
    Measurement,
    build_camera_stage,
    check_buffer_size,
)
from case_studies.quad_landing.sim.config import SimConfig, load_config
from case_studies.quad_landing.sim.flight import Flight
from ipcverify.data import PerceptionDataset
from ipcverify.data._files import atomic_write
from ipcverify.errors import InvalidInputError

__all__ = [
    "DatasetSpec",
    "CAMERA_SECTIONS",
    "collect_mixed",
    "collect_mixed_many",
    "collect_pilot_many",
    "as_dataset",
    "FLIGHT_STRIDE",
    "cached_many",
    "cached_mixed",
    "is_cached",
    "alignment_deg",
    "SOURCE_PATHS",
    "SOURCE_APPROACH",
    "SOURCE_PILOT",
]

#: ``flight = source * FLIGHT_STRIDE + path`` (:func:`as_dataset`): a label per flight across sources.
FLIGHT_STRIDE = 1_000_000

#: Values of the ``source`` column.
SOURCE_PATHS, SOURCE_APPROACH, SOURCE_PILOT = 0, 1, 2
_KEY_VERSION = 4  # 4: the camera-timing model, flights recorded once and measured per camera


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


@dataclass(frozen=True)
class DatasetSpec:
    """One dataset to collect: the camera it is measured with and its size.

    ``config`` is the camera variant's full simulator configuration: it may differ from
    the configuration the flights are flown with only in ``[camera_timing]``, ``[render]``
    and ``[detector]`` (what the camera and the detector do), never in what the vehicle
    flies. ``path`` is the dataset's cache file (``.parquet``), if any.
    """

    name: str
    config: SimConfig
    buffer_size: BufferSize
    n: int
    path: Path | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "buffer_size", check_buffer_size(self.buffer_size))


#: The sections a camera variant may change; the others decide the flights themselves.
CAMERA_SECTIONS = ("camera_timing", "render", "detector")


def _flying_part(config: SimConfig) -> dict[str, Any]:
    tree = config.as_dict()
    for name in (*CAMERA_SECTIONS, "collect"):
        del tree[name]
    return _normalise(tree)


def _check_variants(specs: Sequence[DatasetSpec], config: SimConfig) -> None:
    base = _flying_part(config)
    for spec in specs:
        if _flying_part(spec.config) != base:
            raise InvalidInputError(
                f"dataset {spec.name!r}: its configuration changes the flights themselves; a camera "
                f"variant may change only {', '.join(CAMERA_SECTIONS)}"
            )


def _aligned_off(margin: float, pad_yaw: float) -> Callable[[Measurement], bool]:
    return lambda m: bool(alignment_deg(m.state[8], pad_yaw) >= margin)


def _measure_flights(
    specs: Sequence[DatasetSpec],
    need: dict[str, int],
    record: Callable[[int], FlightRecording],
    keep: Callable[[Measurement], bool] | None,
    progress: Callable[[int], None] | None,
) -> dict[str, list[PathRecord]]:
    """Record flights ``0, 1, ...`` once each and measure them with every spec still short of rows."""
    stages = {s.name: build_camera_stage(s.config, s.buffer_size) for s in specs}
    parts: dict[str, list[PathRecord]] = {s.name: [] for s in specs}
    index = 0
    while any(v > 0 for v in need.values()):
        rec = record(index)
        for name, stage in stages.items():
            if need[name] <= 0:
                continue
            part = measure_recording(rec, stage, keep=keep, limit=need[name])
            take = min(len(part.rows), need[name])
            parts[name].append(part.head(take))
            need[name] -= take
            if progress is not None and take:
                progress(take)
        index += 1
        if index > 50 + 10 * max(s.n for s in specs):
            raise InvalidInputError("the flights produce no detections; check the camera and pad settings")
    return parts


def _frame(parts: Sequence[PathRecord], source: int, buffer_size: int, seed: int) -> pd.DataFrame:
    data, _ = dataset_from_records(parts, buffer_size=buffer_size, seed=seed, started=0.0)
    data["source"] = source
    return data


def collect_mixed_many(
    specs: Sequence[DatasetSpec],
    *,
    seed: int,
    approach: ApproachParams,
    config: SimConfig,
    progress: Callable[[int], None] | None = None,
) -> dict[str, pd.DataFrame]:
    """Mixed datasets for several cameras from the same flights, each flown once.

    Each dataset has ``round(fraction n)`` samples from approach flights and the rest from
    exploration paths (without rows at pad headings within ``aligned_margin_deg`` of the
    image axes), exactly as :func:`collect_mixed` would give it alone.

    Parameters
    ----------
    specs : sequence of DatasetSpec
        The datasets (names distinct).
    seed : int
        Seeds the paths, the approach flights and their sensors.
    approach : ApproachParams
        The approach flights and the mixing fraction.
    config : SimConfig
        The configuration the flights are flown with.
    progress : callable, optional
        Called with the number of new samples as they are added.

    Returns
    -------
    dict of str to pandas.DataFrame
        By spec name: :data:`.columns.DATASET_COLUMNS` plus ``source``.
    """
    _check_variants(specs, config)
    cfg = config.replace(collect={"sample_every": approach.sample_every})
    flight = Flight(cfg, buffer_size=0)
    n_app = {s.name: int(round(approach.fraction * s.n)) for s in specs}
    keep = _aligned_off(approach.aligned_margin_deg, cfg.pad.yaw) if approach.aligned_margin_deg > 0 else None
    paths = _measure_flights(
        specs,
        {s.name: s.n - n_app[s.name] for s in specs},
        lambda i: record_path(flight, i, seed),
        keep,
        progress,
    )
    flights = _measure_flights(
        specs,
        dict(n_app),
        lambda i: record_approach(flight, i, seed=seed, params=approach),
        None,
        progress,
    )
    out = {}
    for s in specs:
        parts = [_frame(paths[s.name], SOURCE_PATHS, s.buffer_size, seed)] if paths[s.name] else []
        if flights[s.name]:
            parts.append(_frame(flights[s.name], SOURCE_APPROACH, s.buffer_size, seed))
        out[s.name] = pd.concat(parts, ignore_index=True)
    return out


def collect_pilot_many(
    specs: Sequence[DatasetSpec],
    *,
    seed: int,
    pilot: PilotParams,
    margin: float,
    config: SimConfig,
    progress: Callable[[int], None] | None = None,
) -> dict[str, pd.DataFrame]:
    """Table I test sets: pilot flights (:mod:`.pilot`) measured with several cameras.

    Rows at pad headings within ``margin`` degrees of the image axes are left out, as in
    the training data. ``source`` is :data:`SOURCE_PILOT`; ``path`` the flight index.
    """
    _check_variants(specs, config)
    flight = Flight(config, buffer_size=0)
    keep = _aligned_off(margin, config.pad.yaw) if margin > 0 else None
    parts = _measure_flights(
        specs,
        {s.name: s.n for s in specs},
        lambda i: record_pilot(flight, i, seed=seed, params=pilot),
        keep,
        progress,
    )
    return {s.name: _frame(parts[s.name], SOURCE_PILOT, s.buffer_size, seed) for s in specs}


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
        Camera buffer size.
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
    spec = DatasetSpec("data", cfg, buffer_size, int(n))
    return collect_mixed_many([spec], seed=seed, approach=approach, config=cfg, progress=progress)["data"]


def as_dataset(data: pd.DataFrame, source: str = "<memory>") -> PerceptionDataset:
    """The ``x_C``, ``y_C``, ``yhat_C`` columns as a :class:`~ipcverify.data.PerceptionDataset`.

    The other columns (world frame, path, time, source) are kept as extra columns. With
    ``source`` and ``path`` it adds ``flight``, one label per flight or path across sources
    (``path`` numbers each source's flights from 0): the exchangeable unit for flight-level
    calibration and tests (``group_column="flight"``).

    Examples
    --------
    >>> from case_studies.quad_landing.data.approach import ApproachParams
    >>> frame = collect_mixed(6, buffer_size=1, seed=0, approach=ApproachParams.defaults(hover_points=1))
    >>> flights = as_dataset(frame).extra["flight"]
    >>> bool((flights == frame["source"] * FLIGHT_STRIDE + frame["path"]).all())
    True
    """
    used = set(X_COLUMNS) | set(Y_COLUMNS) | set(YHAT_COLUMNS)
    extra = {c: data[c].to_numpy() for c in data.columns if c not in used}
    if "source" in extra and "path" in extra and "flight" not in extra:
        extra["flight"] = extra["source"].astype(np.int64) * FLIGHT_STRIDE + extra["path"].astype(np.int64)
    return PerceptionDataset(
        data[list(X_COLUMNS)].to_numpy(float),
        data[list(Y_COLUMNS)].to_numpy(float),
        data[list(YHAT_COLUMNS)].to_numpy(float),
        source=source,
        x_columns=X_COLUMNS,
        y_columns=Y_COLUMNS,
        yhat_columns=YHAT_COLUMNS,
        extra=extra,
    )


def _key(spec: DatasetSpec, seed: int, params: TomlSection) -> dict[str, Any]:
    sim = spec.config.as_dict()
    del sim["collect"]["buffer_size"]  # the collect command's default; the dataset's is buffer_size
    return {
        "version": _KEY_VERSION,
        "n": int(spec.n),
        "buffer_size": int(spec.buffer_size),
        "seed": int(seed),
        params.toml_section: params.to_table(),
        "sim": sim,
    }


def _normalise(obj: Any) -> Any:
    return json.loads(json.dumps(obj, default=list))


def _is_cached(spec: DatasetSpec, seed: int, params: TomlSection) -> bool:
    if spec.path is None:
        return False
    p = Path(spec.path)
    key_path = p.with_suffix(".key.json")
    if not (p.exists() and key_path.exists()):
        return False
    try:
        return bool(json.loads(key_path.read_text()) == _normalise(_key(spec, seed, params)))
    except (json.JSONDecodeError, OSError):
        return False


def cached_many(
    specs: Sequence[DatasetSpec],
    *,
    seed: int,
    params: ApproachParams | PilotParams,
    config: SimConfig,
    margin: float = 0.0,
    progress: Callable[[int], None] | None = None,
) -> dict[str, tuple[pd.DataFrame, bool]]:
    """Load the specs whose cache file (``spec.path``) holds them; collect the others together.

    ``params`` says the kind: :class:`.approach.ApproachParams` for mixed datasets
    (:func:`collect_mixed_many`), :class:`.pilot.PilotParams` for pilot test sets
    (:func:`collect_pilot_many`, leaving out headings within ``margin`` degrees of the image
    axes). Every collected dataset is written to its ``spec.path`` with a ``.key.json``
    sidecar recording every setting that went into it.

    Returns
    -------
    dict of str to (pandas.DataFrame, bool)
        By spec name: the data and whether they came from the cache.
    """
    out: dict[str, tuple[pd.DataFrame, bool]] = {}
    todo = []
    for spec in specs:
        if _is_cached(spec, seed, params):
            out[spec.name] = (pd.read_parquet(Path(spec.path)), True)  # type: ignore[arg-type]
        else:
            todo.append(spec)
    if not todo:
        return out
    if isinstance(params, PilotParams):
        fresh = collect_pilot_many(
            todo, seed=seed, pilot=params, margin=margin, config=config, progress=progress
        )
    else:
        fresh = collect_mixed_many(todo, seed=seed, approach=params, config=config, progress=progress)
    for spec in todo:
        data = fresh[spec.name]
        if spec.path is not None:
            _write_cached(
                Path(spec.path), data, json.dumps(_normalise(_key(spec, seed, params)), indent=1) + "\n"
            )
        out[spec.name] = (data, False)
    return out


def _write_cached(path: Path, data: pd.DataFrame, key: str) -> None:
    """``path`` (parquet) and its ``.key.json`` sidecar, each written atomically."""
    atomic_write(path, lambda fh: data.to_parquet(fh, index=False))
    atomic_write(path.with_suffix(".key.json"), lambda fh: fh.write(key), "w")


def is_cached(
    path: str | Path, n: int, *, buffer_size: int, seed: int, approach: ApproachParams, config: SimConfig
) -> bool:
    """Whether ``path`` holds the mixed dataset these settings would collect (see :func:`cached_mixed`)."""
    return _is_cached(DatasetSpec("data", config, int(buffer_size), int(n), Path(path)), seed, approach)


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
    spec = DatasetSpec("data", config, buffer_size, int(n), Path(path))
    return cached_many([spec], seed=seed, params=approach, config=config, progress=progress)["data"]
