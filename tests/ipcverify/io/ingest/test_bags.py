"""Bags written with rosbags (ROS 1, ROS 2 sqlite3, ROS 2 MCAP, raw MCAP) read back into the right triples.

Truth and estimate are recorded at different rates and stamped by different clocks; the
triples are checked against the formulas of the reference motion (conftest.py).
"""

from __future__ import annotations

import numpy as np
import pytest

from ipcverify.errors import DataError
from ipcverify.io.ingest import ingest_bags, list_topics
from ipcverify.io.ingest._samples import MANIFEST_KEY

H, S = 0.5, 0.25
CONTAINERS = ("ros1", "ros2_sqlite3", "ros2_mcap", "mcap")
TRUTH_CLOCK = 1_700_000_000.0  # the motion-capture computer's clock, for t = 0
EST_CLOCK = 52.0  # the estimator's clock, for t = 0 (the truth runs 1_699_999_948 s ahead)
OFFSET = EST_CLOCK - TRUTH_CLOCK

POSE_TYPES = [
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "geometry_msgs/msg/TransformStamped",
    "nav_msgs/msg/Odometry",
]


def _bag(
    bagkit,
    container,
    tmp_path,
    motions,
    truth_type="geometry_msgs/msg/PoseStamped",
    est_type="nav_msgs/msg/Odometry",
):
    truth, est = motions
    t_truth = np.arange(-0.5, 6.5, 1 / 100)  # 100 Hz
    t_est = 0.0137 + np.arange(0.0, 6.0, 1 / 30)  # 30 Hz
    topics = [
        bagkit.pose_topic("/mocap", truth_type, truth, t_truth, TRUTH_CLOCK, receive_clock=10.004),
        bagkit.pose_topic("/odom", est_type, est, t_est, EST_CLOCK, receive_clock=10.02),
    ]
    return bagkit.write_bag(container, tmp_path / f"run_{container}", topics), t_est


def _check(df, motions, t_est):
    truth, est = motions
    t0 = S * np.arange(len(df))
    np.testing.assert_allclose(df["t"], t0, atol=1e-9)
    assert t0[-1] + H < t_est[-1] - t_est[0] <= t0[-1] + S + H
    # header stamps are whole nanoseconds: the motion is read back to about 1e-9 s of its time
    at = t_est[0] + t0
    np.testing.assert_allclose(df[["y_0", "y_1", "y_2"]], truth.displacement(at, H), atol=1e-6)
    np.testing.assert_allclose(df[["yhat_0", "yhat_1", "yhat_2"]], est.displacement(at, H), atol=1e-6)
    np.testing.assert_allclose(
        df[["x_2", "x_3", "x_4"]], est.rotation(at).inv().apply([0, 0, 1.0]), atol=1e-6
    )


@pytest.mark.parametrize("container", CONTAINERS)
def test_round_trip_through_every_container(container, tmp_path, motions, bagkit):
    path, t_est = _bag(bagkit, container, tmp_path, motions)
    df = ingest_bags([path], truth_topic="/mocap", estimate_topic="/odom", options=_opts(OFFSET))
    _check(df, motions, t_est)
    assert (df["run"] == f"run_{container}").all()
    infos = {i.topic: i for i in list_topics(path)}
    assert infos["/mocap"].msgtype == "geometry_msgs/msg/PoseStamped" and infos["/mocap"].count == 700
    assert infos["/odom"].count == 180 and infos["/odom"].start == pytest.approx(
        10.0 + 0.0137 + 0.02, abs=1e-6
    )


def _opts(offset):
    from ipcverify.io.ingest import IngestOptions

    return IngestOptions(t_offset=offset)


@pytest.mark.parametrize("msgtype", POSE_TYPES)
def test_every_pose_type(msgtype, tmp_path, motions, bagkit):
    path, t_est = _bag(bagkit, "ros2_sqlite3", tmp_path, motions, truth_type=msgtype, est_type=msgtype)
    _check(
        ingest_bags([path], truth_topic="/mocap", estimate_topic="/odom", options=_opts(OFFSET)),
        motions,
        t_est,
    )


def test_tf_with_child_frames(tmp_path, motions, bagkit):
    path, t_est = _bag(
        bagkit,
        "ros1",
        tmp_path,
        motions,
        truth_type="tf2_msgs/msg/TFMessage",
        est_type="tf2_msgs/msg/TFMessage",
    )
    df = ingest_bags(
        [path], truth_topic="/mocap", estimate_topic="/odom", child_frame="body", options=_opts(OFFSET)
    )
    _check(df, motions, t_est)
    with pytest.raises(DataError, match="name the body's frame with child_frame"):
        ingest_bags([path], truth_topic="/mocap", estimate_topic="/odom")
    with pytest.raises(DataError, match="topic /mocap has no pose with child frame 'base'"):
        ingest_bags([path], truth_topic="/mocap", estimate_topic="/odom", child_frame="base")
    # the message lists what the topic holds (a real /tf has many frames; the user must pick one)
    with pytest.raises(
        DataError,
        match=r"its transforms \(parent -> child frame\): world -> other \(700\), world -> body \(700\)",
    ):
        ingest_bags([path], truth_topic="/mocap", estimate_topic="/odom", child_frame="base")


def test_the_same_topic_as_truth_and_estimate_is_refused(tmp_path, motions, bagkit):
    """Seen on a real bag (evo's tf_example: one /tf trajectory, no truth): 205 rows with y == yhat."""
    path, _ = _bag(bagkit, "ros2_mcap", tmp_path, motions)
    with pytest.raises(DataError, match=r"every one of the \d+ samples has its estimate equal to its truth "
                       r"\(truth: topic /odom; estimate: topic /odom\)"):  # fmt: skip
        ingest_bags([path], truth_topic="/odom", estimate_topic="/odom")
    df = ingest_bags([path], truth_topic="/mocap", estimate_topic="/odom", options=_opts(OFFSET))
    assert len(df) > 0  # two topics: accepted


def test_receive_stamps_and_several_bags_as_runs(tmp_path, motions, bagkit):
    a, t_est = _bag(bagkit, "ros2_mcap", tmp_path, motions)
    b, _ = _bag(bagkit, "ros1", tmp_path, motions)
    # by receive time the truth arrives 0.004 s after its instant and the estimate 0.02 s after:
    # at a receive time the truth shows an instant 0.016 s later than the estimate does
    df = ingest_bags([a, b], truth_topic="/mocap", estimate_topic="/odom", stamp="receive", runs=["a", "b"])
    assert sorted(set(df["run"])) == ["a", "b"]
    truth, est = motions
    one = df[df["run"] == "a"]
    at = t_est[0] + S * np.arange(len(one))
    np.testing.assert_allclose(one[["y_0", "y_1", "y_2"]], truth.displacement(at + 0.016, H), atol=1e-6)
    m = df.attrs[MANIFEST_KEY]
    assert m["stamp"] == "receive" and [i["role"] for i in m["inputs"]] == ["bag", "bag"]


def test_state_topic_fields_are_appended(tmp_path, motions, bagkit):
    truth, est = motions
    t_truth = np.arange(0.0, 4.0, 0.01)
    t_est = np.arange(0.0, 4.0, 0.05)
    odom = [
        (
            float(s),
            (
                lambda k: (
                    lambda ts: bagkit.make_message(
                        ts, "nav_msgs/msg/Odometry", float(k), [0, 0, 0], [0, 0, 0, 1]
                    )
                )
            )(s),
        )
        for s in np.arange(0.1, 4.0, 0.4)
    ]
    topics = [
        bagkit.pose_topic("/gt", "geometry_msgs/msg/PoseStamped", truth, t_truth),
        bagkit.pose_topic("/est", "geometry_msgs/msg/PoseStamped", est, t_est),
        ("/odom", "nav_msgs/msg/Odometry", odom),
    ]
    path = bagkit.write_bag("ros1", tmp_path / "s", topics)
    df = ingest_bags(
        [path],
        truth_topic="/gt",
        estimate_topic="/est",
        state_topic="/odom",
        state_fields=["twist.twist.linear.x"],
    )
    # the builder writes the stamp into twist.linear.x: the held value is the last stamp <= t0
    expected = 0.1 + 0.4 * np.floor((df["t"].to_numpy() - 0.1) / 0.4 + 1e-9)
    np.testing.assert_allclose(df["x_5"], expected, atol=1e-9)
    assert df.attrs[MANIFEST_KEY]["x_columns"]["x_5"] == "twist.twist.linear.x"
    with pytest.raises(DataError, match=r"no field 'speed' in nav_msgs/msg/Odometry; it has .*twist"):
        ingest_bags(
            [path], truth_topic="/gt", estimate_topic="/est", state_topic="/odom", state_fields=["speed"]
        )


def test_missing_topic_lists_the_topics_and_their_types(tmp_path, motions, bagkit):
    path, _ = _bag(bagkit, "ros1", tmp_path, motions)
    with pytest.raises(
        DataError, match=r"no topic '/vicon'; its topics: /mocap \(geometry_msgs/msg/PoseStamped, 700"
    ):
        ingest_bags([path], truth_topic="/vicon", estimate_topic="/odom")


def test_unsupported_type_lists_the_supported_ones(tmp_path, motions, bagkit):
    truth, _ = motions
    t = np.arange(0.0, 2.0, 0.1)
    topics = [
        bagkit.pose_topic("/gt", "geometry_msgs/msg/PoseStamped", truth, t),
        (
            "/imu",
            "std_msgs/msg/Float64",
            [(float(s), lambda ts: ts.types["std_msgs/msg/Float64"](data=1.0)) for s in t],
        ),
    ]
    path = bagkit.write_bag("mcap", tmp_path / "u", topics)
    with pytest.raises(
        DataError, match=r"topic /imu has type std_msgs/msg/Float64, which holds no pose; supported: "
    ):
        ingest_bags([path], truth_topic="/gt", estimate_topic="/imu")


def test_zero_header_stamps_are_refused_with_a_hint(tmp_path, motions, bagkit):
    truth, est = motions
    t = np.arange(0.0, 3.0, 0.05)
    topics = [
        bagkit.pose_topic("/gt", "geometry_msgs/msg/PoseStamped", truth, t),
        bagkit.pose_topic("/est", "geometry_msgs/msg/PoseStamped", est, t, receive_clock=0.01),
    ]
    # the estimate's publisher leaves its header stamps at zero: rebuild its messages so
    p, q = est.position(t), est.rotation(t).as_quat()
    msgtype = "geometry_msgs/msg/PoseStamped"

    def unstamped(k):
        return lambda ts: bagkit.make_message(ts, msgtype, 0.0, p[k], q[k])

    topics[1] = ("/est", msgtype, [(float(t[k]) + 0.01, unstamped(k)) for k in range(len(t))])
    path = bagkit.write_bag("ros2_sqlite3", tmp_path / "z", topics)
    with pytest.raises(DataError, match="topic /est: every header stamp is zero .*use stamp='receive'"):
        ingest_bags([path], truth_topic="/gt", estimate_topic="/est")
    df = ingest_bags([path], truth_topic="/gt", estimate_topic="/est", stamp="receive")
    assert len(df) > 0


def test_bag_without_type_definitions_needs_a_typestore(tmp_path, motions, bagkit):
    path, t_est = _bag(bagkit, "ros2_sqlite3", tmp_path, motions, truth_type="geometry_msgs/msg/PoseStamped")
    bagkit.strip_definitions(path)
    with pytest.raises(DataError, match="carries no message type definitions; .* typestore='ros2_humble'"):
        ingest_bags([path], truth_topic="/mocap", estimate_topic="/odom")
    df = ingest_bags(
        [path], truth_topic="/mocap", estimate_topic="/odom", typestore="ros2_humble", options=_opts(OFFSET)
    )
    _check(df, motions, t_est)
    with pytest.raises(DataError, match="unknown type store 'ros3'; use one of .*ros2_humble"):
        list_topics(path, typestore="ros3")


def test_no_time_overlap_hints_at_the_offset_and_receive_stamps(tmp_path, motions, bagkit):
    path, _ = _bag(bagkit, "ros1", tmp_path, motions)
    with pytest.raises(DataError, match=r"do not overlap in time; .*t_offset .*stamp='receive'"):
        ingest_bags([path], truth_topic="/mocap", estimate_topic="/odom")


def test_not_a_bag(tmp_path):
    (tmp_path / "x.bag").write_bytes(b"not a bag at all")
    with pytest.raises(DataError, match="x.bag: cannot read as a bag"):
        list_topics(tmp_path / "x.bag")
    (tmp_path / "x.txt").write_text("")
    with pytest.raises(DataError, match="not a bag: use a ROS 1 .bag file"):
        list_topics(tmp_path / "x.txt")
    (tmp_path / "r.bag").write_bytes(bytes(range(200, 256)) * 50)  # not even a text first line
    with pytest.raises(
        DataError, match=r"r\.bag: cannot read as a bag: its content is not a ROS bag's \(Unicode"
    ):
        list_topics(tmp_path / "r.bag")


def test_without_rosbags_the_error_says_what_to_install(tmp_path, monkeypatch):
    import sys

    for name in [m for m in sys.modules if m == "rosbags" or m.startswith("rosbags.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "rosbags", None)  # an import of rosbags now fails
    (tmp_path / "a.bag").write_bytes(b"")
    with pytest.raises(DataError, match=r"reading bags needs rosbags: pip install 'ipcverify\[ros\]'"):
        list_topics(tmp_path / "a.bag")
