"""``ipcverify certify``: the printed verdict line (weak targets said so), --units and --labels, bare runs."""

from __future__ import annotations

import json

import pytest

from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.data._dataset import save_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.io._modelio import save_model
from ipcverify.network._architecture import ModelConfig


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("certify_summary")
    net = IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")))
    cal = make_lagged_perception(1500, seed=91)
    save_model(calibrate(net, cal, 0.01, 0.01), d / "strong.pt")
    save_model(calibrate(net, cal, 0.5, 0.01), d / "weak.pt")
    save_dataset(make_lagged_perception(1000, seed=92), d / "test.csv")
    return d


def _lines(stdout: str) -> list[str]:
    return [line for line in stdout.splitlines() if line.strip()]


def test_weak_target_verdict_line_units_and_labels(run_cli, files, tmp_path):
    res = run_cli(
        "certify", files / "weak.pt", "--data", files / "test.csv", "--out", tmp_path,
        "--units", "m", "--labels", "forward, left,up",
    )  # fmt: skip
    assert res.code == 0, res.stderr
    first = _lines(res.stdout)[0]
    assert first.startswith(
        "CERTIFIED, WEAK TARGET (epsilon = 0.5: up to half the truths may lie outside): calibrated contract"
    )
    s = json.loads((tmp_path / "certificate.json").read_text())["summary"]
    assert s["verdict"] == first and s["units"] == "m" and s["labels"] == ["forward", "left", "up"]
    page = (tmp_path / "report.html").read_text()
    assert "WEAK TARGET (ε = 0.5: up to half the truths may lie outside)" in page
    assert "forward, left, up, in m" in page


def test_strong_target_verdict_line_says_certified_once(run_cli, files, tmp_path):
    res = run_cli("certify", files / "strong.pt", "--data", files / "test.csv", "--out", tmp_path)
    assert res.code == 0, res.stderr
    first = _lines(res.stdout)[0]
    assert first == "CERTIFIED: calibrated contract, test data consistent with the calibration"
    assert "certified: certified" not in res.stdout.lower() and "WEAK" not in res.stdout


def test_bare_run_says_the_held_out_test_was_not_run(run_cli, files, tmp_path):
    res = run_cli("certify", files / "strong.pt", "--out", tmp_path)
    assert res.code == 0, res.stderr
    flat = " ".join(res.stdout.replace("│", " ").split())  # the table's wrapped cells, joined
    assert "0/0 test" not in flat and "no test data given: the held-out test was not run" in flat
    assert _lines(res.stdout)[0].startswith("UNTESTED: certified by calibration")
    page = (tmp_path / "report.html").read_text()
    assert "no test data given: the held-out test was not run" in page and "0/0 test" not in page


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--labels", "forward,left"], "labels must name the 3 coordinates of y (the output columns)"),
        (["--labels", "forward,,up"], "one non-empty label each"),
        (["--units", " "], "the units of y must not be empty"),
    ],
)
def test_bad_labels_or_units_exit_2_with_one_line(run_cli, files, tmp_path, args, message):
    res = run_cli("certify", files / "strong.pt", "--data", files / "test.csv", "--out", tmp_path, *args)
    assert res.code == 2
    err = res.stderr.strip()
    assert err.startswith("error: ") and message in err and len(err.splitlines()) == 1
    assert not (tmp_path / "certificate.json").exists()


def test_the_set_size_is_printed_beside_the_error_of_the_estimate(run_cli, files, tmp_path):
    """On a real log (evo's EuRoC V1_02 estimate, 60 calibration rows) the calibrated sets were
    7-11x the estimate's 90th-percentile error, wider than the displacements themselves, and no
    output said so; certify now prints both, and certificate.json keeps them."""
    import numpy as np

    from ipcverify.data._dataset import load_dataset
    from ipcverify.io._modelio import load_model

    res = run_cli(
        "certify", files / "weak.pt", "--data", files / "test.csv", "--out", tmp_path, "--units", "m"
    )  # fmt: skip
    assert res.code == 0, res.stderr
    vol = json.loads((tmp_path / "certificate.json").read_text())["volume"]
    test = load_dataset(files / "test.csv")
    half = load_model(files / "weak.pt").predict_unguarded(test.x, test.yhat).half_widths()
    np.testing.assert_allclose(vol["median_half_width"], np.median(half, axis=0), rtol=1e-6)
    np.testing.assert_allclose(
        vol["estimate_error_q90"], np.quantile(np.abs(test.y - test.yhat), 0.9, axis=0)
    )
    flat = " ".join(res.stdout.replace("│", " ").split())  # the table wraps its cells
    hw = ", ".join(f"{h:.3g}" for h in vol["median_half_width"])
    assert f"set size median half-width per axis {hw} m; |y - yhat| 90th percentile" in flat
