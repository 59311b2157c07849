"""The renderer: what a camera sees of the pad."""

from __future__ import annotations

import numpy as np

from case_studies.quad_landing import Flight, Pad, load_config
from case_studies.quad_landing.sim.frames import Pose

CFG = load_config()


def test_renderer_draws_nothing_of_a_pad_behind_the_camera():
    f = Flight(CFG, buffer_size=0, seed=0)
    # looking straight up from below the pad: T_CW with optical axis +z_W
    T_CW = Pose(np.eye(3), np.array([0.0, 0.0, -0.5]))  # pad at z_C = -0.5
    img = f.renderer.render(T_CW, Pad((0.0, 0.0, 0.0), yaw=0.0), 0)
    assert img.shape == (240, 320) and img.max() < 200  # no white pad
