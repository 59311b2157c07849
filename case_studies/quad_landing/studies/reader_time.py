"""How long the vehicle's reader loop needs per frame: the ArUco time measured here, to scale to a Pi 3.

The camera-timing model (:mod:`case_studies.quad_landing.sim.camera.timing`) drains the V4L2
queue with a reader whose per-frame time is drawn from a *measured* distribution, scaled
to the paper's Raspberry Pi 3. This module measures it on this machine:

* ``detector`` — what the paper's code most plausibly ran: OpenCV's ``ArucoDetector``
  with its default parameters (no corner refinement), ``DICT_4X4_50``, and
  ``solvePnP(..., SOLVEPNP_IPPE_SQUARE)`` on the detected corners, per 320 x 240 frame.
  The frames are this simulator's renders along exploration paths (marker sizes, tilts and
  blur as in the data). Each frame is timed ``repeat`` times and the minimum kept (the
  scheduler's noise removed: the Pi's own jitter is modelled separately).
* ``detector_640`` — the same on the frames upscaled to 640 x 480, to compare with the
  published Raspberry Pi Zero figure (Frappe, Jones & Hauert, J. Real-Time Image Proc. 2023:
  standard ArUco at 640 x 480 about five times slower than their > 60 Hz, i.e. ~83 ms).
* ``threads`` — the same at 320 x 240 with ``threads`` OpenCV threads: ArUco's candidate
  search runs in parallel over its threshold window sizes, as it does by default on the
  Pi's four cores. The one- and multi-thread rounds alternate so both see the same load
  (on a shared machine the speed-up comes out low, never high).
* ``convert`` — YUYV -> BGR -> grey of one frame (``VideoCapture.retrieve`` and the app).

``python -m case_studies.quad_landing reader-timing`` prints the numbers and the
``[camera_timing]`` lines of ``defaults.toml`` they give.

Examples
--------
>>> q = quantiles_ms(np.array([1.0, 2.0, 3.0]), 3)
>>> q.tolist()
[1.0, 2.0, 3.0]
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from case_studies.quad_landing.data.collect import pad_outline_world, path_rng, start_state
from case_studies.quad_landing.sim.config import SimConfig, load_config
from case_studies.quad_landing.sim.flight import Flight
from case_studies.quad_landing.sim.paths import TEMPLATES, fit_to_view, make_path

__all__ = ["ReaderTiming", "measure_reader_time", "quantiles_ms", "path_frames"]

UInt8Image = NDArray[np.uint8]


def quantiles_ms(samples: NDArray[np.float64], count: int = 21) -> NDArray[np.float64]:
    """``count`` equally spaced quantiles (0 % ... 100 %) of ``samples``, rounded to 1 us."""
    return np.round(np.quantile(np.asarray(samples, dtype=np.float64), np.linspace(0, 1, count)), 3)


def path_frames(n: int, config: SimConfig | None = None, seed: int = 5, every: int = 6) -> list[UInt8Image]:
    """``n`` rendered frames (no lag) along exploration paths, one every ``every`` camera frames."""
    cfg = load_config(overrides={"camera_timing": {"model": "frames"}}) if config is None else config
    flight = Flight(cfg, buffer_size=0, seed=seed)
    frames: list[UInt8Image] = []
    index = 0
    while len(frames) < n:
        rng = path_rng(seed, index)
        path = make_path(TEMPLATES[index % len(TEMPLATES)], rng, flight.pad.position, cfg.paths)
        path = fit_to_view(path, flight.camera, pad_outline_world(cfg), cfg.paths.view_margin_px,
                           cfg.quad.gravity)  # fmt: skip
        flight.reset(start_state(path), seed=int(rng.integers(2**31)))
        for frame in flight.follow(path):
            if frame % every == 0 and len(frames) < n:
                T_CW = flight.camera_pose().inverse()
                frames.append(flight.renderer.render(T_CW, flight.pad, len(frames)))
        index += 1
    return frames


def _time_each(fn: Callable[[UInt8Image], object], frames: Sequence[UInt8Image], repeat: int) -> NDArray:
    out = np.empty((repeat, len(frames)))
    for r in range(repeat):
        for i, f in enumerate(frames):
            t0 = time.perf_counter()
            fn(f)
            out[r, i] = time.perf_counter() - t0
    return out.min(axis=0) * 1e3


@dataclass(frozen=True)
class ReaderTiming:
    """Per-frame times measured here (ms): see the module docstring.

    Attributes
    ----------
    detector : ndarray
        Default ArUco + IPPE pose per 320 x 240 frame, one OpenCV thread.
    detector_640 : ndarray
        The same at 640 x 480.
    detector_threads : ndarray
        The same at 320 x 240 with ``threads`` OpenCV threads.
    threads : int
    convert : float
        YUYV -> BGR -> grey at 320 x 240 (median).
    """

    detector: NDArray[np.float64]
    detector_640: NDArray[np.float64]
    detector_threads: NDArray[np.float64]
    threads: int
    convert: float

    @property
    def parallel_speedup(self) -> float:
        """Median one-thread time over median ``threads``-thread time."""
        return float(np.median(self.detector) / np.median(self.detector_threads))

    def cpu_scale(self, pi_zero_640_ms: float = 83.0, pi3_core_over_zero: float = 3.0) -> float:
        """Raspberry Pi 3 (one core) over this machine: ``pi_zero_640_ms / median(640) / ratio``."""
        return float(pi_zero_640_ms / np.median(self.detector_640) / pi3_core_over_zero)

    def toml_lines(self) -> str:
        """The ``[camera_timing]`` keys these measurements give (quantiles every 5 %)."""
        q = ", ".join(f"{v:.3f}" for v in quantiles_ms(self.detector))
        return "\n".join(
            [
                f"detector_ms = [{q}]",
                f"convert_ms = {self.convert:.3f}",
                f"cpu_scale = {self.cpu_scale():.1f}",
                f"parallel_speedup = {self.parallel_speedup:.2f}",
            ]
        )


def measure_reader_time(
    frames: Sequence[UInt8Image], *, threads: int = 2, repeat: int = 3, rounds: int = 3
) -> ReaderTiming:
    """Time the default ArUco pipeline on ``frames`` (see the module docstring).

    Each frame's time is the minimum over ``rounds * repeat`` runs; the one-thread and the
    ``threads``-thread rounds alternate. OpenCV's thread count is restored afterwards.
    """
    cfg = load_config()
    from case_studies.quad_landing.sim.camera import Camera

    K = Camera(cfg.camera).K
    K640 = K.copy()
    K640[:2] *= 2.0
    obj = cfg.marker.object_points()
    detector = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50), cv2.aruco.DetectorParameters()
    )

    def run(img: UInt8Image, KK: NDArray[np.float64] = K) -> None:
        corners, ids, _ = detector.detectMarkers(img)
        if ids is not None:
            c = np.asarray(corners[0], dtype=np.float64).reshape(4, 2)
            cv2.solvePnP(obj, c, KK, None, flags=cv2.SOLVEPNP_IPPE_SQUARE)

    before = cv2.getNumThreads()
    one = many = np.full(len(frames), np.inf)
    try:
        for _ in range(rounds):  # interleaved, so both see the same machine load
            cv2.setNumThreads(1)
            one = np.minimum(one, _time_each(run, frames, repeat))
            cv2.setNumThreads(threads)
            many = np.minimum(many, _time_each(run, frames, repeat))
        cv2.setNumThreads(1)
        big = [
            np.asarray(cv2.resize(f, (640, 480), interpolation=cv2.INTER_LINEAR), np.uint8) for f in frames
        ]
        at640 = _time_each(lambda f: run(f, K640), big, repeat)
        yuyv = np.random.default_rng(0).integers(0, 256, (240, 320, 2), dtype=np.uint8)

        def convert(_: UInt8Image) -> None:
            cv2.cvtColor(cv2.cvtColor(yuyv, cv2.COLOR_YUV2BGR_YUYV), cv2.COLOR_BGR2GRAY)

        conv = float(np.median(_time_each(convert, frames[:50], repeat)))
    finally:
        cv2.setNumThreads(before)
    return ReaderTiming(one, at640, many, threads, conv)
