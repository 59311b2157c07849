"""The perception error that the camera lag causes, and that x_C (with the image's age) predicts."""

from __future__ import annotations

import numpy as np

from case_studies.quad_landing import Flight, load_config
from case_studies.quad_landing.data.collect import fly_path

CFG = load_config(overrides={"camera_timing": {"model": "frames"}})  # the fixed k-frame lag
TIMED = load_config(overrides={"detector": {"corner_refinement": "apriltag"}})  # unbiased corners


def test_median_error_grows_with_the_buffer_size_at_speed():
    """Same path (same seed and index) flown with k = 0..5: median error strictly grows.

    The lag error at speed is about k (v_C + omega_C x y_C) / fps, ~1 cm per frame here,
    against ~5 mm of noise, so the medians are far apart.
    """
    cfg = CFG.replace(paths={"duration": 4.0})
    medians = []
    for k in range(6):
        rec = fly_path(Flight(cfg, buffer_size=k), index=3, seed=11)  # "dash"
        assert len(rec.rows) >= 100
        err = np.linalg.norm(rec.rows[:, 15:18] - rec.rows[:, 12:15], axis=1)
        medians.append(float(np.median(err)))
    assert all(b > a for a, b in zip(medians, medians[1:], strict=False))
    per_frame = np.diff(medians[1:])
    assert 0.003 < float(np.min(per_frame)) and float(np.max(per_frame)) < 0.05


def test_lag_error_is_explained_by_the_camera_frame_state():
    """yhat_C - y_C ~ k/fps (omega_C x y_C + v_C): x_C carries what predicts the lag."""
    cfg = CFG.replace(paths={"duration": 4.0})
    k = 3
    rec = fly_path(Flight(cfg, buffer_size=k), index=0, seed=5)  # "orbit"
    x_c, y_c, yhat = rec.rows[:, 0:12], rec.rows[:, 12:15], rec.rows[:, 15:18]
    tau = k / cfg.camera.fps
    predicted = tau * (np.cross(x_c[:, 9:12], y_c) + x_c[:, 3:6])
    err = yhat - y_c
    residual = np.linalg.norm(err - predicted, axis=1)
    assert np.median(residual) < 0.35 * np.median(np.linalg.norm(err, axis=1))


def test_timed_camera_error_is_explained_by_each_images_age():
    """With the timing model the lag varies per image: yhat_C - y_C ~ age (omega_C x y_C + v_C)."""
    cfg = TIMED.replace(paths={"duration": 4.0}, render={"noise_std": 0.0})
    rec = fly_path(Flight(cfg, buffer_size=3), index=0, seed=5)  # "orbit"
    x_c, y_c, yhat = rec.rows[:, 0:12], rec.rows[:, 12:15], rec.rows[:, 15:18]
    assert np.ptp(rec.ages) > 0.01  # the age is not a fixed number of frames
    predicted = rec.ages[:, None] * (np.cross(x_c[:, 9:12], y_c) + x_c[:, 3:6])
    err = yhat - y_c
    residual = np.linalg.norm(err - predicted, axis=1)
    assert np.median(residual) < 0.35 * np.median(np.linalg.norm(err, axis=1))
