"""Grouped (flight-level) calibration: statistical guarantees on correlated flights, records, refusals.

Synthetic flights: flight ``g`` has its own bias ``b_g ~ N(0, SB^2)`` (wind, a miscalibrated
sensor) shared by all its samples, plus per-sample noise ``e ~ N(0, SE^2)``, and
``L_g ~ Uniform{10, ..., 40}`` samples. The set rule is fixed (an interval of half-width
``s`` around ``yhat``), so the score of a sample is ``|b_g + e|`` and no training is needed.
The true violation probabilities of a threshold ``t`` are known:

* per sample (a random sample of a new flight): ``P(|N(0, SB^2 + SE^2)| > t)``, exactly;
* per flight (any of its samples outside): ``1 - E[F_b(t)^L]`` with
  ``F_b(t) = P(|b + e| <= t | b)``, by Gauss--Hermite quadrature over ``b`` (120 nodes; it
  agrees with a 400,000-flight Monte Carlo to 1e-3).

Every p-value of this file is compared with ``LEVEL = ALPHA / N_CHECKS`` (Bonferroni), so
the family-wise chance that a correct implementation fails is at most ``ALPHA``. The power
checks show that row-level calibration under-covers on the same flights (and does not when
the flights are uncorrelated), and that the risk-control check catches a plug-in without
the ``+1``. Proofs: proofs/group_calibration.md.
"""

from __future__ import annotations

import json
import math
from fractions import Fraction

import numpy as np
import pytest
from scipy import stats

from ipcverify.calibration._bounds import min_calibration_size, smallest_epsilon
from ipcverify.calibration._group_counts import group_violation_counts
from ipcverify.calibration._group_fit import runs_needed, smallest_run_rate
from ipcverify.calibration._grouped import GroupedCalibration
from ipcverify.calibration._kinds import calibration_from_dict
from ipcverify.calibration._protocol import CalibrationSummary
from ipcverify.calibration._risk_control import risk_control_threshold
from ipcverify.calibration._threshold import threshold_scores
from ipcverify.errors import DataError, InvalidInputError, SampleSizeError

SB, SE = 1.0, 0.5
S_TOTAL = math.hypot(SB, SE)
LENGTHS = np.arange(10, 41)
_NODES, _W = np.polynomial.hermite_e.hermegauss(120)
_W = _W / _W.sum()

ALPHA = 1e-3
PAC_CASES = [(150, 0.05, 0.1), (300, 0.02, 0.2)]  # (groups, epsilon, delta)
MARGINAL_CASES = [(100, 0.1), (300, 0.05)]  # (groups, epsilon)
# 2 per PAC case and guarantee, 3 per marginal trajectory case, 2 per risk-control case, 5 power checks
N_CHECKS = 2 * 2 * len(PAC_CASES) + 3 * len(MARGINAL_CASES) + 2 * len(MARGINAL_CASES) + 5
LEVEL = ALPHA / N_CHECKS
R_PAC = 2000
R_MARGINAL = 1000


def _flights(rng: np.random.Generator, G: int, sb: float = SB) -> tuple[np.ndarray, np.ndarray]:
    """Scores and flight labels of ``G`` correlated flights."""
    lengths = rng.choice(LENGTHS, size=G)
    runs = np.repeat(np.arange(G), lengths)
    bias = rng.normal(0.0, sb, size=G)[runs] if sb > 0 else 0.0
    return np.abs(bias + rng.normal(0.0, SE, size=runs.size)), runs


def _sample_violation(t: np.ndarray, sb: float = SB) -> np.ndarray:
    """P(a random sample of a new flight has score > t), exactly."""
    return 2.0 * stats.norm.sf(np.asarray(t) / math.hypot(sb, SE))


#: The within-run share of the share-of-runs claim tested here (its gamma is each case's epsilon).
SHARE = 0.2


def _runs_over(t: np.ndarray, share: float = SHARE) -> np.ndarray:
    """P(a new flight has more than ``share`` of its samples with score > t), by quadrature over its bias."""
    t = np.asarray(t, dtype=float)[:, None]
    b = SB * _NODES[None, :]
    outside = 1.0 - (stats.norm.cdf((t - b) / SE) - stats.norm.cdf((-t - b) / SE))  # (T, nodes)
    over = [stats.binom.sf(int(Fraction(share) * int(n)), int(n), outside) @ _W for n in LENGTHS]
    return np.mean(over, axis=0)


def _flight_violation(t: np.ndarray) -> np.ndarray:
    """P(a new flight has some sample with score > t), by quadrature over the flight's bias."""
    t = np.asarray(t, dtype=float)[:, None]
    b = SB * _NODES[None, :]
    inside = stats.norm.cdf((t - b) / SE) - stats.norm.cdf((-t - b) / SE)  # (T, nodes)
    all_in = np.mean([(inside**n) @ _W for n in LENGTHS], axis=0)
    return 1.0 - all_in


def _fit(scores, runs, eps, delta, mode, guarantee, seed=0, gamma=None):
    return GroupedCalibration.fit(
        scores,
        runs,
        eps,
        delta,
        mode,
        guarantee=guarantee,
        column="run",
        gamma=gamma,
        seed=seed,
        data_hash="d",
        network_hash="h",
    )


# ---------------------------------------------------------------------------------------------
# (a) the guarantees hold at the claimed level


def _pac_draws(G, eps, delta, guarantee, seed, sb=SB):
    """Per draw: the grouped order statistic, its k, and the row-level PAC threshold on all rows.

    ``"share-of-runs"`` is calibrated with the within-run share :data:`SHARE` and gamma = ``eps``.
    """
    rng = np.random.default_rng(seed)
    stat, scale, row_t = np.empty(R_PAC), np.empty(R_PAC), np.empty(R_PAC)
    ks = set()
    for r in range(R_PAC):
        s, runs = _flights(rng, G, sb)
        if guarantee == "share-of-runs":
            cal = _fit(s, runs, SHARE, delta, "pac", guarantee, seed=r, gamma=eps)
        else:
            cal = _fit(s, runs, eps, delta, "pac", guarantee, seed=r)
        stat[r], scale[r] = cal.order_statistic, cal.scale
        ks.add(cal.k_groups)
        row_t[r] = threshold_scores(s, eps, delta, "pac").order_statistic
    (k,) = ks
    return stat, scale, k, row_t


@pytest.mark.parametrize("guarantee", ["trajectory", "share-of-runs"])
@pytest.mark.parametrize(("G", "eps", "delta"), PAC_CASES)
def test_pac_grouped_fraction_of_bad_calibrations_is_at_most_delta(G, eps, delta, guarantee):
    stat, scale, k, _ = _pac_draws(G, eps, delta, guarantee, seed=3000 + G + len(guarantee))
    truth = _flight_violation if guarantee == "trajectory" else _runs_over
    fail_stat = int((truth(stat) > eps).sum())
    fail_scale = int((truth(scale) > eps).sum())
    assert fail_scale <= fail_stat
    # the group statistics (maxima, or each flight's within-flight quantile) are i.i.d. and continuous,
    # so a draw is bad with probability exactly q = P(Binomial(G, eps) <= G - k) <= delta
    q = stats.binom.cdf(G - k, G, eps)
    assert q <= delta
    assert stats.binom.sf(fail_stat - 1, R_PAC, delta) >= LEVEL, (
        f"{fail_stat}/{R_PAC} bad draws, delta={delta}"
    )
    assert stats.binomtest(fail_stat, R_PAC, q).pvalue >= LEVEL, f"{fail_stat}/{R_PAC} bad draws, q={q:.4f}"


def _marginal_pvalues(coverage, G, eps):
    p_low = stats.ttest_1samp(coverage, 1 - eps, alternative="less").pvalue
    p_high = stats.ttest_1samp(coverage, 1 - eps + 1 / (G + 1), alternative="greater").pvalue
    return float(p_low), float(p_high)


@pytest.mark.parametrize(("G", "eps"), MARGINAL_CASES)
def test_marginal_trajectory_coverage_within_conformal_limits(G, eps):
    rng = np.random.default_rng(4000 + G)
    stat = np.empty(R_MARGINAL)
    for r in range(R_MARGINAL):
        s, runs = _flights(rng, G)
        cal = _fit(s, runs, eps, 0.5, "marginal", "trajectory")
        stat[r], k = cal.order_statistic, cal.k_groups
    cover = 1.0 - _flight_violation(stat)  # probability that a new flight stays inside throughout
    p_low, p_high = _marginal_pvalues(cover, G, eps)
    assert p_low >= LEVEL, f"mean flight coverage {cover.mean():.4f} below 1 - eps"
    assert p_high >= LEVEL, f"mean flight coverage {cover.mean():.4f} above 1 - eps + 1/(G+1)"
    # the maxima are i.i.d. and continuous: the coverage of the k-th is exactly Beta(k, G - k + 1)
    assert stats.kstest(cover, stats.beta(k, G - k + 1).cdf).pvalue >= LEVEL


def _crc_risks(G, eps, seed, plug_in=False):
    rng = np.random.default_rng(seed)
    risk = np.empty(R_MARGINAL)
    for r in range(R_MARGINAL):
        s, runs = _flights(rng, G)
        if plug_in:  # a wrong method: the empirical mean risk <= eps, without risk control's +1
            t = _empirical_risk_threshold(s, runs, eps)
        else:
            t = _fit(s, runs, eps, 0.5, "marginal", "expected-share").order_statistic
        risk[r] = _sample_violation(t)
    return risk


def _empirical_risk_threshold(s, runs, eps):
    sizes = np.bincount(runs)
    order = np.argsort(s)
    mean_risk = (len(sizes) - np.cumsum(1.0 / sizes[runs[order]])) / len(sizes)
    return s[order][np.flatnonzero(mean_risk <= eps)[0]]


@pytest.mark.parametrize(("G", "eps"), MARGINAL_CASES)
def test_risk_control_expected_violation_fraction_is_at_most_epsilon(G, eps):
    risk = _crc_risks(G, eps, seed=5000 + G)
    upper = stats.ttest_1samp(risk, eps, alternative="greater").pvalue
    assert upper >= LEVEL, f"mean per-sample violation {risk.mean():.5f} significantly above eps={eps}"
    # and not vacuous: E[V_new] >= eps - (2 + 1/min length) / (G + 1) (proofs/group_calibration.md)
    floor = eps - (2 + 1 / LENGTHS.min()) / (G + 1)
    lower = stats.ttest_1samp(risk, floor, alternative="less").pvalue
    assert lower >= LEVEL, f"mean per-sample violation {risk.mean():.5f} significantly below {floor:.5f}"


# ---------------------------------------------------------------------------------------------
# (b) power: the checks catch wrong methods, and row-level calibration under-covers correlated flights


def test_row_level_pac_under_covers_correlated_flights():
    G, eps, delta = PAC_CASES[0]
    _, _, _, row_t = _pac_draws(G, eps, delta, "trajectory", seed=77)
    fails = int((_sample_violation(row_t) > eps).sum())
    # a row-level PAC calibration claims at most delta bad draws; on correlated flights it has far more
    assert stats.binom.sf(fails - 1, R_PAC, delta) < LEVEL, f"only {fails}/{R_PAC} bad draws"
    assert fails > 2 * delta * R_PAC


def test_row_level_pac_is_valid_when_flights_are_uncorrelated():
    """Control for the power check: without a shared bias the same row-level calibration is valid."""
    G, eps, delta = PAC_CASES[0]
    _, _, _, row_t = _pac_draws(G, eps, delta, "trajectory", seed=78, sb=0.0)
    fails = int((_sample_violation(row_t, sb=0.0) > eps).sum())
    assert stats.binom.sf(fails - 1, R_PAC, delta) >= LEVEL, f"{fails}/{R_PAC} bad draws"


def test_row_level_marginal_exceeds_its_allowed_rate_on_correlated_flights():
    """A global marginal calibration allows its Beta(n - k + 1, k) quantile; correlated rows break it."""
    G, eps, delta = 100, 0.1, 0.05
    rng = np.random.default_rng(79)
    over = 0
    for _ in range(R_MARGINAL):
        s, _ = _flights(rng, G)
        t = threshold_scores(s, eps, delta, "marginal")
        allowed = stats.beta.ppf(1 - delta, t.n - t.k + 1, t.k)
        over += bool(_sample_violation(t.order_statistic) > allowed)
    assert stats.binom.sf(over - 1, R_MARGINAL, delta) < LEVEL, f"only {over}/{R_MARGINAL} draws above"


def test_row_level_threshold_breaks_the_trajectory_claim():
    """A row-level marginal threshold at eps lets far more than eps of the flights leave their sets."""
    G, eps = 100, 0.1
    rng = np.random.default_rng(80)
    row_t = [threshold_scores(_flights(rng, G)[0], eps, 0.5, "marginal").order_statistic for _ in range(200)]
    viol = _flight_violation(np.array(row_t))
    assert stats.ttest_1samp(viol, 2 * eps, alternative="greater").pvalue < LEVEL, f"mean {viol.mean():.3f}"


def test_risk_control_check_catches_the_plug_in_without_plus_one():
    G, eps = 30, 0.1
    risk = _crc_risks(G, eps, seed=81, plug_in=True)
    assert stats.ttest_1samp(risk, eps, alternative="greater").pvalue < LEVEL


# ---------------------------------------------------------------------------------------------
# (c) exact thresholds on toy data, records, protocol, refusals and messages


def _toy(seed=0, G=60):
    rng = np.random.default_rng(seed)
    return _flights(rng, G)


def test_trajectory_threshold_is_the_kth_group_maximum():
    s, runs = _toy()
    for mode in ("pac", "marginal"):
        cal = _fit(s, runs, 0.1, 0.1, mode, "trajectory")
        maxima = np.array([s[runs == g].max() for g in range(60)])
        ref = threshold_scores(maxima, 0.1, 0.1, mode)
        assert (cal.k_groups, cal.order_statistic, cal.scale) == (ref.k, ref.order_statistic, ref.scale)
        assert cal.n == cal.n_rows == len(s) and cal.n_inside == int((s <= cal.order_statistic).sum())


def test_a_legacy_one_sample_per_group_record_is_read_and_checked_as_before():
    """Model files written before the share bound hold ``guarantee_kind="sample"`` without a method."""
    s, runs = _toy()
    used = s[np.array([np.flatnonzero(runs == g)[0] for g in range(60)])]  # one row per flight
    t = threshold_scores(used, 0.1, 0.1, "pac")
    legacy = {
        "kind": "grouped", "column": "run", "guarantee_kind": "sample", "mode": "pac", "epsilon": 0.1,
        "delta": 0.1, "n_groups": 60, "k_groups": t.k, "order_statistic": t.order_statistic, "scale": t.scale,
        "risk": None, "n_rows": len(s), "n_used": 60, "n_inside": int((used <= t.order_statistic).sum()),
        "size_min": int(np.bincount(runs).min()), "size_median": float(np.median(np.bincount(runs))),
        "size_max": int(np.bincount(runs).max()), "seed": 1, "data_hash": "d", "network_hash": "h",
    }  # fmt: skip
    cal = calibration_from_dict(legacy)
    assert (cal.method, cal.guarantee_kind, cal.n, cal.k_groups) == (
        "one-per-group",
        "expected-share",
        60,
        t.k,
    )
    assert cal.group_claim().unit == "sample" and cal.certified_epsilon == t.certified_epsilon
    assert "one seeded random row of each group used" in cal.summary().grouping
    assert calibration_from_dict(json.loads(json.dumps(cal.to_dict()))) == cal
    with pytest.raises(InvalidInputError, match="inconsistent with method 'one-per-group'"):
        calibration_from_dict(legacy | {"n_used": len(s)})


def test_risk_control_matches_a_brute_force_reference():
    rng = np.random.default_rng(5)
    for G, eps in ((12, 0.2), (30, 0.1), (40, 0.05)):
        runs = np.repeat(np.arange(G), rng.integers(1, 7, size=G))
        s = np.round(rng.exponential(size=runs.size), 1)  # ties on purpose
        t, risk = risk_control_threshold(s, runs, eps)
        sizes = np.bincount(runs)

        def risk_sum(u, sizes=sizes, runs=runs, s=s, G=G):
            return sum(Fraction(int((s[runs == g] > u).sum()), int(sizes[g])) for g in range(G))

        ok = [u for u in np.unique(s) if risk_sum(u) + 1 <= Fraction(eps) * (G + 1)]
        assert t == ok[0] and risk == pytest.approx(float(risk_sum(t) / G), rel=1e-12)
        cal = _fit(s, runs, eps, 0.5, "marginal", "expected-share")
        assert cal.order_statistic == t and cal.risk == risk and cal.k_groups is None


@pytest.mark.parametrize("guarantee", ["trajectory", "expected-share", "share-of-runs"])
@pytest.mark.parametrize("mode", ["pac", "marginal"])
def test_record_round_trips_and_protocol(mode, guarantee):
    s, runs = _toy(seed=1, G=80)
    gamma = 0.1 if guarantee == "share-of-runs" else None
    eps = 0.2 if guarantee == "share-of-runs" else 0.1
    cal = _fit(s, runs, eps, 0.05, mode, guarantee, seed=4, gamma=gamma)
    back = calibration_from_dict(json.loads(json.dumps(cal.to_dict())))
    assert back == cal and back.to_dict() == cal.to_dict() and back.kind == "grouped"
    x, yhat = np.zeros((5, 2)), np.zeros((5, 1))
    assert np.array_equal(cal.scale_for(x, yhat), np.full(5, cal.scale))
    assert np.array_equal(cal.group_index(x, yhat), np.zeros(5, dtype=np.intp))
    (g,) = cal.groups()
    assert (g.n, g.k, g.scale) == (cal.n, cal.n_inside, cal.scale)
    summary = cal.summary()
    assert isinstance(summary, CalibrationSummary)
    d = summary.to_dict()
    assert d["kind"] == "grouped" and d["n_groups"] == 80 and d["group_column"] == "run"
    assert d["guarantee_kind"] == guarantee and d["group_size_min"] >= 10 and d["group_size_max"] <= 40
    assert d["min_groups"] == runs_needed(guarantee, mode, eps, 0.05, gamma)
    allowed = cal.allowed_violation_rate()
    if (mode, guarantee) == ("marginal", "expected-share"):
        assert allowed.rate is None and "no per-draw claim" in allowed.reason
        assert d["method"] == "risk-control"
    else:
        assert allowed.rate is not None and "test group" in allowed.reason
    if mode == "pac" and guarantee == "share-of-runs":
        assert allowed.rate == cal.certified_gamma <= gamma and cal.certified_epsilon == eps
    elif mode == "pac":
        assert allowed.rate == cal.certified_epsilon <= 0.1
    # every run-level method uses every row
    assert d["n"] == d["n_rows"] and "every row used" in d["grouping"]
    assert f"80 groups of run ({d['n_rows']:,} rows)" in d["grouping"]
    assert d["smallest_epsilon"] == cal.smallest_epsilon
    if mode == "pac":  # no PAC claim about a new run goes below the floor; a marginal one averages
        assert d["floor"] < cal.smallest_epsilon
    sentence = cal.guarantee()
    assert "80 calibration groups (by 'run')" in sentence
    assert ("i.i.d." if mode == "pac" else "exchangeable") in sentence
    assert ("at some sample" in sentence) == (guarantee == "trajectory")
    assert ("of new groups have more than 0.2" in sentence) == (guarantee == "share-of-runs")


def test_too_few_groups_names_the_minimum_and_says_rows_do_not_help():
    runs = np.repeat(np.arange(20), 500)  # the real log's 20 runs, 10,000 rows
    scores = np.random.default_rng(0).random(runs.size)
    with pytest.raises(SampleSizeError) as info:
        _fit(scores, runs, 0.01, 0.001, "pac", "trajectory")
    msg = str(info.value)
    assert "20 groups of column 'run' are too few" in msg and "at least 688 groups are needed" in msg
    assert "more rows per group do not help" in msg and "mode='marginal' (needs 99 groups)" in msg
    assert "the smallest is 0.293" in msg and "no claim about a new group goes below 0.292" in msg
    with pytest.raises(SampleSizeError, match=r"at least 99 groups .* the smallest is 0\.0477\)$"):
        _fit(scores, runs, 0.01, 0.001, "marginal", "expected-share")
    with pytest.raises(
        SampleSizeError, match=r"at least 46 groups .* epsilon \(with 20 groups the smallest is 0\.212"
    ):
        _fit(scores, runs, 0.1, 0.01, "pac", "expected-share")
    with pytest.raises(
        SampleSizeError, match=r"at least 44 groups .* gamma \(with 20 groups the smallest is 0\.206"
    ):
        _fit(scores, runs, 0.1, 0.01, "pac", "share-of-runs", gamma=0.1)
    # the suggested rate works
    for mode, guarantee in (("pac", "trajectory"), ("marginal", "trajectory"), ("pac", "expected-share")):
        smallest = smallest_run_rate(guarantee, mode, 20, 0.001)
        assert _fit(scores, runs, smallest, 0.001, mode, guarantee).n_groups == 20
    gamma = smallest_run_rate("share-of-runs", "pac", 20, 0.001)
    assert _fit(scores, runs, 0.1, 0.001, "pac", "share-of-runs", gamma=gamma).n_groups == 20


def test_smallest_epsilon_is_the_smallest_on_its_grid():
    for G, delta, mode in (
        (20, 0.001, "pac"),
        (50, 0.1, "pac"),
        (20, 0.1, "marginal"),
        (7, 0.05, "marginal"),
    ):
        e = smallest_epsilon(G, delta, mode)
        assert (
            min_calibration_size(e, delta, mode) <= G < min_calibration_size(round(e - 0.001, 3), delta, mode)
        )


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"guarantee": "row"}, InvalidInputError, "guarantee must be 'expected-share'"),
        ({"guarantee": "share-of-runs"}, InvalidInputError, "a share-of-runs claim needs gamma"),
        ({"gamma": 0.1}, InvalidInputError, "gamma goes with the share-of-runs claim only"),
        ({"mode": "bayes"}, InvalidInputError, "mode must be 'pac' or 'marginal'"),
        ({"epsilon": 1.5}, InvalidInputError, "epsilon must lie strictly between 0 and 1"),
        ({"seed": 1.5}, InvalidInputError, "seed must be an integer"),
        ({"scores": -np.ones(600)}, InvalidInputError, "finite values >= 0"),
        (
            {"groups": np.arange(5)},
            InvalidInputError,
            "600 calibration scores but 5 labels in group column 'run'",
        ),
        ({"groups": np.r_[np.nan, np.ones(599)]}, DataError, r"row 0 \(0-based\) has no group label"),
    ],
)
def test_fit_refuses_bad_input(kwargs, error, match):
    args = {
        "scores": np.ones(600),
        "groups": np.repeat(np.arange(60), 10),
        "epsilon": 0.1,
        "delta": 0.1,
        "mode": "pac",
        "guarantee": "trajectory",
    } | kwargs
    with pytest.raises(error, match=match):
        GroupedCalibration.fit(**args, column="run", data_hash="d", network_hash="h")


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("k_groups", 30, "order statistic k=30 is below"),
        ("n_groups", 5, "n_groups=5 is below the minimum"),
        ("n_inside", 0, "inconsistent with method"),
        ("size_max", 9, "group sizes disagree"),
        ("scale", -1.0, "scale must be finite"),
        ("guarantee_kind", "row", "guarantee must be"),
        ("method", "share-bound", "does not fit a pac trajectory claim"),
        ("gamma", 0.2, "gamma goes with a share-of-runs claim only"),
    ],
)
def test_inconsistent_records_are_refused(field, value, match):
    s, runs = _toy(seed=2)
    d = _fit(s, runs, 0.1, 0.1, "pac", "trajectory").to_dict() | {field: value}
    with pytest.raises(InvalidInputError, match=match):
        calibration_from_dict(d)


def test_inconsistent_risk_control_record_is_refused():
    s, runs = _toy(seed=2)
    d = _fit(s, runs, 0.1, 0.1, "marginal", "expected-share").to_dict()
    with pytest.raises(InvalidInputError, match=r"breaks \(G \* risk \+ 1\) / \(G \+ 1\) <= epsilon"):
        calibration_from_dict(d | {"risk": 0.2})
    with pytest.raises(InvalidInputError, match="needs k_groups"):
        calibration_from_dict(_fit(s, runs, 0.1, 0.1, "pac", "trajectory").to_dict() | {"risk": 0.01})
    share = _fit(s, runs, 0.2, 0.1, "pac", "expected-share").to_dict()
    with pytest.raises(InvalidInputError, match="must lie between the mean share"):
        calibration_from_dict(share | {"bound": 0.25})
    with pytest.raises(InvalidInputError, match="must lie between the mean share"):
        calibration_from_dict(share | {"bound": None})


def test_risk_control_refuses_too_few_groups():
    with pytest.raises(SampleSizeError, match=r"5 groups are too few .* at least 9 groups"):
        risk_control_threshold(np.ones(10), np.repeat(np.arange(5), 2), 0.1)


def test_group_violation_counts():
    v = np.array([0, 1, 0, 0, 0, 0, 1, 1], dtype=bool)
    runs = np.array(["a", "a", "b", "b", "c", "c", "d", "d"])
    assert group_violation_counts(v, runs, "trajectory").violations == 2
    counts = {group_violation_counts(v, runs, "sample", seed=k).violations for k in range(30)}
    assert counts == {1, 2}  # flight d always counts, flight a half the time
    assert group_violation_counts(v, runs, "sample", seed=3) == group_violation_counts(
        v, runs, "sample", seed=3
    )
    with pytest.raises(InvalidInputError, match="8 violation flags but 3 group labels"):
        group_violation_counts(v, ["a", "b", "c"], "trajectory")
    with pytest.raises(InvalidInputError, match="a group count is 'trajectory' or 'sample'"):
        group_violation_counts(v, runs, "rows")  # type: ignore[arg-type]


def test_grouped_calibration_survives_a_model_file(tmp_path):
    from ipcverify.contract._model import IPCModel, IPCNetwork
    from ipcverify.io._modelio import load_model, save_model
    from ipcverify.network._architecture import ModelConfig

    s, runs = _toy(seed=3)
    cal = _fit(s, runs, 0.2, 0.1, "pac", "expected-share", seed=9)
    model = IPCModel(
        IPCNetwork(ModelConfig(x_dim=2, y_dim=1, hidden=(4,), param="cholesky"))
    ).with_calibration(cal)
    save_model(model, tmp_path / "m.pt")
    assert load_model(tmp_path / "m.pt").calibration == cal
