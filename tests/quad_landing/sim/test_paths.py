"""Exploration paths: the pad stays in view, consistent derivatives, refusals."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from case_studies.quad_landing import load_config
from case_studies.quad_landing.data.collect import pad_outline_world
from case_studies.quad_landing.sim.camera import Camera
from case_studies.quad_landing.sim.paths import (
    TEMPLATES,
    ExplorationPath,
    PathParams,
    fit_to_view,
    make_path,
    pad_in_view_along,
)
from ipcverify.errors import InvalidInputError

CFG = load_config()


@settings(max_examples=15, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), which=st.integers(0, 4))
def test_fitted_paths_keep_the_pad_in_view(seed, which):
    cam = Camera(CFG.camera)
    outline = pad_outline_world(CFG)
    raw = make_path(TEMPLATES[which], np.random.default_rng(seed), CFG.pad.position, CFG.paths)
    fitted = fit_to_view(raw, cam, outline, CFG.paths.view_margin_px)
    assert pad_in_view_along(fitted, cam, outline, CFG.paths.view_margin_px)
    assert np.all(fitted.amplitude[:2] <= raw.amplitude[:2] + 1e-12)
    r = fitted.sample(np.linspace(0, fitted.duration, 200))
    heights = r.position[:, 2] - CFG.pad.position[2]
    assert heights.min() >= CFG.paths.min_height - 1e-9
    assert heights.max() <= CFG.paths.max_height + 1e-9
    assert np.all(np.abs(r.position[:, :2]) < 3.0)  # inside the workspace


def test_path_derivatives_are_consistent():
    path = make_path("lissajous", np.random.default_rng(1), (0, 0, 0), PathParams.defaults())
    t = np.linspace(0.5, 5.0, 50)
    h = 1e-5
    a, b, m = path.sample(t + h), path.sample(t - h), path.sample(t)
    np.testing.assert_allclose((a.position - b.position) / (2 * h), m.velocity, atol=1e-6)
    np.testing.assert_allclose((a.velocity - b.velocity) / (2 * h), m.acceleration, atol=1e-6)
    np.testing.assert_allclose((a.acceleration - b.acceleration) / (2 * h), m.jerk, atol=1e-5)
    np.testing.assert_allclose((a.yaw - b.yaw) / (2 * h), m.yaw_rate, atol=1e-6)


def test_fit_to_view_refuses_a_path_that_cannot_see_the_pad():
    cam = Camera(CFG.camera)
    low = ExplorationPath(name="low", center=(0, 0, 0.15), amplitude=(0, 0, 0), omega=(1, 1, 1),
                          phase=(0, 0, 0), duration=1.0)  # fmt: skip
    with pytest.raises(InvalidInputError, match="leaves the image even without"):
        fit_to_view(low, cam, pad_outline_world(CFG), 3.0)
