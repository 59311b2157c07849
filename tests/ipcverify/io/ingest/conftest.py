"""Trajectories whose interpolation is exact, and bags written with rosbags in every container.

The reference motion: positions linear in time and rotations at a constant rate about a
fixed axis. Linear interpolation of such positions and slerp of such rotations are exact, so
the samples ``ingest`` builds can be checked against formulas computed directly from the
motion, with no interpolation on the test's side.
"""

from __future__ import annotations

import dataclasses
import sqlite3
from collections.abc import Callable, Sequence
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ipcverify.io.ingest._trajectory import Trajectory


@dataclasses.dataclass(frozen=True)
class Motion:
    """``p(t) = p0 + v t``, ``R(t) = exp(t w axis) R0`` (body to world), then a body-frame offset ``Rc``."""

    p0: np.ndarray
    v: np.ndarray
    axis: np.ndarray
    w: float
    R0: Rotation
    Rc: Rotation

    def position(self, t: np.ndarray) -> np.ndarray:
        return self.p0 + np.outer(t, self.v)

    def rotation(self, t: np.ndarray) -> Rotation:
        return Rotation.from_rotvec(np.outer(t, self.axis * self.w)) * self.R0 * self.Rc

    def trajectory(self, t: np.ndarray, source: str = "<motion>") -> Trajectory:
        return Trajectory(t, self.position(t), self.rotation(t).as_quat(), source)

    def displacement(self, t0: np.ndarray, horizon: float) -> np.ndarray:
        """``R(t0)^T (p(t0 + H) - p(t0))``, computed from the formulas."""
        return self.rotation(t0).inv().apply(np.tile(self.v * horizon, (len(t0), 1)))


TRUTH = Motion(
    p0=np.array([1.0, -2.0, 0.5]),
    v=np.array([0.8, 0.3, -0.1]),
    axis=np.array([0.0, 0.6, 0.8]),
    w=0.7,
    R0=Rotation.from_euler("xyz", [0.1, -0.2, 0.3]),
    Rc=Rotation.identity(),
)
#: The estimate: a different velocity (a drift) and a constant body-frame rotation error.
ESTIMATE = dataclasses.replace(
    TRUTH, v=TRUTH.v + np.array([0.02, -0.01, 0.005]), Rc=Rotation.from_euler("z", 0.05)
)


@pytest.fixture
def motions() -> tuple[Motion, Motion]:
    return TRUTH, ESTIMATE


def _typestore(container: str):
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    if container != "ros1":
        return get_typestore(Stores.ROS2_HUMBLE)
    ts = get_typestore(Stores.ROS1_NOETIC)  # its store lacks tf2_msgs, which ROS 1 bags of /tf carry
    ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    return ts


def _header(ts, stamp: float, frame: str):
    T = ts.types
    sec = int(np.floor(stamp))
    nsec = int(round((stamp - sec) * 1e9))
    if nsec == 1_000_000_000:
        sec, nsec = sec + 1, 0
    time = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
    fields = T["std_msgs/msg/Header"].__dataclass_fields__
    if "seq" in fields:
        return T["std_msgs/msg/Header"](seq=0, stamp=time, frame_id=frame)
    return T["std_msgs/msg/Header"](stamp=time, frame_id=frame)


def make_message(ts, msgtype: str, stamp: float, p: Sequence[float], q: Sequence[float], child: str = "body"):
    """A message of ``msgtype`` holding the pose (p, q) stamped ``stamp``."""
    T = ts.types
    point = T["geometry_msgs/msg/Point"](x=float(p[0]), y=float(p[1]), z=float(p[2]))
    vec = T["geometry_msgs/msg/Vector3"](x=float(p[0]), y=float(p[1]), z=float(p[2]))
    quat = T["geometry_msgs/msg/Quaternion"](x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))
    pose = T["geometry_msgs/msg/Pose"](position=point, orientation=quat)
    cov = np.zeros(36, dtype=np.float64)
    hdr = _header(ts, stamp, "world")
    if msgtype == "geometry_msgs/msg/PoseStamped":
        return T[msgtype](header=hdr, pose=pose)
    if msgtype == "geometry_msgs/msg/PoseWithCovarianceStamped":
        return T[msgtype](
            header=hdr, pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov)
        )
    transform = T["geometry_msgs/msg/Transform"](translation=vec, rotation=quat)
    tfs = T["geometry_msgs/msg/TransformStamped"](header=hdr, child_frame_id=child, transform=transform)
    if msgtype == "geometry_msgs/msg/TransformStamped":
        return tfs
    if msgtype == "tf2_msgs/msg/TFMessage":
        other = T["geometry_msgs/msg/TransformStamped"](
            header=hdr, child_frame_id="other", transform=transform
        )
        return T[msgtype](transforms=[other, tfs])
    twist = T["geometry_msgs/msg/Twist"](
        linear=T["geometry_msgs/msg/Vector3"](x=stamp, y=0.0, z=0.0),
        angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
    )
    return T["nav_msgs/msg/Odometry"](
        header=hdr,
        child_frame_id=child,
        pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=cov),
    )


#: A topic to write: (topic, msgtype, messages as (receive time s, message builder(ts))).
Topic = tuple[str, str, list[tuple[float, Callable]]]


def write_bag(container: str, path: Path, topics: Sequence[Topic]) -> Path:
    """Write the topics into a bag of the given container; returns the path to read."""
    ts = _typestore(container)
    records = sorted(
        ((recv, i, build) for i, (_, _, msgs) in enumerate(topics) for recv, build in msgs),
        key=lambda r: r[0],
    )
    if container == "ros1":
        from rosbags.rosbag1 import Writer

        out = path.with_suffix(".bag")
        with Writer(out) as w:
            conns = [w.add_connection(topic, msgtype, typestore=ts) for topic, msgtype, _ in topics]
            for recv, i, build in records:
                c = conns[i]
                w.write(c, int(round(recv * 1e9)), ts.serialize_ros1(build(ts), c.msgtype))
        return out
    from rosbags.rosbag2 import StoragePlugin, Writer

    plugin = StoragePlugin.SQLITE3 if container == "ros2_sqlite3" else StoragePlugin.MCAP
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns = [w.add_connection(topic, msgtype, typestore=ts) for topic, msgtype, _ in topics]
        for recv, i, build in records:
            c = conns[i]
            w.write(c, int(round(recv * 1e9)), ts.serialize_cdr(build(ts), c.msgtype))
    if container == "mcap":  # the storage file alone, without the bag directory's metadata
        raw = path.parent / f"{path.name}.mcap"
        next(path.glob("*.mcap")).rename(raw)
        for f in path.iterdir():
            f.unlink()
        path.rmdir()
        return raw
    return path


def pose_topic(
    topic: str,
    msgtype: str,
    motion: Motion,
    t: np.ndarray,
    stamp_clock: float = 0.0,
    receive_clock: float = 0.0,
) -> Topic:
    """The motion's poses at times ``t``: stamped ``stamp_clock + t``, received at ``receive_clock + t``."""
    p = motion.position(t)
    q = motion.rotation(t).as_quat()

    def builder(k: int) -> Callable:
        return lambda ts: make_message(ts, msgtype, stamp_clock + float(t[k]), p[k], q[k])

    return topic, msgtype, [(receive_clock + float(t[k]), builder(k)) for k in range(len(t))]


def strip_definitions(bag_dir: Path) -> None:
    """Remove the message definitions from a ROS 2 sqlite3 bag (as in bags recorded before Iron)."""
    db = next(bag_dir.glob("*.db3"))
    with sqlite3.connect(db) as con:
        con.execute("DELETE FROM message_definitions")


@pytest.fixture
def bagkit():
    """The bag-writing helpers above, for test modules (which cannot import conftest)."""
    return SimpleNamespace(
        write_bag=write_bag,
        pose_topic=pose_topic,
        make_message=make_message,
        strip_definitions=strip_definitions,
    )
