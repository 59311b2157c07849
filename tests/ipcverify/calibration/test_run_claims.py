"""Run-level claims that use every row: the share bounds, the expected-share threshold, the floor.

Proofs: proofs/run_claims.md. Every p-value here is compared with ``LEVEL = ALPHA / N_CHECKS``
(Bonferroni), so the family-wise chance that a correct implementation fails is at most ``ALPHA``.
The shares of the bound tests come from fixed laws on ``[0, 1]`` whose means are known exactly:
a Bernoulli (the worst case of a bounded variable), a Beta, a point mass mixed with a Beta, and
a spike at 1 (a run entirely outside) mixed with small shares.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from ipcverify.calibration._grouped import GroupedCalibration
from ipcverify.calibration._run_fit import expected_share_threshold, run_quantiles, run_shares
from ipcverify.calibration._share_bound import (
    FLOOR_WEIGHT,
    run_floor,
    runs_for_share,
    share_lower_bound,
    share_rejects,
    share_upper_bound,
    smallest_share_epsilon,
)
from ipcverify.errors import InvalidInputError, SampleSizeError

ALPHA = 1e-3
N_CHECKS = 2 * 4 + 2
LEVEL = ALPHA / N_CHECKS
R = 1000


def _laws():
    """(name, sampler(rng, size), exact mean) of the share laws tested."""
    return [
        ("bernoulli", lambda rng, n: (rng.random(n) < 0.15).astype(float), 0.15),
        ("beta", lambda rng, n: rng.beta(2.0, 18.0, n), 0.1),
        ("zero-or-beta", lambda rng, n: np.where(rng.random(n) < 0.5, 0.0, rng.beta(1.0, 4.0, n)), 0.1),
        ("spike-at-one", lambda rng, n: np.where(rng.random(n) < 0.05, 1.0, rng.beta(1.0, 19.0, n)), 0.0975),
    ]


@pytest.mark.slow
@pytest.mark.parametrize(("name", "draw", "mean"), _laws(), ids=[law[0] for law in _laws()])
def test_share_bounds_cover_the_mean_at_their_level(name, draw, mean):
    rng = np.random.default_rng(sum(map(ord, name)))
    delta, n = 0.05, 40
    above = below = 0
    for _ in range(R):
        x = draw(rng, n)
        above += share_upper_bound(x, delta) < mean
        below += share_lower_bound(x, delta) > mean
    # each bound misses the mean with probability at most delta
    assert stats.binom.sf(above - 1, R, delta) >= LEVEL, f"upper bound below the mean in {above}/{R}"
    assert stats.binom.sf(below - 1, R, delta) >= LEVEL, f"lower bound above the mean in {below}/{R}"


def test_bounds_bracket_the_sample_mean_and_are_monotone():
    rng = np.random.default_rng(0)
    x = rng.beta(2, 10, 50)
    lo, hi = share_lower_bound(x, 0.05), share_upper_bound(x, 0.05)
    assert 0 < lo < x.mean() < hi < 1
    assert share_upper_bound(x, 0.01) > hi and share_lower_bound(x, 0.01) < lo  # more confidence, wider
    assert share_upper_bound(np.minimum(x + 0.05, 1), 0.05) > hi  # larger shares, larger bound
    # the upper bound is where the test starts to reject
    assert share_rejects(x, hi, 0.05) and not share_rejects(x, hi - 1e-6, 0.05)
    assert share_upper_bound(np.ones(5), 0.05) == 1.0 and share_lower_bound(np.zeros(5), 0.05) == 0.0


@pytest.mark.parametrize(("G", "delta"), [(4, 0.01), (20, 0.01), (20, 0.1), (44, 0.01), (200, 0.001)])
def test_no_violation_reaches_near_the_floor(G, delta):
    floor = run_floor(G, delta)
    smallest = smallest_share_epsilon(G, delta)
    assert floor < smallest <= 1.0 - (FLOOR_WEIGHT * delta) ** (1.0 / G)
    assert smallest <= floor * (1.0 + math.log(1.0 / FLOOR_WEIGHT) / math.log(1.0 / delta))
    assert share_rejects(np.zeros(G), smallest, delta) and not share_rejects(np.zeros(G), floor, delta)
    assert runs_for_share(smallest, delta) <= G


def test_twenty_runs_certify_within_ten_percent_of_the_floor():
    """Issue acceptance: from 20 runs at delta 0.01 the smallest certifiable share is <= 1.1 x the floor."""
    floor = run_floor(20, 0.01)
    assert round(floor, 4) == 0.2057 and smallest_share_epsilon(20, 0.01) <= 1.1 * floor <= 0.227
    runs = np.repeat(np.arange(20), 50)
    scores = np.random.default_rng(1).exponential(size=runs.size)
    cal = GroupedCalibration.fit(scores, runs, 0.227, 0.01, guarantee="expected-share", column="run",
                                 data_hash="d", network_hash="h")  # fmt: skip
    assert cal.method == "share-bound" and cal.bound <= 0.227 and cal.order_statistic < scores.max()


def test_expected_share_threshold_matches_a_brute_force_scan():
    rng = np.random.default_rng(3)
    for G, eps, delta in ((50, 0.2, 0.05), (120, 0.1, 0.01), (80, 0.3, 0.1)):
        codes = np.repeat(np.arange(G), rng.integers(1, 30, size=G))
        scores = np.round(rng.exponential(size=codes.size) * rng.uniform(0.5, 2.0, G)[codes], 2)  # ties
        fit = expected_share_threshold(scores, codes, G, eps, delta)
        last = None
        for t in np.unique(scores)[::-1]:
            if not share_rejects(run_shares(scores, codes, G, t), eps, delta):
                break
            last = t
        assert fit.threshold == last
        shares = run_shares(scores, codes, G, last)
        assert fit.mean_share == pytest.approx(shares.mean()) and fit.upper_bound <= eps


def test_expected_share_threshold_refuses_when_even_the_largest_score_fails():
    codes = np.repeat(np.arange(10), 5)
    fit = expected_share_threshold(np.arange(50.0), codes, 10, 0.1, 0.01)
    assert fit.threshold is None
    with pytest.raises(SampleSizeError, match="at least 46 groups are needed"):
        GroupedCalibration.fit(np.arange(50.0), codes, 0.1, 0.01, guarantee="expected-share", column="run",
                               data_hash="d", network_hash="h")  # fmt: skip


def test_run_quantiles_leave_at_most_epsilon_of_each_run_outside():
    rng = np.random.default_rng(4)
    codes = np.repeat(np.arange(30), rng.integers(1, 40, size=30))
    scores = rng.random(codes.size)
    for eps in (0.05, 0.1, 0.29, 0.5):
        q = run_quantiles(scores, codes, 30, eps)
        for g in range(30):
            s = np.sort(scores[codes == g])
            allowed = math.floor(eps * len(s) + 1e-12)
            assert (s > q[g]).sum() <= allowed
            assert (s >= q[g]).sum() > allowed  # one step lower would leave more out


def _runs(rng, G, L, rho, cond):
    """Scores of ``G`` runs of ``L`` rows: AR(1) errors in 3-D (coefficient ``rho``) scaled per run."""
    z = rng.normal(size=(G, L, 3))
    for i in range(1, L):
        z[:, i] = rho * z[:, i - 1] + math.sqrt(1 - rho**2) * z[:, i]
    scale = np.exp(cond * rng.normal(size=G))[:, None]
    return (scale * np.sqrt((z**2).sum(axis=2))).ravel(), np.repeat(np.arange(G), L)


def _oracle(rng, eps, rho, cond):
    """The threshold at which a new run's expected share outside is exactly eps (large Monte Carlo)."""
    scores, _ = _runs(rng, 20000, 50, rho, cond)
    return float(np.quantile(scores, 1 - eps))  # equal run lengths: the expected share is the row share


@pytest.mark.slow
@pytest.mark.parametrize(("rho", "cond"), [(0.0, 0.0), (0.9, 0.0), (0.9, 0.15)])
def test_expected_share_is_valid_and_near_the_oracle_with_many_runs(rho, cond):
    """PAC validity on autocorrelated runs with per-run conditions, and 200 runs within 1.15x the oracle."""
    rng = np.random.default_rng(int(100 * rho + 1000 * cond))
    eps, delta = 0.1, 0.05
    oracle = _oracle(rng, eps, rho, cond)
    big = np.sort(_runs(rng, 20000, 50, rho, cond)[0])
    ratios, bad = [], 0
    for _ in range(200):
        scores, codes = _runs(rng, 200, 50, rho, cond)
        t = expected_share_threshold(scores, codes, 200, eps, delta).threshold
        ratios.append(t / oracle)
        bad += 1.0 - np.searchsorted(big, t, side="right") / big.size > eps
    assert stats.binom.sf(bad - 1, 200, delta) >= LEVEL, f"{bad}/200 calibrations false"
    assert np.median(ratios) <= 1.15, f"median scale {np.median(ratios):.3f} x the oracle"


def test_bound_inputs_are_checked():
    with pytest.raises(InvalidInputError, match=r"shares must be finite numbers in \[0, 1\]"):
        share_upper_bound([0.2, 1.5], 0.05)
    with pytest.raises(InvalidInputError, match="need at least one value"):
        share_lower_bound([], 0.05)
    with pytest.raises(InvalidInputError, match="delta must lie strictly between 0 and 1"):
        share_upper_bound([0.1], 1.0)
    with pytest.raises(InvalidInputError, match="number of runs must be a positive integer"):
        run_floor(0, 0.1)
    with pytest.raises(InvalidInputError, match="epsilon must lie strictly between 0 and 1"):
        runs_for_share(0.0, 0.1)
