"""Approach flights: the same flights at every buffer size, argument checks."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing import Flight
from case_studies.quad_landing.data.approach import (
    ApproachParams,
    collect_approach,
    fly_approach,
    record_approach,
)
from case_studies.quad_landing.data.recording import measure_recording
from case_studies.quad_landing.sim.camera import build_camera_stage
from ipcverify.errors import InvalidInputError


def test_approach_flights_are_the_same_at_every_buffer_size():
    params = ApproachParams.defaults(hover_points=1, dwell=(0.2, 0.2))
    a = record_approach(Flight(buffer_size=1), 2, seed=5, params=params)
    b = record_approach(Flight(buffer_size=3), 2, seed=5, params=params)
    np.testing.assert_array_equal(a.sample_times, b.sample_times)
    assert a.sensor_seed == b.sensor_seed and len(a.history) == len(b.history) > 100
    for t in np.linspace(0.0, a.flight_time, 50):
        np.testing.assert_array_equal(a.history.state_at(t), b.history.state_at(t))
    # measured with different buffer sizes: older images on the same flight
    one = measure_recording(a, build_camera_stage(Flight(buffer_size=1).config, 1))
    three = measure_recording(a, build_camera_stage(Flight(buffer_size=1).config, 3))
    assert len(one.rows) > 10 and np.median(three.ages) > np.median(one.ages)


def test_measuring_a_recording_is_measuring_during_the_flight():
    params = ApproachParams.defaults(hover_points=1, dwell=(0.2, 0.2))
    flight = Flight(buffer_size=2)
    live = fly_approach(flight, 1, seed=5, params=params)
    replay = measure_recording(record_approach(flight, 1, seed=5, params=params), flight.camera_stage)
    np.testing.assert_array_equal(live.rows, replay.rows)
    np.testing.assert_array_equal(live.outcomes, replay.outcomes)


def test_the_scenario_of_an_approach_flight_takes_the_approach_ranges():
    params = ApproachParams.defaults(pad_region=0.7, transit_speed=(0.5, 0.9), deceleration=2.5)
    sc = params.scenario()
    assert (sc.pad_region, sc.transit_speed, sc.deceleration) == (0.7, (0.5, 0.9), 2.5)
    assert (sc.start_distance, sc.start_height, sc.prior_radius, sc.aligned_margin_deg) == (
        params.start_distance,
        params.start_height,
        params.prior_radius,
        params.aligned_margin_deg,
    )


def test_collect_approach_checks_its_arguments():
    with pytest.raises(InvalidInputError, match="positive integer"):
        collect_approach(0, buffer_size=1, seed=0, params=ApproachParams.defaults())
    with pytest.raises(InvalidInputError, match="non-negative"):
        collect_approach(5, buffer_size=1, seed=-1, params=ApproachParams.defaults())
