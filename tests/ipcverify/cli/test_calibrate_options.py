"""The calibrate command maps its options to a calibration spec and a domain spec, with their defaults."""

from __future__ import annotations

import click
import pytest

from ipcverify.calibration import Global, Grouped, Mondrian
from ipcverify.cli import app
from ipcverify.cli.certify import calibration_method
from ipcverify.contract import IPCModel, calibrate
from ipcverify.data import PerceptionDataset, save_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import InvalidInputError
from ipcverify.guard import DomainSpec
from ipcverify.io import load_model, save_model
from ipcverify.io._modelio import load_data_for_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.network._modules import IPCNetwork


def _option(name: str) -> click.Parameter:
    cmd = app.commands["calibrate"]
    return next(p for p in cmd.params if p.name == name)


@pytest.mark.parametrize(
    ("options", "spec"),
    [
        (("pac", None, None, None, None, 0), None),  # the library chooses by the data
        (("pac", None, None, None, None, 0, "row"), Global(mode="pac")),
        (("marginal", None, None, None, None, 4), Global(mode="marginal")),
        (
            ("marginal", None, None, None, None, 4, None, None, ("flight",)),
            Grouped(column="flight", seed=4, mode="marginal"),
        ),
        (("pac", "x_2", None, None, None, 5), Mondrian(column="x_2", seed=5)),
        (("marginal", "x_3", 4, None, None, 1), Mondrian(column="x_3", bins=4, seed=1, mode="marginal")),
        (("pac", None, None, "flight", None, 2), Grouped(column="flight", seed=2)),
        (
            ("marginal", None, None, "run", "trajectory", 0),
            Grouped(column="run", guarantee="trajectory", mode="marginal"),
        ),
        (
            ("pac", None, None, "run", "share-of-runs", 0, None, 0.2),
            Grouped(column="run", guarantee="share-of-runs", gamma=0.2),
        ),
        (("pac", None, None, None, None, 0, "run", None, ("flight",)), Grouped(column="flight")),
    ],
)  # fmt: skip
def test_the_options_name_one_spec(options, spec):
    assert calibration_method(*options) == spec


def test_the_options_defaults_are_the_specs_defaults():
    assert _option("mode").default == Global().mode == Grouped(column="c").mode == Mondrian(column="c").mode
    assert _option("guarantee").default is None and Grouped(column="c").guarantee == "expected-share"
    assert _option("unit").default is None and _option("gamma").default is Grouped(column="c").gamma is None
    assert (
        _option("seed").default == Grouped(column="c").seed == Mondrian(column="c").seed == DomainSpec().seed
    )
    assert _option("domain_flag_rate").default == DomainSpec().flag_rate
    assert _option("bins").default is Mondrian(column="c").bins is None


def test_option_combinations_without_a_spec_are_refused():
    with pytest.raises(
        InvalidInputError, match=r"bins needs a group column \(CLI: --mondrian-column COL --bins K\)"
    ):
        calibration_method("pac", None, 3, None, None, 0)
    with pytest.raises(InvalidInputError, match=r"choose one of a Mondrian column .* cannot be combined"):
        calibration_method("pac", "x_0", None, "flight", None, 0)
    with pytest.raises(InvalidInputError, match=r"--unit row makes a claim about rows, --group-column one"):
        calibration_method("pac", None, None, "flight", None, 0, "row")
    with pytest.raises(InvalidInputError, match=r"--unit run needs the column .* 2 such columns \(a, b\)"):
        calibration_method("pac", None, None, None, None, 0, "run", None, ("a", "b"))
    with pytest.raises(InvalidInputError, match=r"--guarantee and --gamma choose a claim about runs"):
        calibration_method("pac", None, None, None, "trajectory", 0)
    with pytest.raises(InvalidInputError, match=r"--mondrian-column makes a row-level claim"):
        calibration_method("pac", "x_0", None, None, None, 0, "run")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("calibrate_options")
    model = IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")))
    save_model(model, d / "model.pt")
    data = make_lagged_perception(1200, seed=61)
    flights = PerceptionDataset(
        data.x, data.y, data.yhat, extra={"flight": [i // 10 for i in range(1200)]}, source="cal.csv"
    )
    save_dataset(flights, d / "cal.csv")
    return d


def test_the_command_calibrates_as_python_does_with_the_spec(files, run_cli, tmp_path):
    args = ["--epsilon", "0.2", "--delta", "0.05", "--domain-flag-rate", "0.05", "--seed", "3"]
    res = run_cli(
        "calibrate", files / "model.pt", files / "cal.csv", *args, "--group-column", "flight",
        "--out", tmp_path / "g.pt",
    )  # fmt: skip
    assert res.code == 0, res.stderr
    model = load_model(files / "model.pt")
    data = load_data_for_model(files / "cal.csv", model)
    expect = calibrate(
        model, data, 0.2, 0.05, Grouped(column="flight", seed=3), domain=DomainSpec(flag_rate=0.05, seed=3)
    )
    got = load_model(tmp_path / "g.pt")
    assert got.calibration == expect.calibration
    assert got.domain is not None and got.domain.threshold == expect.domain.threshold
    assert got.domain.n_groups == 120  # the group column is the domain test's units too


def test_the_refusals_exit_2_with_one_line(files, run_cli, tmp_path):
    base = [
        files / "model.pt",
        files / "cal.csv",
        "--epsilon",
        "0.1",
        "--delta",
        "0.05",
        "--out",
        tmp_path / "x.pt",
    ]
    res = run_cli("calibrate", *base, "--bins", "3")
    assert res.code == 2 and res.stderr.strip() == (
        "error: bins needs a group column (CLI: --mondrian-column COL --bins K)"
    )
    res = run_cli("calibrate", *base, "--mondrian-column", "x_0", "--group-column", "flight")
    assert res.code == 2 and "cannot be combined" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    res = run_cli("calibrate", *base, "--domain-flag-rate", "1.5")
    said = "domain test: --domain-flag-rate must lie strictly between 0 and 1; got 1.5"
    assert res.code == 2 and said in res.stderr
    assert not (tmp_path / "x.pt").exists()
