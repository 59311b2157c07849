"""benchmarks/bench_runs.py: the validity study of the claims about runs, its record and its page.

The record (``benchmarks/runs_results.json``) is what ``python -m benchmarks.bench_runs`` measured
(500 calibrations per setting and size); these tests check that the page shows it, that it says
what the issue asked (every claim called valid is false in at most delta of the calibrations, the
row-level claim fails where the rows are correlated, the run monitor keeps its false-alarm bound,
200 runs put the expected-share scale within 1.15x the oracle), and run the benchmark's code on a
few draws.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from benchmarks.bench_runs import CASES, DELTA, OUT, PAGE, _Truth, page_blocks, paste, scores_of
from benchmarks.run_logs import SETTINGS, make_run_log

RUN_CLAIMS = ("expected share", "share of runs", "trajectory")


@pytest.fixture(scope="module")
def record():
    return json.loads(OUT.read_text())


def test_the_page_shows_the_record(record):
    text = PAGE.read_text(encoding="utf-8")
    assert paste(text, record) == text, "rerun python -m benchmarks.bench_runs (or paste the record)"
    for block in page_blocks(record).values():
        assert block in text


def test_every_claim_about_runs_is_valid_and_the_row_claim_fails_on_correlated_rows(record):
    assert record["draws"] >= 500 and record["delta"] == DELTA
    for name, entry in record["settings"].items():
        for case, claims in entry["cases"].items():
            for claim in RUN_CLAIMS:
                rec = claims[claim]
                assert rec["calibrations"] + rec["refused"] == record["draws"]
                assert rec["valid"], f"{name}, {case}, {claim}: {rec['false']}/{rec['calibrations']} false"
                lo, hi = rec["false_interval_99"]
                assert lo <= rec["false"] / rec["calibrations"] <= hi
            if name != "independent":
                assert claims["row PAC"]["valid"] is False, f"{name}, {case}: the row claim did not fail"
    # where the rows are independent given the state the row-level claim is valid too
    assert all(c["row PAC"]["valid"] for c in record["settings"]["independent"]["cases"].values())


def test_two_hundred_runs_are_within_fifteen_percent_of_the_oracle_and_twenty_certify_0_227(record):
    for name, entry in record["settings"].items():
        share = entry["cases"]["200 runs"]["expected share"]
        assert share["target"] == 0.1 and share["scale_over_oracle_median"] <= 1.15, name
        twenty = entry["cases"]["20 runs"]["expected share"]
        assert twenty["target"] == pytest.approx(0.227) and twenty["refused"] == 0, name
    curve = record["floor_curve"]
    i = curve["runs"].index(20)
    assert curve["expected share"][i] <= 1.1 * curve["floor"][i] <= 0.227


def test_the_run_monitor_keeps_its_false_alarm_bound_where_the_row_monitor_does_not(record):
    for name, entry in record["settings"].items():
        m = entry["monitor"]
        assert m["run_monitor_valid"], name
        assert m["false_alarms"]["runs"]["interval_99"][0] <= DELTA, name
        if name != "independent":
            assert m["false_alarms"]["rows"]["interval_99"][0] > DELTA, (
                f"{name}: the row monitor did not fail"
            )
        assert m["detected_within_40_runs"] > 0.5, name


def test_the_generator_and_the_truth_are_what_the_benchmark_says():
    log = make_run_log(50, 200, SETTINGS[3], seed=1)
    assert len(log) == 10_000 and np.isfinite(scores_of(log)).all()
    again = make_run_log(50, 200, SETTINGS[3], seed=1)
    assert np.array_equal(log.yhat, again.yhat) and np.array_equal(log.extra["run"], again.extra["run"])
    truth = _Truth(SETTINGS[3], CASES[0][1], seed=3)
    t = truth.oracle("expected share", 0.1)
    assert truth.rate("expected share", t) == pytest.approx(0.1, abs=1e-9)  # exact
    assert truth.rate("trajectory", truth.oracle("trajectory", 0.2)) == pytest.approx(0.2, abs=0.001)
    # with independent rows the scores are i.i.d.: the exact rate is what fresh rows show (4 sd)
    independent = _Truth(SETTINGS[0], CASES[0][1], seed=5)
    t = independent.oracle("row PAC", 0.1)
    scores = scores_of(make_run_log(2000, 200, SETTINGS[0], seed=6))
    assert abs(float((scores > t).mean()) - 0.1) <= 4 * (0.1 * 0.9 / scores.size) ** 0.5


def test_the_benchmark_code_runs_on_a_few_draws(tmp_path):
    from benchmarks import bench_runs

    got = bench_runs._calibrations(SETTINGS[1], CASES[0], draws=5)
    assert set(got) >= {"row PAC", *RUN_CLAIMS} and got["expected share"]["calibrations"] == 5
    assert Path(bench_runs.FIGURES["floor"]).name == "runs_floor.png"
