"""split_file / ``ipcverify split``: a log into train, calibration and test files, with a record."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ipcverify.data import PerceptionDataset, load_dataset, save_dataset, split_file
from ipcverify.data._files import file_sha256
from ipcverify.errors import DataError, InvalidInputError

LOG = Path(__file__).resolve().parents[3] / "data" / "euroc_mh04_vislam.csv"


def _run(argv: list[str]) -> int:
    from ipcverify.cli import main

    with pytest.raises(SystemExit) as exc:
        main(argv)
    return int(exc.value.code)


def test_a_split_by_method_and_run_keeps_every_run_whole_and_loses_no_row(tmp_path):
    s = split_file(LOG, tmp_path / "parts", group_column=["method", "run"], seed=3)
    source = pd.read_csv(LOG)
    parts = {p.name: pd.read_csv(p.path) for p in s.parts}
    runs = {name: set(zip(df["method"], df["run"], strict=True)) for name, df in parts.items()}
    assert not (
        runs["train"] & runs["calibration"]
        or runs["train"] & runs["test"]
        or runs["calibration"] & runs["test"]
    )
    assert sum(len(r) for r in runs.values()) == 20  # the log's 20 runs, each in one part
    assert (
        [p.groups for p in s.parts] == [len(runs[n]) for n in ("train", "calibration", "test")] == [12, 4, 4]
    )
    # every row of the source is in exactly one part, unchanged (CSV floats read back exactly)
    merged = pd.concat(list(parts.values())).sort_values(["method", "run", "t"]).reset_index(drop=True)
    pd.testing.assert_frame_equal(merged, source.sort_values(["method", "run", "t"]).reset_index(drop=True))
    assert sum(p.rows for p in s.parts) == len(source)


def test_the_record_names_the_source_and_every_part_by_sha256(tmp_path):
    s = split_file(LOG, tmp_path, group_column="run")
    record = json.loads((tmp_path / "split.json").read_text())
    assert record["source_sha256"] == file_sha256(LOG)
    assert record["group_columns"] == ["run"] and record["seed"] == 0
    for p in s.parts:
        assert record["parts"][p.name]["sha256"] == file_sha256(p.path)
        assert record["parts"][p.name]["rows"] == len(load_dataset(p.path))
        assert record["parts"][p.name]["content_sha256"] == load_dataset(p.path).content_hash()


def test_the_record_matches_what_train_calibrate_and_certify_record_of_their_data(tmp_path):
    from ipcverify import calibrate, certify, train
    from ipcverify.calibration import Global
    from ipcverify.network import ModelConfig
    from ipcverify.training import TrainConfig

    s = split_file(LOG, tmp_path, (0.5, 0.3, 0.2), group_column=["method", "run"], seed=1)
    train_part, cal_part, test_part = (load_dataset(p.path) for p in s.parts)
    config = ModelConfig(x_dim=5, y_dim=3, hidden=(8,), param="cholesky")
    model = train(train_part, config, TrainConfig(epochs=1, seed=0)).model
    model = calibrate(model, cal_part, epsilon=0.2, delta=0.05, method=Global())
    cert = certify(model, test_part).certificate
    hashes = [p.content_sha256 for p in s.parts]
    assert hashes == [
        model.metadata["train_data_hash"],
        model.calibration.data_hash,
        cert.test_data.content_sha256,
    ]


def test_the_same_seed_gives_the_same_files_and_another_seed_other_ones(tmp_path):
    a = split_file(LOG, tmp_path / "a", group_column=["method", "run"], seed=1)
    b = split_file(LOG, tmp_path / "b", group_column=["method", "run"], seed=1)
    c = split_file(LOG, tmp_path / "c", group_column=["method", "run"], seed=2)
    assert [p.sha256 for p in a.parts] == [p.sha256 for p in b.parts]
    assert [p.sha256 for p in a.parts] != [p.sha256 for p in c.parts]


def test_a_row_split_has_the_requested_shares_and_a_zero_share_writes_no_file(tmp_path):
    ds = PerceptionDataset(np.arange(100.0)[:, None], np.zeros((100, 2)), np.ones((100, 2)))
    save_dataset(ds, tmp_path / "log.npz")
    s = split_file(tmp_path / "log.npz", tmp_path / "out", (0.7, 0.3, 0.0))
    assert [p.rows for p in s.parts] == [70, 30, 0] and s.parts[2].path is None
    assert not (tmp_path / "out" / "test.npz").exists() and s.group_columns == ()
    x = np.concatenate([load_dataset(p.path).x[:, 0] for p in s.parts[:2]])
    assert sorted(x.tolist()) == list(range(100))


def test_npz_parts_say_which_columns_they_cannot_hold(tmp_path):
    s = split_file(LOG, tmp_path, group_column="run", suffix=".npz")
    assert s.dropped_columns == ("t", "sequence", "method", "run")
    assert all(p.path.suffix == ".npz" for p in s.parts)


def test_a_part_is_never_written_over_the_input_nor_a_stale_part_left_beside_the_split(tmp_path):
    save_dataset(load_dataset(LOG).subset(np.arange(200)), tmp_path / "train.csv")
    before = (tmp_path / "train.csv").read_bytes()
    with pytest.raises(InvalidInputError, match="train part .* is also the input DATA"):
        split_file(tmp_path / "train.csv", tmp_path)
    assert (tmp_path / "train.csv").read_bytes() == before
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "test.csv").write_text("old")
    with pytest.raises(InvalidInputError, match="exists, but this split has no test part"):
        split_file(tmp_path / "train.csv", tmp_path / "out", (0.5, 0.5, 0.0))
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["test.csv"]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"group_column": "flight"}, "no column 'flight'"),
        ({"fractions": (0.5, 0.6, 0.0)}, "summing to 1"),
        ({"suffix": ".txt"}, "unknown data format '.txt'"),
        ({"group_column": "sequence"}, "too few for split"),
    ],
)
def test_bad_requests_are_refused_before_anything_is_written(tmp_path, kwargs, match):
    with pytest.raises(DataError, match=match):
        split_file(LOG, tmp_path / "out", **kwargs)
    assert not (tmp_path / "out").exists()


def test_the_cli_splits_by_several_columns_and_prints_the_parts(tmp_path, capsys):
    out = tmp_path / "parts"
    assert _run(["split", str(LOG), "--out", str(out), "--by", "method,run", "--seed", "3"]) == 0
    text = capsys.readouterr().out
    assert "method+run groups" in text and "split.json" in text
    record = json.loads((out / "split.json").read_text())
    assert record["group_columns"] == ["method", "run"]
    assert [record["parts"][n]["groups"] for n in ("train", "calibration", "test")] == [12, 4, 4]


def test_the_cli_names_the_candidate_group_columns_after_a_row_split(tmp_path, capsys):
    assert _run(["split", str(LOG), "--out", str(tmp_path), "--fractions", "0.5,0.25,0.25"]) == 0
    err = capsys.readouterr().err
    assert "assumes independent rows" in err and "method, run" in err


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--fractions", "0.5,0.5"], "--fractions must be three comma-separated shares"),
        (["--by", "flight"], "no column 'flight'"),
    ],
)
def test_the_cli_refuses_bad_options_in_one_line_with_status_2(tmp_path, capsys, extra, message):
    assert _run(["split", str(LOG), "--out", str(tmp_path / "o"), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and message in err and "\n" not in err
    assert not (tmp_path / "o").exists()


def test_a_named_group_column_carries_each_rows_group_into_every_part(tmp_path):
    s = split_file(LOG, tmp_path, group_column=["method", "run"], group_name="flight", seed=3)
    assert s.group_name == "flight" and json.loads(s.record.read_text())["group_name"] == "flight"
    for p in s.parts:
        df = pd.read_csv(p.path)
        assert (df["flight"] == df["method"] + ":" + df["run"].astype(str)).all()
        assert df["flight"].nunique() == p.groups
    # the parts then calibrate and certify by that one column
    part = load_dataset(s.parts[1].path)
    assert part.column("flight").dtype.kind in "OUS" and len(np.unique(part.column("flight"))) == 4


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"group_name": "flight"}, "needs the columns that name a group"),
        ({"group_column": "run", "group_name": "method"}, "already has a column 'method'"),
        ({"group_column": "run", "group_name": "x_0"}, "already has a column 'x_0'"),
    ],
)
def test_a_group_column_is_named_only_from_groups_and_never_over_a_column(tmp_path, kwargs, match):
    with pytest.raises(InvalidInputError, match=match):
        split_file(LOG, tmp_path / "out", **kwargs)
    assert not (tmp_path / "out").exists()


def test_joined_values_that_would_merge_two_groups_are_refused(tmp_path):
    z = np.zeros((4, 1))
    a, b = np.array(["p:q", "p:q", "p", "p"]), np.array(["r", "r", "q:r", "q:r"])  # both join to "p:q:r"
    save_dataset(PerceptionDataset(z, z, z, extra={"run": a, "flight": b}), tmp_path / "log.csv")
    with pytest.raises(InvalidInputError, match="name fewer groups than they are"):
        split_file(
            tmp_path / "log.csv",
            tmp_path / "out",
            (0.5, 0.5, 0.0),
            group_column=["run", "flight"],
            group_name="g",
        )
