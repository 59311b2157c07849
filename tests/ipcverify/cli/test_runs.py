"""Logs of runs end to end: the claim about runs by default, plan, evaluate and certify counted by runs.

The data: runs whose estimates carry a per-run offset (so that a run's rows are correlated). The
checks are on what a user sees: which claim ``calibrate`` makes, what it prints, what ``plan``,
``evaluate`` and ``certify`` say per run, and the refusals.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from ipcverify.calibration._dependence import measure_dependence
from ipcverify.calibration._run_plan import plan_runs
from ipcverify.calibration._share_bound import run_floor, smallest_share_epsilon
from ipcverify.contract import IPCModel
from ipcverify.data import PerceptionDataset, save_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import InvalidInputError
from ipcverify.io import load_model, save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.network._modules import IPCNetwork


def _runs(n_runs: int, rows: int, seed: int, column: str = "run") -> PerceptionDataset:
    base = make_lagged_perception(n_runs * rows, seed=seed)
    offset = np.random.default_rng(seed).normal(0.0, 0.05, size=(n_runs, 3))
    run = np.repeat(np.arange(n_runs), rows)
    return PerceptionDataset(
        base.x, base.y, base.yhat + offset[run], source=f"runs {seed}", extra={column: run}
    )


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("runs")
    save_model(IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky"))), d / "m.pt")
    save_dataset(_runs(60, 20, seed=1), d / "cal.csv")
    save_dataset(_runs(30, 20, seed=2), d / "test.csv")
    save_dataset(_runs(8, 20, seed=3), d / "few.csv")
    two = _runs(60, 20, seed=4)
    two = PerceptionDataset(
        two.x, two.y, two.yhat, extra={"run": two.extra["run"], "flight": two.extra["run"] // 2}
    )
    save_dataset(two, d / "two.csv")
    return d


def test_calibrate_makes_a_claim_about_the_runs_the_data_name(files, run_cli, tmp_path):
    res = run_cli("calibrate", files / "m.pt", files / "cal.csv", "--epsilon", "0.2", "--delta", "0.05",
                  "--out", tmp_path / "c.pt")  # fmt: skip
    assert res.code == 0, res.stderr
    cal = load_model(tmp_path / "c.pt")
    assert cal.calibration.kind == "grouped" and cal.calibration.guarantee_kind == "expected-share"
    assert cal.calibration.n_groups == 60 and cal.domain.n_groups == 60  # the domain test by runs too
    assert "its rows come in runs of 'run', so the claim is about runs" in res.stderr
    assert "expected fraction of a new group's samples" in res.stdout
    assert "From 60 independent runs at delta=0.05" in res.stdout and "Within-run dependence" in res.stdout
    record = cal.metadata["calibration_runs"]
    assert (record["unit"], record["n_runs"], record["row_claim_chosen"]) == ("run", 60, False)
    assert record["plan"]["floor"] == pytest.approx(run_floor(60, 0.05))


def test_too_few_runs_are_refused_with_what_they_allow_and_the_row_claim_named(files, run_cli, tmp_path):
    res = run_cli("calibrate", files / "m.pt", files / "few.csv", "--epsilon", "0.1", "--delta", "0.01",
                  "--out", tmp_path / "c.pt")  # fmt: skip
    assert res.code == 2 and len(res.stderr.strip().splitlines()) == 1, res.stderr
    smallest = f"{smallest_share_epsilon(8, 0.01):.3f}"[:4]
    assert "8 groups of column 'run' are too few" in res.stderr and "at least 46 groups" in res.stderr
    assert f"the smallest is {smallest}" in res.stderr and "--unit row" in res.stderr
    assert not (tmp_path / "c.pt").exists()


def test_several_run_columns_ask_which(files, run_cli, tmp_path):
    res = run_cli("calibrate", files / "m.pt", files / "two.csv", "--epsilon", "0.2", "--delta", "0.05",
                  "--out", tmp_path / "c.pt")  # fmt: skip
    assert (
        res.code == 2 and "several columns could name the runs ('run' (60 groups), 'flight' (30" in res.stderr
    )
    ok = run_cli("calibrate", files / "m.pt", files / "two.csv", "--epsilon", "0.2", "--delta", "0.05",
                 "--group-column", "flight", "--out", tmp_path / "f.pt")  # fmt: skip
    assert ok.code == 0 and load_model(tmp_path / "f.pt").calibration.n_groups == 30


def test_share_of_runs_and_trajectory_from_the_command_line(files, run_cli, tmp_path):
    common = [files / "m.pt", files / "cal.csv", "--delta", "0.05", "--group-column", "run"]
    res = run_cli("calibrate", *common, "--epsilon", "0.1", "--guarantee", "share-of-runs", "--gamma", "0.2",
                  "--out", tmp_path / "s.pt")  # fmt: skip
    assert res.code == 0, res.stderr
    cal = load_model(tmp_path / "s.pt").calibration
    assert (cal.guarantee_kind, cal.gamma, cal.method) == ("share-of-runs", 0.2, "run-quantile")
    assert "of new groups have more than 0.1 of their samples" in res.stdout
    cert = run_cli("certify", tmp_path / "s.pt", "--data", files / "test.csv", "--out", tmp_path / "cert")
    assert cert.code in (0, 1), cert.stderr
    d = json.loads((tmp_path / "cert" / "certificate.json").read_text())
    assert d["group_test"]["compared_unit"] == "share-of-runs" and d["group_test"]["share_of_runs"]["n"] == 30
    assert d["summary"]["unit"] == "group" and d["summary"]["unit_statistic"] == "share-of-runs"
    bad = run_cli(
        "calibrate", *common, "--epsilon", "0.1", "--guarantee", "share-of-runs", "--out", tmp_path / "x.pt"
    )
    assert bad.code == 2 and "a share-of-runs claim needs gamma" in bad.stderr


def test_certify_checks_a_run_claim_with_the_runs_shares(files, run_cli, tmp_path):
    run_cli("calibrate", files / "m.pt", files / "cal.csv", "--epsilon", "0.2", "--delta", "0.05",
            "--out", tmp_path / "c.pt")  # fmt: skip
    res = run_cli("certify", tmp_path / "c.pt", "--data", files / "test.csv", "--out", tmp_path / "cert")
    assert res.code in (0, 1), res.stderr
    d = json.loads((tmp_path / "cert" / "certificate.json").read_text())
    test = d["test"]
    assert test["statistic"] == "mean" and test["n"] == 30 and "betting" in test["bound"]
    assert d["status"] in ("CERTIFIED", "CONTRADICTED")
    assert (d["status"] == "CONTRADICTED") == (test["lower_bound"] > 0.2)
    assert d["runs"]["unit"] == "run" and d["runs"]["n_runs"] == 60
    assert "what the runs support" in [c["check"] for c in d["summary"]["checks"]]
    assert "calibration runs (run)" in res.stdout and "mean share" in res.stdout


def test_plan_counts_the_runs_and_says_what_a_target_needs(files, run_cli):
    res = run_cli("plan", files / "cal.csv", "--delta", "0.01", "--epsilon", "0.1", "--json")
    assert res.code == 0, res.stderr
    plan = json.loads(res.stdout)
    assert plan["n_runs"] == 60 and plan["source"] == "cal.csv: 60 runs of 'run'"
    assert plan["claims"] == plan_runs(60, 0.01, epsilon=0.1).to_dict()["claims"]
    table = run_cli("plan", "--runs", "20", "--delta", "0.01", "--epsilon", "0.1")
    assert table.code == 0 and "no pac claim about a new run goes below 0.206" in table.stdout
    assert "an expected share of 0.1 needs at least 46 runs" in table.stdout
    for args, message in (
        ((files / "cal.csv", "--runs", "3", "--delta", "0.1"), "either a data file or --runs G, not both"),
        (("--delta", "0.1"), "either a data file or --runs G"),
        ((files / "two.csv", "--delta", "0.1"), "name the column of its runs with --group-column"),
        (("--runs", "0", "--delta", "0.1"), "the number of runs must be a positive integer"),
        (("--runs", "5", "--delta", "2"), "delta must lie strictly between 0 and 1"),
    ):
        bad = run_cli("plan", *args)
        assert bad.code == 2 and message in bad.stderr, bad.stderr


def test_evaluate_counts_per_run(files, run_cli):
    res = run_cli("evaluate", files / "m.pt", files / "test.csv", "--json")
    assert res.code == 0, res.stderr
    by_run = json.loads(res.stdout)["by_run"]
    assert by_run["column"] == "run" and by_run["n_runs"] == 30
    assert by_run["share"]["lower_bound"] <= by_run["mean_share"] <= by_run["share"]["upper_bound"]
    table = run_cli("evaluate", files / "m.pt", files / "test.csv")
    assert "per run of run (the unit of a claim about runs)" in table.stdout
    plain = run_cli("evaluate", files / "m.pt", files / "test.csv", "--group-column", "nope", "--json")
    assert plain.code == 2 and "no column 'nope'" in plain.stderr


def test_plan_and_dependence_refuse_bad_input():
    with pytest.raises(InvalidInputError, match="needs the number of runs, a target epsilon, or both"):
        plan_runs(None, 0.01)
    with pytest.raises(InvalidInputError, match="need one finite score per row"):
        measure_dependence([1.0, np.nan], [0, 1], 0.5, "run")
    d = measure_dependence(np.zeros(10), np.repeat([0, 1], 5), 0.5, "run")
    assert d.effective_rows is None and "cannot be measured" in d.sentence()


def test_a_log_that_names_its_runs_otherwise_is_certified_and_monitored_by_them(files, run_cli, tmp_path):
    """A contract calibrated by 'run', deployed on a log whose runs are named 'flight' (--group-column)."""
    run_cli("calibrate", files / "m.pt", files / "cal.csv", "--epsilon", "0.2", "--delta", "0.05",
            "--out", tmp_path / "c.pt")  # fmt: skip
    test = _runs(30, 20, seed=2, column="flight")
    save_dataset(test, tmp_path / "flights.csv")
    missing = run_cli(
        "certify", tmp_path / "c.pt", "--data", tmp_path / "flights.csv", "--out", tmp_path / "x"
    )
    assert (
        missing.code == 2 and "name the column of the test data's runs (--group-column COL)" in missing.stderr
    )
    named = run_cli("certify", tmp_path / "c.pt", "--data", tmp_path / "flights.csv",
                    "--group-column", "flight", "--out", tmp_path / "cert")  # fmt: skip
    assert named.code in (0, 1), named.stderr
    d = json.loads((tmp_path / "cert" / "certificate.json").read_text())
    assert d["test"]["n"] == 30 and d["group_test"]["n_groups"] == 30
    assert "runs are i.i.d." in d["assumption"]
    no_runs = run_cli("monitor", tmp_path / "c.pt", tmp_path / "flights.csv", "--out", tmp_path / "m0")
    assert no_runs.code == 2 and "name the column of the log's runs" in no_runs.stderr
    mon = run_cli("monitor", tmp_path / "c.pt", tmp_path / "flights.csv", "--group-column", "flight",
                  "--out", tmp_path / "m")  # fmt: skip
    record = json.loads((tmp_path / "m" / "monitor.json").read_text())
    assert record["observations"] == 30 and record["unit"].startswith("groups of flight")
    assert mon.code == (1 if record["alarm"] or record["domain_alarm"] else 0)


def test_a_domain_alarm_alone_is_an_alarm(files, run_cli, tmp_path):
    run_cli("calibrate", files / "m.pt", files / "cal.csv", "--epsilon", "0.2", "--delta", "0.05",
            "--out", tmp_path / "c.pt")  # fmt: skip
    far = _runs(30, 20, seed=5)
    far = PerceptionDataset(far.x + np.r_[0, 0, 0, 0, 40.0, 0], far.y, far.yhat, extra=dict(far.extra))
    save_dataset(far, tmp_path / "far.csv")
    res = run_cli("monitor", tmp_path / "c.pt", tmp_path / "far.csv", "--out", tmp_path / "m")
    record = json.loads((tmp_path / "m" / "monitor.json").read_text())
    assert record["domain_alarm"] and res.code == 1, res.stdout + res.stderr
    first = res.stderr.strip().splitlines()[0]
    assert first.startswith(("DOMAIN ALARM at group", "ALARM at group")) and "OK" not in first
