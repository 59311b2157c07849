"""The online violation monitor: false alarms at most delta, power after a planted shift, edge cases.

False alarms: under H0 (violation rate at most epsilon given the past) a monitor alarms with
probability at most delta over the whole stream (Ville). Over ``R_NULL`` seeded streams per
case the number of alarms is tested one-sided against Binomial(R_NULL, delta); the file's
p-values are Bonferroni-corrected (``LEVEL = ALPHA / N_CHECKS``). A fixed-sample z-test
repeated at every step (peeking) fails the same check, so the check can fail.

Power: after a planted shift (the rate jumps from epsilon to 3 epsilon, or to 0.3, at
``T``) the monitor must alarm after ``T`` in at least 90 % of the streams within the
horizon, with a median delay within a stated multiple (4, or 8 for a jump to 30 epsilon) of
``log(1/delta) / KL(rate || epsilon)`` (about the delay of an oracle that knows the new rate
and the change point). Proof: proofs/monitor.md.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from ipcverify.certification._report import figure_to_png
from ipcverify.errors import InvalidInputError
from ipcverify.guard._eprocess import MAX_BET_FRACTION, BettingEProcess
from ipcverify.guard._monitor import (
    ALARM_MARGIN,
    MonitorState,
    ViolationMonitor,
    plot_monitor,
)

ALPHA = 1e-3
R_NULL = 1000
# (epsilon, delta, true rate, stream length)
NULL_CASES = [(0.05, 0.1, 0.05, 4000), (0.01, 0.05, 0.01, 10000), (0.05, 0.1, 0.025, 4000)]
# (epsilon, delta, T, horizon after T, rate after T, allowed median delay in units of the oracle's):
# 3 epsilon: the adaptive bets get close to Kelly; a jump to 30 epsilon after a long in-control stretch
# is limited by how fast the bets' rate estimates move (about 30 observations), not by the information
SHIFT_CASES = [
    (0.05, 0.01, 2000, 3000, 0.15, 4),
    (0.01, 0.01, 5000, 15000, 0.03, 4),
    (0.01, 0.01, 5000, 2000, 0.3, 8),
]
R_SHIFT = 200
# one per null case, the adapted null, the peeking power check, one pre-change check per shift case
N_CHECKS = len(NULL_CASES) + 2 + len(SHIFT_CASES)
LEVEL = ALPHA / N_CHECKS


def _alarms(streams: np.ndarray, eps: float, delta: float) -> np.ndarray:
    """Alarm index of every stream (-1 if none)."""
    out = np.empty(len(streams), dtype=int)
    for r, x in enumerate(streams):
        a = ViolationMonitor(eps, delta).run(x).final.alarm_index
        out[r] = -1 if a is None else a
    return out


@pytest.mark.parametrize(("eps", "delta", "rate", "n"), NULL_CASES)
def test_false_alarms_at_most_delta_under_the_null(eps, delta, rate, n):
    rng = np.random.default_rng(int(1e5 * eps) + n)
    alarms = int((_alarms(rng.random((R_NULL, n)) < rate, eps, delta) >= 0).sum())
    assert stats.binom.sf(alarms - 1, R_NULL, delta) >= LEVEL, (
        f"{alarms}/{R_NULL} false alarms, delta={delta}"
    )


def _adapted_null(rng: np.random.Generator, R: int, n: int, eps: float) -> np.ndarray:
    """Streams that are not i.i.d.: P(violation | past) is eps after an even number of violations, eps/4
    after an odd one, and 0 in every other block of 100 -- always at most eps given the past."""
    x = np.zeros((R, n), dtype=bool)
    count = np.zeros(R, dtype=int)
    for t in range(n):
        p = np.where(count % 2 == 0, eps, eps / 4) * ((t // 100) % 2 == 0)
        x[:, t] = rng.random(R) < p
        count += x[:, t]
    return x


def test_false_alarms_at_most_delta_for_a_non_iid_null():
    eps, delta, n = 0.05, 0.1, 4000
    alarms = int((_alarms(_adapted_null(np.random.default_rng(11), R_NULL, n, eps), eps, delta) >= 0).sum())
    assert stats.binom.sf(alarms - 1, R_NULL, delta) >= LEVEL, f"{alarms}/{R_NULL} false alarms"


def test_null_check_catches_a_peeking_fixed_sample_test():
    """A one-sided z-test of 'rate <= eps' at level delta, repeated after every observation."""
    eps, delta, n = 0.05, 0.1, 4000
    x = np.random.default_rng(12).random((R_NULL, n)) < eps
    t = np.arange(1, n + 1)
    z = (np.cumsum(x, axis=1) - t * eps) / np.sqrt(t * eps * (1 - eps))
    alarms = int((z >= stats.norm.isf(delta)).any(axis=1).sum())
    assert stats.binom.sf(alarms - 1, R_NULL, delta) < LEVEL, f"only {alarms}/{R_NULL} alarms"


def _kl(p: float, q: float) -> float:
    return p * math.log(p / q) + (1 - p) * math.log((1 - p) / (1 - q))


@pytest.mark.parametrize(("eps", "delta", "T", "H", "rate", "factor"), SHIFT_CASES)
def test_a_planted_shift_is_detected_after_it_happens(eps, delta, T, H, rate, factor):
    rng = np.random.default_rng(int(1e4 * rate) + T)
    streams = np.hstack([rng.random((R_SHIFT, T)) < eps, rng.random((R_SHIFT, H)) < rate])
    alarm = _alarms(streams, eps, delta)
    early = int(((alarm >= 0) & (alarm < T)).sum())
    detected = alarm >= T
    delays = alarm[detected] - T
    oracle = math.log(1 / delta) / _kl(rate, eps)
    # before T the stream is at the null: early alarms are false alarms
    assert stats.binom.sf(early - 1, R_SHIFT, delta) >= LEVEL, f"{early}/{R_SHIFT} alarms before the shift"
    assert detected.mean() >= 0.9, f"only {detected.mean():.0%} of the streams alarmed within {H} after T"
    assert np.median(delays) <= factor * oracle, f"median delay {np.median(delays)} vs oracle {oracle:.0f}"


# ---------------------------------------------------------------------------------------------
# exact values, bookkeeping, edge cases


def test_first_step_matches_the_formula():
    eps = 0.02
    e = BettingEProcess(eps)
    assert math.isclose(math.exp(np.logaddexp.reduce(e.log_weights)), 1.0, rel_tol=1e-12)  # weights sum to 1
    assert e.lambdas.max() * eps == MAX_BET_FRACTION and e.lambdas.min() * eps >= eps / 4
    (log_k,) = e.advance([1.0])
    # the adaptive bets start at the prior rate eps, so they bet 0 on the first observation
    expect = np.mean(1 + e.lambdas * (1 - eps)) / 3 + 2 / 3
    assert math.isclose(log_k, math.log(expect), rel_tol=1e-12)
    assert e.log_value == pytest.approx(log_k, rel=1e-12)


def test_no_violations_never_alarm_and_bets_shrink_to_zero():
    res = ViolationMonitor(0.01, 0.01).run(np.zeros(5000, dtype=bool))
    assert not res.final.alarm and (res.log_e_value <= 0).all()
    assert np.all(np.diff(res.log_e_value) <= 0)
    # the adaptive bets stay at 0 (their wealth at 1); only the constant bets lose
    e = BettingEProcess(0.01)
    n = 300
    expect = np.mean((1 - e.lambdas * 0.01) ** n) / 3 + 2 / 3
    assert e.advance(np.zeros(n))[-1] == pytest.approx(math.log(expect), rel=1e-12)


def test_batches_and_single_updates_agree():
    rng = np.random.default_rng(3)
    x = rng.random(3000) < np.r_[np.full(1500, 0.02), np.full(1500, 0.08)]
    d = rng.random(3000) < 0.9
    whole = ViolationMonitor(0.02, 0.01, domain_rate=0.2).run(x, d)
    chunked = ViolationMonitor(0.02, 0.01, domain_rate=0.2)
    paths = [chunked.run(x[a:b], d[a:b]) for a, b in ((0, 7), (7, 1000), (1000, 1000), (1000, 3000))]
    single = ViolationMonitor(0.02, 0.01, domain_rate=0.2)
    states = [single.update(bool(v), bool(i)) for v, i in zip(x[:400], d[:400], strict=True)]
    joined = np.concatenate([p.log_e_value for p in paths])
    np.testing.assert_allclose(joined, whole.log_e_value, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(
        [s.log_e_value for s in states], whole.log_e_value[:400], rtol=1e-10, atol=1e-10
    )
    assert chunked.state.alarm_index == whole.final.alarm_index is not None
    assert whole.final.alarm_index > 1500
    assert paths[-1].start_index == 1000 and paths[2].log_e_value.size == 0
    for state in (chunked.state, whole.final):
        assert state.log_e_value == pytest.approx(whole.log_e_value[-1], rel=1e-12)
        assert state.to_dict() | {"log_e_value": 0, "domain_log_e_value": 0} == whole.final.to_dict() | {
            "log_e_value": 0,
            "domain_log_e_value": 0,
        }
    assert states[-1].index == 399 and states[-1].n_in_domain == int(d[:400].sum())


def test_out_of_domain_observations_skip_the_violation_test():
    x = np.array([True, True, False, True, False])
    d = np.array([True, False, True, False, True])
    res = ViolationMonitor(0.1, 0.05).run(x, d)
    assert d.flags.writeable and not res.in_domain.flags.writeable  # the caller's array is untouched
    assert res.log_e_value[1] == res.log_e_value[0] and res.log_e_value[3] == res.log_e_value[2]
    assert (res.final.n_tested, res.final.violations, res.final.n_in_domain) == (3, 1.0, 3)
    np.testing.assert_allclose(res.in_domain_fraction, [1, 1 / 2, 2 / 3, 2 / 4, 3 / 5])
    assert res.final.violation_rate == pytest.approx(1 / 3)
    every = ViolationMonitor(0.1, 0.05, in_domain_only=False).run(x, d)
    assert every.final.n_tested == 5 and every.final.log_e_value > res.final.log_e_value


def test_the_domain_test_alarms_on_a_high_out_of_domain_rate():
    rng = np.random.default_rng(4)
    d = rng.random(2000) > 0.3  # 30 % out of domain against an allowed 10 %
    res = ViolationMonitor(0.05, 0.01, domain_rate=0.1).run(np.zeros(2000, dtype=bool), d)
    assert res.final.domain_alarm and not res.final.alarm
    assert res.final.domain_alarm_index < 300
    assert res.config.domain_delta == 0.01
    assert ViolationMonitor(0.05, 0.01).run([False]).domain_log_e_value is None


def test_fractions_are_observations_too():
    """One observation per flight: the fraction of its samples outside their sets."""
    res = ViolationMonitor(0.05, 0.01).run(np.full(400, 0.2))
    assert res.final.alarm and res.final.violations == pytest.approx(80.0)


def test_alarm_stays_and_e_value_overflows_to_inf():
    mon = ViolationMonitor(0.01, 0.01)
    first = mon.run(np.ones(400, dtype=bool))
    assert first.final.alarm_index == int(
        np.flatnonzero(first.log_e_value >= -math.log(0.01) + ALARM_MARGIN)[0]
    )
    later = mon.run(np.zeros(10, dtype=bool))
    assert later.final.alarm and later.alarm_index == first.alarm_index
    assert first.final.log_e_value > 709 and first.final.e_value == math.inf
    assert later.to_dict()["final"]["alarm_index"] == first.alarm_index


@pytest.mark.parametrize(
    ("violated", "in_domain", "match"),
    [
        ([0, 2], None, r"observation 1 \(0-based\): violated=.*2.* is not in \[0, 1\]"),
        ([0.0, float("nan")], None, r"observation 1 \(0-based\): violated=.*nan"),
        (["yes"], None, "violated must be booleans or numbers"),
        ([[0, 1]], None, r"one value per observation \(1-D\)"),
        ([0, 1], [True], r"in_domain has shape \(1,\) but violated has \(2,\)"),
        ([0, 1], [0.5, 1], "in_domain must be booleans"),
    ],
)
def test_bad_observations_are_refused(violated, in_domain, match):
    with pytest.raises(InvalidInputError, match=match):
        ViolationMonitor(0.1, 0.1).run(violated, in_domain)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"epsilon": 0.0, "delta": 0.1}, "epsilon must lie strictly between 0 and 1"),
        ({"epsilon": 0.1, "delta": 1.0}, "delta must lie strictly between 0 and 1"),
        ({"epsilon": 0.1, "delta": 0.1, "domain_delta": 0.1}, "domain_delta needs domain_rate"),
        ({"epsilon": 0.1, "delta": 0.1, "domain_rate": 2.0}, "domain_rate must lie strictly"),
        ({"epsilon": True, "delta": 0.1}, "epsilon must lie strictly"),
    ],
)
def test_bad_configuration_is_refused(kwargs, match):
    with pytest.raises(InvalidInputError, match=match):
        ViolationMonitor(**kwargs)


def test_bad_state_and_raw_observations_are_refused():
    with pytest.raises(InvalidInputError, match="an alarm needs its index"):
        MonitorState(
            index=3, log_e_value=0.0, alarm=True, alarm_index=None, violations=0, n_tested=0, n_in_domain=0,
            in_domain_fraction=None,
        )  # fmt: skip
    with pytest.raises(InvalidInputError, match=r"observations must be finite numbers in \[0, 1\]"):
        BettingEProcess(0.1).advance([1.5])


def test_plot_marks_the_level_the_alarm_and_the_change():
    rng = np.random.default_rng(5)
    x = np.r_[rng.random(500) < 0.05, rng.random(500) < 0.3]
    res = ViolationMonitor(0.05, 0.01, domain_rate=0.5).run(x, rng.random(1000) < 0.95)
    fig = plot_monitor(res, change_index=500, title="shift at 500")
    ax = fig.axes[0]
    levels = [line.get_ydata()[0] for line in ax.get_lines() if len(set(line.get_ydata())) == 1]
    assert any(math.isclose(v, -math.log(0.01)) for v in levels)
    labels = ax.get_legend_handles_labels()[1]
    assert f"alarm at {res.alarm_index}" in labels and "change at 500" in labels
    assert ax.get_title() == "shift at 500" and figure_to_png(fig)[:4] == b"\x89PNG"
