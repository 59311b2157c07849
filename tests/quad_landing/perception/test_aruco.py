"""ArUco detection and pose: accuracy without lag, corners, no false detections, settings."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing import Flight, hover_state, load_config
from case_studies.quad_landing.perception.aruco import ArucoPerception, DetectorParams
from case_studies.quad_landing.perception.marker import MarkerParams
from case_studies.quad_landing.sim.camera import RenderParams
from ipcverify.errors import InvalidInputError

CFG = load_config()
#: The geometry tests use AprilTag refinement (unbiased corners); the default is OpenCV's, none.
APRIL = CFG.replace(detector={"corner_refinement": "apriltag"})


def test_no_lag_recovers_the_pad_within_1cm_at_1m():
    """Twenty poses 1 m above the pad, tilted and turned, with noise and blur (AprilTag refinement)."""
    f = Flight(APRIL, buffer_size=0, seed=1)
    rng = np.random.default_rng(7)
    errors = []
    for _ in range(20):
        x = hover_state((rng.uniform(-0.15, 0.15), rng.uniform(-0.1, 0.1), 1.05),
                        yaw=rng.uniform(-np.pi, np.pi))  # fmt: skip
        x[6:8] = rng.uniform(-0.1, 0.1, 2)
        f.reset(x)
        m = f.measure()
        assert m.detected and m.capture_time == m.time
        assert np.linalg.norm(m.y_c) == pytest.approx(1.0, abs=0.08)
        errors.append(np.linalg.norm(m.yhat_c - m.y_c))
        np.testing.assert_allclose(m.yhat_w, m.world_from_camera.apply(m.yhat_c))
        np.testing.assert_allclose(m.y_w, CFG.pad.position, atol=1e-12)
    assert max(errors) < 0.01


def test_detected_corners_match_the_projected_marker():
    """Noise-free image: AprilTag-refined corners within 0.2 px of the pinhole projection.

    Without the half-pixel correction they are ~0.45 px off in both axes.
    """
    cfg = APRIL.replace(render={"noise_std": 0.0, "blur_sigma": 0.0})
    f = Flight(cfg, buffer_size=0, seed=0)
    x = hover_state((0.12, -0.07, 1.3), yaw=0.9)
    x[6:8] = [0.05, -0.08]
    f.reset(x)
    corners = f.perception.detect(f.latest_image())
    assert corners is not None
    T_CW = f.camera_pose().inverse()
    expected = f.camera.project(f.renderer.marker_corners_camera(T_CW, f.pad))
    assert np.max(np.abs(corners - expected)) < 0.2
    raw = ArucoPerception(
        f.camera,
        cfg.marker,
        DetectorParams.defaults(corner_refinement="apriltag", april_tag_corner_shift_px=0.0),
    )
    shift = raw.detect(f.latest_image()) - expected
    assert np.all((shift > 0.3) & (shift < 0.6))


def test_nothing_is_detected_without_the_marker():
    f = Flight(CFG, buffer_size=0, seed=0)
    assert f.perception.estimate(np.full((240, 320), 110, np.uint8)) is None
    # a camera looking at the floor far away from the pad
    f.reset(hover_state((2.5, 2.5, 1.0)))
    m = f.measure()
    assert not m.detected and not m.pad_in_view
    # a detector looking for another id ignores the pad's marker
    f.reset(hover_state((0.05, -0.03, 1.0)))
    other = ArucoPerception(f.camera, MarkerParams.defaults(marker_id=7), DetectorParams.defaults())
    assert f.perception.estimate(f.latest_image()) is not None
    assert other.estimate(f.latest_image()) is None


def test_the_default_detector_is_opencvs_and_reads_the_range_long():
    """OpenCV's default (no corner refinement): corners inside the black border, so the marker
    looks smaller and the range comes out long (docs/case_study.md: +0.7 ... +3 %)."""
    import cv2

    assert CFG.detector.corner_refinement == "none"
    assert cv2.aruco.DetectorParameters().cornerRefinementMethod == cv2.aruco.CORNER_REFINE_NONE
    rng = np.random.default_rng(3)
    ratios = []
    for cfg in (CFG, APRIL):
        f = Flight(cfg, buffer_size=0, seed=2)
        r = []
        for _ in range(15):
            f.reset(
                hover_state((rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), 1.6), yaw=rng.uniform(-3, 3))
            )
            m = f.measure()
            if m.detected:
                r.append(np.linalg.norm(m.yhat_c) / np.linalg.norm(m.y_c) - 1.0)
        assert len(r) >= 10
        ratios.append(float(np.median(r)))
    assert 0.007 < ratios[0] < 0.04 and abs(ratios[1]) < 0.003


def test_detector_and_render_params_validate():
    with pytest.raises(InvalidInputError, match="corner_refinement must be one of"):
        DetectorParams.defaults(corner_refinement="magic")
    with pytest.raises(InvalidInputError, match="render.floor must be one of"):
        RenderParams.defaults(floor="carpet")
    with pytest.raises(InvalidInputError, match="4x4 ArUco dictionary"):
        MarkerParams.defaults(dictionary="DICT_6X6_50")
    with pytest.raises(InvalidInputError, match="marker_id must be an integer"):
        MarkerParams.defaults(marker_id=50)
