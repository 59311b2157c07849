"""The previous camera model: the image read is the one captured k ticks earlier, paired with now."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing import Flight, hover_state, load_config
from case_studies.quad_landing.sim.camera.buffer import check_buffer_size
from case_studies.quad_landing.sim.camera.framebuffer import FrameLagCamera, noise_key
from ipcverify.errors import InvalidInputError

FRAMES = load_config(overrides={"camera_timing": {"model": "frames"}})


@pytest.mark.parametrize("k", [0, 1, 3])
def test_measurement_uses_the_image_of_k_frames_ago(k):
    f = Flight(FRAMES, buffer_size=k, seed=0)
    assert isinstance(f.camera_stage, FrameLagCamera)
    f.reset(hover_state((0, 0, 1.2)))
    for i in range(1, 8):
        f.step()
        m = f.measure()
        assert m.time == pytest.approx(f.time)
        assert m.capture_time == pytest.approx(max(i - k, 0) / FRAMES.camera.fps)


def test_the_image_is_the_lagged_state_with_the_frame_noise():
    cfg = FRAMES.replace(render={"noise_std": 0.0})
    f = Flight(cfg, buffer_size=2, seed=3)
    f.reset(hover_state((0.1, 0, 1.4), yaw=0.2))
    for _ in range(4):
        f.step()
    m = f.measure()
    shown = f.history.state_at(m.capture_time)
    expected = f.renderer.render(f.camera_pose(shown).inverse(), f.pad, 0)
    np.testing.assert_array_equal(f.camera_stage.image(), expected)


def test_buffer_size_and_noise_keys():
    assert check_buffer_size(4) == 4
    with pytest.raises(InvalidInputError, match="buffer size must be an integer"):
        check_buffer_size(-1)
    with pytest.raises(InvalidInputError, match="buffer size must be an integer"):
        Flight(FRAMES, buffer_size=99)
    assert noise_key(3, 10) >= 0 and noise_key(3, -10) >= 0 and noise_key(3, 10) != noise_key(4, 10)
    with pytest.raises(InvalidInputError, match="call Flight.reset"):
        Flight(FRAMES, buffer_size=1).camera_stage.measure(0.0)
