"""Exact binomial machinery: definitions, exact coverage, error messages, property checks."""

from __future__ import annotations

import math
import re
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from ipcverify.calibration._bounds import (
    calibration_index,
    clopper_pearson_interval,
    clopper_pearson_lower,
    clopper_pearson_upper,
    count_text,
    marginal_conformal_index,
    min_calibration_size,
    pac_calibration_index,
    pac_epsilon,
    pac_rows_allowing,
)
from ipcverify.errors import InvalidInputError, SampleSizeError


def _upper_by_bisection(k: int, n: int, delta: float) -> float:
    """Independent reference: the p with P(Bin(n, p) <= k) = delta, by bisection on the binomial cdf."""
    lo, hi = k / n, 1.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if stats.binom.cdf(k, n, mid) > delta:
            lo = mid
        else:
            hi = mid
    return hi


@pytest.mark.parametrize(
    ("k", "n", "delta"), [(0, 10, 0.05), (3, 100, 0.001), (50, 5000, 0.001), (9, 10, 0.2)]
)
def test_clopper_pearson_upper_matches_its_definition(k, n, delta):
    u = clopper_pearson_upper(k, n, delta)
    assert u == pytest.approx(_upper_by_bisection(k, n, delta), rel=1e-7)
    # conservative side of the defining equation
    assert stats.binom.cdf(k, n, u) <= delta * (1 + 1e-6)


def test_clopper_pearson_edge_values():
    assert clopper_pearson_upper(7, 7, 0.01) == 1.0
    assert clopper_pearson_lower(0, 7, 0.01) == 0.0
    # rule of three: zero violations in n gives about 3/n at 95 %
    assert clopper_pearson_upper(0, 1000, 0.05) == pytest.approx(1 - 0.05 ** (1 / 1000), rel=1e-8)


@pytest.mark.parametrize("n", [1, 7, 30, 200])
@pytest.mark.parametrize("delta", [0.2, 0.05, 0.001])
def test_clopper_pearson_exact_coverage(n, delta):
    """P_p(p <= U(K)) >= 1 - delta for every p, computed exactly (no simulation).

    Coverage as a function of p jumps down just above each U(k); the grid holds those points.
    """
    k = np.arange(n + 1)
    ups = np.array([clopper_pearson_upper(int(i), n, delta) for i in k])
    los = np.array([clopper_pearson_lower(int(i), n, delta) for i in k])
    grid = np.unique(
        np.concatenate(
            [np.linspace(1e-6, 1 - 1e-6, 401), np.minimum(ups * (1 + 1e-9), 1.0), los * (1 - 1e-9)]
        )
    )
    grid = grid[(grid > 0) & (grid < 1)]
    pmf = stats.binom.pmf(k[None, :], n, grid[:, None])
    cover_up = (pmf * (ups[None, :] >= grid[:, None])).sum(1)
    cover_lo = (pmf * (los[None, :] <= grid[:, None])).sum(1)
    assert cover_up.min() >= 1 - delta - 1e-12
    assert cover_lo.min() >= 1 - delta - 1e-12
    lo2 = np.array([clopper_pearson_interval(int(i), n, delta)[0] for i in k])
    hi2 = np.array([clopper_pearson_interval(int(i), n, delta)[1] for i in k])
    cover_two = (pmf * ((lo2[None, :] <= grid[:, None]) & (hi2[None, :] >= grid[:, None]))).sum(1)
    assert cover_two.min() >= 1 - delta - 1e-12


def test_clopper_pearson_coverage_by_simulation():
    """Seeded simulation: the failure count is within a binomial tolerance of delta."""
    rng = np.random.default_rng(12345)
    n, p, delta, reps = 250, 0.03, 0.1, 4000
    ks = rng.binomial(n, p, size=reps)
    fails = sum(clopper_pearson_upper(int(k), n, delta) < p for k in ks)
    # P(Bin(reps, delta) >= fails) must not be tiny
    assert stats.binom.sf(fails - 1, reps, delta) > 1e-4


@settings(derandomize=True, max_examples=200, deadline=None)
@given(
    n=st.integers(1, 2000),
    frac=st.floats(0, 1),
    delta=st.floats(1e-6, 0.5),
)
def test_clopper_pearson_properties(n, frac, delta):
    k = int(round(frac * n))
    u = clopper_pearson_upper(k, n, delta)
    lo = clopper_pearson_lower(k, n, delta)
    assert lo <= k / n <= u <= 1.0
    if k < n:
        assert clopper_pearson_upper(k + 1, n, delta) >= u
        assert clopper_pearson_upper(k, n, min(0.9, 2 * delta)) <= u


@pytest.mark.parametrize(
    ("n", "eps", "delta"), [(688, 0.01, 0.001), (5000, 0.01, 0.001), (1000, 0.1, 0.05), (45, 0.1, 0.01)]
)
def test_pac_index_is_the_smallest_valid_k(n, eps, delta):
    k = pac_calibration_index(n, eps, delta)
    assert 1 <= k <= n
    assert stats.binom.cdf(n - k, n, eps) <= delta
    if k > 1:  # k - 1 would not be valid
        assert stats.binom.cdf(n - k + 1, n, eps) > delta * (1 - 1e-6)
    assert pac_epsilon(n, k, delta) <= eps


def test_pac_index_reference_value():
    # P(Bin(5000, 0.01) <= 29) <= 0.001 < P(Bin(5000, 0.01) <= 30)
    assert stats.binom.cdf(29, 5000, 0.01) <= 0.001 < stats.binom.cdf(30, 5000, 0.01)
    assert pac_calibration_index(5000, 0.01, 0.001) == 4971


@pytest.mark.parametrize(("eps", "delta"), [(0.01, 0.001), (0.05, 0.05), (0.2, 1e-6), (0.001, 0.01)])
def test_pac_minimum_sample_size(eps, delta):
    need = min_calibration_size(eps, delta, "pac")
    assert need == math.ceil(math.log(delta) / math.log1p(-eps))
    assert pac_calibration_index(need, eps, delta) == need
    with pytest.raises(SampleSizeError, match=rf"at least {need} are needed"):
        pac_calibration_index(need - 1, eps, delta)


@pytest.mark.parametrize("eps", [1e-12, 1e-15, 1e-16, 1e-300, 5e-324])
def test_an_epsilon_too_small_for_any_sample_is_a_sample_size_error_not_a_crash(eps):
    """A tiny epsilon needs about ln(1/delta) / epsilon samples: found quickly (bisection below 2**53,
    the closed form above it), quoted in the message, never a crash or a hang."""
    need = min_calibration_size(eps, 0.05, "pac")
    assert isinstance(need, int)
    assert Fraction(need) * Fraction(eps) == pytest.approx(-math.log(0.05), rel=1e-6)
    with pytest.raises(SampleSizeError, match=rf"at least {re.escape(count_text(need))} are needed"):
        pac_calibration_index(5000, eps, 0.05)
    with pytest.raises(SampleSizeError, match=r"at least \d[.\d]*(e\+\d+)? are needed"):
        marginal_conformal_index(5000, eps)


def test_counts_in_messages_are_full_up_to_15_digits_then_rounded_down():
    assert count_text(688) == "688" and count_text(10**15 - 1) == "999999999999999"
    assert count_text(10**15) == "1.0e+15"
    assert count_text(2999 * 10**297) == "2.9e+300"  # rounded down: "at least 2.9e+300" stays true


def test_marginal_index_and_minimum():
    assert marginal_conformal_index(99, 0.01) == 99
    assert marginal_conformal_index(100, 0.1) == 91  # ceil(101 * 0.9) = ceil(90.9)
    assert marginal_conformal_index(9, 0.1) == 9  # (n + 1)(1 - eps) = 9 exactly
    assert min_calibration_size(0.01, 0.5, "marginal") == 99
    with pytest.raises(SampleSizeError, match=r"at least 99 are needed"):
        marginal_conformal_index(98, 0.01)
    for n in (10, 57, 1000):
        for eps in (0.3, 0.05):
            if n >= min_calibration_size(eps, 0.5, "marginal"):
                k = marginal_conformal_index(n, eps)
                assert k / (n + 1) >= 1 - eps > (k - 1) / (n + 1)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: clopper_pearson_upper(5, 4, 0.1), r"0 <= k <= n"),
        (lambda: clopper_pearson_upper(0, 0, 0.1), r"n >= 1"),
        (lambda: clopper_pearson_upper(1, 4, 1.5), r"delta must lie strictly between 0 and 1"),
        (lambda: clopper_pearson_upper(1.5, 4, 0.1), r"integers"),
        (lambda: pac_calibration_index(100, 0.0, 0.1), r"epsilon must lie strictly between 0 and 1"),
        (lambda: pac_calibration_index(0, 0.1, 0.1), r"positive integer"),
        (lambda: marginal_conformal_index(10, float("nan")), r"epsilon"),
        (lambda: calibration_index(10, 0.1, 0.1, "bayes"), r"mode must be 'pac' or 'marginal'"),
        (lambda: min_calibration_size(0.1, 0.1, "bayes"), r"mode must be 'pac' or 'marginal'"),
        (lambda: pac_epsilon(10, 11, 0.1), r"k must be an integer in \[1, n\]"),
    ],
)
def test_bad_inputs_are_refused_with_a_message(call, match):
    with pytest.raises(InvalidInputError, match=match):
        call()


@pytest.mark.parametrize(("eps", "delta"), [(0.1, 0.01), (0.01, 0.001), (0.05, 0.1), (0.3, 1e-6)])
@pytest.mark.parametrize("outside", [0, 1, 5])
def test_pac_rows_allowing_is_the_fewest_samples_that_let_some_lie_outside(eps, delta, outside):
    n = pac_rows_allowing(outside, eps, delta)
    assert pac_calibration_index(n, eps, delta) <= n - outside
    if outside == 0:
        assert n == min_calibration_size(eps, delta)
    else:  # one sample fewer allows fewer outside (or none)
        assert pac_calibration_index(n - 1, eps, delta) > n - 1 - outside
