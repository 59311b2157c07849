"""The coverage check on real landing runs: its record, and summary.json's layout of it."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing.reproduction.coverage import coverage_check
from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.guard import DomainModel


def _queries(runs):
    qs = [(i, q) for r in runs for i, q in enumerate(r.queries) if q.detected and q.x_c is not None]
    return qs, np.array([q.x_c for _, q in qs]), np.array([q.yhat_c for _, q in qs])


def test_coverage_check_counts_every_query_and_keeps_the_layout(baseline_runs, make_ipc):
    qs, x, yhat = _queries(baseline_runs)
    assert len(qs) >= 6
    rng = np.random.default_rng(0)
    xs, ys = np.repeat(x, 10, axis=0), np.repeat(yhat, 10, axis=0)  # ten noisy copies of each query
    ref = PerceptionDataset(xs + rng.normal(0, 0.01, xs.shape), ys, ys + rng.normal(0, 0.01, ys.shape))
    model = make_ipc(True)
    with pytest.raises(InvalidInputError, match="no domain-of-validity test"):
        coverage_check(model, ref, ref, baseline_runs)
    domain = DomainModel.fit(ref.x, ref.yhat, flag_rate=0.1, k=2)
    model = model.with_calibration(model.calibration, domain)
    check = coverage_check(model, ref, ref, baseline_runs, delta=0.05)
    d_queries = domain.distance(x, yhat)
    first = np.array([i == 0 for i, _ in qs])
    assert check.groups["all"].n == len(qs) and check.groups["first"].n == int(first.sum())
    assert check.groups["all"].exceed == int((d_queries > domain.threshold).sum())
    lo, hi = check.groups["all"].interval
    assert lo <= check.groups["all"].rate <= hi and check.groups["all"].lower <= check.groups["all"].rate
    assert check.shift_detected == any(g.lower > domain.flag_rate for g in check.groups.values())
    assert sorted(check.distances["queries"]) == sorted(d_queries.tolist())
    full, kept = check.to_dict(), check.to_dict(distances=False)
    assert list(full) == ["method", "quantile", "threshold", "test", "null_rate", "confidence", "groups",
                          "shift_detected", "distances", "feature_range"]  # fmt: skip
    assert list(kept) == [k for k in full if k != "distances"]
    assert full["groups"]["all"]["interval"] == [lo, hi] and full["test"]["n"] == len(ref)
    # no queries: no groups, no shift verdict
    empty = coverage_check(model, ref, ref, []).to_dict()
    assert empty["groups"] == {} and empty["shift_detected"] is None and "distances" not in empty
