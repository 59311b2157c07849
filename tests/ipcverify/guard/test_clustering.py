"""ViolationRuns: violations that come in runs, which the row-by-row monitor's alarm must mention.

Found on a real log (KITTI 00, held-out 5 s blocks of one drive): 7.9 % of the rows outside
against a certified 9.87 %, yet the row-by-row monitor alarmed at row 22, because after a
violation the next row violated 61 % of the time. The tests below plant that in seeded streams.
"""

from __future__ import annotations

import numpy as np
import pytest

from ipcverify.errors import InvalidInputError
from ipcverify.guard import ViolationMonitor
from ipcverify.guard._clustering import RUNS_LEVEL, ViolationRuns


def _sticky(n: int, rate: float, stick: float, rng: np.random.Generator) -> np.ndarray:
    """A two-state Markov chain of violations: stationary rate ``rate``, P(violation | violation) = stick."""
    enter = rate * (1 - stick) / (1 - rate)
    u = rng.random(n)
    v = np.zeros(n, dtype=bool)
    state = bool(rng.random() < rate)
    for i in range(n):
        state = bool(u[i] < (stick if state else enter))
        v[i] = state
    return v


def test_the_counts_of_a_known_sequence():
    r = ViolationRuns.of([1, 1, 0, 1, 0, 0, 1, 1, 1])
    # rows after a violation: indices 1, 2, 4, 7, 8 (the last row has no successor); 1, 7 and 8 violate
    assert (r.rows, r.violations, r.after, r.violations_after) == (9, 6, 5, 3)
    assert r.rate == pytest.approx(6 / 9) and r.rate_after == pytest.approx(3 / 5)
    empty = ViolationRuns.of([])
    assert (empty.rate, empty.rate_after, empty.p_value, empty.clustered) == (0.0, 0.0, 1.0, False)
    record = r.to_dict()
    assert record["after_violation"] == 5 and record["violations_after_violation"] == 3


def test_independent_violations_are_not_called_runs():
    """1,600 seeded i.i.d. streams: the test is at level 1e-3, so about 1.6 flags are expected."""
    rng = np.random.default_rng(0)
    flagged = sum(
        ViolationRuns.of(rng.random(1000) < p).clustered for p in (0.02, 0.05, 0.2, 0.5) for _ in range(400)
    )
    # P(Binomial(1600, 1e-3) >= 6) = 0.006: more than 5 would say the level is not held
    assert flagged <= 5
    assert RUNS_LEVEL == 1e-3


def test_sticky_violations_below_epsilon_alarm_the_row_monitor_and_are_called_runs():
    """The monitor's row-by-row null (a rate <= epsilon given the past) fails for sticky rows.

    100 seeded streams of 2,000 rows at a stationary rate of 4 % (below epsilon = 5 %), where a
    violation is followed by another 60 % of the time: the row-by-row monitor alarms in far more
    than the delta = 1 % of them its guarantee allows for rows that meet its null; every stream is
    called clustered; one observation per block of 50 rows (the share outside) never alarms.
    """
    rng = np.random.default_rng(1)
    row_alarms = block_alarms = clustered = 0
    rates = []
    for _ in range(100):
        v = _sticky(2000, 0.04, 0.6, rng)
        rates.append(v.mean())
        row_alarms += ViolationMonitor(0.05, 0.01).run(v).alarm_index is not None
        block_alarms += (
            ViolationMonitor(0.05, 0.01).run(v.reshape(-1, 50).mean(axis=1)).alarm_index is not None
        )
        clustered += ViolationRuns.of(v).clustered
    assert abs(np.mean(rates) - 0.04) < 0.005  # the marginal rate is below epsilon
    # under the null, alarms ~ Binomial(100, <= 0.01): P(>= 10) < 1e-7; the sticky rows give ~47
    assert row_alarms >= 10
    assert clustered == 100
    assert block_alarms <= 5  # P(Binomial(100, 0.01) >= 6) < 6e-4


def test_inconsistent_counts_are_refused():
    with pytest.raises(InvalidInputError, match="violations_after <= after"):
        ViolationRuns(rows=3, violations=1, after=2, violations_after=0)
    with pytest.raises(InvalidInputError, match="one flag per row"):
        ViolationRuns.of(np.zeros((2, 2)))
