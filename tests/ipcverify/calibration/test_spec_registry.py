"""Calibration kinds as spec objects: a toy kind defined only here registers itself with one line and
is fitted by calibrate(), read back from a model file and certified; the built-in specs check their
options and fit exactly what their calibration classes fit; the registry refuses clashes."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from ipcverify.calibration import Global, Grouped, Mondrian
from ipcverify.calibration._global_scale import GlobalCalibration
from ipcverify.calibration._grouped import GroupedCalibration
from ipcverify.calibration._kinds import KINDS, METHODS, calibration_from_dict, register_kind
from ipcverify.calibration._method import CalibrationRecord, CalibrationSample, CalibrationSpec
from ipcverify.calibration._mondrian import MondrianCalibration
from ipcverify.calibration._protocol import GroupInfo
from ipcverify.calibration._threshold import threshold_scores
from ipcverify.certification import certify
from ipcverify.contract import IPCModel, calibrate
from ipcverify.data import PerceptionDataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import Hint, InvalidInputError
from ipcverify.guard import DomainModel, DomainSpec
from ipcverify.io import load_model, save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.network._modules import IPCNetwork

TOY = "every-other-row"


# ------------------------------------------------------------------ a new kind, one module's worth
@dataclass(frozen=True, kw_only=True)
class EveryOtherRowCalibration(GlobalCalibration):
    """A toy kind: the global order statistic of every other calibration row (valid, and wasteful).

    It answers the Calibration protocol as a global calibration does, under its own kind.
    """

    kind: ClassVar[str] = TOY

    def groups(self) -> tuple[GroupInfo, ...]:
        t = self.threshold
        return (GroupInfo(label="every other row", n=t.n, k=t.k, scale=t.scale),)


@dataclass(frozen=True, kw_only=True)
class EveryOtherRow(CalibrationSpec):
    """The toy kind's spec: what a user passes to calibrate()."""

    kind: ClassVar[str] = TOY
    record: ClassVar[CalibrationRecord] = EveryOtherRowCalibration

    def fit(self, sample: CalibrationSample) -> EveryOtherRowCalibration:
        t = threshold_scores(sample.scores[::2], sample.epsilon, sample.delta, self.mode)
        return EveryOtherRowCalibration(threshold=t, **sample.ids)


@pytest.fixture
def registered():
    """The toy kind registered (the one line a new kind adds), and removed again afterwards."""
    register_kind(EveryOtherRow)
    yield EveryOtherRow
    del METHODS[TOY], KINDS[TOY]


@pytest.fixture(scope="module")
def model():
    return IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")))


@pytest.fixture(scope="module")
def cal_data():
    return make_lagged_perception(2000, seed=41)


def test_an_unregistered_kind_is_refused(model, cal_data):
    assert TOY not in METHODS
    with pytest.raises(
        InvalidInputError, match=r"kind 'every-other-row' \(EveryOtherRow\) is not registered"
    ):
        calibrate(model, cal_data, 0.1, 0.05, EveryOtherRow())


def test_a_registered_toy_kind_is_fitted_saved_read_back_and_certified(registered, model, cal_data, tmp_path):
    cal_model = calibrate(model, cal_data, 0.1, 0.05, registered())
    cal = cal_model.calibration
    assert cal.kind == TOY and isinstance(cal, EveryOtherRowCalibration)
    scores = model.raw_scores(cal_data.x, cal_data.y, cal_data.yhat)
    assert cal.threshold == threshold_scores(scores[::2], 0.1, 0.05, "pac")
    assert cal.data_hash == cal_data.content_hash()
    # the rest of the pipeline reads it through the protocol only
    sets = cal_model.predict_unguarded(cal_data.x[:50], cal_data.yhat[:50])
    raw = model.predict_raw(cal_data.x[:50], cal_data.yhat[:50])
    np.testing.assert_allclose(sets.shapes, raw.shapes / cal.threshold.scale, rtol=1e-12)
    save_model(cal_model, tmp_path / "toy.pt")
    back = load_model(tmp_path / "toy.pt")
    assert back.calibration == cal and calibration_from_dict(cal.to_dict()) == cal
    cert = certify(back, make_lagged_perception(1500, seed=42)).certificate
    assert cert.calibration is not None and cert.calibration.kind == TOY
    assert cert.calibration.groups[0].label == "every other row"


def test_the_registry_refuses_a_clash_and_a_mismatched_record(registered):
    assert register_kind(registered) is registered  # registering the same spec again is harmless

    @dataclass(frozen=True)
    class Impostor(EveryOtherRow):
        pass

    with pytest.raises(
        InvalidInputError, match=r"kind 'every-other-row' is already registered \(by EveryOtherRow\)"
    ):
        register_kind(Impostor)

    @dataclass(frozen=True)
    class Mismatched(EveryOtherRow):
        kind: ClassVar[str] = "other-name"

    with pytest.raises(InvalidInputError, match=r"fits kind 'other-name' but its record class is of kind"):
        register_kind(Mismatched)
    assert "other-name" not in METHODS and METHODS[TOY] is EveryOtherRow


def test_the_built_in_kinds_are_registered_by_name():
    assert {k: METHODS[k] for k in ("global", "mondrian", "grouped")} == {
        "global": Global,
        "mondrian": Mondrian,
        "grouped": Grouped,
    }
    assert [KINDS[k] for k in ("global", "mondrian", "grouped")] == [
        GlobalCalibration,
        MondrianCalibration,
        GroupedCalibration,
    ]
    for name, spec in METHODS.items():
        assert spec.kind == name and KINDS[name] is spec.record


# ------------------------------------------------------------------ the built-in specs
def _flights(data: PerceptionDataset, per_flight: int) -> PerceptionDataset:
    flight = np.arange(len(data)) // per_flight
    return PerceptionDataset(data.x, data.y, data.yhat, extra={"flight": flight}, source="flights")


def test_each_spec_fits_what_its_calibration_class_fits():
    data = _flights(make_lagged_perception(3000, seed=43), 15)
    scores = np.random.default_rng(0).random(len(data)) ** 2
    ids = {"data_hash": "d", "network_hash": "h"}
    sample = CalibrationSample(scores=scores, data=data, epsilon=0.1, delta=0.05, **ids)
    assert Global(mode="marginal").fit(sample) == GlobalCalibration.fit(scores, 0.1, 0.05, "marginal", **ids)
    mondrian = Mondrian(column="x_3", bins=3, edge_fraction=0.25, seed=7)
    assert mondrian.fit(sample) == MondrianCalibration.fit(
        scores,
        data.x[:, 3],
        column="x_3",
        source="x",
        index=3,
        bins=3,
        epsilon=0.1,
        delta=0.05,
        mode="pac",
        edge_fraction=0.25,
        seed=7,
        **ids,
    )
    for guarantee in ("sample", "trajectory"):
        for mode in ("pac", "marginal"):
            spec = Grouped(column="flight", guarantee=guarantee, seed=3, mode=mode)
            assert spec.unit_column == "flight"
            assert spec.fit(sample) == GroupedCalibration.fit(
                scores,
                data.column("flight"),
                0.1,
                0.05,
                mode,
                guarantee=guarantee,
                column="flight",
                seed=3,
                **ids,
            )


def test_the_domain_spec_fits_what_domain_model_fits(model):
    data = _flights(make_lagged_perception(2000, seed=44), 10)
    with pytest.warns(Hint, match=r"a row-level claim on data with runs of 'flight' \(chosen explicitly\)"):
        rows = calibrate(model, data, 0.1, 0.05, Global(), domain=DomainSpec(flag_rate=0.05, k=2))
    ref = DomainModel.fit(data.x, data.yhat, flag_rate=0.05, k=2, seed=0)
    assert (rows.domain.threshold, rows.domain.k, rows.domain.n_groups) == (ref.threshold, 2, ref.n_groups)
    # a grouped calibration's column is the domain test's units unless the spec names another
    by_flight = calibrate(model, data, 0.1, 0.05, Grouped(column="flight"), domain=DomainSpec(flag_rate=0.05))
    grouped_ref = DomainModel.fit(data.x, data.yhat, flag_rate=0.05, groups=data.column("flight"))
    assert by_flight.domain.n_groups == 200 and by_flight.domain.threshold == grouped_ref.threshold
    with pytest.warns(Hint, match=r"its rows come in runs of 'flight', so the claim is about runs"):
        auto = calibrate(model, data, 0.1, 0.05, domain=None)
    assert auto.domain is None and auto.calibration.kind == "grouped" and auto.calibration.n_groups == 200


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: Global(mode="bayes"), r"mode must be 'pac' or 'marginal'; got 'bayes'"),
        (lambda: Mondrian(column=""), r"a Mondrian calibration needs a column name"),
        (lambda: Mondrian(column="x_1", bins=0), r"bins must be a positive integer; got 0"),
        (lambda: Mondrian(column="x_1", bins=True), r"bins must be a positive integer; got True"),
        (lambda: Mondrian(column="x_1", edge_fraction=1.0), r"edge_fraction must lie in \(0, 1\); got 1.0"),
        (lambda: Mondrian(column="x_1", seed=1.5), r"seed must be an integer; got 1.5"),
        (
            lambda: Grouped(column="run", guarantee="always"),
            r"guarantee must be 'expected-share'.*got 'always'",
        ),
        (lambda: Grouped(column="run", guarantee="share-of-runs"), r"a share-of-runs claim needs gamma"),
        (lambda: Grouped(column="run", gamma=0.2), r"gamma goes with the share-of-runs claim only"),
        (
            lambda: Grouped(column="run", guarantee="share-of-runs", gamma=1.0),
            r"gamma must lie strictly between 0 and 1; got 1.0",
        ),
        (lambda: Grouped(column=None), r"a grouped calibration needs a group column name; got None"),
        (lambda: Grouped(column="run", seed=True), r"seed must be an integer; got True"),
        (lambda: Grouped(column="run", mode="conformal"), r"mode must be 'pac' or 'marginal'"),
        (
            lambda: DomainSpec(flag_rate=0.0),
            r"domain test: flag_rate must lie strictly between 0 and 1; got 0.0",
        ),
        (lambda: DomainSpec(k=0), r"domain test: k must be a positive integer; got 0"),
        (lambda: DomainSpec(group_column=""), r"domain test: group_column must be a column name"),
    ],
)
def test_specs_refuse_bad_options_when_made(make, message):
    with pytest.raises(InvalidInputError, match=message):
        make()


def test_specs_are_frozen_and_keyword_only():
    spec = Grouped(column="run")
    with pytest.raises(AttributeError):
        spec.column = "flight"  # type: ignore[misc]
    with pytest.raises(TypeError):
        Grouped("run")  # type: ignore[misc]
    assert (spec.guarantee, spec.gamma, spec.seed, spec.mode) == ("expected-share", None, 0, "pac")
    assert Mondrian(column="x_0") == Mondrian(column="x_0", bins=None, edge_fraction=0.2, seed=0, mode="pac")
