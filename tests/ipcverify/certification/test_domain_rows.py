"""A row-level domain test on correlated rows: the certificate names it as a second explanation of a "shift".

Rows of one run are near-copies of each other, so a domain test fitted row by row has a short
threshold, and the rows of a new run fall outside it far more often than the flag rate although the runs
are exchangeable. The certificate must not call that a shift without saying so: it names the
run-like column and the remedy (fit the test by group), and the group-aware test on the same
data flags about the flag rate of the queries.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from ipcverify import calibrate
from ipcverify._wording._audience import Audience, speaking
from ipcverify.calibration import Global
from ipcverify.certification._certify import certify
from ipcverify.certification._summarize import summarize
from ipcverify.contract import IPCModel
from ipcverify.data import PerceptionDataset
from ipcverify.errors import Hint
from ipcverify.guard import DomainReport, DomainSpec
from ipcverify.network import ModelConfig
from ipcverify.network._modules import IPCNetwork

ALPHA = 0.05
#: certify's hint that the test rows have a run column is the subject of other tests
pytestmark = pytest.mark.filterwarnings("ignore:.*certifying row by row:ipcverify.errors.Hint")


def _runs(n_runs: int, rows: int, seed: int) -> PerceptionDataset:
    """Runs at random places of the state space, each run's rows within 1e-3 of its place."""
    rng = np.random.default_rng(seed)
    run = np.repeat(np.arange(n_runs), rows)
    x = rng.normal(size=(n_runs, 4))[run] + 1e-3 * rng.normal(size=(n_runs * rows, 4))
    yhat = rng.normal(size=(n_runs, 2))[run] + 1e-3 * rng.normal(size=(n_runs * rows, 2))
    y = yhat + 0.1 * rng.normal(size=yhat.shape)
    return PerceptionDataset(x, y, yhat, source=f"runs seed {seed}", extra={"run": run})


@pytest.fixture(scope="module")
def net() -> IPCModel:
    torch.manual_seed(3)
    return IPCModel(IPCNetwork(ModelConfig.recipe("v1", x_dim=4, y_dim=2, hidden=(8,))))


@pytest.fixture(scope="module")
def data() -> dict[str, PerceptionDataset]:
    return {"cal": _runs(60, 10, seed=1), "test": _runs(40, 10, seed=2)}


def _calibrated(net: IPCModel, cal: PerceptionDataset, group_column: str | None) -> IPCModel:
    from ipcverify import calibrate

    domain = DomainSpec(flag_rate=ALPHA, group_column=group_column)
    if group_column is not None:
        return calibrate(net, cal, 0.2, 0.05, Global(), domain=domain)
    with pytest.warns(
        Hint, match=r"DomainSpec\(group_column='run'\)"
    ):  # the row-level claim's hint names the remedy
        return calibrate(net, cal, 0.2, 0.05, Global(), domain=domain)


def test_a_row_level_test_on_correlated_rows_is_named_beside_the_shift(net, data):
    model = _calibrated(net, data["cal"], None)
    d = certify(model, data["test"]).certificate.domain
    assert d is not None and d.well_above_flag_rate and d.outside_fraction > 0.5  # nearly every new run
    assert d.row_level_column == "run" and d.to_dict()["row_level_column"] == "run"
    # 60 calibration runs allow a test by run at this flag rate (0.05) as it is: no --domain-flag-rate named
    assert d.row_level_groups == 60
    assert (
        "refit it with whole groups (calibrate(..., domain=DomainSpec(group_column='run'))) to tell"
        in d.sentence()
    )
    cert = certify(model, data["test"]).certificate
    (check,) = [c for c in summarize(cert).checks if c.name == "domain of validity"]
    assert check.verdict.startswith("SHIFT, or a row-level test on correlated rows")
    assert "DomainSpec(group_column='run')" in check.detail


def test_the_same_runs_fitted_by_group_are_not_a_shift(net, data):
    model = _calibrated(net, data["cal"], "run")
    d = certify(model, data["test"]).certificate.domain
    assert d is not None and d.row_level_column is None and not d.well_above_flag_rate
    assert "shifted" not in d.sentence()


def test_the_remedy_names_the_flag_rate_the_calibration_groups_allow():
    r = DomainReport(method="knn", flag_rate=0.01, threshold=1.0, n_reference=800, n=600, outside=180,
                     row_level_column="segment", row_level_groups=10)  # fmt: skip
    assert (
        "(calibrate(..., domain=DomainSpec(group_column='segment', flag_rate=0.091))) to tell" in r.sentence()
    )
    with speaking(Audience.CLI):  # the same remedy, on the command line
        assert "(calibrate --domain-group-column segment --domain-flag-rate 0.091) to tell" in r.sentence()
    assert r.to_dict()["row_level_groups"] == 10


@pytest.mark.parametrize(("outside", "named"), [(40, True), (1, False)])
def test_the_remedy_is_said_only_for_a_share_well_above_flag_rate(outside, named):
    r = DomainReport(method="knn", flag_rate=0.01, threshold=1.0, n_reference=100, n=100, outside=outside,
                     row_level_column="segment")  # fmt: skip
    assert ("DomainSpec(group_column='segment')" in r.sentence()) is named
    plain = DomainReport(method="knn", flag_rate=0.01, threshold=1.0, n_reference=100, n=100, outside=outside)
    assert "DomainSpec(" not in plain.sentence()


def test_a_run_column_of_the_test_data_alone_names_no_row_level_test(net, data):
    # calibration data without a run column (nothing recorded in the model file), test data with one
    cal = data["cal"]
    plain = PerceptionDataset(cal.x, cal.y, cal.yhat, source="no runs")
    model = calibrate(net, plain, 0.2, 0.05, Global(), domain=DomainSpec(flag_rate=ALPHA))
    d = certify(model, data["test"]).certificate.domain
    assert d is not None and d.well_above_flag_rate and d.row_level_column is None
    assert "DomainSpec(" not in d.sentence()


def test_the_cli_warning_names_the_remedy(net, data, tmp_path, run_cli):
    from ipcverify.data import save_dataset
    from ipcverify.io import save_model

    save_model(_calibrated(net, data["cal"], None), tmp_path / "m.pt")
    save_dataset(data["test"], tmp_path / "test.csv")
    res = run_cli("certify", tmp_path / "m.pt", "--data", tmp_path / "test.csv", "--out", tmp_path / "c")
    assert res.code in (0, 1), res.stderr
    err = " ".join(res.stderr.split())
    assert "warning:" in err and "the deployment data have shifted, or the test, fitted row by row" in err
    assert "(calibrate --domain-group-column run) to tell the two apart" in err


def test_predict_and_evaluate_give_the_same_second_explanation(net, data):
    from ipcverify.certification import evaluate
    from ipcverify.contract._prediction import predict_sets
    from ipcverify.data import PerceptionInputs

    model = _calibrated(net, data["cal"], None)
    test = data["test"]
    for report in (
        predict_sets(model, PerceptionInputs(test.x, test.yhat)).domain,
        evaluate(model, test).domain,
    ):
        assert report is not None and report.well_above_flag_rate and report.row_level_column == "run"
        assert (
            "(calibrate(..., domain=DomainSpec(group_column='run'))) to tell the two apart"
            in report.sentence()
        )
