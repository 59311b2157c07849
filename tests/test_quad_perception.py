"""Rendering, ArUco detection and pose, the frame buffer, and the lag it causes."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing import Flight, Pad, hover_state, load_config
from case_studies.quad_landing.data.collect import fly_path
from case_studies.quad_landing.perception.aruco import ArucoPerception, DetectorParams
from case_studies.quad_landing.sim.framebuffer import Frame, FrameBuffer
from case_studies.quad_landing.sim.frames import Pose
from case_studies.quad_landing.sim.marker import MarkerParams
from case_studies.quad_landing.sim.render import RenderParams
from ipcverify.errors import InvalidInputError

CFG = load_config()


def test_no_lag_recovers_the_pad_within_1cm_at_1m():
    """Twenty poses 1 m above the pad, tilted and turned, with noise and blur."""
    f = Flight(CFG, buffer_size=0, seed=1)
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
    cfg = CFG.replace(render={"noise_std": 0.0, "blur_sigma": 0.0})
    f = Flight(cfg, buffer_size=0, seed=0)
    x = hover_state((0.12, -0.07, 1.3), yaw=0.9)
    x[6:8] = [0.05, -0.08]
    f.reset(x)
    corners = f.perception.detect(f.latest_image())
    assert corners is not None
    T_CW = f.camera_pose().inverse()
    expected = f.camera.project(f.renderer.marker_corners_camera(T_CW, f.pad))
    assert np.max(np.abs(corners - expected)) < 0.2
    raw = ArucoPerception(f.camera, cfg.marker, DetectorParams.defaults(april_tag_corner_shift_px=0.0))
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
    f.reset(hover_state((0.0, 0.0, 1.0)))
    other = ArucoPerception(f.camera, MarkerParams.defaults(marker_id=7), DetectorParams.defaults())
    assert f.perception.estimate(f.latest_image()) is not None
    assert other.estimate(f.latest_image()) is None


def test_renderer_draws_nothing_of_a_pad_behind_the_camera():
    f = Flight(CFG, buffer_size=0, seed=0)
    # looking straight up from below the pad: T_CW with optical axis +z_W
    T_CW = Pose(np.eye(3), np.array([0.0, 0.0, -0.5]))  # pad at z_C = -0.5
    img = f.renderer.render(T_CW, Pad((0.0, 0.0, 0.0), yaw=0.0), 0)
    assert img.shape == (240, 320) and img.max() < 200  # no white pad


def test_frame_buffer_returns_the_frame_k_ticks_old():
    buf = FrameBuffer(3)
    img = np.zeros((2, 2), np.uint8)
    buf.fill(Frame(0.0, np.zeros(12), img))
    for i in range(1, 8):
        buf.capture(Frame(float(i), np.zeros(12), img))
        assert buf.read().time == max(i - 3, 0)
        assert buf.newest().time == i
    assert len(buf) == 4
    with pytest.raises(InvalidInputError, match="buffer size must be an integer"):
        FrameBuffer(-1)
    with pytest.raises(InvalidInputError, match="call fill"):
        FrameBuffer(2).read()


@pytest.mark.parametrize("k", [0, 1, 3])
def test_measurement_uses_the_image_of_k_frames_ago(k):
    f = Flight(CFG, buffer_size=k, seed=0)
    f.reset(hover_state((0, 0, 1.2)))
    for _ in range(10):
        f.step()
    m = f.measure()
    assert m.capture_time == pytest.approx(m.time - k / CFG.camera.fps)
    assert f.buffer.read().state is not f.buffer.newest().state or k == 0


def test_lazy_rendering_gives_the_same_pixels_as_eager_rendering():
    f = Flight(CFG, buffer_size=2, seed=3)
    f.reset(hover_state((0.1, 0, 1.4), yaw=0.2))
    f.step()
    frame = f.buffer.newest()
    lazy = frame.image
    eager_pose = f.camera_pose(frame.state).inverse()
    # the noise key is drawn at capture, so redrawing from the frame's state differs
    # only if the noise differs: compare with noise switched off
    cfg = CFG.replace(render={"noise_std": 0.0})
    g = Flight(cfg, buffer_size=2, seed=3)
    g.reset(hover_state((0.1, 0, 1.4), yaw=0.2))
    g.step()
    again = g.renderer.render(eager_pose, g.pad, 0)
    np.testing.assert_array_equal(g.buffer.newest().image, again)
    assert np.mean(np.abs(lazy.astype(int) - again.astype(int))) < 3  # noise sigma 2


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


def test_detector_and_render_params_validate():
    with pytest.raises(InvalidInputError, match="corner_refinement must be one of"):
        DetectorParams.defaults(corner_refinement="magic")
    with pytest.raises(InvalidInputError, match="render.floor must be one of"):
        RenderParams.defaults(floor="carpet")
    with pytest.raises(InvalidInputError, match="4x4 ArUco dictionary"):
        MarkerParams.defaults(dictionary="DICT_6X6_50")
    with pytest.raises(InvalidInputError, match="marker_id must be an integer"):
        MarkerParams.defaults(marker_id=50)
