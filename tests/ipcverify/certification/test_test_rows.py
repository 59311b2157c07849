"""certify() counts only fresh test rows, each distinct row once (ipcverify.certification._test_rows)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch

from ipcverify.calibration import Grouped
from ipcverify.certification._certify import certify, write_certificate
from ipcverify.certification._report import render_report
from ipcverify.certification._test_rows import TestRows, fresh_test_rows
from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._fingerprints import ROWS_KEY
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import DataError, DataWarning, Hint, InvalidInputError
from ipcverify.guard import DomainSpec
from ipcverify.guard._domain import DomainModel
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train


@pytest.fixture(scope="module")
def setup():
    torch.manual_seed(0)
    train_data = make_lagged_perception(1000, seed=60)
    cal_data = make_lagged_perception(1500, seed=61)
    test_data = make_lagged_perception(1200, seed=62)
    model = train(train_data, ModelConfig(x_dim=6, y_dim=3, hidden=(8,)), TrainConfig(epochs=1)).model
    return {
        "model": calibrate(model, cal_data, 0.1, 0.05),
        "train": train_data,
        "cal": cal_data,
        "test": test_data,
    }


def _rows(*parts: PerceptionDataset, source: str = "test.csv") -> PerceptionDataset:
    """The rows of ``parts`` one after another (extra columns kept when every part has them)."""
    extra = {}
    for name in parts[0].extra:
        extra[name] = np.concatenate([p.extra[name] for p in parts])
    arrays = (np.vstack([getattr(p, a) for p in parts]) for a in ("x", "y", "yhat"))
    return PerceptionDataset(*arrays, source=source, extra=extra)


def _copy(ds: PerceptionDataset, how: str) -> PerceptionDataset:
    n = len(ds)
    index = {
        "shuffled": np.random.default_rng(7).permutation(n),
        "minus one row": np.arange(1, n),
        "a tenth": np.arange(0, n, 10),
        "every row twice": np.r_[np.arange(n), np.arange(n)],
    }[how]
    return _rows(ds.subset(index))


@pytest.mark.parametrize("how", ["shuffled", "minus one row", "a tenth", "every row twice"])
@pytest.mark.parametrize("role", ["calibration", "training"])
def test_copies_of_calibration_or_training_rows_are_never_counted_as_fresh(setup, role, how):
    copy = _copy(setup["cal" if role == "calibration" else "train"], how)
    n = len(copy)
    with pytest.raises(
        InvalidInputError, match=rf"test.csv: {n:,} of {n:,} test rows are rows of the {role} data"
    ):
        certify(setup["model"], copy)


def test_one_reused_row_among_fresh_rows_is_enough_to_refuse_and_both_sets_are_counted(setup):
    mixed = _rows(setup["test"], setup["cal"].subset([3]), setup["train"].subset([4, 9]))
    with pytest.raises(
        InvalidInputError,
        match=r"test.csv: 1 of 1,203 test rows are rows of the calibration data, and 2 of 1,203 test rows "
        r"are rows of the training data \(by their row fingerprints\); a test counts only fresh rows",
    ):
        certify(setup["model"], mixed)


def test_repeated_test_rows_are_counted_once_and_do_not_tighten_the_bound(setup):
    model, test = setup["model"], setup["test"]
    once = certify(model, test).certificate
    rng = np.random.default_rng(8)
    repeats = test.subset(rng.integers(0, len(test), 500))  # 500 more rows, each a copy of a test row
    with pytest.warns(DataWarning, match=r"test.csv: 500 of 1,700 test rows repeat an earlier row"):
        res = certify(model, _rows(test, repeats))
    cert = res.certificate
    assert cert.test == once.test  # the same counts and bounds: the repeats are not counted
    assert cert.domain == once.domain and cert.coverage == once.coverage
    assert cert.test_rows == TestRows(n=1700, distinct=1200, training="rows", calibration="rows")
    assert cert.test_data.n == 1700  # the file as given
    assert len(res.evidence.violated) == 1200
    d = cert.to_dict()["test_rows"]
    assert (d["rows"], d["distinct"], d["repeated"], d["counted"]) == (1700, 1200, 500, 1200)
    assert d["calibration_rows"]["overlap"] == 0 and d["training_rows"]["by_rows"] is True
    check = next(c for c in cert.summary.checks if c.name == "fresh test rows")
    assert check.verdict == "500 repeated rows counted once" and check.level == "warn"
    assert "500 of 1,700 test rows repeat an earlier row" in check.detail
    page = render_report(res)
    assert "repeated rows (each distinct row is counted once)" in page


def test_twice_every_row_gives_the_bound_of_the_rows_once(setup):
    model, test = setup["model"], setup["test"]
    with pytest.warns(DataWarning):
        twice = certify(model, _rows(test, test)).certificate
    assert twice.test == certify(model, test).certificate.test
    assert twice.test_rows.repeated == 1200


def test_test_data_made_mostly_of_repeats_is_refused(setup):
    one = setup["test"].subset(np.zeros(1000, dtype=int))
    with pytest.raises(
        DataError, match=r"only 1 distinct row among 1000 test rows: a repeated row is one sample"
    ):
        certify(setup["model"], _rows(one))
    few = setup["test"].subset(np.r_[np.arange(10), np.zeros(11, dtype=int)])  # 10 distinct among 21
    with pytest.raises(DataError, match=r"only 10 distinct rows among 21 test rows"):
        fresh_test_rows(setup["model"], few)
    half = setup["test"].subset(np.r_[np.arange(10), np.arange(10)])  # 10 among 20: half repeat, not most
    with pytest.warns(DataWarning):
        assert len(fresh_test_rows(setup["model"], half)[0]) == 10


def test_clean_test_data_is_counted_as_given_and_the_page_says_it_was_checked(setup):
    model, test = setup["model"], setup["test"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        warnings.simplefilter("error", Hint)
        rows, record = fresh_test_rows(model, test)
        res = certify(model, test)
    assert rows is test and record == TestRows(n=1200, distinct=1200, training="rows", calibration="rows")
    cert = res.certificate
    assert cert.test.n == 1200 and cert.test_rows == record
    assert [c.name for c in cert.summary.checks if c.name == "fresh test rows"] == []
    held = next(c for c in cert.summary.checks if c.name == "held-out test")
    assert held.detail.endswith(
        "counted on 1,200 distinct test rows, none of them a training or calibration row (row fingerprints)"
    )


def test_a_run_level_claim_counts_the_distinct_rows_of_each_run(setup):
    model = setup["model"]

    def runs(ds: PerceptionDataset, size: int) -> PerceptionDataset:
        return PerceptionDataset(
            ds.x, ds.y, ds.yhat, source="runs.csv", extra={"run": np.arange(len(ds)) // size}
        )

    cal = runs(make_lagged_perception(3000, seed=63), 30)
    by_run = calibrate(
        model, cal, 0.2, 0.1, Grouped(column="run"), domain=DomainSpec(flag_rate=0.1), recalibrate=True
    )
    test = runs(make_lagged_perception(1200, seed=64), 20)
    once = certify(by_run, test).certificate
    # a run whose rows repeat: the run's share would be weighted by its repeats if they were counted
    doubled = _rows(test, test.subset(np.flatnonzero(test.extra["run"] == 0)), source="runs.csv")
    with pytest.warns(DataWarning, match=r"20 of 1,220 test rows repeat"):
        cert = certify(by_run, doubled).certificate
    assert cert.test == once.test and cert.test.statistic == "mean" and cert.test.n == 60
    assert cert.group_test == once.group_test


def test_a_model_file_without_row_fingerprints_checks_exact_copies_and_says_the_rest_is_unchecked(
    setup, tmp_path
):
    model = setup["model"]
    meta = {k: v for k, v in model.metadata.items() if k != ROWS_KEY}
    old = IPCModel(model.source, model.calibration, meta, model.domain)
    with pytest.raises(InvalidInputError, match=r"the test data is the calibration data"):
        certify(old, setup["cal"])
    shuffled = _copy(setup["cal"], "shuffled")
    with pytest.warns(Hint, match=r"records no fingerprints of its calibration rows .*only an exact copy"):
        res = certify(old, shuffled)  # not recognisable without the fingerprints: certified, and said so
    cert = res.certificate
    assert cert.test_rows.unchecked() == ("training", "calibration")
    check = next(c for c in cert.summary.checks if c.name == "fresh test rows")
    assert (
        check.verdict == "overlap with training rows not checked; overlap with calibration rows not checked"
    )
    assert "written before ipcverify recorded them" in check.detail and check.level == "warn"
    d = cert.to_dict()["test_rows"]
    assert d["calibration_rows"]["checked"] == "file" and d["calibration_rows"]["overlap"] is None
    write_certificate(res, tmp_path)
    assert "an exact copy of the whole file only" in (tmp_path / "report.html").read_text(encoding="utf-8")
    # the training data given for Theorem 1 stand in for the training rows' fingerprints
    with pytest.raises(InvalidInputError, match=r"999 of 999 test rows are rows of the training data"):
        certify(old, _copy(setup["train"], "minus one row"), train_data=setup["train"])
    with pytest.warns(Hint, match="calibration rows"):
        given = certify(old, setup["test"], train_data=setup["train"]).certificate.test_rows
    assert (given.training, given.calibration) == ("training data given", "file")


def test_a_domain_test_of_radius_0_from_an_old_model_file_is_named_as_such(setup):
    model, test = setup["model"], setup["test"]
    d = model.domain.to_dict()
    broken = DomainModel.from_dict({**d, "threshold": 0.0})
    cert = certify(IPCModel(model.source, model.calibration, model.metadata, broken), test).certificate
    check = next(c for c in cert.summary.checks if c.name == "domain of validity")
    assert (
        check.verdict.startswith("radius 0")
        and "recalibrate" in check.detail
        and "SHIFT" not in check.verdict
    )
    assert "radius 0" in cert.summary.status_detail
