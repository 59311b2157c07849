"""Measure the range bias and speed of ArUco corner-refinement methods (no lag).

For each range, random hovering poses are drawn (whole pad in the image, roll and
pitch up to 0.15 rad, any heading); each image is rendered once and every detector
estimates ``yhat_C`` from the same image. The relative range error is
``|yhat_C| / |y_C| - 1``; its median over poses is the bias.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
import pandas as pd

from case_studies.quad_landing.perception.aruco import ArucoPerception, DetectorParams
from case_studies.quad_landing.sim.config import SimConfig, load_config
from case_studies.quad_landing.sim.dynamics import hover_state
from case_studies.quad_landing.sim.flight import Flight
from ipcverify.errors import InvalidInputError

__all__ = ["refinement_bias", "default_detectors"]


def default_detectors(config: SimConfig) -> dict[str, DetectorParams]:
    """The detectors compared by default: each refinement, and AprilTag with OpenCV's default
    ``aprilTagMinWhiteBlackDiff = 5`` next to the configured value."""
    base = config.detector
    out = {}
    for method in ("apriltag", "subpix", "contour", "none"):
        label = f"{method}" if method != "apriltag" else (
            f"apriltag (diff {base.april_tag_min_white_black_diff})"
        )  # fmt: skip
        out[label] = replace(base, corner_refinement=method)
    out["apriltag (diff 5, OpenCV default)"] = replace(
        base, corner_refinement="apriltag", april_tag_min_white_black_diff=5
    )
    return out


def refinement_bias(
    ranges: Sequence[float] = (0.8, 1.2, 1.6, 2.0, 2.4),
    poses: int = 100,
    *,
    detectors: Mapping[str, DetectorParams] | None = None,
    seed: int = 0,
    config: SimConfig | None = None,
) -> pd.DataFrame:
    """Range bias, error and time per detection of each detector at each range.

    Parameters
    ----------
    ranges : sequence of float
        Camera heights above the pad (m).
    poses : int
        Random poses per range; the whole pad is in view in each.
    detectors : mapping of str to DetectorParams, optional
        Detectors to compare, by label (:func:`default_detectors` if None).
    seed : int
        Seeds the poses and the sensor noise.
    config : SimConfig, optional
        Camera, marker and rendering settings.

    Returns
    -------
    pandas.DataFrame
        One row per (detector, range): ``detected`` (fraction), ``bias_pct`` (median
        relative range error, %), ``iqr_pct``, ``median_error_mm`` (median ``|yhat_C -
        y_C|``) and ``ms_per_detection`` (wall time of detection plus pose).

    Examples
    --------
    >>> df = refinement_bias(ranges=(1.0,), poses=5,
    ...                      detectors={"apriltag": DetectorParams.defaults()})
    >>> df[["detector", "range", "detected"]].to_dict("records")
    [{'detector': 'apriltag', 'range': 1.0, 'detected': 1.0}]
    """
    if int(poses) != poses or poses < 1:
        raise InvalidInputError(f"poses must be a positive integer, got {poses}")
    if not ranges or any(not (0.3 <= r <= 3.0) for r in ranges):
        raise InvalidInputError(f"ranges must be heights in [0.3, 3] m, got {list(ranges)}")
    cfg = load_config() if config is None else config
    flight = Flight(cfg, buffer_size=0, seed=seed)
    chosen = default_detectors(cfg) if detectors is None else dict(detectors)
    perceptions = {
        label: ArucoPerception(flight.camera, cfg.marker, params) for label, params in chosen.items()
    }
    rng = np.random.default_rng(seed)
    rows = []
    pad = cfg.pad.position
    p = cfg.camera
    for r in ranges:
        results: dict[str, list[tuple[float, float]]] = {m: [] for m in perceptions}
        elapsed = dict.fromkeys(perceptions, 0.0)
        for _ in range(int(poses)):
            while True:  # draw until the whole pad is in view
                dx = rng.uniform(-0.3, 0.3) * (p.width / p.fx) * r
                dy = rng.uniform(-0.3, 0.3) * (p.height / p.fy) * r
                x = hover_state(pad + np.array([dx, dy, r - p.offset[2]]),
                                rng.uniform(-np.pi, np.pi))  # fmt: skip
                x[6:8] = rng.uniform(-0.15, 0.15, 2)
                outline = flight.renderer.pad_corners_camera(flight.camera_pose(x).inverse(), flight.pad)
                if flight.camera.in_view(outline, margin_px=3.0):
                    break
            flight.reset(x)
            image = flight.latest_image()
            y_c = flight.measure().y_c
            for m, det in perceptions.items():
                t0 = time.perf_counter()
                yhat = det.estimate(image)
                elapsed[m] += time.perf_counter() - t0
                if yhat is not None:
                    rel = float(np.linalg.norm(yhat) / np.linalg.norm(y_c) - 1.0)
                    results[m].append((rel, float(np.linalg.norm(yhat - y_c))))
        for m in perceptions:
            res = np.array(results[m]).reshape(-1, 2)
            q25, q50, q75 = np.percentile(res[:, 0], [25, 50, 75]) if len(res) else (np.nan,) * 3
            rows.append(
                {
                    "detector": m,
                    "range": float(r),
                    "detected": len(res) / poses,
                    "bias_pct": 100 * q50,
                    "iqr_pct": 100 * (q75 - q25),
                    "median_error_mm": 1000 * float(np.median(res[:, 1])) if len(res) else np.nan,
                    "ms_per_detection": 1000 * elapsed[m] / poses,
                }
            )
    return pd.DataFrame(rows)
