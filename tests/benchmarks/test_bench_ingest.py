"""The ingestion benchmark and the worked example of docs/ingest.md, on tiny sizes (numbers mean nothing)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks import bench_ingest  # noqa: E402
from docgen import ingest_example  # noqa: E402


@pytest.mark.slow
def test_benchmark_writes_its_numbers_and_checks_the_rows(tmp_path):
    res = bench_ingest.main(["--messages", "3000", "--out", str(tmp_path / "r.json")])
    saved = json.loads((tmp_path / "r.json").read_text())
    assert [r["container"] for r in saved["runs"]] == ["ros1", "ros2_mcap"]
    for r in res["runs"]:
        # 3000 messages at 250 Hz in all: 12 s of flight, samples every 0.25 s while t0 + 0.5 s fits
        assert r["messages"] == 3000 and 40 <= r["rows"] <= 47
        assert r["max_truth_error_vs_motion_m"] < 1e-4 and r["ingest_cpu_s"] > 0
        assert r["meets_target"] == (r["ingest_wall_s"] <= 30.0)


def test_example_flights_ingest_and_draw(tmp_path, run_cli):
    bags = ingest_example.write_flights(tmp_path, flights=2, seconds=4.0)
    cmds = ingest_example.commands(tmp_path, bags * 5, ingest_only=False)  # ten "flights": 3 / 5 / 2
    assert [c[:2] for c in cmds] == [["ingest", "topics"]] + [["ingest", "bag"]] * 3 + [
        ["train", str(tmp_path / "train.parquet")],
        ["calibrate", str(tmp_path / "model.pt")],
        ["certify", str(tmp_path / "calibrated.pt")],
    ]
    assert [sum(a.endswith(".bag") for a in c) for c in cmds[1:4]] == [3, 5, 2]
    res = run_cli(*ingest_example.commands(tmp_path, bags + bags, ingest_only=True)[1])  # the training flight
    assert res.code == 0, res.stderr
    ingest = ["ingest", "bag", "--truth", ingest_example.TRUTH, "--estimate", ingest_example.ESTIMATE]
    res = run_cli(
        *ingest, "--t-offset", str(-ingest_example.MOCAP_AHEAD), *bags, "--out", tmp_path / "both.parquet"
    )
    assert res.code == 0, res.stderr
    both = pd.read_parquet(tmp_path / "both.parquet")
    assert sorted(set(both["run"])) == ["flight_000", "flight_001"] and len(both) == 28  # t0 = 0 .. 3.25 s
    # the simulated estimator errs by centimetres, not by a clock offset's metres
    err = np.linalg.norm(
        both[["y_0", "y_1", "y_2"]].to_numpy() - both[["yhat_0", "yhat_1", "yhat_2"]].to_numpy(), axis=1
    )
    assert 0 < err.max() < 0.2
    ingest_example.plot_flight(tmp_path / "both.parquet", "flight_001", tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 10_000
