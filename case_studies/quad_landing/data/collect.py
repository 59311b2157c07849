"""Data collection: fly exploration paths, record lagged measurements, write datasets.

:func:`collect` flies :mod:`.paths` one after another (each starts at its own reference,
flies ``warmup_time`` unrecorded, then records a measurement every ``sample_every``
camera frames; :func:`fly_path`) until ``n`` measurements *with a detection* are
recorded. Frames
without a detection are not rows of the dataset; they are counted in
:class:`CollectStats`, split into "marker (partly) outside the lagged image" and "in
view but not detected".

The returned DataFrame has the columns of :mod:`case_studies.quad_landing.data.columns`.
"""

from __future__ import annotations

import json
import multiprocessing
import time
from collections import deque
from collections.abc import Callable, Generator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from case_studies.quad_landing.data.columns import FLOAT_COLUMNS
from case_studies.quad_landing.data.recording import (
    FlightRecording,
    PathRecord,
    measure_recording,
    recording_of,
)
from case_studies.quad_landing.sim.camera import check_buffer_size
from case_studies.quad_landing.sim.config import SimConfig, load_config
from case_studies.quad_landing.sim.flight import Flight
from case_studies.quad_landing.sim.paths import TEMPLATES, ExplorationPath, fit_to_view, make_path
from ipcverify.data._files import atomic_write
from ipcverify.errors import InvalidInputError

__all__ = [
    "CollectStats",
    "PathRecord",
    "dataset_from_records",
    "collect",
    "fly_path",
    "record_path",
    "path_rng",
    "write_dataset",
    "start_state",
    "pad_outline_world",
]


@dataclass(frozen=True)
class CollectStats:
    """What a collection run did.

    Attributes
    ----------
    buffer_size, seed : int
        Settings used.
    samples : int
        Measurements with a detection (rows of the dataset).
    measurements : int
        All measurements taken (``samples + missed_out_of_view + missed_in_view``).
    missed_out_of_view : int
        No detection, and the marker was (partly) outside the lagged image.
    missed_in_view : int
        No detection although the whole marker was inside the lagged image.
    paths : int
        Exploration paths flown.
    flight_time : float
        Simulated time (s), warm-ups included.
    wall_time : float
        Real time taken (s).
    """

    buffer_size: int
    seed: int
    samples: int
    measurements: int
    missed_out_of_view: int
    missed_in_view: int
    paths: int
    flight_time: float
    wall_time: float

    @property
    def missed(self) -> int:
        """Measurements without a detection."""
        return self.missed_out_of_view + self.missed_in_view

    @property
    def detection_rate(self) -> float:
        """Fraction of measurements with a detection."""
        return self.samples / self.measurements if self.measurements else float("nan")

    def as_dict(self) -> dict[str, float | int]:
        """Plain data, including ``missed`` and ``detection_rate``."""
        d: dict[str, float | int] = dict(asdict(self))
        d["missed"] = self.missed
        d["detection_rate"] = self.detection_rate
        return d

    def summary(self) -> str:
        """One line for humans."""
        return (
            f"{self.samples} samples from {self.measurements} measurements "
            f"(detection rate {100 * self.detection_rate:.2f} %; missed {self.missed}: "
            f"{self.missed_out_of_view} out of view, {self.missed_in_view} in view) on "
            f"{self.paths} paths, {self.flight_time:.1f} s flown, buffer size "
            f"{self.buffer_size}, {self.wall_time:.1f} s wall time"
        )


def start_state(path: ExplorationPath) -> np.ndarray:
    """A level state on the path's reference at ``t = 0``, moving with it."""
    ref = path.reference(0.0)
    x = np.zeros(12)
    x[0:3] = ref.position
    x[3:6] = ref.velocity
    x[8] = ref.yaw
    return x


def pad_outline_world(config: SimConfig) -> np.ndarray:
    """Corners of the white pad square in W, shape (4, 3)."""
    return config.pad.world_from_marker().apply(config.marker.pad_outline())


def dataset_from_records(
    parts: Sequence[PathRecord], *, buffer_size: int, seed: int, started: float
) -> tuple[pd.DataFrame, CollectStats]:
    """The rows of ``parts`` as a dataset (:data:`.columns.DATASET_COLUMNS`) and its statistics.

    ``started`` is the :func:`time.perf_counter` reading when flying began (for the wall time).
    """
    outcomes = np.concatenate([r.outcomes for r in parts])
    data = pd.DataFrame(np.vstack([r.rows for r in parts]), columns=list(FLOAT_COLUMNS))
    data["path"] = np.concatenate([np.full(len(r.rows), r.index, np.int64) for r in parts])
    data["t"] = np.concatenate([r.times for r in parts])
    data["age"] = np.concatenate([r.ages for r in parts])
    stats = CollectStats(
        buffer_size=int(buffer_size),
        seed=int(seed),
        samples=len(data),
        measurements=len(outcomes),
        missed_out_of_view=int(np.sum(outcomes == 1)),
        missed_in_view=int(np.sum(outcomes == 2)),
        paths=len(parts),
        flight_time=float(sum(r.flight_time for r in parts)),
        wall_time=time.perf_counter() - started,
    )
    return data, stats


def path_rng(seed: int, index: int) -> np.random.Generator:
    """The generator of path ``index`` in a collection seeded with ``seed``.

    Depends on nothing else, so path ``i`` is the same for every buffer size, sample
    count and number of worker processes.
    """
    return np.random.default_rng([int(seed), int(index)])


def record_path(flight: Flight, index: int, seed: int) -> FlightRecording:
    """Fly exploration path ``index`` (warm-up included) and keep it with its sampling instants.

    The instants are every ``sample_every`` camera frames after ``warmup_time``
    (``[collect]`` of the flight's configuration). Nothing is measured: see
    :func:`.recording.measure_recording`.
    """
    cfg = flight.config
    params = cfg.collect
    rng = path_rng(seed, index)
    path = make_path(TEMPLATES[index % len(TEMPLATES)], rng, flight.pad.position, cfg.paths)
    path = fit_to_view(path, flight.camera, pad_outline_world(cfg), cfg.paths.view_margin_px,
                       cfg.quad.gravity)  # fmt: skip
    flight.reset(start_state(path), seed=int(rng.integers(2**31)))
    fps = cfg.camera.fps
    warmup = int(round(params.warmup_time * fps))
    times = [
        flight.time
        for frame in flight.follow(path, warmup / fps + path.duration)
        if frame > warmup and (frame - warmup) % params.sample_every == 0
    ]
    return recording_of(flight, index=index, sample_times=times)


def fly_path(flight: Flight, index: int, seed: int, limit: int | None = None) -> PathRecord:
    """Fly exploration path ``index`` and record a measurement every ``sample_every`` frames.

    Parameters
    ----------
    flight : Flight
        The simulator (its config and camera are used).
    index : int
        Path index: the template is ``TEMPLATES[index % 5]``; parameters and sensor noise
        come from :func:`path_rng`.
    seed : int
        Collection seed.
    limit : int, optional
        Stop after this many detections.
    """
    return measure_recording(record_path(flight, index, seed), flight.camera_stage, limit=limit)


_WORKER_FLIGHT: Flight | None = None


def _worker_init(config: SimConfig, buffer_size: int) -> None:
    global _WORKER_FLIGHT
    import cv2

    cv2.setNumThreads(1)  # one process per core already
    _WORKER_FLIGHT = Flight(config, buffer_size=buffer_size)


def _worker_fly(index: int, seed: int) -> PathRecord:
    assert _WORKER_FLIGHT is not None
    return fly_path(_WORKER_FLIGHT, index, seed)


def _records(cfg: SimConfig, buffer_size: int, seed: int, jobs: int) -> Generator[PathRecord, None, None]:
    """Path records in index order, flown here (jobs = 1) or by worker processes."""
    if jobs == 1:
        flight = Flight(cfg, buffer_size=buffer_size)
        index = 0
        while True:
            yield fly_path(flight, index, seed)
            index += 1
    ctx = multiprocessing.get_context("spawn")  # OpenCV's threads do not survive fork
    with ProcessPoolExecutor(jobs, mp_context=ctx, initializer=_worker_init,
                             initargs=(cfg, buffer_size)) as pool:  # fmt: skip
        index = 0
        pending: deque[Future[PathRecord]] = deque()
        while True:
            while len(pending) < 2 * jobs:
                pending.append(pool.submit(_worker_fly, index, seed))
                index += 1
            yield pending.popleft().result()


def collect(
    n: int | None = None,
    *,
    buffer_size: int | None = None,
    seed: int = 0,
    config: SimConfig | None = None,
    jobs: int = 1,
    progress: Callable[[int], None] | None = None,
) -> tuple[pd.DataFrame, CollectStats]:
    """Collect ``n`` lagged measurements with a detection along exploration paths.

    Path ``i`` is always the same path with the same sensor noise for a given ``seed``
    (:func:`path_rng`), whatever ``n``, ``buffer_size`` or ``jobs``: datasets for
    different buffer sizes are flown on the same paths, and ``jobs`` only changes the
    wall time, never the data.

    Parameters
    ----------
    n : int, optional
        Samples to collect (``config.collect.n`` if None).
    buffer_size : int, optional
        Camera buffer size ``k`` (``config.collect.buffer_size`` if None). Resolved once
        here and handed to the simulator; the config is not rewritten with it.
    seed : int
        Seeds the path parameters and the sensor noise.
    config : SimConfig, optional
        Defaults from ``defaults.toml`` if None.
    jobs : int
        Worker processes flying paths in parallel (1 = in this process).
    progress : callable, optional
        Called with the number of new samples as they are added.

    Returns
    -------
    data : pandas.DataFrame
        ``n`` rows, columns :data:`.columns.DATASET_COLUMNS`.
    stats : CollectStats
        Detection counts and timing.

    Examples
    --------
    >>> data, stats = collect(20, buffer_size=1, seed=0)
    >>> len(data), stats.samples, stats.measurements >= 20
    (20, 20, True)
    """
    cfg = load_config() if config is None else config
    if n is not None:
        cfg = cfg.replace(collect={"n": n})
    k = check_buffer_size(cfg.collect.buffer_size if buffer_size is None else buffer_size)
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise InvalidInputError(f"seed must be a non-negative integer, got {seed!r}")
    if isinstance(jobs, bool) or int(jobs) != jobs or jobs < 1:
        raise InvalidInputError(f"jobs must be a positive integer, got {jobs!r}")
    n_target = cfg.collect.n
    t0 = time.perf_counter()
    parts: list[PathRecord] = []
    n_done = 0
    records = _records(cfg, k, int(seed), int(jobs))
    try:
        for rec in records:
            take = min(len(rec.rows), n_target - n_done)
            parts.append(rec.head(take))  # measurements up to the last sample used
            n_done += take
            if progress is not None and take:
                progress(take)
            if n_done >= n_target:
                break
    finally:
        records.close()
    return dataset_from_records(parts, buffer_size=k, seed=int(seed), started=t0)


def write_dataset(data: pd.DataFrame, out: str | Path, stats: CollectStats | None = None) -> Path:
    """Write ``data`` atomically to ``.parquet`` or ``.csv`` (by extension).

    The file is written to a temporary file in the same directory and moved into place
    with :func:`os.replace` (:func:`ipcverify.data.atomic_write`), so readers never see a
    partial file and a failed write leaves an old file intact. With ``stats``, a
    ``<stem>.stats.json`` sidecar is written the same way.

    Raises
    ------
    InvalidInputError
        If the extension is neither ``.parquet`` nor ``.csv`` or the directory is missing.
    """
    path = Path(out)
    suffix = path.suffix.lower()
    if suffix not in (".parquet", ".csv"):
        raise InvalidInputError(f"output file must end in .parquet or .csv, got {path.name!r}")
    if not path.parent.exists():
        raise InvalidInputError(f"output directory {path.parent} does not exist; create it first")

    if suffix == ".parquet":
        atomic_write(path, lambda fh: data.to_parquet(fh, index=False))
    else:
        atomic_write(path, lambda fh: data.to_csv(fh, index=False, float_format="%.17g"), "w")
    if stats is not None:
        text = json.dumps(stats.as_dict(), indent=2) + "\n"
        atomic_write(path.with_name(path.stem + ".stats.json"), lambda fh: fh.write(text), "w")
    return path
