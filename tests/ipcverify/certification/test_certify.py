"""certify(): the certificate's content, refusals, statuses; the calibrate and certify CLI commands."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ipcverify.calibration import Global, Mondrian
from ipcverify.calibration._bounds import clopper_pearson_upper
from ipcverify.certification._certificate import CertificateStatus
from ipcverify.certification._certify import certify
from ipcverify.certification._certify_steps import DEFAULT_DELTA, no_statistics
from ipcverify.certification._evaluation import evaluate
from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.data._dataset import PerceptionDataset, save_dataset
from ipcverify.data._files import file_sha256
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import InvalidInputError
from ipcverify.io._modelio import load_model, save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train

CFG = ModelConfig(x_dim=6, y_dim=3, hidden=(16, 16), param="cholesky")  # Theorem 1 needs the paper's head


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    d = tmp_path_factory.mktemp("certify")
    train_data = make_lagged_perception(1500, seed=50)
    cal_data = make_lagged_perception(2000, seed=51)
    test_data = make_lagged_perception(3000, seed=52)
    model = train(train_data, CFG, TrainConfig.recipe("v1", epochs=3, batch_size=128)).model
    for name, ds in (("train", train_data), ("cal", cal_data), ("test", test_data)):
        save_dataset(ds, d / f"{name}.csv")
    save_model(model, d / "model.pt")
    cal_model = calibrate(model, cal_data, 0.05, 0.01)
    save_model(cal_model, d / "cal.pt")
    return {
        "dir": d,
        "model": model,
        "cal_model": cal_model,
        "train": train_data,
        "cal": cal_data,
        "test": test_data,
    }


def test_certificate_content(setup):
    res = certify(setup["cal_model"], setup["test"], train_data=setup["train"])
    cert = res.certificate
    d = cert.to_dict()
    assert cert.status is CertificateStatus.CERTIFIED
    assert d["n_parameters"] == setup["model"].n_parameters
    c = d["calibration"]
    t = setup["cal_model"].calibration.threshold
    assert (c["epsilon"], c["delta"], c["n"], c["k"], c["scale"], c["mode"]) == (
        0.05,
        0.01,
        2000,
        t.k,
        t.scale,
        "pac",
    )
    ev = evaluate(setup["cal_model"], setup["test"])  # evaluate uses the calibrated sets too
    assert d["test"]["n"] == 3000 and d["test"]["violations"] == ev.violations
    assert d["test"]["empirical_rate"] == pytest.approx(ev.violation_rate)
    assert d["test"]["upper_bound"] == clopper_pearson_upper(ev.violations, 3000, 0.01)
    assert d["volume"]["mean_log"] == pytest.approx(ev.log_volume_mean)
    assert d["volume"]["median_log"] == pytest.approx(ev.log_volume_median)
    t1 = d["theorem1"]
    assert t1["computed"] and t1["vacuous"] and t1["lipschitz_sound"] >= t1["lipschitz_empirical"] > 0
    assert t1["bound"] > 1 and t1["guarantee"] is False
    assert d["data"]["train"]["matches_model_metadata"] is True
    assert d["model"]["architecture"]["hidden"] == [16, 16]
    assert "exchangeable" in d["assumption"] and "With probability at least 0.99" in cert.statement
    # per-sample evidence matches the certificate
    assert res.evidence.violated.sum() == ev.violations
    assert ((res.evidence.normalized_scores > 1) == res.evidence.violated).all()


def test_uncalibrated_model_is_certified_on_the_test_set_only(setup):
    res = certify(setup["model"], setup["test"])
    cert = res.certificate
    assert cert.status is CertificateStatus.NOT_CALIBRATED
    assert cert.calibration is None and cert.to_dict()["calibration"] is None
    assert cert.statement.startswith("No calibration certificate")
    assert cert.test.delta == DEFAULT_DELTA
    assert certify(setup["model"], setup["test"], delta=0.2).certificate.test.delta == 0.2
    bare = IPCModel(setup["model"].network, None, {"train_config": setup["model"].metadata["train_config"]})
    t1 = certify(bare, setup["test"]).certificate.to_dict()["theorem1"]
    assert t1["computed"] is False and t1["bound"] is None
    assert t1["reason"] == no_statistics() and "train_data" in t1["reason"] and "retrain" in t1["reason"]


def test_theorem1_from_stored_training_statistics_equals_theorem1_from_the_training_data(setup):
    stored = certify(setup["model"], setup["test"]).certificate.to_dict()["theorem1"]
    fresh = certify(setup["model"], setup["test"], train_data=setup["train"]).certificate.to_dict()[
        "theorem1"
    ]
    assert stored["source"] == "statistics stored at training time" and fresh["source"] == "training data"
    for key in ("bound", "n_train", "empirical_term", "lipschitz_sound", "confidence_term"):
        assert stored[key] == pytest.approx(fresh[key], rel=1e-12), key
    # the empirical L_g is a max of float32 gradient norms: equal up to float32 summation order
    assert stored["lipschitz_empirical"] == pytest.approx(fresh["lipschitz_empirical"], rel=1e-5)


def test_contradicting_test_data_is_flagged(setup):
    shifted = make_lagged_perception(3000, seed=53, lag_frames=4.0, noise=0.02)
    cert = certify(setup["cal_model"], shifted).certificate
    assert cert.status is CertificateStatus.CONTRADICTED
    assert cert.consistency.consistent is False
    assert cert.statement.startswith("WARNING: the test data contradicts the calibration")


def test_marginal_and_mondrian_certificates(setup):
    marg = calibrate(setup["model"], setup["cal"], 0.1, 0.01, Global(mode="marginal"))
    cert = certify(marg, setup["test"]).certificate
    assert cert.consistency.checked and cert.status is CertificateStatus.CERTIFIED
    mond = calibrate(setup["model"], setup["cal"], 0.1, 0.05, Mondrian(column="x_2", bins=2))
    d = certify(mond, setup["test"]).certificate.to_dict()
    assert d["calibration"]["kind"] == "mondrian" and len(d["calibration"]["k"]) == 2
    assert sum(g["n"] for g in d["test"]["groups"]) == 3000


def test_refusals(setup):
    with pytest.raises(InvalidInputError, match=r"the test data is the calibration data"):
        certify(setup["cal_model"], setup["cal"])
    with pytest.raises(InvalidInputError, match=r"the test data is the training data"):
        certify(setup["model"], setup["train"])
    bad = PerceptionDataset(np.zeros((5, 2)), np.zeros((5, 3)), np.zeros((5, 3)), source="bad.csv")
    with pytest.raises(InvalidInputError, match=r"bad.csv: test data has x_dim=2"):
        certify(setup["model"], bad)
    other = IPCModel(IPCNetwork(CFG), setup["cal_model"].calibration)
    with pytest.raises(InvalidInputError, match=r"calibration was computed for a different network"):
        certify(other, setup["test"])
    with pytest.raises(InvalidInputError, match=r"delta must lie strictly between 0 and 1"):
        certify(setup["model"], setup["test"], delta=2.0)
    # Theorem 1 from data the model was not trained on would be a bound about other data
    half = setup["train"].subset(np.arange(750))
    with pytest.raises(InvalidInputError, match=r"this is not the data the model was trained on"):
        certify(setup["cal_model"], setup["test"], train_data=half)
    # a model file that records no training data cannot tell: the data given is taken as it
    meta = {k: v for k, v in setup["cal_model"].metadata.items() if k != "train_data_hash"}
    unrecorded = IPCModel(setup["model"].network, setup["cal_model"].calibration, meta)
    assert certify(unrecorded, setup["test"], train_data=half).certificate.theorem1 is not None


# --------------------------------------------------------------------------------- CLI
def test_cli_calibrate_then_certify(setup, run_cli, tmp_path):
    d = setup["dir"]
    out = tmp_path / "c.pt"
    res = run_cli(
        "calibrate", d / "model.pt", d / "cal.csv", "--epsilon", "0.05", "--delta", "0.01", "--out", out
    )
    assert res.code == 0, res.stderr
    assert "With probability at least 0.99" in res.stdout
    assert load_model(out).calibration == setup["cal_model"].calibration
    cdir = tmp_path / "cert"
    res = run_cli("certify", out, "--data", d / "test.csv", "--train-data", d / "train.csv", "--out", cdir)
    assert res.code == 0, res.stderr
    assert "CERTIFIED" in res.stdout and "vacuous (proves nothing)" in res.stdout
    cert = json.loads((cdir / "certificate.json").read_text())
    for key in ("n_parameters", "calibration", "test", "theorem1", "volume", "model", "data"):
        assert key in cert
    for key in ("epsilon", "delta", "n", "k", "scale", "mode"):
        assert key in cert["calibration"]
    for key in ("n", "violations", "empirical_rate", "upper_bound"):
        assert key in cert["test"]
    for key in ("bound", "vacuous", "lipschitz_empirical", "lipschitz_sound", "n_needed"):
        assert key in cert["theorem1"]
    assert cert["model"]["file_sha256"] == file_sha256(out)
    assert cert["data"]["test"]["file_sha256"] == file_sha256(d / "test.csv")
    assert (cdir / "report.html").stat().st_size > 10_000
    assert not list(cdir.glob("*.tmp"))  # atomic writes leave no temporaries


def test_cli_uncalibrated_and_contradicted(setup, run_cli, tmp_path):
    d = setup["dir"]
    res = run_cli(
        "certify", d / "model.pt", "--data", d / "test.csv", "--out", tmp_path / "u", "--delta", "0.05"
    )
    assert res.code == 0 and "NOT_CALIBRATED" in res.stdout and "ABSENT" in res.stdout
    cert = json.loads((tmp_path / "u" / "certificate.json").read_text())
    assert cert["calibration"] is None and cert["test"]["delta"] == 0.05
    assert cert["theorem1"]["computed"] and cert["theorem1"]["source"] == "statistics stored at training time"
    save_dataset(make_lagged_perception(2000, seed=54, lag_frames=4.0, noise=0.02), tmp_path / "shift.csv")
    res = run_cli("certify", d / "cal.pt", "--data", tmp_path / "shift.csv", "--out", tmp_path / "s")
    assert res.code == 1 and "CONTRADICTED" in res.stdout


def test_cli_errors(setup, run_cli, tmp_path):
    d = setup["dir"]

    def calibrate(model, data, epsilon, delta):
        out = tmp_path / "x.pt"
        return run_cli("calibrate", d / model, d / data, "--epsilon", epsilon, "--delta", delta, "--out", out)

    res = calibrate("cal.pt", "cal.csv", "0.05", "0.01")
    assert res.code == 2 and "already calibrated" in res.stderr and "--recalibrate" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    res = calibrate("model.pt", "cal.csv", "0.001", "0.001")
    assert res.code == 2 and "at least 6905 are needed" in res.stderr
    res = calibrate("model.pt", "train.csv", "0.05", "0.01")
    assert res.code == 2 and "training data" in res.stderr
    res = run_cli("certify", d / "cal.pt", "--data", d / "cal.csv", "--out", tmp_path / "y")
    assert res.code == 2 and "the test data is the calibration data" in res.stderr
    res = run_cli(
        "calibrate", d / "model.pt", d / "cal.csv", "--epsilon", "0.05", "--delta", "0.01",
        "--recalibrate", "--mondrian-column", "x_0", "--bins", "3", "--out", tmp_path / "m.pt",
    )  # fmt: skip
    assert res.code == 0 and "x_0 <" in res.stdout


def test_the_certificate_reports_worst_bin_coverage_over_every_state_column(setup):
    cert = certify(setup["cal_model"], setup["test"]).certificate
    w = cert.to_dict()["conditional_coverage"]
    assert set(w["by_column"]) == {*setup["test"].x_columns, "||yhat||"}
    assert w["worst_coverage"] == min(v["coverage"] for v in w["by_column"].values())
    assert 0.0 <= w["worst_coverage"] <= 1.0 - cert.test.empirical_rate + 1e-12
