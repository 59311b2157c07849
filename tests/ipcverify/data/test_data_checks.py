"""Degenerate data refused, weak data warned about, correlated rows hinted at (ipcverify.data._checks)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ipcverify.calibration import Global, Grouped
from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.data._checks import (
    check_informative,
    group_like_counts,
    input_ranges,
    warn_correlated_rows,
    warn_out_of_time_order,
    warn_outside_training,
)
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import DataError, DataWarning, Hint
from ipcverify.guard import DomainSpec
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train


def _ds(x, y=None, yhat=None, **extra) -> PerceptionDataset:
    x = np.asarray(x, dtype=float).reshape(len(x), -1)
    y = np.arange(len(x), dtype=float)[:, None] if y is None else y
    yhat = y + 0.5 if yhat is None else yhat
    return PerceptionDataset(x, y, yhat, source="log.csv", extra=extra)


def test_identical_rows_are_refused_for_training_and_calibration():
    same = PerceptionDataset(np.ones((2855, 2)), np.ones((2855, 1)), np.ones((2855, 1)), source="log.csv")
    for purpose in ("training", "calibration"):
        with pytest.raises(
            DataError, match=rf"log.csv: only 1 distinct row among 2855: .* {purpose} would count"
        ):
            check_informative(same, purpose)  # type: ignore[arg-type]


def test_mostly_repeated_rows_are_refused_and_a_few_are_a_warning():
    base = make_lagged_perception(100, seed=0)
    half = base.subset(np.r_[np.arange(49), np.zeros(51, dtype=int)])  # 49 distinct of 100
    with pytest.raises(DataError, match="only 49 distinct rows among 100"):
        check_informative(half, "calibration")
    few = base.subset(np.r_[np.arange(100), [3, 4]])
    with pytest.warns(DataWarning, match="2 of 102 training rows repeat an earlier row"):
        check_informative(few, "training")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_informative(base, "training")  # distinct rows, no constant column: silent


def test_constant_columns_are_all_named_refused_for_training_and_warned_for_calibration():
    x = np.column_stack([np.full(50, 2.0), np.arange(50.0), np.full(50, -1.0)])
    ds = _ds(x)
    with pytest.raises(
        DataError, match=r"columns x_0 \(every row is 2\), x_2 \(every row is -1\) are constant"
    ):
        check_informative(ds, "training")
    with pytest.warns(DataWarning, match=r"calibration columns x_0 .* x_2 .* domain of validity flags"):
        check_informative(ds, "calibration")


def test_train_refuses_constant_data_and_stores_the_input_ranges():
    ds = make_lagged_perception(200, seed=0)
    flat = PerceptionDataset(ds.x * np.r_[0.0, 1, 1, 1, 1, 1], ds.y, ds.yhat, source="flat.csv")
    with pytest.raises(DataError, match="flat.csv: column x_0 .* is constant"):
        train(flat, train_config=TrainConfig(epochs=1))
    model = train(ds, ModelConfig(x_dim=6, y_dim=3, hidden=(4,), members=1), TrainConfig(epochs=1)).model
    ranges = model.metadata["training_inputs"]
    assert ranges == input_ranges(ds) and ranges["columns"][6:] == ["yhat_0", "yhat_1", "yhat_2"]
    assert ranges["lower"][0] == float(ds.x[:, 0].min()) and ranges["upper"][8] == float(ds.yhat[:, 2].max())


def test_calibration_far_from_the_training_inputs_is_a_warning():
    ds = make_lagged_perception(400, seed=0)
    meta = {"training_inputs": input_ranges(ds)}
    near = make_lagged_perception(400, seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        share = warn_outside_training(meta, near)
    assert share is not None and share < 0.2  # fresh draws: a few extremes beyond the training range
    far = PerceptionDataset(near.x + np.r_[0, 0, 0, 100.0, 0, 0], near.y, near.yhat, source="far.csv")
    with pytest.warns(
        DataWarning, match=r"far.csv: 100 % of the calibration inputs lie outside .*\(x_3: 100 %"
    ):
        assert warn_outside_training(meta, far) == 1.0
    assert warn_outside_training({}, far) is None  # a model from before the ranges were stored
    few = make_lagged_perception(10, seed=3)  # 10 training rows, 9 inputs: any share outside is expected
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert warn_outside_training({"training_inputs": input_ranges(few)}, near) > 0.5


def test_calibrate_warns_far_from_training_and_hints_at_runs(recwarn):
    ds = make_lagged_perception(600, seed=0)
    model = IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(4,), param="cholesky")))
    model = IPCModel(model.network, None, {"training_inputs": input_ranges(ds)})
    cal = make_lagged_perception(1500, seed=1)
    runs = np.repeat(np.arange(15), 100)
    far = PerceptionDataset(
        cal.x - np.r_[50.0, 0, 0, 0, 0, 0], cal.y, cal.yhat, source="cal.csv", extra={"run": runs}
    )
    calibrate(model, far, 0.05, 0.01, Global())  # a row-level claim on runs, chosen explicitly
    messages = [(w.category, str(w.message)) for w in recwarn]
    assert any("lie outside the ranges of the training inputs" in m for c, m in messages if c is DataWarning)
    hint = [m for c, m in messages if c is Hint]
    assert len(hint) == 1 and "a row-level claim on data with runs of 'run'" in hint[0]
    assert "1,500 rows in 15 runs of 'run'" in hint[0] and "Grouped(column='run')" in hint[0]
    recwarn.clear()
    calibrate(model, far, 0.3, 0.2, Grouped(column="run"), domain=DomainSpec(flag_rate=0.1))
    assert not [w for w in recwarn if w.category is Hint]  # grouped by choice: no hint


def test_group_like_counts_need_a_fitting_name_and_more_than_one_group():
    n = 12
    ds = _ds(
        np.arange(n),
        Flight_ID=np.repeat(["a", "b", "c"], 4),
        sequence=np.full(n, "MH_04"),  # one group: nothing to be correlated with
        run=np.arange(n),  # one row per run: not a group
        t=np.arange(n),
    )
    assert group_like_counts(ds) == {"Flight_ID": 3}
    two = _ds(np.arange(n), run=np.tile([0, 1], 6), flight=np.repeat(["a", "b", "c"], 4))
    assert list(group_like_counts(two).items()) == [("flight", 3), ("run", 2)]  # the most groups first
    with pytest.warns(Hint, match=r"group_column=\'flight\' \(or group_column=\'run\'\)"):
        warn_correlated_rows(two, "calibrating", "to calibrate by group")
    with pytest.warns(Hint, match=r"log.csv has a 'Flight_ID' column \(3 groups\).*certifying row by row"):
        warn_correlated_rows(ds, "certifying", "to count per group")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_correlated_rows(_ds(np.arange(n), t=np.arange(n)), "calibrating", "x")


def test_a_log_out_of_time_order_within_a_run_gets_a_hint_and_one_in_order_none():
    from pathlib import Path

    from ipcverify.data._dataset import load_dataset
    from ipcverify.errors import Hint

    log = load_dataset(Path(__file__).resolve().parents[3] / "data" / "euroc_mh04_vislam.csv")
    with warnings.catch_warnings():  # 20 runs, each in time order (the clock restarts per run)
        warnings.simplefilter("error", Hint)
        warn_out_of_time_order(log, "the monitor replays")
    swapped = np.arange(len(log))
    swapped[[10, 11]] = [11, 10]  # two rows of run 0 swapped
    back = r"column 't' goes back in time at row 11 \(0-based\) within run 0, from 2\.75 to 2\.5"
    with pytest.warns(Hint, match=back):
        warn_out_of_time_order(log.subset(swapped), "the monitor replays")
    # without a column naming runs, a restart of the clock may be a new run: the hint says so
    flat = _ds(np.arange(4), t=np.array([0.0, 1.0, 0.0, 1.0]))
    with pytest.warns(Hint, match=r"at row 2 \(0-based\), from 1 to 0.*or a new run starts there"):
        warn_out_of_time_order(flat, "the monitor replays")
    # text in a column called t is not a clock
    with warnings.catch_warnings():
        warnings.simplefilter("error", Hint)
        warn_out_of_time_order(_ds(np.arange(3), t=np.array(["b", "a", "c"])), "the monitor replays")


@pytest.mark.parametrize(("groups", "too_few"), [(2, True), (4, True), (6, True), (7, False), (30, False)])
def test_the_runs_hint_says_when_the_runs_are_too_few_to_be_the_units(groups, too_few):
    """KITTI 00, TUM and the ROS example bag hold 2 runs: the hint offered --group-column run, which
    can certify no epsilon below 0.9 at delta 0.01; it now says so and suggests time blocks."""
    from ipcverify.calibration._bounds import smallest_epsilon

    n = 60
    data = PerceptionDataset(
        np.zeros((n, 1)), np.zeros((n, 1)), np.zeros((n, 1)), extra={"run": np.arange(n) % groups}
    )
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        warn_correlated_rows(data, "calibrating", "to calibrate by run")
    (text,) = [str(w.message) for w in seen if issubclass(w.category, Hint)]
    assert text.count("group_column='run'") == 1
    floor = smallest_epsilon(groups, 0.01)  # the calibration's own number, by group
    assert (f"can certify no epsilon below {floor:.2g} at delta = 0.01" in text) is too_few
    assert ("contiguous time blocks" in text) is too_few
