"""``ipcverify certify`` reports Theorem 1 for a default-recipe model (the low-rank ensemble).

Bare (from the statistics stored at training time), with fresh test data, with the training
data, and for an old model file that stores no statistics (a message, not a crash).
"""

from __future__ import annotations

import json

import pytest

from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel
from ipcverify.data._dataset import save_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.io._modelio import load_model, save_model


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    from ipcverify.cli import main

    d = tmp_path_factory.mktemp("thm1")
    save_dataset(make_lagged_perception(600, seed=20), d / "train.csv")
    save_dataset(make_lagged_perception(400, seed=21), d / "test.csv")
    with pytest.raises(SystemExit) as exc:  # the default recipe
        main(
            [
                "train",
                str(d / "train.csv"),
                "--out",
                str(d / "model.pt"),
                "--epochs",
                "3",
                "--hidden",
                "16,16",
            ]
        )
    assert exc.value.code == 0
    model = load_model(d / "model.pt")
    save_model(calibrate(model, make_lagged_perception(1000, seed=22), 0.1, 0.05), d / "cal.pt")
    old = {k: v for k, v in model.metadata.items() if k != "training_statistics"}
    old["theorem1_unavailable"] = "not available for this architecture: (as files written before said)"
    save_model(IPCModel(model.network, None, old), d / "old.pt")
    return d


def _certify(run_cli, out, *args):
    res = run_cli("certify", *args, "--out", out)
    assert res.code == 0, res.stderr
    return res, json.loads((out / "certificate.json").read_text()), (out / "report.html").read_text()


def _check_reported(t1: dict, stdout: str, page: str, model: IPCModel) -> None:
    assert t1["computed"] is True
    # p counts every member's trainable parameters: body (9 -> 16 -> 16 -> 15), centre and factor skip paths
    per_member = (9 * 16 + 16) + (16 * 16 + 16) + (16 * 15 + 15) + (9 * 3 + 3) + (9 * 9 + 9)
    assert t1["n_parameters"] == model.n_parameters == 5 * per_member
    assert t1["alpha"] == 1.0 and t1["n_train"] == 600
    assert t1["lipschitz_sound"] >= t1["lipschitz_empirical"] > 0
    assert t1["vacuous"] is True and t1["bound"] >= 1.0 and t1["guarantee"] is False
    assert isinstance(t1["n_needed"], int) and t1["n_needed"] > t1["n_train"]
    assert t1["bound_with_empirical_lipschitz"] <= t1["bound"]
    # printed: the verdict, the sound bound and L_g, p, N and the N needed, the empirical L_g
    flat = " ".join(stdout.split())
    assert "Theorem 1" in flat and "vacuous (proves nothing): bound" in flat
    assert f"{t1['bound']:.3g}" in flat and f"{t1['lipschitz_sound']:.3g}" in flat
    assert f"{t1['lipschitz_empirical']:.3g}" in flat and f"{t1['n_needed']:.3g}" in flat
    assert f"p = {t1['n_parameters']:,}" in flat
    assert "not available" not in flat
    # the report: the verdict and the table with both constants
    assert "Theorem 1 is vacuous" in page and "sound L_g (upper bound; valid)" in page
    assert f"p = {t1['n_parameters']:,} parameters" in page and f"{t1['lipschitz_sound']:.4g}" in page
    assert "not available" not in page.lower()


def test_bare_certify_reports_theorem1_of_the_default_model(run_cli, files, tmp_path):
    model = load_model(files / "cal.pt")
    assert model.config.param == "lowrank" and model.config.members == 5
    res, cert, page = _certify(run_cli, tmp_path / "bare", files / "cal.pt")
    t1 = cert["theorem1"]
    assert t1["source"] == "statistics stored at training time"
    _check_reported(t1, res.stdout, page, model)
    assert "statistics stored at training time" in page


def test_certify_with_data_reports_the_same_theorem1(run_cli, files, tmp_path):
    model = load_model(files / "cal.pt")
    _, bare, _ = _certify(run_cli, tmp_path / "bare", files / "cal.pt")
    res, cert, page = _certify(run_cli, tmp_path / "data", files / "cal.pt", "--data", files / "test.csv")
    t1 = cert["theorem1"]
    _check_reported(t1, res.stdout, page, model)
    assert cert["test"]["n"] == 400
    assert t1 == bare["theorem1"]  # the test data plays no role in Theorem 1
    # the training data gives the same numbers as the statistics stored when it was trained on
    res, fresh, page = _certify(
        run_cli,
        tmp_path / "train",
        files / "cal.pt",
        "--data",
        files / "test.csv",
        "--train-data",
        files / "train.csv",
    )
    _check_reported(fresh["theorem1"], res.stdout, page, model)
    assert fresh["theorem1"]["source"] == "training data"
    assert fresh["data"]["train"]["matches_model_metadata"] is True
    for key in ("bound", "lipschitz_sound", "lipschitz_empirical", "n_needed", "empirical_term"):
        assert fresh["theorem1"][key] == pytest.approx(t1[key], rel=1e-12), key


def test_an_old_model_file_without_statistics_gets_a_message_not_a_crash(run_cli, files, tmp_path):
    res, cert, page = _certify(run_cli, tmp_path / "old", files / "old.pt")
    t1 = cert["theorem1"]
    assert t1["computed"] is False and t1["bound"] is None and t1["lipschitz_sound"] is None
    assert "no training statistics" in t1["reason"] and "--train-data" in t1["reason"]
    assert "retrain" in t1["reason"]
    assert "--train-data" in " ".join(res.stdout.split())
    assert "Not computed: training data not given" in page
    res, cert, _ = _certify(run_cli, tmp_path / "old2", files / "old.pt", "--train-data", files / "train.csv")
    assert cert["theorem1"]["computed"] is True and cert["theorem1"]["source"] == "training data"
