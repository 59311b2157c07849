"""Row fingerprints: the same row gives the same fingerprint after a file round trip; other rows do not."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from ipcverify.data._dataset import PerceptionDataset, load_dataset, save_dataset
from ipcverify.data._fingerprints import (
    BYTES_PER_ROW,
    DROPPED_BITS,
    ROWS_KEY,
    SCHEME,
    count_recorded,
    first_distinct_rows,
    first_occurrences,
    recorded_rows,
    rounded_bits,
    row_fingerprints,
    with_recorded_rows,
)
from ipcverify.data._synthetic import make_lagged_perception


def _wide_values(n: int, seed: int) -> np.ndarray:
    """Values over 60 decades, both signs, built from correctly rounded operations only."""
    rng = np.random.default_rng(seed)
    mantissa = 1.0 + rng.random(n)
    scale = np.array([2.0**e for e in rng.integers(-100, 100, n).tolist()])
    sign = np.where(rng.random(n) < 0.5, -1.0, 1.0)
    return sign * mantissa * scale


def test_the_rounding_is_float32_rounding_in_float32_range():
    v = _wide_values(200_000, seed=0)
    assert np.array_equal(rounded_bits(v).view(np.float64), v.astype(np.float32).astype(np.float64))


def test_the_rounding_keeps_float64_range_ties_to_even_and_signed_zero():
    huge = np.array([1e300, -1e-300, 3.5e38 * 2.0])  # outside float32: no overflow, no flush to zero
    r = rounded_bits(huge).view(np.float64)
    assert np.all(np.isfinite(r)) and np.all(r != 0) and np.all(np.abs(r - huge) <= np.abs(huge) * 2.0**-24)
    one = 1.0
    tie_down, tie_up = one + 2.0**-24, one + 3 * 2.0**-24  # halfway between 24-bit neighbours
    out = rounded_bits(np.array([tie_down, tie_up, -0.0, 0.0])).view(np.float64)
    assert out[0] == one and out[1] == one + 2 * 2.0**-23 and out[2] == 0.0 and out[3] == 0.0
    assert not np.signbit(out[2])
    assert DROPPED_BITS == 52 - 23


def _fp(ds: PerceptionDataset) -> np.ndarray:
    return row_fingerprints(ds)


@pytest.fixture(scope="module")
def data() -> PerceptionDataset:
    return make_lagged_perception(5000, seed=3)


@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".npz"])
def test_save_dataset_round_trips_keep_every_fingerprint(data, tmp_path, suffix):
    p = tmp_path / f"d{suffix}"
    save_dataset(data, p)
    assert np.array_equal(_fp(load_dataset(p)), _fp(data))


def test_a_pandas_csv_with_its_default_float_format_keeps_every_fingerprint(data, tmp_path):
    p = tmp_path / "pandas.csv"
    data.to_frame().to_csv(p, index=False)  # shortest round-trip text
    assert np.array_equal(_fp(load_dataset(p)), _fp(data))


@pytest.mark.parametrize("suffix", [".parquet", ".npz"])
def test_a_float32_copy_keeps_every_fingerprint(data, tmp_path, suffix):
    p = tmp_path / f"f32{suffix}"
    if suffix == ".parquet":
        data.to_frame().astype("float32").to_parquet(p, index=False)
    else:
        np.savez(
            p, x=data.x.astype(np.float32), y=data.y.astype(np.float32), yhat=data.yhat.astype(np.float32)
        )
    assert np.array_equal(_fp(load_dataset(p)), _fp(data))


def test_a_12_digit_text_keeps_nearly_every_fingerprint(data, tmp_path):
    """A value changes its rounding only within the text's error e = 5e-12 of a float32 boundary: a
    share e * 2^24 of the values at most, so at most 12 e 2^24 of the 12-value rows (binomial tail)."""
    p = tmp_path / "g12.csv"
    data.to_frame().to_csv(p, index=False, float_format="%.12g")
    changed = int((_fp(load_dataset(p)) != _fp(data)).sum())
    p_row = 12 * 5e-12 * 2.0**24
    assert changed <= stats.binom.isf(1e-9, len(data), p_row)


def test_shuffled_cut_and_repeated_copies_are_counted_row_by_row(data):
    fp = _fp(data)
    recorded = np.unique(fp)
    rng = np.random.default_rng(0)
    assert count_recorded(_fp(data.subset(rng.permutation(len(data)))), recorded) == len(data)
    assert count_recorded(_fp(data.subset(np.arange(1, len(data)))), recorded) == len(data) - 1
    twice = data.subset(np.r_[np.arange(len(data)), np.arange(len(data))])
    assert count_recorded(_fp(twice), recorded) == 2 * len(data)
    other = make_lagged_perception(3000, seed=4)
    assert count_recorded(_fp(other), recorded) == 0
    mixed = PerceptionDataset(
        np.vstack([other.x, data.x[:7]]),
        np.vstack([other.y, data.y[:7]]),
        np.vstack([other.yhat, data.yhat[:7]]),
    )
    assert count_recorded(_fp(mixed), recorded) == 7
    assert count_recorded(fp, np.array([], dtype=np.uint64)) == 0
    assert count_recorded(fp[:10], fp[::-1]) == 10  # unsorted, with repeats: the training data given


def test_rows_that_differ_in_one_value_beyond_float32_precision_are_different_rows(data):
    x = data.x.copy()
    x[:, 0] *= 1.0 + 2.0**-20  # a change float32 keeps
    assert count_recorded(_fp(PerceptionDataset(x, data.y, data.yhat)), np.unique(_fp(data))) == 0
    assert len(np.unique(_fp(data))) == len(data)  # no two of 5,000 distinct rows collide


def test_first_occurrences_keep_the_order_and_the_first_of_each_repeat():
    fp = np.array([7, 3, 7, 9, 3], dtype=np.uint64)
    assert first_occurrences(fp).tolist() == [0, 1, 3]
    assert first_distinct_rows(np.array([[1.0, -0.0], [2.0, 0.0], [1.0, 0.0]])).tolist() == [0, 1]


def test_recorded_rows_are_sorted_distinct_and_each_role_kept():
    meta = with_recorded_rows({"a": 1}, "training", np.array([9, 2, 9], dtype=np.uint64))
    meta = with_recorded_rows(meta, "calibration", np.array([5], dtype=np.uint64))
    assert recorded_rows(meta, "training").tolist() == [2, 9] and recorded_rows(
        meta, "calibration"
    ).tolist() == [5]
    again = with_recorded_rows(meta, "calibration", np.array([4], dtype=np.uint64))  # a recalibration
    assert recorded_rows(again, "calibration").tolist() == [4] and recorded_rows(
        again, "training"
    ).tolist() == [2, 9]
    assert meta["a"] == 1 and meta[ROWS_KEY]["scheme"] == SCHEME
    other = {ROWS_KEY: {**meta[ROWS_KEY], "scheme": "another scheme"}}
    assert recorded_rows(other, "training") is None  # not comparable: the overlap is unchecked
    assert recorded_rows({}, "training") is None
    assert BYTES_PER_ROW == np.dtype(np.uint64).itemsize
