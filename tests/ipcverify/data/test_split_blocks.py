"""split_file / ``ipcverify split --block``: contiguous time blocks of long runs kept whole."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ipcverify.data import PerceptionDataset, save_dataset, split_file
from ipcverify.data._split import time_blocks
from ipcverify.errors import DataError, InvalidInputError

LOG = Path(__file__).resolve().parents[3] / "data" / "euroc_mh04_vislam.csv"


def _run(argv: list[str]) -> int:
    from ipcverify.cli import main

    with pytest.raises(SystemExit) as exc:
        main(argv)
    return int(exc.value.code)


def _two_long_runs(path: Path, seconds: float = 120.0, rate: float = 4.0, t0: float = 0.0) -> Path:
    """Two runs of ``seconds`` each, sampled ``rate`` times a second, times from ``t0`` (rows shuffled)."""
    n = int(seconds * rate)
    t = np.concatenate([t0 + np.arange(n) / rate] * 2)
    run = np.repeat(["orb", "sptam"], n)
    order = np.random.default_rng(0).permutation(2 * n)  # blocks must not rely on the file's order
    z = np.arange(2 * n, dtype=float)[:, None]
    data = PerceptionDataset(z[order], z[order], z[order], extra={"run": run[order], "t": t[order]})
    save_dataset(data, path)
    return path


def test_blocks_are_counted_from_each_runs_first_time():
    t = np.array([10.0, 14.9, 15.0, 29.9, 1e9, 1e9 + 5.0])  # run b on a Unix-epoch clock
    assert time_blocks(t, 5.0, groups=["a"] * 4 + ["b"] * 2).tolist() == [0, 0, 1, 3, 0, 1]
    assert time_blocks(t[:4], 5.0).tolist() == [0, 0, 1, 3]


def test_a_block_split_keeps_every_stretch_of_time_whole_and_loses_no_row(tmp_path):
    log = _two_long_runs(tmp_path / "log.csv")
    s = split_file(log, tmp_path / "parts", group_column="run", block=10.0, seed=1)
    parts = {p.name: pd.read_csv(p.path) for p in s.parts}
    blocks = {
        name: set(zip(df["run"], (df["t"] // 10).astype(int), strict=True)) for name, df in parts.items()
    }
    assert sum(len(b) for b in blocks.values()) == 24  # 2 runs x 12 blocks of 10 s, each in one part
    assert not (blocks["train"] & blocks["calibration"] or blocks["train"] & blocks["test"])
    assert not blocks["calibration"] & blocks["test"]
    assert [p.groups for p in s.parts] == [len(blocks[n]) for n in ("train", "calibration", "test")]
    assert sorted(pd.concat(list(parts.values()))["x_0"]) == list(range(960))
    record = json.loads(s.record.read_text())
    assert record["block_seconds"] == 10.0 and record["time_column"] == "t"
    assert record["group_columns"] == ["run"]


def test_without_by_the_same_times_of_every_run_are_one_block(tmp_path):
    # two estimators replaying one recording: the same stretch of road stays in one part
    log = _two_long_runs(tmp_path / "log.csv")
    s = split_file(log, tmp_path / "parts", block=10.0, group_name="segment")
    for p in s.parts:
        df = pd.read_csv(p.path)
        assert df.groupby("segment")["run"].nunique().eq(2).all()
        assert (df["segment"] == (df["t"] // 10).astype(int)).all()
    assert sum(p.groups for p in s.parts) == 12


def test_a_named_group_column_joins_the_run_and_the_block_number(tmp_path):
    log = _two_long_runs(tmp_path / "log.csv", t0=1.7e9)  # epoch stamps: blocks from each run's start
    s = split_file(log, tmp_path / "parts", group_column="run", block=30.0, group_name="segment")
    df = pd.concat([pd.read_csv(p.path) for p in s.parts])
    want = df["run"] + ":" + ((df["t"] - 1.7e9) // 30).astype(int).astype(str)
    assert (df["segment"] == want).all() and df["segment"].nunique() == 8


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"block": 0.0}, DataError, "positive number of seconds"),
        ({"block": float("nan")}, DataError, "positive number of seconds"),
        ({"block": 10.0, "time_column": "run"}, DataError, "must hold numbers"),
        ({"block": 10.0, "time_column": "clock"}, DataError, "no column 'clock'"),
        ({"time_column": "t"}, InvalidInputError, "only to cut time blocks"),
        ({"block": 100.0}, DataError, "a shorter block gives more blocks"),
    ],
)
def test_bad_block_requests_are_refused_before_anything_is_written(tmp_path, kwargs, error, match):
    log = _two_long_runs(tmp_path / "log.csv")
    with pytest.raises(error, match=match):
        split_file(log, tmp_path / "out", **kwargs)
    assert not (tmp_path / "out").exists()


def test_blocks_need_a_time_column_and_say_how_to_name_one(tmp_path):
    z = np.zeros((10, 1))
    save_dataset(PerceptionDataset(z, z, z, extra={"clock": np.arange(10.0)}), tmp_path / "log.csv")
    with pytest.raises(DataError, match="time_column=COL"):
        split_file(tmp_path / "log.csv", tmp_path / "out", block=2.0)
    s = split_file(tmp_path / "log.csv", tmp_path / "out", block=2.0, time_column="clock")
    assert s.time_column == "clock" and [p.groups for p in s.parts] == [3, 1, 1]


def test_a_missing_time_is_refused_with_its_row(tmp_path):
    z = np.zeros((4, 1))
    t = np.array([0.0, 1.0, np.nan, 3.0])
    save_dataset(PerceptionDataset(z, z, z, extra={"t": t}), tmp_path / "log.csv")
    with pytest.raises(DataError, match=r"row 2 \(0-based\) has no finite time"):
        split_file(tmp_path / "log.csv", tmp_path / "out", block=1.0)


def test_the_cli_splits_into_blocks_and_prints_them(tmp_path, capsys):
    log = _two_long_runs(tmp_path / "log.csv")
    out = tmp_path / "parts"
    assert _run(["split", str(log), "--out", str(out), "--by", "run", "--block", "20"]) == 0
    captured = capsys.readouterr()
    assert "run+20 s block groups" in captured.out and "hint" not in captured.err
    assert json.loads((out / "split.json").read_text())["block_seconds"] == 20.0
    assert _run(["split", str(log), "--out", str(tmp_path / "o"), "--block", "-5"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "positive number of seconds" in err and "\n" not in err


def test_the_row_split_hint_offers_blocks_of_time_and_never_time_as_a_run(tmp_path, capsys):
    assert _run(["split", str(LOG), "--out", str(tmp_path)]) == 0
    err = " ".join(capsys.readouterr().err.split())
    assert "if one of sequence, method, run names runs or flights" in err
    assert "--block SECONDS (blocks of t)" in err and "run, t names" not in err


@pytest.mark.parametrize("seconds", [np.float32(5.0), np.int64(5), 5])
def test_a_block_length_may_be_any_real_number_type(seconds):
    assert time_blocks([0.0, 4.0, 6.0], seconds).tolist() == [0, 0, 1]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"seconds": True}, "positive number of seconds; got True"),
        ({"seconds": 1e-300}, "give a block length in seconds of the same order"),
        ({"seconds": 1.0, "groups": [None, "a", "a"]}, r"group column: row 0 \(0-based\) has no group label"),
    ],
)
def test_block_inputs_that_make_no_sense_are_refused_naming_what_is_wrong(kwargs, match):
    with pytest.raises(DataError, match=match):
        time_blocks([0.0, 1.0, 2.0], **kwargs)
