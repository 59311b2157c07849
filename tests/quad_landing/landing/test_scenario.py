"""Landing scenarios: reproducible, within their ranges, a smooth stop."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing.data.datasets import (
    alignment_deg,
)
from case_studies.quad_landing.landing.scenario import ScenarioParams, draw_scenario, stopping_reference
from case_studies.quad_landing.sim.config import load_config
from ipcverify.errors import InvalidInputError

CFG = load_config()


def test_scenarios_are_reproducible_and_independent_of_anything_else():
    a = draw_scenario(7, seed=3, params=ScenarioParams.defaults(), config=CFG)
    b = draw_scenario(7, seed=3, params=ScenarioParams.defaults(), config=CFG)
    c = draw_scenario(8, seed=3, params=ScenarioParams.defaults(), config=CFG)
    assert np.array_equal(a.start, b.start) and a.pad.yaw == b.pad.yaw and a.noise_seed == b.noise_seed
    assert not np.array_equal(a.start, c.start)


def test_scenarios_respect_their_ranges_and_keep_pad_edges_off_the_image_axes():
    p = ScenarioParams.defaults()
    for i in range(200):
        sc = draw_scenario(i, seed=0, params=p, config=CFG)
        assert np.all(np.abs(sc.pad.position[:2]) <= p.pad_region)
        assert p.start_distance[0] - 1e-9 <= sc.start_distance <= p.start_distance[1] + 1e-9
        speed = float(np.linalg.norm(sc.start[3:6]))
        assert p.transit_speed[0] - 1e-9 <= speed <= p.transit_speed[1] + 1e-9
        assert (
            np.all(np.abs(sc.start[:2]) <= 3.0)
            and np.linalg.norm(sc.search_point[:2] - sc.pad.position[:2]) <= 0.3
        )
        assert float(alignment_deg(sc.yaw, sc.pad.yaw)) >= p.aligned_margin_deg - 1e-9


def test_stopping_reference_is_smooth_and_stops():
    from case_studies.quad_landing.sim.lqr import Reference

    ref = stopping_reference(Reference((0.0, 0.0, 1.0), (1.5, 0.0, 0.0)), 0.0, 1.5)
    t = np.linspace(0, 3, 301)
    v = np.array([ref(s).velocity[0] for s in t])
    a = np.array([ref(s).acceleration[0] for s in t])
    assert v[0] == pytest.approx(1.5) and v[-1] == 0.0
    assert np.all(np.diff(v) <= 1e-12) and a.min() >= -1.5 - 1e-9 and abs(a[0]) < 1e-9
    with pytest.raises(InvalidInputError, match="deceleration"):
        stopping_reference(Reference((0.0, 0.0, 1.0)), 0.0, 0.0)
