"""Poses read straight from serialized messages, without building message objects.

Deserializing a message into objects costs several microseconds; a pose message holds a
stamp, one or two strings and seven float64 numbers at offsets the strings determine. For
the four fixed-layout pose types this module reads those numbers from the raw bytes:

* ROS 1 serialization: little endian, no padding; a string is a uint32 length and its bytes.
* ROS 2 CDR: a 4-byte encapsulation header (little endian only here), then fields aligned
  to their size relative to the end of that header; a string is a uint32 length that counts
  its terminating NUL.

A parser is offered only when the bag's definition of the type is the standard one (the
structure's MD5, as rosbags computes it, equals that of the ROS 1 Noetic or ROS 2 Humble
definition); otherwise, for ``/tf`` messages and for big-endian CDR, the caller deserializes.
``tests/ipcverify/io/ingest/test_rawpose.py`` checks every parser against rosbags' deserializer.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

from ipcverify.io.ingest._messages import PoseRow

#: Strings between the header and the pose, per type.
_STRINGS_AFTER_HEADER = {
    "geometry_msgs/msg/PoseStamped": 0,
    "geometry_msgs/msg/PoseWithCovarianceStamped": 0,
    "geometry_msgs/msg/TransformStamped": 1,
    "nav_msgs/msg/Odometry": 1,
}
_U32 = struct.Struct("<I")
_SEVEN = struct.Struct("<7d")
_ROS1_HEADER = struct.Struct("<IIII")  # seq, secs, nsecs, frame_id length
_CDR_HEADER = struct.Struct("<iII")  # sec, nanosec, frame_id length
_STANDARD: dict[tuple[str, bool], str] = {}


def _standard_digest(msgtype: str, ros1: bool) -> str:
    key = (msgtype, ros1)
    if key not in _STANDARD:
        from rosbags.typesys import Stores, get_typestore

        store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        _STANDARD[key] = store.generate_msgdef(msgtype)[1]
    return _STANDARD[key]


def _ros1(strings: int) -> Callable[[bytes], PoseRow | None]:
    def parse(raw: bytes) -> PoseRow | None:
        _, sec, nsec, n = _ROS1_HEADER.unpack_from(raw, 0)
        off = 16 + n
        for _ in range(strings):
            off += 4 + _U32.unpack_from(raw, off)[0]
        return (sec, nsec, *_SEVEN.unpack_from(raw, off))

    return parse


def _cdr(strings: int) -> Callable[[bytes], PoseRow | None]:
    def parse(raw: bytes) -> PoseRow | None:
        if raw[1] != 1:  # not little-endian CDR: let the deserializer handle it
            return None
        sec, nsec, n = _CDR_HEADER.unpack_from(raw, 4)
        pos = 12 + n  # relative to the body (after the 4-byte encapsulation header)
        for _ in range(strings):
            pos = (pos + 3) & ~3
            pos += 4 + _U32.unpack_from(raw, 4 + pos)[0]
        pos = (pos + 7) & ~7
        return (sec, nsec, *_SEVEN.unpack_from(raw, 4 + pos))

    return parse


def raw_pose_parser(msgtype: str, ros1: bool, typestore: Any) -> Callable[[bytes], PoseRow | None] | None:
    """A function from raw message bytes to a pose record, or None when the type needs deserializing.

    Parameters
    ----------
    msgtype : str
        The message type (``geometry_msgs/msg/PoseStamped`` ...).
    ros1 : bool
        ROS 1 serialization (else ROS 2 CDR).
    typestore : rosbags Typestore
        The types the bag defines; the parser is offered only if ``msgtype`` is the standard one.

    Examples
    --------
    >>> import struct
    >>> raw = struct.pack("<IIII", 0, 5, 250, 3) + b"map" + struct.pack("<7d", 1, 2, 3, 0, 0, 0, 1)
    >>> from rosbags.typesys import Stores, get_typestore
    >>> parse = raw_pose_parser("geometry_msgs/msg/PoseStamped", True, get_typestore(Stores.ROS1_NOETIC))
    >>> parse(raw)
    (5, 250, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0)
    """
    strings = _STRINGS_AFTER_HEADER.get(msgtype)
    if strings is None:
        return None
    try:
        if typestore.generate_msgdef(msgtype)[1] != _standard_digest(msgtype, ros1):
            return None
    except Exception:  # noqa: BLE001 -- any trouble with the definitions: deserialize instead
        return None
    return _ros1(strings) if ros1 else _cdr(strings)
