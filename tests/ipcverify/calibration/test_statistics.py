"""Statistical checks of the calibration guarantees, with scores from a known law.

Scores are ``||Z||`` with ``Z ~ N(0, I_3)`` (a chi law with 3 degrees of freedom: what
``g`` is for a perfectly specified Gaussian ellipsoid), so the true coverage of a threshold
``t`` is ``F(t)`` in closed form and no test set is needed. Every check is seeded and its
tolerance comes from the statistics; the family-wise error of this file is at most
``ALPHA`` (Bonferroni over ``N_CHECKS`` p-values). Each check is also run against a
deliberately wrong calibration to show that it can fail.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from ipcverify.calibration._bounds import marginal_conformal_index, pac_calibration_index
from ipcverify.calibration._threshold import threshold_scores

LAW = stats.chi(df=3)
ALPHA = 1e-3
MARGINAL_CASES = [(100, 0.1), (500, 0.05), (1000, 0.01), (60, 0.2)]
PAC_CASES = [(200, 0.05, 0.1), (1000, 0.02, 0.05), (500, 0.1, 0.2)]
N_CHECKS = 3 * len(MARGINAL_CASES) + 2 * len(PAC_CASES)
LEVEL = ALPHA / N_CHECKS
R_MARGINAL = 1000
R_PAC = 4000


def _marginal_pvalues(coverage: np.ndarray, n: int, eps: float) -> tuple[float, float]:
    """One-sided t-tests: H0 mean < 1 - eps (p_low) and H0 mean > 1 - eps + 1/(n+1) (p_high)."""
    res_low = stats.ttest_1samp(coverage, 1 - eps, alternative="less")
    res_high = stats.ttest_1samp(coverage, 1 - eps + 1 / (n + 1), alternative="greater")
    return float(res_low.pvalue), float(res_high.pvalue)


def _draw_marginal(n: int, eps: float, seed: int, shift: int = 0) -> tuple[np.ndarray, np.ndarray, int]:
    rng = np.random.default_rng(seed)
    cover_scale, cover_stat = np.empty(R_MARGINAL), np.empty(R_MARGINAL)
    k = marginal_conformal_index(n, eps) - shift
    for r in range(R_MARGINAL):
        s = LAW.rvs(size=n, random_state=rng)
        if shift == 0:
            t = threshold_scores(s, eps, 0.5, "marginal")
            assert t.k == k
            cover_scale[r], cover_stat[r] = LAW.cdf(t.scale), LAW.cdf(t.order_statistic)
        else:  # a wrong calibration: one order statistic too low
            cover_stat[r] = cover_scale[r] = LAW.cdf(np.sort(s)[k - 1])
    return cover_scale, cover_stat, k


@pytest.mark.parametrize(("n", "eps"), MARGINAL_CASES)
def test_marginal_mean_coverage_within_conformal_limits(n, eps):
    cover, cover_stat, k = _draw_marginal(n, eps, seed=1000 + n)
    p_low, p_high = _marginal_pvalues(cover, n, eps)
    assert p_low >= LEVEL, f"mean coverage {cover.mean():.5f} significantly below 1 - eps = {1 - eps}"
    assert p_high >= LEVEL, f"mean coverage {cover.mean():.5f} significantly above 1 - eps + 1/(n+1)"
    # the unmargined order statistic's coverage is exactly Beta(k, n - k + 1)
    ks = stats.kstest(cover_stat, stats.beta(k, n - k + 1).cdf)
    assert ks.pvalue >= LEVEL


def test_marginal_check_detects_an_off_by_one_threshold():
    n, eps = 100, 0.1
    cover, _, _ = _draw_marginal(n, eps, seed=7, shift=2)
    p_low, _ = _marginal_pvalues(cover, n, eps)
    assert p_low < LEVEL


def _pac_failures(n: int, eps: float, delta: float, seed: int, k: int | None = None) -> tuple[int, int, int]:
    """Count calibration draws whose true violation rate exceeds eps (with scale and without margin)."""
    rng = np.random.default_rng(seed)
    fail_scale = fail_stat = 0
    k_used = -1
    for _ in range(R_PAC):
        s = LAW.rvs(size=n, random_state=rng)
        if k is None:
            t = threshold_scores(s, eps, delta, "pac")
            k_used, scale, stat = t.k, t.scale, t.order_statistic
        else:
            k_used = k
            scale = stat = float(np.partition(s, k - 1)[k - 1])
        fail_scale += LAW.sf(scale) > eps
        fail_stat += LAW.sf(stat) > eps
    return fail_scale, fail_stat, k_used


@pytest.mark.parametrize(("n", "eps", "delta"), PAC_CASES)
def test_pac_fraction_of_bad_calibrations_is_at_most_delta(n, eps, delta):
    fail_scale, fail_stat, k = _pac_failures(n, eps, delta, seed=2000 + n)
    assert k == pac_calibration_index(n, eps, delta)
    q = stats.binom.cdf(n - k, n, eps)  # exact probability of a bad draw for the order statistic
    assert q <= delta
    # not significantly more failures than delta allows
    assert stats.binom.sf(fail_scale - 1, R_PAC, delta) >= LEVEL
    # and the failure count agrees with the exact Beta/binomial theory
    assert stats.binomtest(fail_stat, R_PAC, q).pvalue >= LEVEL
    assert fail_scale <= fail_stat


def test_pac_check_detects_a_marginal_threshold_used_as_pac():
    n, eps, delta = 200, 0.05, 0.1
    k_wrong = marginal_conformal_index(n, eps)
    assert k_wrong < pac_calibration_index(n, eps, delta)
    fail_scale, _, _ = _pac_failures(n, eps, delta, seed=99, k=k_wrong)
    assert stats.binom.sf(fail_scale - 1, R_PAC, delta) < LEVEL
