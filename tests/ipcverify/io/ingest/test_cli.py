"""`ipcverify ingest`: the commands write a table and a manifest that calibrate takes as it is;
every error is one line on stderr, exit status 2, no traceback."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

RUNS = 25


@pytest.fixture(scope="module")
def tum(tmp_path_factory):
    """A truth file at 100 Hz and 25 estimate runs at 20 Hz on a shifted clock, with run-dependent noise."""
    d = tmp_path_factory.mktemp("tum")
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 20.0, 0.01)

    def poses(tt):
        p = np.column_stack([np.cos(tt), np.sin(1.3 * tt), 0.1 * tt])
        return p, Rotation.from_rotvec(np.outer(tt, [0.1, 0.2, 0.7])).as_quat()

    p, q = poses(t)
    np.savetxt(d / "gt.txt", np.column_stack([t, p, q]), header="t x y z qx qy qz qw")
    for k in range(RUNS):
        te = t[::5] + 0.003
        pe, qe = poses(te)
        pe = pe + rng.normal(0.0, 0.01 * (1 + k % 3), pe.shape)
        np.savetxt(d / f"run{k:02d}.txt", np.column_stack([te + 7.0, pe, qe]))
    return d


def _estimates(d, ks):
    return [a for k in ks for a in ("--estimate", d / f"run{k:02d}.txt")]


def test_ingested_runs_train_and_calibrate_by_run(run_cli, tum, tmp_path):
    train, cal = tmp_path / "train.parquet", tmp_path / "cal.csv"
    base = ["ingest", "trajectories", "--truth", tum / "gt.txt", "--t-offset", "7"]
    res = run_cli(*base, *_estimates(tum, range(5)), "--out", train)
    assert res.code == 0, res.stderr
    res = run_cli(*base, *_estimates(tum, range(5, RUNS)), "--out", cal)
    assert res.code == 0, res.stderr
    assert "run run05: 78 of 78 samples kept; dropped: none" in res.stdout
    df = pd.read_csv(cal)
    assert sorted(set(df["run"])) == [f"run{k:02d}" for k in range(5, RUNS)]
    m = json.loads((tmp_path / "cal.manifest.json").read_text())
    assert m["options"]["t_offset"] == 7.0 and len(m["runs"]) == RUNS - 5
    assert m["output"]["sha256"] and m["output"]["rows"] == len(df)
    assert run_cli("train", train, "--out", tmp_path / "m.pt", "--epochs", "2", "--hidden", "8").code == 0
    res = run_cli(
        "calibrate", tmp_path / "m.pt", cal, "--epsilon", "0.2", "--delta", "0.1",
        "--group-column", "run", "--domain-flag-rate", "0.1", "--out", tmp_path / "cal.pt",
    )  # fmt: skip
    assert res.code == 0, res.stderr
    assert "20 calibration groups (by 'run')" in " ".join(res.stdout.split())


def test_topics_lists_a_bag(run_cli, tmp_path, motions, bagkit):
    t = np.arange(0.0, 2.0, 0.1)
    path = bagkit.write_bag(
        "ros2_mcap",
        tmp_path / "b",
        [bagkit.pose_topic("/pose", "geometry_msgs/msg/PoseStamped", motions[0], t)],
    )
    res = run_cli("ingest", "topics", path)
    assert res.code == 0
    assert res.stdout.strip() == "/pose (geometry_msgs/msg/PoseStamped, 20 messages, 0.000..1.900 s)"


def test_bag_command_writes_parquet_and_manifest(run_cli, tmp_path, motions, bagkit):
    truth, est = motions
    t = np.arange(0.0, 5.0, 0.01)
    topics = [
        bagkit.pose_topic("/gt", "geometry_msgs/msg/PoseStamped", truth, t),
        bagkit.pose_topic("/odom", "nav_msgs/msg/Odometry", est, t[::4]),
    ]
    path = bagkit.write_bag("ros1", tmp_path / "flight1", topics)
    out = tmp_path / "log.parquet"
    res = run_cli(
        "ingest", "bag", path, "--truth", "/gt", "--estimate", "/odom", "--state", "/odom",
        "--state-fields", "twist.twist.linear.x", "--out", out,
    )  # fmt: skip
    assert res.code == 0, res.stderr
    df = pd.read_parquet(out)
    assert [c for c in df.columns if c.startswith("x_")] == [f"x_{i}" for i in range(6)]
    assert set(df["run"]) == {"flight1"}
    m = json.loads((tmp_path / "log.manifest.json").read_text())
    assert m["topics"]["truth"] == "/gt" and m["topics"]["state_fields"] == ["twist.twist.linear.x"]
    assert m["inputs"][0]["sha256"] and m["source"] == "bags"


def _one_line_error(res, *fragments):
    assert res.code == 2, res.stdout + res.stderr
    assert "Traceback" not in res.stderr and res.stderr.startswith("error: ")
    assert len(res.stderr.strip().splitlines()) == 1, res.stderr
    for f in fragments:
        assert f in res.stderr, res.stderr


@pytest.fixture
def bag(tmp_path, motions, bagkit):
    truth, est = motions
    t = np.arange(0.0, 5.0, 0.01)
    topics = [
        bagkit.pose_topic("/gt", "geometry_msgs/msg/PoseStamped", truth, t, stamp_clock=1000.0),
        bagkit.pose_topic("/est", "geometry_msgs/msg/PoseStamped", est, t[::5]),
        ("/text", "std_msgs/msg/String", [(0.5, lambda ts: ts.types["std_msgs/msg/String"](data="hi"))]),
    ]
    return bagkit.write_bag("ros2_sqlite3", tmp_path / "bag", topics)


def test_error_missing_topic(run_cli, bag, tmp_path):
    res = run_cli(
        "ingest", "bag", bag, "--truth", "/vicon", "--estimate", "/est", "--out", tmp_path / "o.csv"
    )
    _one_line_error(res, "no topic '/vicon'; its topics: /est (geometry_msgs/msg/PoseStamped, 100 messages")


def test_error_no_time_overlap(run_cli, bag, tmp_path):
    res = run_cli("ingest", "bag", bag, "--truth", "/gt", "--estimate", "/est", "--out", tmp_path / "o.csv")
    _one_line_error(res, "truth (1000.000000..1004.990000 s", "estimate (0.000000..4.950000 s)", "--t-offset")
    ok = run_cli(
        "ingest",
        "bag",
        bag,
        "--truth",
        "/gt",
        "--estimate",
        "/est",
        "--t-offset",
        "-1000",
        "--out",
        tmp_path / "o.csv",
    )
    assert ok.code == 0, ok.stderr


def test_error_too_few_truth_samples(run_cli, bag, tmp_path):
    res = run_cli(
        "ingest",
        "bag",
        bag,
        "--truth",
        "/est",
        "--estimate",
        "/est",
        "--max-gap",
        "0.01",
        "--out",
        tmp_path / "o.csv",
    )
    _one_line_error(res, "has 100 stamps within the estimate's span and its largest gap there is 0.05 s")


def test_error_unsupported_type(run_cli, bag, tmp_path):
    res = run_cli("ingest", "bag", bag, "--truth", "/gt", "--estimate", "/text", "--out", tmp_path / "o.csv")
    _one_line_error(res, "std_msgs/msg/String, which holds no pose; supported: geometry_msgs/msg/PoseStamped")


def test_error_no_type_definitions(run_cli, bag, tmp_path, bagkit):
    bagkit.strip_definitions(bag)
    res = run_cli("ingest", "topics", bag)
    _one_line_error(res, "no message type definitions", "--typestore ros2_humble")
    assert run_cli("ingest", "topics", bag, "--typestore", "ros2_humble").code == 0


def test_error_zero_header_stamps(run_cli, tmp_path, motions, bagkit):
    t = np.arange(0.0, 3.0, 0.05)
    p, q = motions[1].position(t), motions[1].rotation(t).as_quat()

    def unstamped(k):
        return lambda ts: bagkit.make_message(ts, "geometry_msgs/msg/PoseStamped", 0.0, p[k], q[k])

    topics = [
        bagkit.pose_topic("/gt", "geometry_msgs/msg/PoseStamped", motions[0], t),
        ("/est", "geometry_msgs/msg/PoseStamped", [(float(t[k]), unstamped(k)) for k in range(len(t))]),
    ]
    path = bagkit.write_bag("mcap", tmp_path / "z", topics)
    res = run_cli("ingest", "bag", path, "--truth", "/gt", "--estimate", "/est", "--out", tmp_path / "o.csv")
    _one_line_error(res, "every header stamp is zero", "--stamp receive")


@pytest.mark.parametrize(
    ("extra", "fragment"),
    [
        (["--out", "o.json"], "--out must end in .csv, .parquet or .pq (a table); got o.json"),
        (["--tag", "novalue", "--out", "o.csv"], "--tag 'novalue': write KEY=VALUE"),
        (["--align", "se3", "--out", "o.csv"], "--align se3 needs the quantity position or pose"),
        (
            ["--quantity", "position", "--align", "se3", "--out", "o.csv"],
            "name the runs to fit the alignment on",
        ),
        (["--run", "a", "--run", "b", "--out", "o.csv"], "2 run name(s) for 1 input(s)"),
        (["--times", "TIMES", "--out", "o.csv"], "--times applies to KITTI poses only"),
        (["--format", "euroc", "--out", "o.csv"], "a EUROC line holds timestamp_ns"),
        (["--horizon", "-1", "--out", "o.csv"], "--horizon must be a positive number"),
    ],
)
def test_trajectory_errors(run_cli, tum, tmp_path, extra, fragment):
    extra = [str(tum / "gt.txt") if e == "TIMES" else e for e in extra]
    extra = [str(tmp_path / e) if e.startswith("o.") else e for e in extra]
    res = run_cli(
        "ingest", "trajectories", "--truth", tum / "gt.txt", "--estimate", tum / "run00.txt", *extra
    )
    _one_line_error(res, fragment)


def test_up_names_the_world_axis_of_the_tilt_columns_and_refuses_others(run_cli, tum, tmp_path):
    base = ["ingest", "trajectories", "--truth", tum / "gt.txt", "--t-offset", "7", *_estimates(tum, [0])]
    assert run_cli(*base, "--up", "-x", "--out", tmp_path / "a.csv").code == 0
    m = json.loads((tmp_path / "a.manifest.json").read_text())
    assert m["options"]["up"] == "-x" and m["x_columns"]["x_2"].startswith("world -x axis")
    res = run_cli(*base, "--up", "down", "--out", tmp_path / "b.csv")
    assert res.code == 2 and "'down' is not one of" in res.stderr and not (tmp_path / "b.csv").exists()


def test_the_truth_file_given_as_the_estimate_is_refused(run_cli, tum, tmp_path):
    res = run_cli(
        "ingest",
        "trajectories",
        "--truth",
        tum / "gt.txt",
        "--estimate",
        tum / "gt.txt",
        "--out",
        tmp_path / "o.csv",
    )
    _one_line_error(res, "has its estimate equal to its truth", "gt.txt")
    assert not (tmp_path / "o.csv").exists()


def test_topics_of_an_empty_bag_is_a_user_error_not_an_empty_listing(run_cli, tmp_path, bagkit):
    path = bagkit.write_bag("ros1", tmp_path / "empty", [])
    res = run_cli("ingest", "topics", path)
    assert res.code == 2 and res.stdout == ""
    assert res.stderr == f"error: {path}: no topic in it (the recording is empty)\n"
