"""calibrate() and the training rows: no calibration row may be a training row, in any order or number."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch

from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._fingerprints import ROWS_KEY, recorded_rows, row_fingerprints
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import DataWarning, Hint, InvalidInputError
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train


@pytest.fixture(scope="module")
def trained():
    torch.manual_seed(0)
    data = make_lagged_perception(1200, seed=30)
    model = train(data, ModelConfig(x_dim=6, y_dim=3, hidden=(8,)), TrainConfig(epochs=1)).model
    return model, data


def _stack(*parts: PerceptionDataset) -> PerceptionDataset:
    return PerceptionDataset(
        *(np.vstack([getattr(p, a) for p in parts]) for a in ("x", "y", "yhat")), source="cal.csv"
    )


def test_training_records_the_fingerprint_of_every_training_row(trained):
    model, data = trained
    rows = recorded_rows(model.metadata, "training")
    np.testing.assert_array_equal(rows, np.unique(row_fingerprints(data)))
    assert len(rows) == 1200 and rows.nbytes == 8 * 1200


@pytest.mark.parametrize(
    ("copy", "reused", "n"),
    [
        ("minus one row", 1199, 1199),
        ("shuffled", 1200, 1200),
        ("every row twice", 2400, 2400),
        ("three training rows among fresh ones", 3, 1503),
    ],
)
def test_calibration_rows_that_are_training_rows_are_refused_and_counted(trained, copy, reused, n):
    model, data = trained
    fresh = make_lagged_perception(1500, seed=31)
    cal = {
        "minus one row": _stack(data.subset(np.arange(1, 1200))),
        "shuffled": _stack(data.subset(np.random.default_rng(1).permutation(1200))),
        "every row twice": _stack(data, data),
        "three training rows among fresh ones": _stack(fresh, data.subset([5, 50, 500])),
    }[copy]
    with pytest.raises(
        InvalidInputError,
        match=rf"cal.csv: {reused:,} of {n:,} calibration rows are rows of the model's training data "
        r"\(by the fingerprints of the 1,200 training rows the model file records\); calibration needs",
    ):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DataWarning)  # the repeated rows of "every row twice"
            calibrate(model, cal, 0.1, 0.05)


def test_calibration_records_its_rows_keeps_the_training_rows_and_a_recalibration_replaces_them(trained):
    model, _ = trained
    first, second = make_lagged_perception(800, seed=32), make_lagged_perception(900, seed=33)
    once = calibrate(model, first, 0.1, 0.05)
    np.testing.assert_array_equal(
        recorded_rows(once.metadata, "calibration"), np.unique(row_fingerprints(first))
    )
    np.testing.assert_array_equal(
        recorded_rows(once.metadata, "training"), recorded_rows(model.metadata, "training")
    )
    again = calibrate(once, second, 0.1, 0.05, recalibrate=True)
    np.testing.assert_array_equal(
        recorded_rows(again.metadata, "calibration"), np.unique(row_fingerprints(second))
    )
    assert recorded_rows(model.metadata, "calibration") is None  # the trained model is unchanged


def test_a_model_without_training_fingerprints_checks_the_exact_copy_and_says_so(trained):
    model, data = trained
    old = IPCModel(model.source, None, {k: v for k, v in model.metadata.items() if k != ROWS_KEY})
    with pytest.raises(InvalidInputError, match=r"this is the model's training data"):
        calibrate(old, data, 0.1, 0.05)
    shuffled = data.subset(np.random.default_rng(2).permutation(1200))
    with pytest.warns(Hint, match=r"records no fingerprints of its training rows .*only an exact copy"):
        calibrate(old, shuffled, 0.1, 0.05)  # cannot be recognised: calibrated, with the hint
    with warnings.catch_warnings():
        warnings.simplefilter("error", Hint)  # a network trained elsewhere: nothing recorded, nothing to say
        calibrate(IPCModel(model.source), make_lagged_perception(800, seed=34), 0.1, 0.05)


def test_repeated_calibration_rows_are_said_to_break_exchangeability_with_their_number(trained):
    model, _ = trained
    cal = make_lagged_perception(800, seed=35)
    with pytest.warns(DataWarning) as caught:
        doubled = calibrate(model, _stack(cal, cal.subset(np.arange(300))), 0.1, 0.05)
    text = " ".join(str(w.message) for w in caught)
    assert "300 of 1,100 calibration rows repeat an earlier row (800 distinct)" in text
    assert "breaks that exchangeability" in text
    assert doubled.domain is not None and doubled.domain.n == 800 and doubled.domain.threshold > 0
