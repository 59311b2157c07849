"""The Flight: input checks, the lagged frame a measurement reads, lazy rendering, legs."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing import Flight, hover_state, load_config
from case_studies.quad_landing.sim.legs import fly_leg
from ipcverify.errors import InvalidInputError

CFG = load_config()


def test_flight_validates_its_inputs():
    f = Flight(CFG, buffer_size=1)
    with pytest.raises(InvalidInputError, match="call Flight.reset"):
        f.measure()
    with pytest.raises(InvalidInputError, match="12 finite numbers"):
        f.reset(np.zeros(11))
    with pytest.raises(InvalidInputError, match="buffer size must be"):
        Flight(CFG, buffer_size=99)


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


def test_fly_leg_checks_its_target():
    flight = Flight(buffer_size=1)
    flight.reset(hover_state((0.0, 0.0, 1.0)))
    with pytest.raises(InvalidInputError, match="outside the workspace"):
        fly_leg(flight, (0.0, 0.0, 3.5), yaw=0.0, timeout=1.0)
    with pytest.raises(InvalidInputError, match="timeout"):
        fly_leg(flight, (0.0, 0.0, 1.0), yaw=0.0, timeout=0.0)
