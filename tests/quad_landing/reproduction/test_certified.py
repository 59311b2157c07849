"""The certified bound on unsafe landings and the closed-loop statistics."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing.landing.runs import Outcome
from case_studies.quad_landing.reproduction.certified import (
    certified_bound,
    closed_loop_violations,
    hoeffding_upper,
    unsafe_vs_certified,
)
from ipcverify.errors import InvalidInputError


def test_certified_bound_formula():
    b = certified_bound(0.002, 0.001, max_queries=8, queries_per_run=[2] * 200)
    assert b.union_bound == pytest.approx(0.016)
    ucb = 2 + 8 * np.sqrt(np.log(1000) / 400)
    assert b.mean_queries_upper == pytest.approx(ucb)
    assert b.refined_bound == pytest.approx(0.002 * ucb)
    assert b.refined_confidence == pytest.approx(0.998)
    assert certified_bound(0.2, 0.01, max_queries=8, queries_per_run=[1]).vacuous


def test_certified_bound_checks_its_inputs():
    with pytest.raises(InvalidInputError, match="strictly between"):
        certified_bound(0.0, 0.01, max_queries=3, queries_per_run=[1])
    with pytest.raises(InvalidInputError, match="positive integer"):
        certified_bound(0.01, 0.01, max_queries=0, queries_per_run=[1])
    with pytest.raises(InvalidInputError, match="within"):
        hoeffding_upper([5], 0, 3, 0.1)


def test_hoeffding_upper_covers_the_mean():
    """Coverage of the Hoeffding bound over 2000 seeded repetitions (it is conservative)."""
    rng = np.random.default_rng(0)
    delta, n, reps = 0.05, 50, 2000
    misses = sum(hoeffding_upper(rng.integers(0, 4, n), 0, 3, delta) < 1.5 for _ in range(reps))
    # misses ~ Binomial(reps, p) with p <= delta; 0.05 * 2000 = 100, a 5-sigma margin is ~49
    assert misses <= reps * delta + 5 * np.sqrt(reps * delta * (1 - delta))


def test_closed_loop_violations_and_empirical_vs_certified(baseline_runs):
    loop = closed_loop_violations(baseline_runs, 0.002)
    k = sum(1 for r in baseline_runs if r.queries[0].truth_inside is False)
    assert loop.first.n == len(baseline_runs) and loop.first.violations == k
    if k:
        assert loop.first.contradicts_epsilon  # a 0.1 mm ball misses almost always
    assert loop.every.contradicts_epsilon is None and loop.to_dict()["all"] == loop.every.to_dict()
    b = certified_bound(0.002, 0.001, max_queries=1, queries_per_run=[1] * len(baseline_runs))
    ev = unsafe_vs_certified(baseline_runs, b)
    n_unsafe = sum(r.outcome is Outcome.UNSAFE for r in baseline_runs)
    assert ev.unsafe == n_unsafe and ev.bound_at_least_rate == (0.002 >= n_unsafe / len(baseline_runs))
