"""Motion blur and rolling shutter move the detected marker corners by what geometry predicts.

A camera 1 m above the pad, looking straight down, moves at 1 m/s along world x (= image
u). A rolling shutter shows each corner at its own row's instant (a fixed point:
``t = s + row(t) readout / height``); a box exposure of ``E`` smears the marker by
``fx v E / h`` pixels and the detector finds the corners at mid-exposure.
"""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing.perception.aruco import ArucoPerception
from case_studies.quad_landing.sim.camera.exposure import render_exposed, row_weights, subframe_count
from case_studies.quad_landing.sim.camera.pinhole import Camera
from case_studies.quad_landing.sim.camera.render import Renderer
from case_studies.quad_landing.sim.config import load_config
from case_studies.quad_landing.sim.frames import Pose
from case_studies.quad_landing.sim.marker import Pad

H = 1.0  # camera height (m)
V = 1.0  # camera speed along world x = image u (m/s)


@pytest.fixture(scope="module")
def setup():
    cfg = load_config().replace(render={"noise_std": 0.0})
    cam = Camera(cfg.camera)
    renderer = Renderer(cam, cfg.marker, cfg.render)
    # AprilTag refinement: corners unbiased to a tenth of a pixel (OpenCV's default sits inside the border)
    april = cfg.replace(detector={"corner_refinement": "apriltag"}).detector
    return renderer, ArucoPerception(cam, cfg.marker, april), Pad((0.0, 0.0, 0.0), yaw=0.3), cam


def _pose(t: float) -> Pose:
    # looking straight down: camera x = world x, camera y = -world y, camera z = -world z
    return Pose(np.diag([1.0, -1.0, -1.0]), np.array([V * t, 0.0, H])).inverse()


def _corners(renderer: Renderer, cam: Camera, pad: Pad, t: float) -> np.ndarray:
    return cam.project(renderer.marker_corners_camera(_pose(t), pad))


def test_row_weights_model_the_rolling_shutter_and_the_exposure():
    w = row_weights(240, 8, exposure=0.0, readout=0.008)
    centre = (w * np.arange(8)).sum(axis=1)  # weighted bin index per row
    assert np.all(np.diff(centre) >= 0) and centre[0] < 0.5 and centre[-1] > 6.4
    np.testing.assert_allclose(row_weights(240, 10, exposure=0.010, readout=0.0), 0.1, atol=1e-7)
    w = row_weights(240, 12, exposure=0.008, readout=0.004)
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-6)
    # each row's window covers 2/3 of the span: its weights start later row by row
    first = np.argmax(w > 0, axis=1)
    assert first[0] == 0 and first[-1] >= 3 and np.all(np.diff(first) >= 0)


def test_subframe_count_follows_the_motion():
    assert subframe_count(0.0, 0.5, 24) == 2
    assert subframe_count(2.0, 0.5, 24) == 5
    assert subframe_count(1e6, 0.5, 24) == 24


def test_rolling_shutter_moves_corners_as_geometry_predicts(setup):
    renderer, perception, pad, cam = setup
    readout, t0 = 0.016, -0.008
    img = render_exposed(renderer, _pose, pad, t0, exposure=0.0, readout=readout, noise_key=0,
                         max_step_px=0.1, max_subframes=64)  # fmt: skip
    det = perception.detect(img)
    assert det is not None
    predicted = np.empty((4, 2))
    for k in range(4):  # each corner is seen at its own row's instant: a fixed point
        t = t0
        for _ in range(8):
            row = _corners(renderer, cam, pad, t)[k, 1]
            t = t0 + row * readout / cam.params.height
        predicted[k] = _corners(renderer, cam, pad, t)[k]
    shift = predicted - _corners(renderer, cam, pad, t0)
    assert np.abs(shift[:, 0]).max() > 1.0  # well above the detector's accuracy
    assert np.abs(det - predicted).max() < 0.3, det - predicted


def test_motion_blur_centres_corners_at_mid_exposure(setup):
    renderer, perception, pad, cam = setup
    exposure, t0 = 0.016, -0.008
    img = render_exposed(renderer, _pose, pad, t0, exposure=exposure, readout=0.0, noise_key=0,
                         max_step_px=0.1, max_subframes=64)  # fmt: skip
    det = perception.detect(img)
    assert det is not None
    mid, start = _corners(renderer, cam, pad, t0 + exposure / 2), _corners(renderer, cam, pad, t0)
    streak = cam.params.fx * V * exposure / H  # streak length (px)
    np.testing.assert_allclose(np.abs(mid - start)[:, 0], streak / 2, atol=1e-6)
    assert np.abs(det - mid).max() < 0.3, det - mid
    assert np.abs(det - start)[:, 0].min() > 0.75 * streak / 2


def test_window_rendering_matches_full_frame_composition(setup):
    """The pad-only window on a floor drawn once equals composing full sub-renders (flat floor)."""
    renderer, _, pad, cam = setup
    cfg = load_config().replace(render={"noise_std": 0.0, "floor": "flat", "blur_sigma": 0.0})
    flat = Renderer(cam, cfg.marker, cfg.render)
    exposure, readout, t0 = 0.008, 0.0045, 0.0
    fast = render_exposed(flat, _pose, pad, t0, exposure, readout, 0, max_step_px=0.5, max_subframes=24)
    span = exposure + readout  # the same K as render_exposed chooses (the pad moves along u only)
    move = np.abs(_corners(flat, cam, pad, t0 + span) - _corners(flat, cam, pad, t0)).max()
    k = subframe_count(float(move), 0.5, 24)
    times = t0 + (np.arange(k) + 0.5) * span / k
    subs = np.stack([flat.render(_pose(float(t)), pad, 0).astype(np.float32) for t in times])
    full = np.einsum("rk,krc->rc", row_weights(240, k, exposure, readout), subs)
    assert np.abs(fast.astype(float) - np.rint(full)).max() <= 1.0


def test_no_exposure_and_no_readout_is_a_plain_render(setup):
    renderer, _, pad, _ = setup
    plain = renderer.render(_pose(0.1), pad, 3)
    np.testing.assert_array_equal(render_exposed(renderer, _pose, pad, 0.1, 0.0, 0.0, 3), plain)
