"""Approach flights: the same flights at every buffer size, argument checks."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing import Flight
from case_studies.quad_landing.data.approach import ApproachParams, collect_approach, fly_approach
from ipcverify.errors import InvalidInputError


def test_approach_flights_are_the_same_at_every_buffer_size():
    params = ApproachParams.defaults(hover_points=1, dwell=(0.2, 0.2))
    a = fly_approach(Flight(buffer_size=1), 2, seed=5, params=params)
    b = fly_approach(Flight(buffer_size=3), 2, seed=5, params=params)
    n = min(len(a.rows), len(b.rows))
    assert n > 10
    # same states and truths (columns 0..14 = x_C, y_C); the perceived position differs
    np.testing.assert_allclose(a.rows[:n, :15], b.rows[:n, :15])
    assert not np.allclose(a.rows[:n, 15:18], b.rows[:n, 15:18])


def test_collect_approach_checks_its_arguments():
    with pytest.raises(InvalidInputError, match="positive integer"):
        collect_approach(0, buffer_size=1, seed=0, params=ApproachParams.defaults())
    with pytest.raises(InvalidInputError, match="non-negative"):
        collect_approach(5, buffer_size=1, seed=-1, params=ApproachParams.defaults())
