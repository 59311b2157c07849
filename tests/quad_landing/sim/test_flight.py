"""The Flight: input checks, the measurement it reads from its camera stage, legs."""

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


def test_a_timed_measurement_pairs_an_older_image_with_a_motion_capture_state():
    f = Flight(CFG, buffer_size=2, seed=0)
    f.reset(hover_state((0, 0, 1.2)))
    f.hold(0.5)
    m = f.measure()
    assert m.capture_time < m.time <= f.time  # image older than the paired state, both in the past
    assert f.measure() is m  # the same reader iteration: the same measurement
    np.testing.assert_allclose(m.state, f.history.state_at(m.time))


def test_fly_leg_checks_its_target():
    flight = Flight(buffer_size=1)
    flight.reset(hover_state((0.0, 0.0, 1.0)))
    with pytest.raises(InvalidInputError, match="outside the workspace"):
        fly_leg(flight, (0.0, 0.0, 3.5), yaw=0.0, timeout=1.0)
    with pytest.raises(InvalidInputError, match="timeout"):
        fly_leg(flight, (0.0, 0.0, 1.0), yaw=0.0, timeout=0.0)
