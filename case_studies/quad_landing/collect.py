"""Data collection: fly exploration paths, record lagged measurements, write datasets.

:func:`collect` flies :mod:`.paths` one after another (each starts at its own reference,
flies ``warmup_time`` unrecorded, then records a measurement every ``sample_every``
camera frames) until ``n`` measurements *with a detection* are recorded. Frames
without a detection are not rows of the dataset; they are counted in
:class:`CollectStats`, split into "marker (partly) outside the lagged image" and "in
view but not detected".

Columns of the returned DataFrame (float64 unless noted):

* ``x_0 .. x_11`` — state in the camera frame ``x_C`` (:data:`.features.X_DESCRIPTIONS`);
* ``y_0 .. y_2`` — true pad centre in the camera frame ``y_C`` (m);
* ``yhat_0 .. yhat_2`` — perceived pad centre ``yhat_C`` from the lagged image (m);
* ``xw_0 .. xw_11`` — world-frame state ``[p, v, roll, pitch, yaw, omega]``;
* ``yw_0 .. yw_2``, ``yhatw_0 .. yhatw_2`` — true and perceived pad centre in W, the
  perceived one moved with the *current* camera pose, as on the vehicle;
* ``path`` (int), ``t`` — path index and time on the path (s).
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from case_studies.quad_landing.config import SimConfig, load_config
from case_studies.quad_landing.dynamics import STATE_NAMES
from case_studies.quad_landing.features import X_COLUMNS
from case_studies.quad_landing.paths import TEMPLATES, ExplorationPath, fit_to_view, make_path
from case_studies.quad_landing.sim import Flight
from ipcverify.errors import InvalidInputError

__all__ = [
    "CollectStats",
    "collect",
    "write_dataset",
    "start_state",
    "Y_COLUMNS",
    "YHAT_COLUMNS",
    "XW_COLUMNS",
    "DATASET_COLUMNS",
]

#: True pad centre in C.
Y_COLUMNS: tuple[str, ...] = ("y_0", "y_1", "y_2")
#: Perceived pad centre in C.
YHAT_COLUMNS: tuple[str, ...] = ("yhat_0", "yhat_1", "yhat_2")
#: World-frame state, in :data:`.dynamics.STATE_NAMES` order.
XW_COLUMNS: tuple[str, ...] = tuple(f"xw_{i}" for i in range(12))
YW_COLUMNS: tuple[str, ...] = ("yw_0", "yw_1", "yw_2")
YHATW_COLUMNS: tuple[str, ...] = ("yhatw_0", "yhatw_1", "yhatw_2")
#: All dataset columns, in order.
DATASET_COLUMNS: tuple[str, ...] = (
    X_COLUMNS + Y_COLUMNS + YHAT_COLUMNS + XW_COLUMNS + YW_COLUMNS + YHATW_COLUMNS + ("path", "t")
)
_N_FLOAT = len(DATASET_COLUMNS) - 2
assert len(STATE_NAMES) == 12


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


def _pad_outline_w(config: SimConfig) -> np.ndarray:
    return config.pad.world_from_marker().apply(config.marker.pad_outline())


def collect(
    n: int | None = None,
    *,
    buffer_size: int | None = None,
    seed: int = 0,
    config: SimConfig | None = None,
    progress: Callable[[int], None] | None = None,
) -> tuple[pd.DataFrame, CollectStats]:
    """Collect ``n`` lagged measurements with a detection along exploration paths.

    Parameters
    ----------
    n : int, optional
        Samples to collect (``config.collect.n`` if None).
    buffer_size : int, optional
        Camera buffer size ``k`` (``config.collect.buffer_size`` if None).
    seed : int
        Seeds the path parameters and the sensor noise; equal seeds give equal data.
    config : SimConfig, optional
        Defaults from ``defaults.toml`` if None.
    progress : callable, optional
        Called with the number of new samples after each recorded measurement.

    Returns
    -------
    data : pandas.DataFrame
        ``n`` rows, columns :data:`DATASET_COLUMNS` (see the module docstring).
    stats : CollectStats
        Detection counts and timing.

    Examples
    --------
    >>> data, stats = collect(20, buffer_size=1, seed=0)
    >>> len(data), stats.samples
    (20, 20)
    """
    cfg = load_config() if config is None else config
    overrides: dict[str, object] = {}
    if n is not None:
        overrides["n"] = n
    if buffer_size is not None:
        overrides["buffer_size"] = buffer_size
    if overrides:
        cfg = cfg.replace(collect=overrides)
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise InvalidInputError(f"seed must be a non-negative integer, got {seed!r}")
    params = cfg.collect
    rng = np.random.default_rng(int(seed))
    flight = Flight(cfg, buffer_size=params.buffer_size, seed=int(rng.integers(2**31)))
    outline = _pad_outline_w(cfg)
    rows = np.empty((params.n, _N_FLOAT))
    path_idx = np.empty(params.n, dtype=np.int64)
    times = np.empty(params.n)
    n_done = n_meas = n_out = n_in = n_paths = 0
    flight_time = 0.0
    fps = cfg.camera.fps
    warmup = int(round(params.warmup_time * fps))
    t0 = time.perf_counter()
    while n_done < params.n:
        template = TEMPLATES[n_paths % len(TEMPLATES)]
        path = make_path(template, rng, cfg.pad.position, cfg.paths)
        path = fit_to_view(path, flight.camera, outline, cfg.paths.view_margin_px,
                           cfg.quad.gravity)  # fmt: skip
        flight.reset(start_state(path))
        for frame in flight.follow(path, warmup / fps + path.duration):
            if frame <= warmup or (frame - warmup) % params.sample_every or n_done >= params.n:
                continue
            m = flight.measure()
            n_meas += 1
            if m.yhat_c is None:
                if m.pad_in_view:
                    n_in += 1
                else:
                    n_out += 1
                continue
            yhat_w = m.world_from_camera.apply(m.yhat_c)
            rows[n_done] = np.concatenate(
                [m.x_c, m.y_c, m.yhat_c, m.state, m.world_from_camera.apply(m.y_c), yhat_w]
            )
            path_idx[n_done] = n_paths
            times[n_done] = m.time
            n_done += 1
            if progress is not None:
                progress(1)
        flight_time += flight.time
        n_paths += 1
    data = pd.DataFrame(rows, columns=list(DATASET_COLUMNS[:-2]))
    data["path"] = path_idx
    data["t"] = times
    stats = CollectStats(
        buffer_size=params.buffer_size,
        seed=int(seed),
        samples=n_done,
        measurements=n_meas,
        missed_out_of_view=n_out,
        missed_in_view=n_in,
        paths=n_paths,
        flight_time=flight_time,
        wall_time=time.perf_counter() - t0,
    )
    return data, stats


def write_dataset(data: pd.DataFrame, out: str | Path, stats: CollectStats | None = None) -> Path:
    """Write ``data`` atomically to ``.parquet`` or ``.csv`` (by extension).

    The file is written to a temporary file in the same directory and moved into place
    with :func:`os.replace`, so readers never see a partial file. With ``stats``, a
    ``<stem>.stats.json`` sidecar is written the same way.

    Raises
    ------
    InvalidInputError
        If the extension is neither ``.parquet`` nor ``.csv`` or the directory is missing.
    """
    path = Path(out)
    suffix = path.suffix.lower()
    if suffix not in (".parquet", ".csv"):
        raise InvalidInputError(
            f"output file must end in .parquet or .csv, got {path.name!r}"
        )
    if not path.parent.exists():
        raise InvalidInputError(f"output directory {path.parent} does not exist; create it first")

    def _atomic(target: Path, write: Callable[[str], None]) -> None:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
        os.close(fd)
        try:
            write(tmp)
            os.replace(tmp, target)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    if suffix == ".parquet":
        _atomic(path, lambda tmp: data.to_parquet(tmp, index=False))
    else:
        _atomic(path, lambda tmp: data.to_csv(tmp, index=False, float_format="%.9g"))
    if stats is not None:
        sidecar = path.with_name(path.stem + ".stats.json")
        text = json.dumps(stats.as_dict(), indent=2) + "\n"
        _atomic(sidecar, lambda tmp: Path(tmp).write_text(text))
    return path

