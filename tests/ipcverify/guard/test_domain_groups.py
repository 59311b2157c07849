"""The group-aware domain test: leave-one-group-out distances and a risk-control threshold.

Samples of one flight sit close to each other, so a row-level threshold (each calibration
input's distance to its nearest *other* input, usually of the same flight) is far smaller than
a new flight's distances: it flags much of every new flight. The group-aware fit measures each
calibration input against other flights only and sets the threshold by conformal risk control
over the flights, so a new flight's expected share of flagged queries is at most the flag rate.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd
import pytest
from scipy.spatial import cKDTree

from benchmarks.bench_domain_groups import correlated_flights, figure, run
from ipcverify.calibration import Global, Grouped
from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError, SampleSizeError
from ipcverify.guard import DomainSpec
from ipcverify.guard._domain import DomainModel
from ipcverify.guard._neighbours import other_group_distances
from ipcverify.io._modelio import load_model, save_model
from ipcverify.network._architecture import ModelConfig

ALPHA = 0.05
#: Failure probability of the Bernstein bound on the mean flagged share below.
LEVEL = 1e-3


def _flagged_share(dom: DomainModel, z: np.ndarray) -> float:
    return float((~dom.contains(z[:, :3], z[:, 3:])).mean())


def test_other_group_distances_match_brute_force():
    rng = np.random.default_rng(0)
    for k in (1, 3):
        pts = rng.normal(size=(300, 3))
        codes = rng.integers(0, 7, size=300)
        codes[:120] = 0  # one large group: its points need more than one neighbour batch
        got = other_group_distances(cKDTree(pts), pts, codes.astype(np.intp), k)
        d = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=2)
        d[codes[:, None] == codes[None, :]] = np.inf
        want = np.sort(d, axis=1)[:, k - 1]
        np.testing.assert_allclose(got, want, rtol=1e-12)


def test_a_new_flight_is_flagged_at_most_the_flag_rate_on_average_where_the_row_level_test_flags_most():
    """Over independent seeded draws, the mean share of a new flight flagged is <= the flag rate up to a
    Bernstein bound (shares lie in [0, 1] with mean <= r, so variance <= r); the row-level
    threshold on the same data flags far more."""
    draws, shares, row_shares = 200, [], []
    for seed in range(draws):
        rng = np.random.default_rng(seed)
        z, labels = correlated_flights(rng, 60)
        new, _ = correlated_flights(rng, 5)  # five new flights, exchangeable with the calibration flights
        by_flight = DomainModel.fit(z[:, :3], z[:, 3:], flag_rate=ALPHA, groups=labels)
        shares.append(_flagged_share(by_flight, new))
        if seed < 20:
            row_shares.append(_flagged_share(DomainModel.fit(z[:, :3], z[:, 3:], flag_rate=ALPHA), new))
    log = math.log(1 / LEVEL)
    bound = ALPHA + math.sqrt(2 * ALPHA * log / draws) + log / (3 * draws)
    assert np.mean(shares) <= bound
    assert np.mean(row_shares) > 0.5  # the row-level test calls most of a new flight outside


def test_the_group_aware_test_still_flags_a_shift():
    rng = np.random.default_rng(3)
    z, labels = correlated_flights(rng, 100)
    dom = DomainModel.fit(z[:, :3], z[:, 3:], flag_rate=ALPHA, groups=labels)
    shifted, _ = correlated_flights(rng, 5)
    assert _flagged_share(dom, 4.0 * shifted) > 0.8  # ranges x4: mostly far from every flight
    assert dom.n_groups == 100 and "leave-one-group-out" in dom.method


def test_too_few_groups_and_bad_labels_are_refused():
    rng = np.random.default_rng(4)
    z, labels = correlated_flights(rng, 10)
    with pytest.raises(SampleSizeError, match="at least 19 groups"):
        DomainModel.fit(z[:, :3], z[:, 3:], flag_rate=ALPHA, groups=labels)
    with pytest.raises(InvalidInputError, match="groups of shape"):
        DomainModel.fit(z[:, :3], z[:, 3:], flag_rate=ALPHA, groups=labels[:-1])


def test_too_few_groups_names_the_smallest_flag_rate_they_allow_and_it_fits():
    """The refusal says how large the flag rate must be, and that value is accepted."""
    rng = np.random.default_rng(4)
    z, labels = correlated_flights(rng, 6)
    with pytest.raises(
        SampleSizeError, match=r"with 6 groups the flag rate must be at least 1/7: flag_rate="
    ) as info:
        DomainModel.fit(z[:, :3], z[:, 3:], flag_rate=ALPHA, groups=labels)
    smallest = float(re.search(r"flag_rate=([0-9.]+) works\)", str(info.value)).group(1))
    assert 1 / 7 <= smallest < 1 / 7 + 0.001  # eps (G + 1) >= 1, to 3 significant digits
    dom = DomainModel.fit(z[:, :3], z[:, 3:], flag_rate=smallest, groups=labels)
    assert dom.n_groups == 6
    with pytest.raises(SampleSizeError, match="at least 7 groups"):
        DomainModel.fit(z[:, :3], z[:, 3:], flag_rate=1 / 7 - 1e-9, groups=labels)


def _dataset(z: np.ndarray, labels: np.ndarray, rng: np.random.Generator) -> PerceptionDataset:
    y = z[:, 3:] + 0.01 * rng.normal(size=(len(z), 2))
    return PerceptionDataset(z[:, :3], y, z[:, 3:], extra={"flight": labels})


def test_calibrate_fits_the_domain_by_flight_and_the_model_file_keeps_it(tmp_path):
    rng = np.random.default_rng(5)
    z, labels = correlated_flights(rng, 120)
    data = _dataset(z, labels, rng)
    net = IPCModel(IPCNetwork(ModelConfig.recipe("v1", x_dim=3, y_dim=2, hidden=(8,))))
    rows = calibrate(net, data, 0.05, 0.01, Global())  # row-level claims, chosen explicitly
    flights = calibrate(
        net, data, 0.05, 0.01, Global(), domain=DomainSpec(flag_rate=ALPHA, group_column="flight")
    )
    grouped = calibrate(
        net, data, 0.05, 0.01, Grouped(column="flight", mode="marginal"), domain=DomainSpec(flag_rate=ALPHA)
    )
    assert rows.domain is not None and rows.domain.n_groups is None
    assert flights.domain is not None and grouped.domain is not None
    assert flights.domain.n_groups == grouped.domain.n_groups == 120
    assert flights.domain.threshold > rows.domain.threshold  # other flights lie farther than one's own rows
    save_model(flights, tmp_path / "m.pt")
    back = load_model(tmp_path / "m.pt").domain
    assert back is not None and back.n_groups == 120 and back.threshold == flights.domain.threshold


def test_cli_calibrate_domain_group_column(tmp_path, run_cli):
    rng = np.random.default_rng(6)
    z, labels = correlated_flights(rng, 120)
    frame = pd.DataFrame(z[:, :3], columns=[f"x_{i}" for i in range(3)])
    for i in range(2):
        frame[f"y_{i}"] = z[:, 3 + i] + 0.01 * rng.normal(size=len(z))
        frame[f"yhat_{i}"] = z[:, 3 + i]
    frame["flight"] = labels
    frame.to_csv(tmp_path / "cal.csv", index=False)
    net = IPCNetwork(ModelConfig.recipe("v1", x_dim=3, y_dim=2, hidden=(8,)))
    save_model(IPCModel(net), tmp_path / "m.pt")
    args = ["calibrate", tmp_path / "m.pt", tmp_path / "cal.csv", "--epsilon", "0.05", "--delta", "0.01",
            "--domain-flag-rate", "0.05", "--unit", "row", "--out", tmp_path / "cal.pt"]  # fmt: skip
    res = run_cli(*args, "--domain-group-column", "flight")
    assert res.code == 0, res.stderr
    dom = load_model(tmp_path / "cal.pt").domain
    assert dom is not None and dom.n_groups == 120
    res = run_cli(*args, "--domain-group-column", "nope", "--force")
    assert res.code == 2 and "nope" in res.stderr and len(res.stderr.strip().splitlines()) == 1


def test_the_benchmark_reports_both_fits_and_draws_its_figure(tmp_path):
    result = run(draws=4)
    mean = result["mean_flagged_share"]
    assert set(mean) == {"rows_new", "flight_new", "rows_shifted", "flight_shifted"}
    assert mean["rows_new"] > mean["flight_new"] and min(mean["rows_shifted"], mean["flight_shifted"]) > 0.5
    figure(result, tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 10_000
