"""Tests of dataset loading, validation, splitting and saving."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from ipcverify.data._dataset import PerceptionDataset, load_dataset, save_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import DataError


@pytest.fixture
def small() -> PerceptionDataset:
    return make_lagged_perception(50, seed=3)


@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".npz"])
def test_roundtrip_formats(tmp_path, small, suffix):
    p = tmp_path / f"d{suffix}"
    save_dataset(small, p)
    back = load_dataset(p)
    assert np.array_equal(back.x, small.x)
    assert np.array_equal(back.y, small.y)
    assert np.array_equal(back.yhat, small.yhat)
    assert back.content_hash() == small.content_hash()


def test_custom_columns_and_extra(tmp_path):
    df = pd.DataFrame(
        {
            "speed": [1.0, 2.0],
            "px": [0.1, 0.2],
            "py": [0.3, 0.4],
            "ex": [0.1, 0.25],
            "ey": [0.3, 0.4],
            "grp": ["a", "b"],
        }
    )
    p = tmp_path / "c.csv"
    df.to_csv(p, index=False)
    ds = load_dataset(p, x_columns=["speed"], y_columns=["px", "py"], yhat_columns=["ex", "ey"])
    assert ds.x_dim == 1 and ds.y_dim == 2
    assert list(ds.column("grp")) == ["a", "b"]
    assert ds.column("py")[1] == 0.4


def test_split_is_deterministic_and_disjoint(small):
    a = small.split((0.6, 0.2, 0.2), seed=7)
    b = small.split((0.6, 0.2, 0.2), seed=7)
    c = small.split((0.6, 0.2, 0.2), seed=8)
    assert np.array_equal(a.train.x, b.train.x) and np.array_equal(a.test.y, b.test.y)
    assert not np.array_equal(a.train.x, c.train.x)
    rows = np.concatenate([a.train.x, a.calibration.x, a.test.x])
    assert len(rows) == len(small)
    assert len(np.unique(rows, axis=0)) == len(small)
    assert (len(a.train), len(a.calibration), len(a.test)) == (30, 10, 10)


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


#: (file name, content, column names passed, the error): each refusal names the file, the row
#: and the column at fault.
BAD_FILES = [
    pytest.param("m.csv", "x_0,y_0,y_1,yhat_0\n1,2,3,4\n", {}, r"m\.csv: y has 2 columns but yhat has 1",
                 id="missing-column-named"),
    pytest.param("n.csv", "x_0,y_0\n1,2\n", {}, r"n\.csv: no yhat columns \(expected yhat_0",
                 id="no-yhat-columns"),
    pytest.param("g.csv", "x_0,x_2,y_0,yhat_0\n1,2,3,4\n", {}, r"missing x_1", id="gap-in-numbering"),
    pytest.param("e.csv", "x_0,y_0,yhat_0\n1,2,3\n", {"x_columns": ["speed"]}, r"missing column\(s\) speed",
                 id="explicit-missing-column"),
    pytest.param("f.csv", "x_0,y_0,yhat_0\n1,2,3\n1,nan,3\n", {},
                 r"f\.csv: row 1 \(0-based\), column 'y_0': non-finite value", id="non-finite"),
    pytest.param("na.csv", "x_0,y_0,yhat_0\n1,2,3\nn/a,2,3\n", {},
                 r"row 1 \(0-based\), column 'x_0': non-finite value nan \(an empty cell, or text such as NA",
                 id="na-text"),
    pytest.param("inf.csv", "x_0,y_0,yhat_0\n1,2,3\ninf,2,3\n", {},
                 r"row 1 \(0-based\), column 'x_0': non-finite value inf; drop", id="infinite"),
    pytest.param("t.csv", "x_0,y_0,yhat_0\n1,2,3\n1,2,abc\n", {},
                 r"t\.csv: row 1 \(0-based\), column 'yhat_0': not a number \('abc'\)", id="non-numeric"),
    pytest.param("empty.csv", "", {}, r"empty\.csv: the file is empty", id="empty-file"),
    pytest.param("h.csv", "x_0,y_0,yhat_0\n", {}, r"h\.csv: the file has a header but no samples",
                 id="header-only"),
    pytest.param("d.json", "{}", {}, r"unknown data format '\.json'", id="unknown-suffix"),
    pytest.param("s.csv", "x_0, y_0, yhat_0\n1,2,3\n", {},
                 r"s\.csv: no y columns .*the column names ' y_0', ' yhat_0' have spaces around them",
                 id="spaces-in-header"),
    pytest.param("tw.csv", "x_0,x_1,y_0,yhat_0\n1,2,3,4\n", {"x_columns": ["x_0", "x_0"]},
                 r"tw\.csv: column 'x_0' is twice among the x columns", id="column-listed-twice"),
    pytest.param("ty.csv", "x_0,y_0,yhat_0\n1,2,3\n", {"x_columns": ["x_0", "y_0"]},
                 r"ty\.csv: column 'y_0' is both an x and a y column", id="truth-as-state"),
    pytest.param("te.csv", "x_0,y_0,yhat_0\n1,2,3\n", {"y_columns": ["yhat_0"]},
                 r"te\.csv: column 'yhat_0' is both a y and a yhat column", id="estimate-as-truth"),
]  # fmt: skip


@pytest.mark.parametrize(("name", "text", "columns", "match"), BAD_FILES)
def test_a_bad_file_is_refused_with_what_is_wrong(tmp_path, name, text, columns, match):
    with pytest.raises(DataError, match=match):
        load_dataset(_write(tmp_path, name, text), **columns)


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_dataset(tmp_path / "nope.csv")


def test_npz_missing_array(tmp_path):
    p = tmp_path / "a.npz"
    np.savez(p, x=np.zeros((2, 1)), y=np.zeros((2, 1)))
    with pytest.raises(DataError, match=r"NPZ lacks array\(s\) yhat"):
        load_dataset(p)


def test_npz_dimension_mismatch(tmp_path):
    p = tmp_path / "b.npz"
    np.savez(p, x=np.zeros((2, 1)), y=np.zeros((2, 3)), yhat=np.zeros((2, 2)))
    with pytest.raises(DataError, match=r"y has dimension 3 but yhat has 2"):
        load_dataset(p)


def test_complex_npz_is_refused_not_cut_to_its_real_part(tmp_path):
    p = tmp_path / "c.npz"
    np.savez(p, x=np.ones((2, 1)) * (1 + 2j), y=np.zeros((2, 1)), yhat=np.zeros((2, 1)))
    with pytest.raises(
        DataError, match=r"c\.npz: array 'x' is complex \(dtype complex128\); store real numbers"
    ):
        load_dataset(p)


def test_numbers_stored_as_text_in_parquet_name_the_column_not_a_row(tmp_path):
    p = tmp_path / "t.parquet"
    frame = pd.DataFrame({"x_0": ["0.5", "1.5"], "y_0": [1.0, 2.0], "yhat_0": [1.0, 2.0]})
    frame.astype({"x_0": object}).to_parquet(p, index=False)
    with pytest.raises(DataError, match=r"t\.parquet: column 'x_0' holds numbers stored as text .*numeric"):
        load_dataset(p)


def test_corrupt_parquet(tmp_path):
    p = _write(tmp_path, "bad.parquet", "this is not parquet")
    with pytest.raises(DataError, match=r"bad\.parquet: cannot read as PARQUET"):
        load_dataset(p)


def test_bad_split_fractions(small):
    with pytest.raises(DataError, match="summing to 1"):
        small.split((0.5, 0.5, 0.5))


def test_unknown_column_lists_available(small):
    with pytest.raises(DataError, match=r"no column 'speed'; available: x_0"):
        small.column("speed")


def test_save_is_atomic_on_failure(tmp_path, small, monkeypatch):
    p = tmp_path / "keep.csv"
    save_dataset(small, p)
    before = p.read_bytes()

    def boom(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(pd.DataFrame, "to_csv", boom)
    with pytest.raises(RuntimeError):
        save_dataset(make_lagged_perception(5, seed=1), p)
    assert p.read_bytes() == before
    assert [f.name for f in tmp_path.iterdir()] == ["keep.csv"]


def test_saved_files_get_ordinary_permissions(tmp_path, small):
    import os

    old = os.umask(0o027)
    try:
        save_dataset(small, tmp_path / "d.csv")
    finally:
        os.umask(old)
    assert (tmp_path / "d.csv").stat().st_mode & 0o777 == 0o640


def _with_runs(n_runs: int, rows: int = 5) -> PerceptionDataset:
    runs = np.repeat([f"run{i:02d}" for i in range(n_runs)], rows)
    n = len(runs)
    x = np.arange(n, dtype=float)[:, None]
    return PerceptionDataset(x, np.zeros((n, 1)), np.zeros((n, 1)), source="log", extra={"run": runs})


def test_group_split_keeps_whole_groups_and_is_deterministic():
    ds = _with_runs(20)
    a = ds.split((0.6, 0.2, 0.2), seed=3, group_column="run")
    b = ds.split((0.6, 0.2, 0.2), seed=3, group_column="run")
    c = ds.split((0.6, 0.2, 0.2), seed=4, group_column="run")
    parts = (a.train, a.calibration, a.test)
    runs = [set(p.column("run")) for p in parts]
    assert [len(r) for r in runs] == [12, 4, 4]  # shares count groups
    assert not (runs[0] & runs[1]) and not (runs[0] & runs[2]) and not (runs[1] & runs[2])
    assert [len(p) for p in parts] == [60, 20, 20]  # whole groups: 5 rows each
    rows = np.sort(np.concatenate([p.x[:, 0] for p in parts]))
    assert np.array_equal(rows, ds.x[:, 0])  # every row exactly once
    assert all(np.array_equal(p.x, q.x) for p, q in zip(parts, (b.train, b.calibration, b.test), strict=True))
    assert set(c.calibration.column("run")) != runs[1]


def test_group_split_does_not_depend_on_row_order():
    ds = _with_runs(10, rows=3)
    perm = np.random.default_rng(0).permutation(len(ds))
    shuffled = ds.subset(perm)
    a = ds.split((0.5, 0.3, 0.2), seed=1, group_column="run")
    b = shuffled.split((0.5, 0.3, 0.2), seed=1, group_column="run")
    assert set(a.calibration.column("run")) == set(b.calibration.column("run"))


def test_split_without_group_column_is_unchanged(small):
    a = small.split((0.6, 0.2, 0.2), seed=7)
    b = small.split((0.6, 0.2, 0.2), seed=7, group_column=None)
    perm = np.random.default_rng(7).permutation(len(small))
    assert np.array_equal(a.train.x, small.x[np.sort(perm[:30])])
    assert np.array_equal(a.test.x, b.test.x)


def test_group_split_refuses_unknown_column_and_too_few_groups():
    ds = _with_runs(2)
    with pytest.raises(DataError, match=r"log: no column 'flight'; available: x_0, y_0, yhat_0, run"):
        ds.split(group_column="flight")
    with pytest.raises(
        DataError,
        match=r"log: group column 'run' has 2 groups, too few for split fractions \[0\.6, 0\.2, 0\.2\]: "
        r"the calibration part would get no group; use about 5 or more groups",
    ):
        ds.split((0.6, 0.2, 0.2), group_column="run")
    with pytest.raises(DataError, match=r"has 1 group, .*the calibration and test parts would get no group"):
        _with_runs(1).split((0.6, 0.2, 0.2), group_column="run")
    # a zero share may be empty
    parts = ds.split((0.5, 0.5, 0.0), group_column="run")
    assert parts.test is None and len(parts.train) == len(parts.calibration) == 5


def test_group_split_refuses_missing_labels():
    ds = _with_runs(4)
    runs = np.array(ds.column("run"), dtype=object)
    runs[7] = None
    bad = PerceptionDataset(ds.x, ds.y, ds.yhat, source="log", extra={"run": runs})
    with pytest.raises(DataError, match=r"log: group column 'run': row 7 \(0-based\) has no group label"):
        bad.split(group_column="run")
    numeric = np.repeat(np.arange(4.0), len(ds) // 4 + 1)[: len(ds)]
    numeric[3] = np.nan  # a numeric group column with a missing value: no np.float64(nan) in the message
    bad = PerceptionDataset(ds.x, ds.y, ds.yhat, source="log", extra={"run": numeric})
    with pytest.raises(DataError, match=r"row 3 \(0-based\) has no group label \(it is empty\)") as info:
        bad.split(group_column="run")
    assert "np." not in str(info.value) and "nan" not in str(info.value)


def test_gapped_columns_name_the_file_the_gap_and_what_to_do(tmp_path):
    path = tmp_path / "gap.csv"
    pd.DataFrame({"x_0": [0.0], "x_2": [1.0], "y_0": [0.0], "yhat_0": [0.1]}).to_csv(path, index=False)
    with pytest.raises(
        DataError, match=r"gap\.csv: columns x_0\.\.x_2 are not contiguous: missing x_1 -- number"
    ) as e:
        load_dataset(path)
    assert "--x-columns" in str(e.value) and "\n" not in str(e.value)
