"""Tests of the core CLI verbs: train, evaluate, predict, demo, and their errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ipcverify.data._dataset import save_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.io._modelio import load_model


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    save_dataset(make_lagged_perception(600, seed=0), d / "train.parquet")
    save_dataset(make_lagged_perception(400, seed=1), d / "test.csv")
    return d


@pytest.fixture(scope="module")
def model_path(files):
    from ipcverify.cli import main

    p = files / "model.pt"
    with pytest.raises(SystemExit) as exc:
        main(["train", str(files / "train.parquet"), "--out", str(p), "--epochs", "3", "--hidden", "16,16"])
    assert exc.value.code == 0
    return p


def test_train_writes_a_loadable_model(model_path):
    m = load_model(model_path)
    assert m.config.hidden == (16, 16)
    assert m.metadata["train_config"]["epochs"] == 3


def test_train_loss_and_center_warm_start_flags(files, tmp_path):
    from ipcverify.cli import main

    p = tmp_path / "lik.pt"
    argv = [
        "train",
        str(files / "train.parquet"),
        "--out",
        str(p),
        "--epochs",
        "2",
        "--hidden",
        "8",
        "--force",
    ]
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--recipe", "v1", "--loss", "likelihood", "--center-warm-start"])
    assert exc.value.code == 0
    tc = load_model(p).metadata["train_config"]
    assert (tc["loss"], tc["center_warm_start"]) == ("likelihood", True)
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--recipe", "v1"])
    assert exc.value.code == 0
    tc = load_model(p).metadata["train_config"]
    assert (tc["loss"], tc["center_warm_start"]) == ("hinge", False)


def test_train_recipes_by_name_and_explicit_options_override_them(files, tmp_path):
    from ipcverify.cli import main
    from ipcverify.network._architecture import ModelConfig
    from ipcverify.training._train import TrainConfig

    p = tmp_path / "m.pt"
    base = ["train", str(files / "train.parquet"), "--out", str(p), "--hidden", "8", "--force"]
    expected = {
        "tight": ("lowrank", "offset", 5, "likelihood", 0.15),
        "v1": ("cholesky", "offset", 1, "hinge", 0.0),
        "paper": ("full", "raw", 1, "hinge", 0.0),
    }
    for recipe, (param, center, members, loss, val) in expected.items():
        with pytest.raises(SystemExit) as exc:
            main([*base, "--recipe", recipe, "--epochs", "1"])
        assert exc.value.code == 0
        m = load_model(p)
        tc = m.metadata["train_config"]
        assert (m.config.param, m.config.center, m.config.members) == (param, center, members)
        assert (tc["loss"], tc["val_fraction"], tc["epochs"], m.config.hidden) == (loss, val, 1, (8,))
        # everything not given on the command line is the recipe's; for "paper", alpha, lambda and
        # the batch size are the ones its selection rule chose (recorded beside them)
        chosen = {}
        if recipe == "paper":
            pick = m.metadata["selection"]["chosen"]
            chosen = {"alpha": pick["alpha"], "lam": pick["lam"], "batch_size": pick["batch_size"]}
        want = TrainConfig.recipe(recipe, epochs=1, **chosen).to_dict()
        assert tc == want
        assert m.config == ModelConfig.recipe(recipe, x_dim=6, y_dim=3, hidden=(8,))
    # the default recipe is "tight"; --members and --no-linear-center override it
    with pytest.raises(SystemExit) as exc:
        main([*base, "--epochs", "1", "--members", "2", "--no-linear-center", "--batch-size", "32"])
    assert exc.value.code == 0
    m = load_model(p)
    assert (m.config.param, m.config.members, m.config.linear_center) == ("lowrank", 2, False)
    assert m.metadata["train_config"]["batch_size"] == 32


def test_evaluate_json(run_cli, files, model_path):
    res = run_cli("evaluate", model_path, files / "test.csv", "--json")
    assert res.code == 0, res.stderr
    out = json.loads(res.stdout)
    assert out["n"] == 400
    assert out["violations"] == round(out["violation_rate"] * 400)
    assert set(out["log_volume"]) == {"mean", "median"}
    # the numbers agree with the library
    from ipcverify.certification._evaluation import evaluate
    from ipcverify.data._dataset import load_dataset

    ev = evaluate(load_model(model_path), load_dataset(files / "test.csv"))
    assert out["violations"] == ev.violations
    assert out["log_volume"]["mean"] == pytest.approx(ev.log_volume_mean)


def test_evaluate_table_with_bins(run_cli, files, model_path):
    res = run_cli("evaluate", model_path, files / "test.csv", "--bin-column", "x_5", "--bins", "4")
    assert res.code == 0, res.stderr
    assert "violation rate by x_5" in res.stdout


def test_predict_npz(run_cli, files, model_path, tmp_path):
    out = tmp_path / "sets.npz"
    res = run_cli("predict", model_path, files / "test.csv", "--out", out)
    assert res.code == 0, res.stderr
    z = np.load(out)
    assert z["center"].shape == (400, 3) and z["shape"].shape == (400, 3, 3)
    from ipcverify.data._dataset import load_dataset

    ds = load_dataset(files / "test.csv")
    e = load_model(model_path).predict_unguarded(ds.x, ds.yhat)
    assert np.array_equal(z["center"], e.centers) and np.array_equal(z["shape"], e.shapes)


def test_predict_needs_no_truth_and_marks_the_domain(run_cli, files, model_path, tmp_path):
    import pandas as pd

    from ipcverify.contract._calibrate import calibrate
    from ipcverify.io._modelio import save_model

    cal = calibrate(load_model(model_path), make_lagged_perception(1000, seed=5), 0.1, 0.05)
    save_model(cal, tmp_path / "cal.pt")
    frame = pd.read_csv(files / "test.csv")
    queries = frame[[c for c in frame.columns if not c.startswith("y_")]].copy()
    queries.loc[:9, ["x_3", "x_4", "x_5"]] *= 30.0  # ten queries at speeds never seen
    queries.to_csv(tmp_path / "deploy.csv", index=False)
    res = run_cli("predict", tmp_path / "cal.pt", tmp_path / "deploy.csv", "--out", tmp_path / "sets.npz")
    assert res.code == 0, res.stderr
    z = np.load(tmp_path / "sets.npz")
    assert z["in_domain"].shape == (400,) and not z["in_domain"][:10].any()
    assert z["in_domain"][10:].mean() > 0.95 and np.isfinite(z["domain_distance"]).all()
    assert "lie outside the domain of validity" in res.stdout + res.stderr


def test_bare_certify_works_from_the_model_file_alone(run_cli, model_path, tmp_path):
    from ipcverify.contract._calibrate import calibrate
    from ipcverify.io._modelio import save_model

    save_model(
        calibrate(load_model(model_path), make_lagged_perception(1000, seed=6), 0.1, 0.05), tmp_path / "c.pt"
    )
    res = run_cli("certify", tmp_path / "c.pt", "--out", tmp_path / "cert")
    assert res.code == 0, res.stderr
    assert "UNTESTED" in res.stdout and "none given" in res.stdout
    cert = json.loads((tmp_path / "cert" / "certificate.json").read_text())
    assert cert["status"] == "UNTESTED" and cert["test"] is None
    assert cert["calibration"]["k"] == cert["calibration"]["groups"][0]["k"]
    assert cert["domain"]["n_reference"] == 1000 and cert["domain"]["n"] == 0
    # Theorem 1 of the default (low-rank ensemble) from the statistics stored at training time
    t1 = cert["theorem1"]
    assert t1["computed"] and t1["source"] == "statistics stored at training time"
    assert t1["vacuous"] and t1["bound"] >= 1 and t1["lipschitz_sound"] >= t1["lipschitz_empirical"] > 0
    page = (tmp_path / "cert" / "report.html").read_text()
    assert "No test data was given" in page and "Domain of validity" in page
    assert "Theorem 1 is vacuous" in page


def test_demo(run_cli, tmp_path):
    res = run_cli("demo", "--out", tmp_path / "demo", "--n", "400")
    assert res.code == 0, res.stderr
    assert "IPC calibrated (PAC)" in res.stdout and "guarantee:" in res.stdout
    assert (tmp_path / "demo" / "sets.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for name in ("train.csv", "calibration.csv", "test.csv", "model.pt"):
        assert (tmp_path / "demo" / name).is_file()
    cal = load_model(tmp_path / "demo" / "calibrated.pt")
    assert cal.calibration is not None and cal.calibration.n == 5000
    from ipcverify.demo import DEMO_FILES

    assert sorted(p.name for p in (tmp_path / "demo").iterdir()) == sorted(DEMO_FILES)
    assert f"created the folder {tmp_path / 'demo'}" in res.stdout
    again = run_cli("demo", "--out", tmp_path / "demo", "--n", "400")  # refused before computing anything
    assert (
        again.code == 2 and "already holds train.csv, calibration.csv, test.csv, model.pt, " in again.stderr
    )


def test_demo_calibrated_sets_keep_their_guarantee(tmp_path):
    """PAC at epsilon = 0.01, delta = 0.001: with probability >= 0.999 the true violation rate
    is <= 1 %, and then 20,000 test samples show more than the binomial 1 - 1e-6 quantile of
    violations with probability <= 1e-6.  The global ellipsoid is calibrated the same way."""
    from scipy.stats import binom

    from ipcverify.demo import run_demo

    s = run_demo(tmp_path, n_train=600, seed=3)
    limit = binom.ppf(1 - 1e-6, s.calibrated.n, 0.01)
    assert s.calibrated.violations <= limit
    assert s.global_violations <= limit
    # the calibrated IPC is smaller than the global ellipsoid on this input-dependent error
    assert s.calibrated.log_volume_mean < s.global_log_volume


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["train", "{train}", "--out", "{tmp}/m.pt", "--hidden", "64,abc"],
            "--hidden must be comma-separated",
        ),
        (["train", "{train}", "--out", "{tmp}/m.pt", "--epochs", "0"], "epochs must be >= 1"),
        (["train", "{train}", "--out", "{tmp}/m.pt", "--lr", "-1"], "lr must be > 0"),
        (
            ["train", "{train}", "--out", "{tmp}/m.pt", "--val-fraction", "0", "--patience", "2"],
            "needs a validation split",
        ),
        (["train", "{train}", "--out", "{tmp}/m.pt", "--recipe", "best"], "Invalid value for '--recipe'"),
        (
            ["train", "{train}", "--out", "{tmp}/m.pt", "--param", "cholesky", "--members", "3"],
            "ensembles come with the low-rank head",
        ),
        (["train", "{tmp}/missing.csv", "--out", "{tmp}/m.pt"], "does not exist"),
        (["train", "{bad}", "--out", "{tmp}/m.pt"], "non-finite value"),
        (["evaluate", "{bad}", "{test}"], "not a readable model file"),
        (["predict", "{model}", "{test}", "--out", "{tmp}/sets.csv"], "--out must end in .npz"),
        (["evaluate", "{model}", "{test}", "--bin-column", "speed"], "no column 'speed'"),
        (["train", "{train}", "--out", "{tmp}/m.pt", "--param", "diag"], "Invalid value for '--param'"),
        (["train", "{train}", "--out", "{tmp}/m.pt", "--loss", "nll"], "Invalid value for '--loss'"),
        (["train", "{train}", "--out", "{tmp}/m.pt", "--epochs", "abc"], "is not a valid integer"),
        (["train"], "Missing argument 'DATA'"),
        (["no-such-command"], "No such command"),
        (["predict", "{text}", "{test}", "--out", "{tmp}/s.npz"], "not a readable model file: it is not the"),
        (["certify", "{text}"], "not a readable model file"),
        (["predict", "{model}", "{extra_x}", "--out", "{tmp}/s.npz"], "column x_6 looks like an x column"),
        (["evaluate", "{model}", "{extra_x}"], "column x_6 looks like an x column"),
        (["predict", "{model}", "{no_x5}", "--out", "{tmp}/s.npz"], "missing column(s) x_5"),
    ],
)
def test_user_errors_exit_2_with_one_line(run_cli, files, model_path, tmp_path, args, message):
    bad = tmp_path / "bad.csv"
    bad.write_text("x_0,y_0,yhat_0\n1,inf,2\n")
    (tmp_path / "model.txt").write_text("this is a text file, not a model\n")
    import pandas as pd

    frame = pd.read_csv(files / "test.csv")
    frame.assign(x_6=1.0).to_csv(tmp_path / "extra_x.csv", index=False)
    frame.drop(columns=["x_5"]).to_csv(tmp_path / "no_x5.csv", index=False)
    subs = {
        "{text}": str(tmp_path / "model.txt"),
        "{extra_x}": str(tmp_path / "extra_x.csv"),
        "{no_x5}": str(tmp_path / "no_x5.csv"),
        "{train}": str(files / "train.parquet"),
        "{test}": str(files / "test.csv"),
        "{model}": str(model_path),
        "{bad}": str(bad),
        "{tmp}": str(tmp_path),
    }
    argv = []
    for a in args:
        for k, v in subs.items():
            a = a.replace(k, v)
        argv.append(a)
    res = run_cli(*argv)
    assert res.code == 2
    assert message in res.stderr
    assert "Traceback" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1 and res.stderr.startswith("error: ")
    assert not (tmp_path / "m.pt").exists()


def test_train_paper_recipe_reports_p_and_how_its_unstated_settings_were_chosen(files, tmp_path, run_cli):
    """The paper's network on 6 + 3 inputs: p = 9*64 + 64 + 64*128 + 128 + 128*12 + 12 = 10,508;
    alpha, lambda and the batch size are chosen on held-out training rows unless given."""
    p = tmp_path / "paper.pt"
    r = run_cli("train", files / "train.parquet", "--out", p, "--recipe", "paper", "--epochs", "1")
    assert r.code == 0, r.stderr
    assert "p = 10,508 parameters" in r.stdout and "chosen on held-out training rows: alpha = " in r.stdout
    m = load_model(p)
    assert m.n_parameters == 9 * 64 + 64 + 64 * 128 + 128 + 128 * 12 + 12 and m.config.n_outputs == 12
    assert len(m.metadata["selection"]["candidates"]) == 9
    r = run_cli("train", files / "train.parquet", "--out", p, "--recipe", "paper", "--epochs", "1",
                "--alpha", "0.5", "--force")  # fmt: skip
    assert r.code == 0 and "chosen on held-out" not in r.stdout
    m = load_model(p)
    assert "selection" not in m.metadata and m.metadata["train_config"]["alpha"] == 0.5
