"""Poses and fields out of deserialized ROS messages (ROS 1 and ROS 2 alike, as rosbags gives them).

Supported pose types (ROS 1 names are the same without ``/msg/``):

* ``geometry_msgs/msg/PoseStamped`` -- ``pose``
* ``geometry_msgs/msg/PoseWithCovarianceStamped`` -- ``pose.pose``
* ``geometry_msgs/msg/TransformStamped`` -- ``transform``
* ``nav_msgs/msg/Odometry`` -- ``pose.pose``
* ``tf2_msgs/msg/TFMessage`` (``/tf``) -- the transforms whose ``child_frame_id`` is the one asked for

A message object here is whatever rosbags deserialized; it is read by attribute only.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

from ipcverify._wording._spelling import option
from ipcverify.errors import DataError

TF_TYPE = "tf2_msgs/msg/TFMessage"

#: A pose record: header stamp (s, ns), position x, y, z, quaternion x, y, z, w.
PoseRow = tuple[int, int, float, float, float, float, float, float, float]


def _row(stamp: Any, position: Any, orientation: Any) -> PoseRow:
    return (
        int(stamp.sec),
        int(stamp.nanosec),
        float(position.x),
        float(position.y),
        float(position.z),
        float(orientation.x),
        float(orientation.y),
        float(orientation.z),
        float(orientation.w),
    )


def _pose_stamped(m: Any) -> PoseRow:
    return _row(m.header.stamp, m.pose.position, m.pose.orientation)


def _pose_in_pose(m: Any) -> PoseRow:
    return _row(m.header.stamp, m.pose.pose.position, m.pose.pose.orientation)


def _transform(m: Any) -> PoseRow:
    return _row(m.header.stamp, m.transform.translation, m.transform.rotation)


_READERS: dict[str, Callable[[Any], PoseRow]] = {
    "geometry_msgs/msg/PoseStamped": _pose_stamped,
    "geometry_msgs/msg/PoseWithCovarianceStamped": _pose_in_pose,
    "geometry_msgs/msg/TransformStamped": _transform,
    "nav_msgs/msg/Odometry": _pose_in_pose,
}

POSE_TYPES = (*_READERS, TF_TYPE)


def check_pose_type(topic: str, msgtype: str, child_frame: str | None) -> None:
    """Refuse a topic whose type holds no pose, or a ``/tf`` topic without a child frame.

    Parameters
    ----------
    topic : str
        The topic's name.
    msgtype : str
        Its message type.
    child_frame : str or None
        The body's frame (needed for a ``/tf`` topic).

    Examples
    --------
    >>> check_pose_type("/odom", "nav_msgs/msg/Odometry", None)
    >>> check_pose_type("/imu", "sensor_msgs/msg/Imu", None)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ipcverify.errors.DataError: topic /imu has type sensor_msgs/msg/Imu, which holds no pose; supported: ...
    """
    if msgtype not in POSE_TYPES:
        raise DataError(
            f"topic {topic} has type {msgtype}, which holds no pose; supported: {', '.join(POSE_TYPES)}"
        )
    if msgtype == TF_TYPE and not child_frame:
        raise DataError(
            f"topic {topic} is a transform tree ({TF_TYPE}); name the body's frame with "
            f"{option('child_frame')}"
        )


def pose_rows(message: Any, msgtype: str, child_frame: str | None) -> list[PoseRow]:
    """The pose records in one message (several for a ``/tf`` message, maybe none).

    Parameters
    ----------
    message : object
        The decoded message.
    msgtype : str
        Its type.
    child_frame : str or None
        The body's frame on a ``/tf`` topic.
    """
    if msgtype == TF_TYPE:
        want = (child_frame or "").lstrip("/")
        return [_transform(tr) for tr in message.transforms if tr.child_frame_id.lstrip("/") == want]
    return [_READERS[msgtype](message)]


_STEP = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?$")


def field_reader(path: str) -> Callable[[Any], float]:
    """A function reading the number at ``path`` (e.g. ``twist.twist.linear.x`` or ``covariance[0]``).

    Parameters
    ----------
    path : str
        Attribute names separated by dots, the last one optionally indexed.

    Raises
    ------
    DataError
        If the path is malformed; reading a message without that field raises a DataError
        naming the fields the message has.

    Examples
    --------
    >>> from types import SimpleNamespace as NS
    >>> read = field_reader("twist.linear.x")
    >>> read(NS(twist=NS(linear=NS(x=2))))
    2.0
    >>> field_reader("covariance[1]")(NS(covariance=[0.5, 0.25]))
    0.25
    """
    steps = []
    for part in path.split("."):
        m = _STEP.match(part)
        if not m:
            raise DataError(
                f"state field {path!r}: {part!r} is not a field name (use e.g. twist.linear.x or a[0])"
            )
        steps.append((m.group(1), None if m.group(2) is None else int(m.group(2))))

    def read(message: Any) -> float:
        value = message
        for name, index in steps:
            if not hasattr(value, name):
                have = sorted(k for k in getattr(value, "__dataclass_fields__", {}) if not k.startswith("__"))
                raise DataError(
                    f"state field {path!r}: no field {name!r} in "
                    f"{getattr(value, '__msgtype__', 'the message')}; "
                    f"it has {', '.join(have) or 'no fields'}"
                )
            value = getattr(value, name)
            if index is not None:
                try:
                    value = value[index]
                except (IndexError, TypeError):
                    raise DataError(f"state field {path!r}: {name} has no element {index}") from None
        try:
            return float(value)
        except (TypeError, ValueError):
            raise DataError(
                f"state field {path!r} is not a number (its type is {type(value).__name__})"
            ) from None

    return read
