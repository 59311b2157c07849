"""The certificate's test counted per flight (``group_test``): its statistics, keys, statuses, CLI, real log.

(a) Synthetic correlated flights, the model of ``calibration/test_grouped.py``: flight ``g`` has a
bias ``b_g ~ N(0, SB^2)`` shared by its samples, per-sample noise ``e ~ N(0, SE^2)`` and
``L_g ~ Uniform{10, ..., 40}`` samples; a sample violates when ``|b_g + e| > T``. The true rates
are known: a random sample of a new flight violates with probability ``2 P(N(0, SB^2 + SE^2) > T)``
(exactly), a new flight has some violation with probability ``1 - E[F_b(T)^L]`` (Gauss--Hermite
quadrature over ``b``). Over ``R`` seeded draws of ``G`` test flights, a valid one-sided bound at
``1 - DELTA`` misses the truth in a Binomial(R, q <= DELTA) number of draws; the row-level bound
on the same rows misses far more often (it assumes independent rows). Every p-value is compared
with ``LEVEL = ALPHA / N_CHECKS`` (Bonferroni): a correct implementation fails with probability
at most ``ALPHA``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch
from scipy import stats

from ipcverify.calibration import Global, Grouped
from ipcverify.calibration._bounds import clopper_pearson_lower, clopper_pearson_upper
from ipcverify.certification._certificate import CertificateStatus
from ipcverify.certification._certify import certify, write_certificate
from ipcverify.certification._group_check import group_test_step
from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.data._dataset import PerceptionDataset, save_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import InvalidInputError
from ipcverify.guard import DomainSpec
from ipcverify.io._modelio import load_model, save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train

SB, SE, T = 1.0, 0.5, 2.0
LENGTHS = np.arange(10, 41)
_NODES, _W = np.polynomial.hermite_e.hermegauss(120)
_W = _W / _W.sum()
ALPHA = 1e-3
N_CHECKS = 6
LEVEL = ALPHA / N_CHECKS
R, G, DELTA = 2000, 40, 0.05

LOG = Path(__file__).resolve().parents[3] / "data" / "euroc_mh04_vislam.csv"


# ---------------------------------------------------------------------------------------------
# (a) the group-level interval covers the true per-flight rates; the row-level one does not


def _true_sample_rate() -> float:
    return float(2.0 * stats.norm.sf(T / math.hypot(SB, SE)))


def _true_flight_rate() -> float:
    inside = stats.norm.cdf((T - SB * _NODES) / SE) - stats.norm.cdf((-T - SB * _NODES) / SE)
    return float(1.0 - np.mean([(inside**n) @ _W for n in LENGTHS]))


@pytest.fixture(scope="module")
def draws():
    """Per draw: the group test (no calibration) and the row-level Clopper-Pearson bounds."""
    rng = np.random.default_rng(2024)
    out = {k: np.empty(R) for k in ("traj_up", "samp_up", "samp_lo", "row_up", "row_lo")}
    for r in range(R):
        lengths = rng.choice(LENGTHS, size=G)
        flight = np.repeat(np.arange(G), lengths)
        violated = np.abs(rng.normal(0.0, SB, size=G)[flight] + rng.normal(0.0, SE, size=flight.size)) > T
        z = np.zeros((flight.size, 1))
        ds = PerceptionDataset(z, z, z, source="flights", extra={"flight": flight})
        g = group_test_step(None, ds, violated, DELTA, "flight")
        assert g is not None and g.n_groups == G and g.n_rows == flight.size
        out["traj_up"][r], out["samp_up"][r] = g.trajectory.upper_bound, g.sample.upper_bound
        out["samp_lo"][r] = g.sample.lower_bound
        k, n = int(violated.sum()), int(violated.size)
        out["row_up"][r], out["row_lo"][r] = (
            clopper_pearson_upper(k, n, DELTA),
            clopper_pearson_lower(k, n, DELTA),
        )
    return out


def _valid(misses: int) -> float:
    """p-value of ``misses`` under 'at most DELTA per draw' (one-sided binomial)."""
    return float(stats.binom.sf(misses - 1, R, DELTA))


def test_group_upper_bounds_cover_the_true_per_flight_rates(draws):
    p_sample, p_flight = _true_sample_rate(), _true_flight_rate()
    assert 0.02 < p_sample < 0.1 and 0.2 < p_flight < 0.6  # the regime the test is about
    miss_sample = int((draws["samp_up"] < p_sample).sum())
    miss_flight = int((draws["traj_up"] < p_flight).sum())
    assert _valid(miss_sample) >= LEVEL, f"sample bound missed {miss_sample}/{R} (delta {DELTA})"
    assert _valid(miss_flight) >= LEVEL, f"trajectory bound missed {miss_flight}/{R} (delta {DELTA})"
    # not vacuous: the bounds are informative (mean upper bound well below 1)
    assert draws["samp_up"].mean() < 0.3 and draws["traj_up"].mean() < 0.8


def test_group_lower_bound_rarely_exceeds_the_truth_so_contradictions_are_rare(draws):
    false_contradictions = int((draws["samp_lo"] > _true_sample_rate()).sum())
    assert _valid(false_contradictions) >= LEVEL, f"{false_contradictions}/{R} false contradictions"


def test_row_level_bounds_are_optimistic_on_correlated_flights(draws):
    """Power: the same rows, treated as independent, miss the true rate in far more than DELTA of draws."""
    p = _true_sample_rate()
    miss_up = int((draws["row_up"] < p).sum())
    false_contra = int((draws["row_lo"] > p).sum())
    assert _valid(miss_up) < LEVEL and miss_up > 4 * DELTA * R, f"row bound missed only {miss_up}/{R}"
    assert _valid(false_contra) < LEVEL and false_contra > 4 * DELTA * R, f"only {false_contra}/{R}"


# ---------------------------------------------------------------------------------------------
# (b) certificate keys, values, statuses


def _flight_data(n_flights: int, rows: int, seed: int, bias: float = 0.05) -> PerceptionDataset:
    """Synthetic perception with a per-flight offset of yhat (correlated violations within a flight)."""
    base = make_lagged_perception(n_flights * rows, seed=seed)
    flight = np.repeat(np.arange(n_flights), rows)
    offset = np.random.default_rng(seed + 1000).normal(0.0, bias, size=(n_flights, 3))[flight]
    return PerceptionDataset(
        base.x, base.y, base.yhat + offset, source=f"flights seed {seed}", extra={"flight": flight}
    )


@pytest.fixture(scope="module")
def net():
    torch.manual_seed(1)  # fixed: the scenario's network, not the RNG state earlier tests left
    return IPCModel(IPCNetwork(ModelConfig.recipe("v1", x_dim=6, y_dim=3, hidden=(8,))))


@pytest.fixture(scope="module")
def flights():
    return {"cal": _flight_data(150, 12, seed=1), "test": _flight_data(120, 15, seed=2)}


def test_row_level_calibration_reports_both_and_compares_the_per_flight_share(net, flights, tmp_path):
    model = calibrate(net, flights["cal"], 0.1, 0.05, Global())  # a row-level claim, chosen explicitly
    res = certify(model, flights["test"], group_column="flight")
    cert, g = res.certificate, res.certificate.group_test
    assert g is not None and g.column == "flight" and g.compared_unit == "share"
    # the row-level claim rests on independent rows: it is never CERTIFIED on flights
    assert cert.status in (CertificateStatus.ROWS_ASSUMED, CertificateStatus.CONTRADICTED)
    d = cert.to_dict()["group_test"]
    assert set(d) >= {
        "column",
        "n_groups",
        "n_rows",
        "seed",
        "trajectory",
        "sample",
        "consistency",
        "statement",
    }
    assert d["n_groups"] == 120 and d["n_rows"] == 1800 and d["seed"] == 0
    for unit in ("trajectory", "sample"):
        u = d[unit]
        assert 0 <= u["violations"] <= u["n"] == d["n_groups"]
        assert u["lower_bound"] <= u["empirical_rate"] <= u["upper_bound"]
        assert u["upper_bound"] == clopper_pearson_upper(u["violations"], 120, model.calibration.delta)
    # independent count of flights with any violation, from the per-row evidence
    per_flight = np.bincount(flights["test"].extra["flight"], weights=res.evidence.violated.astype(float))
    assert d["trajectory"]["violations"] == int((per_flight > 0).sum())
    assert d["sample"]["violations"] <= d["trajectory"]["violations"] <= cert.test.violations
    shares = np.bincount(flights["test"].extra["flight"], weights=res.evidence.violated.astype(float)) / 15
    assert d["share"]["empirical_rate"] == pytest.approx(shares.mean()) and d["share"]["statistic"] == "mean"
    assert d["share"]["lower_bound"] <= d["share"]["empirical_rate"] <= d["share"]["upper_bound"]
    assert d["consistency"]["allowed_rate"] == cert.consistency.allowed_rate
    assert d["consistency"]["test_lower_bound"] == d["share"]["lower_bound"]
    assert "assumes independent rows" in cert.statement and "Counted per group of 'flight'" in cert.statement
    cert_path, report_path = write_certificate(res, tmp_path)
    on_disk = json.loads(cert_path.read_text())
    assert on_disk["group_test"]["trajectory"]["violations"] == d["trajectory"]["violations"]
    assert "test" in on_disk and on_disk["test"]["unit"] == "samples"  # existing keys unchanged
    page = report_path.read_text()
    assert "assumes <b>independent rows</b>" in page and "compared with the calibration" in page
    # without the option the test data's one column that names runs is counted alike
    assert certify(model, flights["test"]).certificate.group_test == g


@pytest.mark.parametrize(
    ("guarantee", "statistic"), [("expected-share", "share"), ("trajectory", "trajectory")]
)
def test_flight_level_calibration_defaults_to_its_column_and_unit(net, flights, guarantee, statistic):
    model = calibrate(
        net,
        flights["cal"],
        0.1,
        0.05,
        Grouped(column="flight", guarantee=guarantee, seed=3),
        domain=DomainSpec(seed=3),
    )
    cert = certify(model, flights["test"]).certificate  # no group_column: the calibration's
    g = cert.group_test
    assert g is not None and g.column == "flight" and g.compared_unit == statistic and g.seed == 3
    assert (g.compared.violations, g.compared.n) == (cert.test.violations, cert.test.n)
    assert cert.status is not CertificateStatus.ROWS_ASSUMED
    assert g.consistency == cert.consistency
    assert certify(model, flights["test"], group_column="flight").certificate.group_test == g


def test_group_level_contradiction_is_flagged_when_the_row_level_test_is_consistent(net, flights):
    """Many short flights all violating, one long clean flight: rows look fine, flights do not."""
    model = calibrate(net, flights["cal"], 0.1, 0.05, Global())
    clean = _flight_data(1, 6000, seed=5, bias=0.0)
    shifted = _flight_data(40, 2, seed=6, bias=0.0)
    shift = PerceptionDataset(
        shifted.x,
        shifted.y,
        shifted.yhat + 5.0,
        source="shifted",
        extra={"flight": shifted.extra["flight"] + 1},
    )
    test = PerceptionDataset(
        np.vstack([clean.x, shift.x]),
        np.vstack([clean.y, shift.y]),
        np.vstack([clean.yhat, shift.yhat]),
        source="mixed",
        extra={"flight": np.concatenate([clean.extra["flight"], shift.extra["flight"]])},
    )
    cert = certify(model, test, group_column="flight").certificate
    assert certify(model, test).certificate.group_test == cert.group_test  # its one run column, by default
    assert cert.consistency.consistent  # the row-level check alone still passes
    assert cert.group_test.consistency.checked and cert.group_test.consistency.consistent is False
    assert cert.status is CertificateStatus.CONTRADICTED
    assert cert.statement.startswith("WARNING") and "CONTRADICTS the calibration" in cert.statement


def test_uncalibrated_model_reports_the_group_test_without_comparing(net, flights):
    cert = certify(net, flights["test"], group_column="flight").certificate
    assert cert.status is CertificateStatus.NOT_CALIBRATED
    g = cert.group_test
    assert g.compared_unit is None and g.compared is None and g.consistency.reason == "no calibration"


def test_refusals(net, flights):
    ds = flights["test"]
    with pytest.raises(InvalidInputError, match=r"no group column 'run' in the test data .*flight"):
        certify(net, ds, group_column="run")
    one = ds.subset(ds.extra["flight"] == 7, "flight 7")
    with pytest.raises(InvalidInputError, match=r"group column 'flight' has one group only \(7\)"):
        certify(net, one, group_column="flight")
    with pytest.raises(InvalidInputError, match=r"needs test data"):
        certify(net, None, group_column="flight")


# ---------------------------------------------------------------------------------------------
# (c) CLI


def test_cli_group_column_and_its_errors(net, flights, run_cli, tmp_path):
    model = calibrate(net, flights["cal"], 0.1, 0.05, Global())
    save_model(model, tmp_path / "m.pt")
    save_dataset(flights["test"], tmp_path / "test.csv")
    res = run_cli("certify", tmp_path / "m.pt", "--data", tmp_path / "test.csv", "--group-column", "flight",
                  "--out", tmp_path / "c")  # fmt: skip
    assert res.code in (0, 1), res.stderr
    d = json.loads((tmp_path / "c" / "certificate.json").read_text())
    assert d["group_test"]["n_groups"] == 120 and "per flight: share of rows outside" in res.stdout
    assert res.code == (1 if d["status"] == "CONTRADICTED" else 0)
    save_dataset(flights["test"].subset(flights["test"].extra["flight"] < 1, "one"), tmp_path / "one.csv")
    for args, message in (
        (("--data", tmp_path / "test.csv", "--group-column", "run"), "no group column 'run'"),
        (("--data", tmp_path / "one.csv", "--group-column", "flight"), "has one group only"),
        (("--group-column", "flight"), "needs test data"),
    ):
        res = run_cli("certify", tmp_path / "m.pt", *args, "--out", tmp_path / "e")
        assert res.code == 2 and message in res.stderr, res.stderr
        assert len(res.stderr.strip().splitlines()) == 1 and "Traceback" not in res.stderr


# ---------------------------------------------------------------------------------------------
# (d) the real log, flights = method + run


def test_real_log_end_to_end_with_group_column(run_cli, tmp_path):
    df = pd.read_csv(LOG)
    df["flight"] = df["method"] + ":" + df["run"].astype(str)
    parts = {"train": df["run"] <= 3, "cal": df["run"].between(4, 6), "test": df["run"] >= 7}
    for name, mask in parts.items():
        df[mask].to_csv(tmp_path / f"{name}.csv", index=False)
    model = train(
        PerceptionDataset(
            df.loc[parts["train"], [f"x_{i}" for i in range(5)]].to_numpy(),
            df.loc[parts["train"], [f"y_{i}" for i in range(3)]].to_numpy(),
            df.loc[parts["train"], [f"yhat_{i}" for i in range(3)]].to_numpy(),
        ),
        train_config=TrainConfig(epochs=2, seed=0),
    ).model
    save_model(model, tmp_path / "model.pt")
    res = run_cli("calibrate", tmp_path / "model.pt", tmp_path / "cal.csv", "--epsilon", "0.05", "--delta",
                  "0.01", "--unit", "row", "--out", tmp_path / "cal.pt")  # fmt: skip
    assert res.code == 0, res.stderr
    res = run_cli("certify", tmp_path / "cal.pt", "--data", tmp_path / "test.csv", "--group-column", "flight",
                  "--out", tmp_path / "cert")  # fmt: skip
    assert res.code in (0, 1), res.stderr
    d = json.loads((tmp_path / "cert" / "certificate.json").read_text())
    g, test = d["group_test"], df[parts["test"]]
    assert (g["column"], g["n_groups"], g["n_rows"], g["compared_unit"]) == ("flight", 6, len(test), "share")
    # the flights with a violation, counted independently from the calibrated sets
    calibrated = load_model(tmp_path / "cal.pt")
    sets = calibrated.predict_unguarded(
        test[[f"x_{i}" for i in range(5)]].to_numpy(), test[[f"yhat_{i}" for i in range(3)]].to_numpy()
    )
    violated = ~sets.contains(test[[f"y_{i}" for i in range(3)]].to_numpy())
    assert d["test"]["violations"] == int(violated.sum())
    assert g["trajectory"]["violations"] == int(
        pd.Series(violated).groupby(test["flight"].to_numpy()).any().sum()
    )
    assert g["sample"]["violations"] <= g["trajectory"]["violations"]
    page = (tmp_path / "cert" / "report.html").read_text()
    assert "Counted per group of" in page
    # the per-bin coverage intervals count rows as independent: the page says so when rows are grouped
    assert "counts its rows as independent samples; rows of one group of <code>flight</code>" in page
    # the log holds one sequence (MH_04): as a group column it has one group only
    res = run_cli("certify", tmp_path / "cal.pt", "--data", tmp_path / "test.csv",
                  "--group-column", "sequence", "--out", tmp_path / "x")  # fmt: skip
    assert res.code == 2 and "group column 'sequence' has one group only ('MH_04')" in res.stderr
