"""Every output path is guarded: what was accepted silently before now gets a refusal or a warning.

(The refusals -- constant or identical rows, ONNX without --no-domain, flight-level requirements
listed at once -- are rows of the table in test_fuzz.py; here are the warnings and the paths that
now work.)
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from ipcverify.calibration import Grouped
from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._prediction import monitor_log
from ipcverify.data._dataset import PerceptionDataset, save_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.guard import DomainSpec
from ipcverify.io._modelio import save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train


def _flights(ds: PerceptionDataset, flights: int, shift: float = 0.0) -> PerceptionDataset:
    names = np.array([f"vislam_rp_{i // (len(ds) // flights)}" for i in range(len(ds))])
    return PerceptionDataset(ds.x, ds.y + shift, ds.yhat, extra={"flight": names})


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    d = tmp_path_factory.mktemp("guards")
    train_ds = make_lagged_perception(600, seed=0)
    mc = ModelConfig.recipe("tight", x_dim=6, y_dim=3, hidden=(8,), members=2)
    model = train(train_ds, mc, TrainConfig.recipe("tight", epochs=3, val_fraction=0.0, patience=None)).model
    cal_ds = make_lagged_perception(3000, seed=1)
    f = {"model": d / "model.pt", "calibrated": d / "calibrated.pt", "flight_model": d / "flight_model.pt"}
    save_model(model, f["model"])
    save_model(calibrate(model, cal_ds, 0.05, 0.01), f["calibrated"])
    flight_cal = calibrate(
        model, _flights(cal_ds, 100), 0.3, 0.1, Grouped(column="flight"), domain=DomainSpec(flag_rate=0.1)
    )
    save_model(flight_cal, f["flight_model"])
    test = make_lagged_perception(600, seed=2)
    far = PerceptionDataset(test.x + np.r_[0, 0, 0, 0, 40.0, 0], test.y, test.yhat)
    logs = {
        "cal_runs": PerceptionDataset(
            cal_ds.x, cal_ds.y, cal_ds.yhat, extra={"run": np.repeat(np.arange(30), 100)}
        ),
        "cal_far": PerceptionDataset(cal_ds.x - np.r_[30.0, 0, 0, 0, 0, 0], cal_ds.y, cal_ds.yhat),
        "far": far,
        "flights": _flights(test, 6),
        "bad_flights": _flights(test, 6, shift=5.0),
    }
    for name, ds in logs.items():
        f[name] = d / f"{name}.csv"
        save_dataset(ds, f[name])
    return f


def test_evaluate_reports_the_domain_in_its_table_and_json_and_warns_when_all_is_outside(setup, run_cli):
    res = run_cli("evaluate", setup["calibrated"], setup["far"], "--json")
    assert res.code == 0
    dom = json.loads(res.stdout)["domain"]
    assert dom["n"] == 600 and dom["outside"] == 600 and dom["outside_fraction"] == 1.0
    assert dom["violations_inside"] == 0 and dom["violations_outside"] == json.loads(res.stdout)["violations"]
    assert dom["well_above_flag_rate"] is True
    assert res.stderr.startswith("warning: 600 of 600 queries (100.00 %) lie outside the domain of validity")
    table = run_cli("evaluate", setup["calibrated"], setup["far"])
    assert "outside the domain of validity │ 600 (100.00 %)" in table.stdout
    assert "violations inside / outside" in table.stdout and table.stderr.startswith("warning: ")
    raw = run_cli("evaluate", setup["model"], setup["far"], "--json")
    assert json.loads(raw.stdout)["domain"] is None and raw.stderr == ""  # no domain test to report
    assert "none in this model" in run_cli("evaluate", setup["model"], setup["far"]).stdout


def test_a_text_group_column_bins_by_value_in_evaluate_and_certify(setup, run_cli, tmp_path):
    res = run_cli("evaluate", setup["calibrated"], setup["flights"], "--bin-column", "flight", "--json")
    assert res.code == 0, res.stderr
    by_bin = json.loads(res.stdout)["by_bin"]
    assert by_bin["labels"] == [f"vislam_rp_{i}" for i in range(6)] and by_bin["edges"] == []
    assert by_bin["counts"] == [100] * 6
    table = run_cli("evaluate", setup["calibrated"], setup["flights"], "--bin-column", "flight")
    assert "vislam_rp_5 │ 100 │" in table.stdout
    out = tmp_path / "cert"
    res = run_cli(
        "certify", setup["calibrated"], "--data", setup["flights"], "--bin-column", "flight", "--out", out
    )
    assert res.code == 0, res.stderr
    cov = json.loads((out / "certificate.json").read_text())["coverage_by_bin"]
    assert cov["column"] == "flight" and cov["labels"][0] == "vislam_rp_0"


def test_calibrate_warns_when_the_inputs_lie_outside_the_training_inputs(setup, run_cli, tmp_path):
    res = run_cli(
        "calibrate",
        setup["model"],
        setup["cal_far"],
        "--epsilon",
        "0.05",
        "--delta",
        "0.01",
        "--out",
        tmp_path / "c.pt",
    )
    assert res.code == 0
    warning = [line for line in res.stderr.splitlines() if line.startswith("warning:")]
    assert (
        len(warning) == 1
        and "100 % of the calibration inputs lie outside the ranges of the training" in warning[0]
    )


def test_a_run_column_is_calibrated_by_runs_unless_rows_are_chosen_and_certified_by_runs(
    setup, run_cli, tmp_path
):
    args = ["--epsilon", "0.05", "--delta", "0.01", "--out", tmp_path / "c.pt"]
    # the data name 30 runs: the claim is about runs, and 30 runs cannot certify 5 %; the refusal says why
    res = run_cli("calibrate", setup["model"], setup["cal_runs"], *args)
    assert res.code == 2 and len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert "30 groups of column 'run' are too few" in res.stderr and "--unit row" in res.stderr
    assert "hint:" not in res.stderr  # no hint before the error it belongs to
    rows = run_cli("calibrate", setup["model"], setup["cal_runs"], *args, "--unit", "row")
    assert rows.code == 0, rows.stderr
    hints = [line for line in rows.stderr.splitlines() if line.startswith("hint:")]
    assert len(hints) == 1 and "a row-level claim on data with runs of 'run' (chosen explicitly)" in hints[0]
    assert "3,000 rows in 30 runs of 'run' are worth about" in hints[0] and "--unit run" in hints[0]
    assert "Within-run dependence: 3,000 rows in 30 runs" in rows.stdout
    grouped = run_cli(
        "calibrate", setup["model"], setup["cal_runs"], *args, "--group-column", "run", "--epsilon", "0.3",
        "--delta", "0.2", "--domain-flag-rate", "0.2", "--force",
    )  # fmt: skip
    assert grouped.code == 0, grouped.stderr
    assert "hint:" not in grouped.stderr and "From 30 independent runs at delta=0.2" in grouped.stdout
    # the test data's flights are counted per flight, with or without --group-column
    cert = run_cli("certify", setup["calibrated"], "--data", setup["flights"], "--out", tmp_path / "cert")
    counted = run_cli(
        "certify", setup["calibrated"], "--data", setup["flights"], "--group-column", "flight",
        "--out", tmp_path / "c2",
    )  # fmt: skip
    assert cert.code == counted.code == 0 and "hint:" not in cert.stderr + counted.stderr
    first, second = (json.loads((tmp_path / d / "certificate.json").read_text()) for d in ("cert", "c2"))
    assert first["group_test"]["column"] == "flight" and first["group_test"] == second["group_test"]


def test_monitor_takes_a_flight_level_model_one_observation_per_flight(setup, run_cli, tmp_path):
    res = run_cli("monitor", setup["flight_model"], setup["flights"], "--out", tmp_path / "ok")
    assert res.code == 0, res.stderr
    assert res.stdout.startswith("OK No alarm over 6 groups of flight (share of rows outside) (600 rows)")
    record = json.loads((tmp_path / "ok" / "monitor.json").read_text())
    assert record["unit"] == "groups of flight (share of rows outside)" and record["observations"] == 6
    assert record["groups"] == [f"vislam_rp_{i}" for i in range(6)] and record["rows"] == 600
    bad = run_cli("monitor", setup["flight_model"], setup["bad_flights"], "--out", tmp_path / "bad")
    assert bad.code == 1  # a verdict against the model, not an error
    assert "ALARM at group 'vislam_rp_" in bad.stderr and "error:" not in bad.stderr


def test_monitor_log_per_group_statistics_are_taken_when_each_group_ends(setup):
    from ipcverify.io._modelio import load_model

    model = load_model(setup["calibrated"])
    test = make_lagged_perception(300, seed=5)
    order = np.array(["b"] * 100 + ["a"] * 100 + ["c"] * 50 + ["b"] * 50)  # b ends last
    y = test.y.copy()
    y[100:110] += 10.0  # ten violations in group a
    data = PerceptionDataset(test.x, y, test.yhat, extra={"leg": order})
    rows = monitor_log(model, data)
    res = monitor_log(model, data, group_column="leg")
    assert res.labels == ("a", "c", "b") and res.n_rows == 300
    for i, g in enumerate(res.labels):
        assert res.violated[i] == pytest.approx(rows.violated[order == g].mean())
    assert res.violated[0] >= 0.1 and res.result.violated.tolist() == res.violated.tolist()


def test_a_row_by_row_alarm_says_once_that_it_is_one_and_names_runs_of_violations(setup, run_cli, tmp_path):
    """Violations in runs (neighbouring rows correlated) get the caveat; spread-out ones do not."""
    test = make_lagged_perception(600, seed=6)
    logs = {}
    for name, rows in (("runs", np.arange(600) % 100 < 20), ("spread", np.arange(600) % 5 == 0)):
        y = test.y.copy()
        y[rows] += 10.0  # 20 % of the rows outside: in runs of 20, or every fifth row
        logs[name] = tmp_path / f"{name}.csv"
        save_dataset(PerceptionDataset(test.x, y, test.yhat), logs[name])
    for name, clustered in (("runs", True), ("spread", False)):
        res = run_cli("monitor", setup["calibrated"], logs[name], "--out", tmp_path / name)
        assert res.code == 1, res.stderr
        assert res.stderr.startswith("ALARM at row ") and "ALARM ALARM" not in res.stderr
        assert ("the violations come in runs" in res.stderr) is clustered
        record = json.loads((tmp_path / name / "monitor.json").read_text())
        assert record["violation_runs"]["clustered"] is clustered
    ok = run_cli("monitor", setup["calibrated"], setup["flights"], "--out", tmp_path / "ok")
    assert ok.code == 0 and ok.stdout.startswith("OK No alarm over 600 rows")
