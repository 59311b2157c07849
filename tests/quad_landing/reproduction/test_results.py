"""The reproduction's typed results: claims and the records behind summary.json."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing.landing.runs import Outcome
from case_studies.quad_landing.reproduction.certified import (
    certified_bound,
    closed_loop_violations,
    unsafe_vs_certified,
)
from case_studies.quad_landing.reproduction.table1 import table1
from ipcverify.errors import InvalidInputError


def test_claims_and_summary_records_from_real_runs(baseline_runs, make_ipc):
    """The typed results of the reproduction on a few real runs: claims, and summary.json's layout."""
    from case_studies.quad_landing.reproduction.campaign import summarize
    from case_studies.quad_landing.reproduction.claims import evaluate_claims
    from case_studies.quad_landing.reproduction.coverage import CoverageCheck, HeldOutFlags
    from case_studies.quad_landing.reproduction.experiments import ContractResults, LandingExperiment
    from ipcverify.data._dataset import PerceptionDataset

    runs = tuple(baseline_runs)
    bound = certified_bound(0.002, 0.001, max_queries=8, queries_per_run=[r.n_queries for r in runs])
    side = {
        "monte_carlo": summarize(runs),
        "runs": runs,
        "paper": summarize(runs[:3]),
        "paper_runs": runs[:3],
    }
    landing = LandingExperiment(
        buffer_size=3,
        tracking_tolerance=0.005,
        max_measurements=8,
        ipc=ContractResults(**side, certified=bound, empirical_vs_certified=unsafe_vs_certified(runs, bound)),
        baseline=ContractResults(**side),
        closed_loop=closed_loop_violations(runs, 0.002),
        coverage=CoverageCheck(
            method="knn",
            quantile=0.99,
            threshold=1.0,
            test=HeldOutFlags(5, 0.5, 0),
            null_rate=0.01,
            confidence=0.95,
            groups={},
            shift_detected=False,
        ),
    )
    x = np.zeros((20, 12))
    x[:, 2] = 1.0
    table = table1(make_ipc(True), {1: PerceptionDataset(x, np.zeros((20, 3)), np.zeros((20, 3)))})
    claims = evaluate_claims(table, landing)
    n_unsafe = sum(r.outcome is Outcome.UNSAFE for r in runs)
    assert claims["baseline_unsafe_in_most_runs"].holds == (n_unsafe > 0.5 * len(runs))
    assert claims["ipc_safe_all_paper_runs"].holds == all(r.outcome is Outcome.SAFE for r in runs[:3])
    assert claims["table1_buffer1_at_most_1pct"].holds and not claims["table1_buffer1_at_most_1pct"].supported
    assert claims["certified_bound_at_least_empirical"].holds == (bound.union_bound >= n_unsafe / len(runs))
    d = landing.to_dict()
    assert d["ipc"]["certified_unsafe_bound"] == bound.union_bound and "certified" not in d["baseline"]
    assert len(d["ipc"]["runs_detail"]) == len(runs) and len(d["ipc"]["paper_runs"]["runs_detail"]) == 3
    assert d["ipc"]["unsafe"] == n_unsafe and landing.shift_detected is False
    assert list(d["coverage"]) == ["method", "quantile", "threshold", "test", "null_rate", "confidence",
                                   "shift_detected", "groups"]  # fmt: skip
    with pytest.raises(InvalidInputError, match="count the runs"):
        ContractResults(**{**side, "runs": runs[:2]})
