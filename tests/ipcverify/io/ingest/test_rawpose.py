"""The raw-bytes pose parsers agree with rosbags' deserializer: every type, serialization, string length."""

from __future__ import annotations

import itertools

import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from ipcverify.io.ingest._messages import pose_rows
from ipcverify.io.ingest._rawpose import raw_pose_parser

TYPES = [
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "geometry_msgs/msg/TransformStamped",
    "nav_msgs/msg/Odometry",
]


@pytest.mark.parametrize(("msgtype", "ros1"), list(itertools.product(TYPES, [True, False])))
def test_parser_matches_the_deserializer(msgtype, ros1, bagkit):
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    parse = raw_pose_parser(msgtype, ros1, ts)
    assert parse is not None
    serialize = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    deserialize = ts.deserialize_ros1 if ros1 else ts.deserialize_cdr
    for k, (frame, child) in enumerate(itertools.product(range(10), range(10))):
        msg = bagkit.make_message(
            ts, msgtype, 1700000000.125 + k, [k + 0.5, -1.25, 3.0], [0.1, -0.2, 0.3, 0.9]
        )
        msg.header.frame_id = "f" * frame
        if hasattr(msg, "child_frame_id"):
            msg.child_frame_id = "c" * child
        raw = bytes(serialize(msg, msgtype))
        assert parse(raw) == pose_rows(deserialize(raw, msgtype), msgtype, None)[0]


def test_no_parser_for_tf_or_a_redefined_type():
    ts = get_typestore(Stores.ROS2_HUMBLE)
    assert raw_pose_parser("tf2_msgs/msg/TFMessage", False, ts) is None
    odd = get_typestore(Stores.EMPTY)
    standard = get_typestore(Stores.ROS2_HUMBLE).fielddefs
    odd.register({k: v for k, v in standard.items() if k != "geometry_msgs/msg/PoseStamped"})
    odd.register(
        get_types_from_msg(
            "std_msgs/Header header\ngeometry_msgs/Point pose", "geometry_msgs/msg/PoseStamped"
        )
    )
    assert (
        odd.generate_msgdef("geometry_msgs/msg/PoseStamped")[1]
        != ts.generate_msgdef("geometry_msgs/msg/PoseStamped")[1]
    )
    assert raw_pose_parser("geometry_msgs/msg/PoseStamped", False, odd) is None


def test_big_endian_cdr_is_left_to_the_deserializer(bagkit):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    parse = raw_pose_parser("geometry_msgs/msg/PoseStamped", False, ts)
    raw = bytearray(
        ts.serialize_cdr(
            bagkit.make_message(ts, "geometry_msgs/msg/PoseStamped", 1.0, [1, 2, 3], [0, 0, 0, 1]),
            "geometry_msgs/msg/PoseStamped",
        )
    )
    raw[1] = 0
    assert parse(bytes(raw)) is None
