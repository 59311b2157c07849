"""The certificate's executive summary: claim, target, unit, one row per check, date, version, hashes.

The summary only writes down what the certificate decided: every verdict here is compared with
the record it comes from (status, consistency, group test, domain report, Theorem 1).
"""

from __future__ import annotations

import json
from datetime import UTC, datetime

import numpy as np
import pytest
from matplotlib.figure import Figure

import ipcverify
from ipcverify.calibration import Global, Grouped
from ipcverify.certification._certificate import CertificateStatus
from ipcverify.certification._certify import certify, labelled, with_files, write_certificate
from ipcverify.certification._report import render_report
from ipcverify.certification._report_plots import plot_coverage, plot_projections, plot_scores
from ipcverify.certification._summary import WEAK_EPSILON, CertificateSummary, target_strength
from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.data._dataset import PerceptionDataset, save_dataset
from ipcverify.data._files import file_sha256
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import Hint, InvalidInputError
from ipcverify.guard import DomainSpec
from ipcverify.io._modelio import save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig
from ipcverify.training._train import train as train_ipc

CFG = ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")
#: The top-level keys of certificate.json before the summary: kept, never renamed (docs/develop.md).
OLD_KEYS = {
    "format", "format_version", "ipcverify_version", "status", "status_text", "statement", "assumption",
    "n_parameters", "model", "calibration", "test", "consistency", "theorem1", "volume", "coverage_by_bin",
    "conditional_coverage", "domain", "group_test", "data",
}  # fmt: skip
NAMES = ["calibration certificate", "held-out test", "domain of validity", "Theorem 1 (paper)"]


def _flights(ds: PerceptionDataset, rows_per_flight: int) -> PerceptionDataset:
    """``ds`` with a ``flight`` column: consecutive blocks of i.i.d. rows (so the flights are i.i.d.)."""
    flight = np.arange(len(ds)) // rows_per_flight
    return PerceptionDataset(ds.x, ds.y, ds.yhat, source=ds.source, extra={"flight": flight})


@pytest.fixture(scope="module")
def net():
    """An untrained network: calibration makes its sets honest, which is all a certificate needs.

    Seeded: the tests' verdicts come from exact bounds at a fixed confidence, so they hold for
    most networks, not all; a fixed one makes every run check the same thing.
    """
    import torch

    torch.manual_seed(0)
    return IPCModel(IPCNetwork(CFG))


@pytest.fixture(scope="module")
def files(tmp_path_factory, net):
    d = tmp_path_factory.mktemp("summary")
    cal = make_lagged_perception(1500, seed=71)
    save_model(calibrate(net, cal, 0.01, 0.01), d / "strong.pt")
    save_model(calibrate(net, cal, 0.5, 0.01), d / "weak.pt")
    save_dataset(make_lagged_perception(2000, seed=72), d / "test.csv")
    return d


@pytest.mark.parametrize(
    ("epsilon", "strength"),
    [(None, "none"), (0.001, "strong"), (0.0999, "strong"), (0.1, "weak"), (0.5, "weak")],
)
def test_a_target_is_weak_from_epsilon_0_1(epsilon, strength):
    assert WEAK_EPSILON == 0.1 and target_strength(epsilon) == strength


def test_summary_of_a_strong_certificate(files):
    from ipcverify.io._modelio import load_data_for_model, load_model

    model = load_model(files / "strong.pt")
    test = load_data_for_model(files / "test.csv", model)
    before = datetime.now(UTC).replace(microsecond=0)
    cert = with_files(certify(model, test), files / "strong.pt", files / "test.csv", None).certificate
    after = datetime.now(UTC)
    s = cert.summary
    assert isinstance(s, CertificateSummary) and cert.status is CertificateStatus.CERTIFIED
    cal = cert.calibration
    assert s.claim == cal.guarantee and (s.epsilon, s.delta, s.certified_epsilon) == (
        0.01,
        0.01,
        cal.certified_epsilon,
    )
    assert s.strength == "strong" and s.unit == "row" and s.unit_column is None
    # the verdict line says the status once, then what it means
    assert s.verdict_text() == "CERTIFIED: calibrated contract, test data consistent with the calibration"
    assert [c.name for c in s.checks] == NAMES
    levels = {c.name: (c.verdict, c.level) for c in s.checks}
    assert levels["calibration certificate"] == ("present", "pass")
    assert levels["held-out test"] == ("consistent with the calibration", "pass")
    assert levels["Theorem 1 (paper)"][0] == "not computed"
    t = cert.test
    held = s.checks[1].detail
    assert f"{t.violations:,} of {t.n:,} test samples outside" in held and f"{t.upper_bound:.4g}" in held
    assert f"{cert.consistency.test_lower_bound:.4g} <= allowed {cert.consistency.allowed_rate:.4g}" in held
    # date (UTC, ISO 8601), version, hashes
    made = datetime.strptime(s.date_utc, "%Y-%m-%dT%H:%M:%SZ").replace(tzinfo=UTC)
    assert before <= made <= after
    assert s.ipcverify_version == ipcverify.__version__
    assert s.model_sha256 == file_sha256(files / "strong.pt") and s.model_sha256_of == "model file"
    assert dict(s.data_sha256) == {
        "test data file": file_sha256(files / "test.csv"),
        "test data content": test.content_hash(),
        "calibration data content": cal.data_sha256,
    }
    assert (
        s.labels == ("y_0", "y_1", "y_2") and s.units is None and s.axis_label(1) == "y_1 (units of the data)"
    )


def test_certificate_json_adds_the_summary_and_keeps_every_key(files, tmp_path):
    from ipcverify.io._modelio import load_data_for_model, load_model

    model = load_model(files / "weak.pt")
    res = certify(model, load_data_for_model(files / "test.csv", model))
    write_certificate(res, tmp_path, units="m", labels=("fwd", "left", "up"))  # the report names y
    res = labelled(res, units="m", labels=("fwd", "left", "up"))
    d = json.loads((tmp_path / "certificate.json").read_text())
    new_keys = {"summary", "test_group_like_columns", "calibration_group_like_columns", "runs", "test_rows"}
    assert OLD_KEYS | new_keys == set(d)
    assert d["runs"] is None  # no runs in the calibration data
    s = d["summary"]
    assert s == json.loads(json.dumps(res.certificate.summary.to_dict()))
    assert s["verdict"].startswith(
        "CERTIFIED, WEAK TARGET (epsilon = 0.5: up to half the truths may lie outside)"
    )
    assert (s["strength"], s["epsilon"], s["delta"], s["unit"]) == ("weak", 0.5, 0.01, "row")
    assert s["units"] == "m" and s["labels"] == ["fwd", "left", "up"]
    assert s["ipcverify_version"] == d["ipcverify_version"] and s["status"] == d["status"]
    assert [c["check"] for c in s["checks"]] == NAMES
    assert s["checks"][0]["verdict"] == "present, weak target" and s["checks"][0]["level"] == "warn"


@pytest.mark.parametrize("epsilon", [0.1, 0.2, 0.5])
def test_a_weak_target_is_said_in_the_verdict(net, epsilon):
    model = calibrate(net, make_lagged_perception(800, seed=73), epsilon, 0.05)
    s = certify(model, make_lagged_perception(800, seed=74)).certificate.summary
    assert s.status == "CERTIFIED" and s.strength == "weak"
    share = "half the" if epsilon == 0.5 else f"{100 * epsilon:.3g} % of the"
    assert s.verdict_text("ε").startswith(
        f"CERTIFIED, WEAK TARGET (ε = {epsilon:g}: up to {share} truths may"
    )


def test_a_contradicted_weak_target_is_not_called_certified(net):
    model = calibrate(net, make_lagged_perception(800, seed=75), 0.5, 0.05)
    good = make_lagged_perception(800, seed=76)
    shifted = PerceptionDataset(good.x, good.y + 1.0, good.yhat, source="shifted")  # every truth far away
    cert = certify(model, shifted).certificate
    s = cert.summary
    assert cert.status is CertificateStatus.CONTRADICTED and s.strength == "weak"
    assert (
        s.verdict_text().startswith("CONTRADICTED: the test data violates") and "WEAK" not in s.verdict_text()
    )
    held = s.checks[1]
    assert held.verdict == "CONTRADICTS the calibration" and held.level == "fail"
    assert f"{cert.test.violations:,} of {cert.test.n:,}" in held.detail


def test_bare_summary_says_the_held_out_test_was_not_run(files):
    from ipcverify.io._modelio import load_model

    cert = certify(load_model(files / "strong.pt")).certificate
    s = cert.summary
    assert cert.status is CertificateStatus.UNTESTED
    by = {c.name: c for c in s.checks}
    assert by["held-out test"].verdict == "not run"
    assert "no test data given: the held-out test was not run" in by["held-out test"].detail
    assert by["domain of validity"].verdict == "not run"
    assert "no test data given: the held-out test was not run" in by["domain of validity"].detail
    assert "0/0" not in json.dumps(s.to_dict()) and "0 of 0" not in json.dumps(s.to_dict())
    assert list(s.data_sha256) == ["calibration data content"] and s.model_sha256_of == "network"
    assert s.model_sha256 == cert.model.network_sha256


def test_uncalibrated_summary_claims_only_the_test_bound(net):
    test = make_lagged_perception(500, seed=77)
    cert = certify(net, test).certificate
    s = cert.summary
    assert s.epsilon is None and s.strength == "none" and s.delta == cert.test.delta
    assert s.claim.startswith("No calibration certificate") and f"{cert.test.upper_bound:.4g}" in s.claim
    assert s.checks[0].verdict == "absent" and s.checks[0].level == "fail"
    assert s.checks[1].verdict == "reported, not compared" and s.verdict_text().startswith("NOT_CALIBRATED: ")
    nothing = certify(net).certificate.summary
    assert nothing.claim.startswith("Nothing is claimed") and nothing.delta is None


def test_theorem1_row_reads_theorem1_with_a_capital(files, net):
    cert = certify(net, make_lagged_perception(300, seed=78)).certificate
    row = cert.summary.checks[-1]
    assert row.name == "Theorem 1 (paper)" and row.verdict == "not computed"
    assert row.detail.startswith("Not computed: training data not given")
    assert "Theorem 1 covered" in row.detail and "theorem 1" not in row.detail
    train = make_lagged_perception(400, seed=79)
    trained = train_ipc(train, CFG, TrainConfig.recipe("v1", epochs=1)).model
    t1 = certify(trained, make_lagged_perception(300, seed=80), train_data=train).certificate
    row = t1.summary.checks[-1]
    assert t1.theorem1 is not None and t1.theorem1.sound.vacuous
    assert row.verdict == "vacuous (proves nothing)" and f"{t1.theorem1.sound.bound:.3g} >= 1" in row.detail


def test_per_flight_result_is_a_row_of_its_own(net):
    model = calibrate(net, make_lagged_perception(1500, seed=81), 0.05, 0.01)
    test = _flights(make_lagged_perception(2000, seed=82), 50)
    cert = certify(model, test, group_column="flight").certificate
    g, rows = cert.group_test, cert.summary.checks
    assert (
        [c.name for c in rows]
        == [
            NAMES[0],
            NAMES[1],
            "per-flight test ('flight'): share of each group's rows outside",
            "per-flight test ('flight'): any violation in a group",
            "independent rows",  # the claim is about rows, and the test rows come in flights
            *NAMES[2:],
        ]
    )
    share, trajectory = rows[2], rows[3]
    assert g.compared_unit == "share" and g.consistency.checked
    assert share.verdict == (
        "consistent with the calibration" if g.consistency.consistent else "CONTRADICTS the calibration"
    )
    assert (
        f"mean share {100 * g.share.empirical_rate:.3g} % outside over {g.share.n:,} groups" in share.detail
    )
    assert trajectory.verdict == "reported only" and trajectory.level == "info"
    assert f"{g.trajectory.violations:,} of {g.trajectory.n:,} groups" in trajectory.detail
    assert f"{g.trajectory.upper_bound:.4g}" in trajectory.detail


def test_a_claim_about_flights_has_flights_as_its_unit(net):
    model = calibrate(
        net,
        _flights(make_lagged_perception(1000, seed=83), 25),
        0.2,
        0.05,
        Grouped(column="flight"),
        domain=DomainSpec(flag_rate=0.1),
    )
    test = _flights(make_lagged_perception(1000, seed=84), 25)
    res = certify(model, test)
    cert, s = res.certificate, res.certificate.summary
    assert (s.unit, s.unit_column, s.unit_statistic) == ("group", "flight", "share")
    assert "group of 'flight'" in s.unit_text() and "share of rows outside" in s.unit_text()
    assert s.strength == "weak"
    held = s.checks[1].detail
    k = int(res.evidence.violated.sum())
    assert f"all test rows: {k:,} of 1,000 outside" in held and "descriptive only" in held
    # the per-flight row that repeats the held-out test's own count says so; the other does not
    same = "the same count as the held-out test above, not a second test"
    rows = {c.name: c.detail for c in s.checks if c.name.startswith("per-flight test")}
    share_row = rows["per-flight test ('flight'): share of each group's rows outside"]
    assert (cert.test.violations, cert.test.n) == (cert.group_test.share.violations, cert.group_test.share.n)
    assert same in share_row
    assert same not in rows["per-flight test ('flight'): any violation in a group"]
    # flights are not called samples; no internal function name reaches the user
    assert "test samples" not in cert.test_bound_note
    text = json.dumps(cert.to_dict())
    assert "group_violation_counts" not in text


def test_labels_and_units_are_checked(net):
    test = make_lagged_perception(300, seed=85)
    res = certify(net, test)
    s = labelled(res, units=" m ", labels=[" forward", "left", "up "]).certificate.summary
    assert s.units == "m" and s.labels == ("forward", "left", "up") and s.axis_label(2) == "up [m]"
    with pytest.raises(InvalidInputError, match=r"labels must name the 3 coordinates of y .* got 2"):
        labelled(res, labels=["forward", "left"])
    with pytest.raises(InvalidInputError, match="one non-empty label each"):
        labelled(res, labels=["forward", "", "up"])
    with pytest.raises(InvalidInputError, match="units of y must not be empty"):
        labelled(res, units="  ")


def _labels(fig: Figure) -> list[str]:
    """Every visible axis label of a figure (a hidden axis measures nothing and carries none)."""
    out = []
    for ax in fig.axes:
        out.append(ax.get_xlabel())
        if ax.get_yaxis().get_visible():
            out.append(ax.get_ylabel())
    return out


def test_every_plot_axis_says_what_it_measures_and_in_which_units(net, monkeypatch):
    test = make_lagged_perception(400, seed=86)
    res = certify(calibrate(net, make_lagged_perception(800, seed=87), 0.05, 0.05), test)
    ev, cert = res.evidence, res.certificate
    assert _labels(plot_scores(ev, True)) == [
        "normalised score g / s (dimensionless; > 1: truth outside its set)",
        "test rows (count)",
    ]
    assert _labels(plot_coverage(cert.coverage, 0.05, 0.05)) == [
        "bin of x_0 (units of the data)",
        "violation rate (share of rows)",
    ]
    default = _labels(plot_projections(ev))
    assert default and all(lab.endswith("(units of the data)") for lab in default)
    # the page draws the projections with the user's labels and units on every axis
    import ipcverify.certification._report as report

    seen: list[list[str]] = []

    def spy(evidence, axis_labels=()):
        fig = plot_projections(evidence, axis_labels)
        seen.append(_labels(fig))
        return fig

    monkeypatch.setattr(report, "plot_projections", spy)
    named = labelled(certify(calibrate(net, make_lagged_perception(800, seed=87), 0.05, 0.05), test),
                     units="m", labels=("forward", "left", "up"))  # fmt: skip
    report.render_report(named)
    assert len(seen) == 1 and len(seen[0]) == 3 * 2 * len(named.evidence.example_index)
    assert set(seen[0]) == {"forward [m]", "left [m]", "up [m]"}
    y1 = np.arange(50.0)[:, None] / 50.0  # distinct rows: a file of one repeated row is refused
    one_d = PerceptionDataset(np.zeros((50, 2)), y1, y1 + 0.01)
    m1 = IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=1, hidden=(4,), param="cholesky")))
    ev1 = certify(m1, one_d).evidence
    assert _labels(plot_projections(ev1, ("range [m]",))) == ["range [m]"] * len(ev1.example_index)


def test_a_test_bound_of_one_is_reported_as_vacuous_everywhere_it_is_written():
    import torch

    torch.manual_seed(0)
    model = IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")))
    d = make_lagged_perception(3, seed=2)
    far = PerceptionDataset(d.x, d.y + 100.0, d.yhat)  # every truth far outside its set
    result = certify(model, far)
    t = result.certificate.test
    assert (t.violations, t.n, t.upper_bound, t.vacuous) == (3, 3, 1.0, True)
    summary = result.certificate.summary
    held_out = next(c for c in summary.checks if c.name == "held-out test")
    assert "upper bound 1 (vacuous: it bounds nothing)" in held_out.detail
    assert "at most 1 (vacuous: it bounds nothing)" in summary.claim
    assert t.to_dict()["vacuous"] is True
    assert "1 (vacuous: it bounds nothing)" in render_report(result)
    # a bound below 1 is not called vacuous
    near = certify(model, d).certificate.test
    assert not near.vacuous and "vacuous" not in near.bound_text()


def test_a_row_level_claim_on_test_rows_grouped_by_flight_is_flagged_as_an_assumption_in_doubt(net):
    row_level = calibrate(net, make_lagged_perception(1500, seed=81), 0.1, 0.01)
    test = _flights(make_lagged_perception(600, seed=82), 50)  # 12 flights
    cert = certify(row_level, test).certificate
    assert dict(cert.test_group_columns) == {"flight": 12}
    assert cert.to_dict()["test_group_like_columns"] == {"flight": 12}
    assert cert.status is not CertificateStatus.CERTIFIED  # never on a row-level claim on flights
    check = next(c for c in cert.summary.checks if c.name == "independent rows")
    assert (check.verdict, check.level) == ("assumed, in doubt", "warn")
    assert "'flight' column (12 groups in 600 test rows)" in check.detail
    assert "recalibrate with Grouped(column='flight')" in check.detail
    # the test data's one flight column: counted per flight by default, and the row says so
    assert "counted per group of 'flight' above" in check.detail
    assert certify(row_level, test, group_column="flight").certificate.group_test == cert.group_test
    # two columns that could name the runs: none is chosen, and the row asks for one
    two = PerceptionDataset(
        test.x, test.y, test.yhat, extra={"flight": test.extra["flight"], "run": test.extra["flight"] % 3}
    )
    asked = certify(row_level, two).certificate
    check = next(c for c in asked.summary.checks if c.name == "independent rows")
    assert asked.group_test is None and "certify with group_column='flight'" in check.detail
    # no such row for a claim about flights, nor for test data without a run or flight column
    by_flight = calibrate(
        net, _flights(make_lagged_perception(3000, seed=83), 10), 0.2, 0.05, Grouped(column="flight"),
        domain=DomainSpec(flag_rate=0.05),
    )  # fmt: skip
    names = [c.name for c in certify(by_flight, test).certificate.summary.checks]
    assert "independent rows" not in names
    plain = certify(row_level, make_lagged_perception(600, seed=82)).certificate
    assert "independent rows" not in [c.name for c in plain.summary.checks] and not plain.test_group_columns


def test_a_row_level_calibration_on_rows_grouped_by_flight_is_recorded_and_flagged(net, tmp_path):
    cal = _flights(make_lagged_perception(1500, seed=91), 50)  # 30 flights, calibrated row by row
    with pytest.warns(Hint, match="a row-level claim on data with runs of 'flight' \\(chosen explicitly\\)"):
        model = calibrate(net, cal, 0.1, 0.01, Global())
    assert model.metadata["calibration_group_like_columns"] == {"flight": 30}
    runs = model.metadata["calibration_runs"]
    assert (runs["column"], runs["n_runs"], runs["unit"], runs["row_claim_chosen"]) == (
        "flight",
        30,
        "row",
        True,
    )
    assert runs["dependence"]["n_rows"] == 1500 and runs["plan"]["n_runs"] == 30
    save_model(model, tmp_path / "m.pt")  # the record survives the model file
    from ipcverify.io._modelio import load_model

    model = load_model(tmp_path / "m.pt")
    # test data without a flight column: the calibration's record alone raises the check
    cert = certify(model, make_lagged_perception(600, seed=92)).certificate
    assert cert.to_dict()["calibration_group_like_columns"] == {"flight": 30}
    assert cert.to_dict()["runs"]["unit"] == "row" and cert.status is CertificateStatus.ROWS_ASSUMED
    check = next(c for c in cert.summary.checks if c.name == "independent rows")
    assert (
        check.level == "warn"
        and "the calibration data had a 'flight' column (30 groups in 1,500 rows)" in check.detail
        and "are worth about" in check.detail
    )
    runs_check = next(c for c in cert.summary.checks if c.name == "what the runs support")
    assert (
        "30 calibration runs of 'flight'" in runs_check.detail
        and "needs at least 46 runs" in runs_check.detail
    )
    assert (
        "could also be counted per run" in check.detail
        and "recalibrate with Grouped(column='flight')" in check.detail
    )
    # recalibrated by flight, the record is dropped and the check is gone
    by_flight = calibrate(
        model, cal, 0.2, 0.05, Grouped(column="flight"), domain=DomainSpec(flag_rate=0.05), recalibrate=True
    )
    assert "calibration_group_like_columns" not in by_flight.metadata
    names = [
        c.name
        for c in certify(
            by_flight, _flights(make_lagged_perception(600, seed=92), 50)
        ).certificate.summary.checks
    ]
    assert "independent rows" not in names


def test_the_coverage_legend_hides_no_interval():
    """KITTI 00's test blocks (counts and violations per speed bin of a real run): the legend sat
    over the 8.07..8.7 bin's interval; the axes now leave room above the highest interval."""
    from ipcverify.certification._evaluation import BinCoverage
    from ipcverify.certification._report_plots import clopper_pearson_interval

    counts = (65, 64, 64, 64, 64, 64, 64, 64, 64, 65)
    viol = (0, 0, 0, 8, 8, 2, 14, 0, 9, 3)
    cov = BinCoverage(column="x_0", edges=tuple(np.linspace(0.0, 11.6, 11)), counts=counts, violations=viol)
    for epsilon in (0.1, 0.5, None):
        fig = plot_coverage(cov, 0.01, epsilon)
        fig.canvas.draw()
        ax = fig.axes[0]
        box = ax.get_legend().get_window_extent()
        tops = [clopper_pearson_interval(v, c, 0.01)[1] for v, c in zip(viol, counts, strict=True)]
        points = ax.transData.transform(np.column_stack([np.arange(len(counts)), tops]))
        assert not any(box.contains(px, py) for px, py in points), epsilon
        assert ax.get_ylim()[1] >= max([*tops, epsilon or 0.0])  # every interval drawn whole


def test_a_certified_verdict_on_queries_mostly_outside_the_domain_says_so():
    """Room change MH_04 -> V1_02 calibrated by flight: 'CERTIFIED ... consistent' with 87 % of the
    queries outside the domain; the verdict line (and the report's banner) now says so."""
    net = IPCModel(IPCNetwork(CFG))
    model = calibrate(net, make_lagged_perception(1500, seed=61), 0.5, 0.01)
    inside = certify(model, make_lagged_perception(1000, seed=62)).certificate
    t = make_lagged_perception(1000, seed=63)
    far = PerceptionDataset(t.x + np.r_[0, 0, 0, 0, 0, 3.0], t.y, t.yhat)  # x_5 moved: a shift
    shifted = certify(model, far).certificate
    assert inside.summary is not None and shifted.summary is not None
    assert inside.status is CertificateStatus.CERTIFIED and shifted.status is CertificateStatus.CERTIFIED
    assert inside.domain is not None and not inside.domain.well_above_flag_rate
    assert "outside the domain" not in inside.summary.verdict_text()
    assert shifted.domain is not None and shifted.domain.well_above_flag_rate
    pct = f"{100 * shifted.domain.outside_fraction:.0f} %"
    assert shifted.summary.verdict_text().endswith(
        f"; but {pct} of the test queries lie outside the domain of validity (a shift: the certificate "
        "promises nothing for them)"  # no run column recorded: no second explanation
    )
    import html

    banner = shifted.summary.verdict_text().split(": ", 1)[1]  # the report's banner: title, then this
    assert html.escape(banner) in render_report(certify(model, far))


def test_certify_takes_the_statistical_inputs_and_the_report_names_y():
    """Issue 39, item 4: units, labels and files belong to the report, not to certify()."""
    import inspect

    assert list(inspect.signature(certify).parameters) == [
        "model", "test_data", "train_data", "delta", "bin_column", "bins", "group_column", "lipschitz_radius",
    ]  # fmt: skip
    assert {"units", "labels"} <= set(inspect.signature(write_certificate).parameters)
