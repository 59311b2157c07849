"""Reading ROS 1 bags, ROS 2 bags (sqlite3 or MCAP) and raw MCAP files through rosbags.

No ROS install is needed: rosbags reads every container and deserializes messages from the
type definitions the bag carries. A bag without definitions (ROS 2 bags before Iron) needs a
type store named with ``typestore`` (``ros2_humble``, ``ros1_noetic``, ...).

What a path is:

* a file ending in ``.bag``: a ROS 1 bag;
* a directory with ``metadata.yaml``: a ROS 2 bag (sqlite3 ``.db3`` or ``.mcap`` storage);
* a file ending in ``.mcap`` or ``.db3``: one ROS 2 storage file read on its own (a raw MCAP file
  must hold ROS 2 (CDR) messages).

rosbags is an optional dependency (``pip install 'ipcverify[ros]'``), imported on first use.
"""

from __future__ import annotations

import os
import struct
from collections import Counter
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ipcverify._wording._spelling import option
from ipcverify.errors import DataError
from ipcverify.io.ingest._messages import TF_TYPE, check_pose_type, field_reader, pose_rows
from ipcverify.io.ingest._rawpose import raw_pose_parser
from ipcverify.io.ingest._trajectory import Trajectory

Stamp = Literal["header", "receive"]


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag: its type, message count and the receive-time span (seconds).

    Attributes
    ----------
    topic : str
        The topic's name.
    msgtype : str
        Its message type.
    count : int
        Its number of messages.
    start, end : float
        The first and last receive time (seconds).
    """

    topic: str
    msgtype: str
    count: int
    start: float
    end: float

    def describe(self) -> str:
        """``/topic (type, N messages, a..b s)``."""
        span = f", {self.start:.3f}..{self.end:.3f} s" if self.count else ""
        return f"{self.topic} ({self.msgtype}, {self.count} messages{span})"


@dataclass(frozen=True, kw_only=True)
class PoseRequest:
    """A pose topic to read, and for a ``/tf`` topic the body's frame.

    Attributes
    ----------
    topic : str
        The name of the topic in the bag, e.g. ``/vicon/body`` or ``/tf``; its message type must
        be one that holds a pose (``ipcverify.io.ingest._messages.POSE_TYPES``).
    child_frame : str or None
        The body's frame on a ``/tf`` topic (None for a pose topic).
    """

    topic: str
    child_frame: str | None = None


@dataclass(frozen=True, eq=False)
class StateSeries:
    """Numbers read from a state topic: stamps (s, increasing), values (M, k), their field names.

    Attributes
    ----------
    t : ndarray, shape (M,)
        Stamps (seconds, increasing).
    values : ndarray, shape (M, k)
        The numbers read, one column per field.
    fields : tuple of str
        The field paths read.
    topic : str
        The topic.
    """

    t: NDArray[np.float64]
    values: NDArray[np.float64]
    fields: tuple[str, ...]
    topic: str = ""


@dataclass(frozen=True, eq=False)
class BagContents:
    """What :func:`read_bag` read: a trajectory per requested name, the repeated stamps dropped, the state.

    Attributes
    ----------
    poses : mapping of str to Trajectory
        A trajectory per requested name (``"truth"``, ``"estimate"``).
    repeated_stamps : mapping of str to int
        Per name, how many poses with a repeated stamp were dropped.
    state : StateSeries or None
        The state topic's numbers (None: no state topic asked for).
    """

    poses: Mapping[str, Trajectory]
    repeated_stamps: Mapping[str, int]
    state: StateSeries | None


def _rosbags() -> Any:
    try:
        from rosbags import highlevel, typesys
    except ImportError:
        raise DataError("reading bags needs rosbags: pip install 'ipcverify[ros]'") from None
    return highlevel, typesys


def typestore_names() -> list[str]:
    """Names accepted for ``typestore`` (rosbags' stores, e.g. ``ros2_humble``)."""
    _, typesys = _rosbags()
    return [s.value for s in typesys.Stores if s.value != "empty"]


@contextmanager
def _open(path: str | os.PathLike[str], typestore: str | None) -> Iterator[Any]:
    highlevel, typesys = _rosbags()
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(2, "No such file", str(p))
    if p.is_file() and p.suffix.lower() not in (".bag", ".mcap", ".db3"):
        raise DataError(
            f"{p}: not a bag: use a ROS 1 .bag file, a ROS 2 bag directory, or a .mcap / .db3 file"
        )
    if p.is_dir() and not (p / "metadata.yaml").is_file():
        raise DataError(
            f"{p}: a directory without metadata.yaml is not a ROS 2 bag; give the bag directory (the one "
            "holding metadata.yaml), or a .bag / .mcap / .db3 file"
        )
    store = None
    if typestore is not None:
        if typestore not in typestore_names():
            raise DataError(f"unknown type store {typestore!r}; use one of {', '.join(typestore_names())}")
        store = typesys.get_typestore(typesys.Stores(typestore))
    try:
        reader = highlevel.AnyReader([p], default_typestore=store)
        reader.open()
    except highlevel.AnyReaderError as exc:
        text = " ".join(str(a) for a in exc.args)
        if "no type definitions" in text:
            raise DataError(
                f"{p}: the bag carries no message type definitions; name the ROS distribution it was "
                f"recorded with, e.g. {option('typestore', 'ros2_humble')} (or ros1_noetic, ros2_foxy, ...)"
            ) from None
        raise DataError(f"{p}: cannot read as a bag: {text}") from None
    except (ValueError, EOFError, struct.error) as exc:  # the reader meets bytes it cannot parse
        raise DataError(
            f"{p}: cannot read as a bag: its content is not a ROS bag's ({type(exc).__name__}: "
            f"{str(exc)[:120]}); check that the file is a complete, uncorrupted recording"
        ) from None
    try:
        yield reader
    finally:
        reader.close()


def _infos(reader: Any, spans: bool) -> list[TopicInfo]:
    out = []
    for topic, info in sorted(reader.topics.items()):
        start = end = float("nan")
        if spans and info.msgcount:
            stamps = [ts for _, ts, _ in reader.messages(connections=info.connections)]
            start, end = min(stamps) * 1e-9, max(stamps) * 1e-9
        out.append(TopicInfo(topic, str(info.msgtype), int(info.msgcount), start, end))
    return out


def list_topics(path: str | os.PathLike[str], typestore: str | None = None) -> list[TopicInfo]:
    """Every topic of a bag with its type, message count and time span (receive times, seconds).

    Parameters
    ----------
    path : path-like
        A ROS 1 bag, a ROS 2 bag directory or an MCAP file.
    typestore : str, optional
        The message-type store to decode with (default: from the bag).

    Raises
    ------
    DataError
        If the path is not a bag rosbags can read, or the bag has no type definitions and no
        ``typestore`` is given.
    """
    with _open(path, typestore) as reader:
        return _infos(reader, spans=True)


def _missing_topic(path: str | os.PathLike[str], topic: str, infos: Sequence[TopicInfo]) -> DataError:
    listing = "; ".join(i.describe() for i in infos) or "none"
    return DataError(f"{path}: no topic {topic!r}; its topics: {listing}")


def _seconds(sec: NDArray[np.int64], nsec: NDArray[np.int64]) -> NDArray[np.float64]:
    return sec.astype(np.float64) + nsec.astype(np.float64) * 1e-9


def _frames_on(transforms: Counter[tuple[str, str, str]], topic: str, most: int = 12) -> str:
    """The transforms a ``/tf`` topic holds, for an error naming a frame it lacks.

    Parameters
    ----------
    transforms : Counter
        Counts of ``(topic, parent frame, child frame)``.
    topic : str
        The topic.
    most : int
        How many to list (the most frequent first).

    Examples
    --------
    >>> _frames_on(Counter({("/tf", "odom", "base_link"): 5, ("/tf", "map", "odom"): 2}), "/tf")
    '; its transforms (parent -> child frame): odom -> base_link (5), map -> odom (2)'
    >>> _frames_on(Counter(), "/tf")
    '; it holds no transform'
    """
    seen = [(n, parent, child) for (t, parent, child), n in transforms.most_common() if t == topic]
    if not seen:
        return "; it holds no transform"
    listed = ", ".join(f"{parent} -> {child} ({n})" for n, parent, child in seen[:most])
    more = f", and {len(seen) - most} more" if len(seen) > most else ""
    return f"; its transforms (parent -> child frame): {listed}{more}"


def read_bag(
    path: str | os.PathLike[str],
    poses: Mapping[str, PoseRequest],
    *,
    stamp: Stamp = "header",
    state_topic: str | None = None,
    state_fields: Sequence[str] = (),
    typestore: str | None = None,
) -> BagContents:
    """Read pose topics (and a state topic's fields) from one bag in one pass.

    Parameters
    ----------
    path : path-like
        A bag (see the module docstring).
    poses : mapping of str to PoseRequest
        A name (e.g. ``"truth"``) for every pose topic to read.
    stamp : {"header", "receive"}
        Time every message by its header stamp (the sensor's clock) or by the time the
        recorder received it.
    state_topic, state_fields : optional
        A topic and the numeric fields to read from it (``twist.twist.linear.x``, ``a[0]``);
        timed by the header stamp if the message has one and ``stamp`` is ``"header"``.
    typestore : str, optional
        Message definitions to use when the bag carries none.

    Raises
    ------
    DataError
        A missing topic (the message lists the bag's topics and types), a type that holds no
        pose (the supported types are listed), ``/tf`` without a child frame or without that
        frame, header stamps all zero (use ``stamp="receive"``), a bag without definitions.
    """
    with _open(path, typestore) as reader:
        infos = _infos(reader, spans=False)
        by_topic = {i.topic: i for i in infos}
        wanted = [r.topic for r in poses.values()] + ([state_topic] if state_topic else [])
        for topic in wanted:
            if topic not in by_topic:
                raise _missing_topic(path, topic, _infos(reader, spans=True))
        for req in poses.values():
            check_pose_type(req.topic, by_topic[req.topic].msgtype, req.child_frame)
        if state_topic and not state_fields:
            raise DataError(
                f"state topic {state_topic}: name the fields to read with {option('state_fields')}"
            )
        readers = [field_reader(f) for f in state_fields]
        topics = set(wanted)
        conns = [c for c in reader.connections if c.topic in topics]
        rows: dict[str, list[Any]] = {name: [] for name in poses}
        receive: dict[str, list[int]] = {name: [] for name in poses}
        state_rows: list[list[float]] = []
        state_stamps: list[int] = []
        state_header = stamp == "header"
        transforms: Counter[tuple[str, str, str]] = Counter()  # (topic, parent, child) on /tf topics
        ros1 = not reader.is2
        parsers = {t: raw_pose_parser(by_topic[t].msgtype, ros1, reader.typestore) for t in topics}
        names_of = {t: [n for n, r in poses.items() if r.topic == t] for t in topics}
        # one file is one reader: iterate it directly, without AnyReader's merge of several
        source = reader.readers[0] if len(reader.readers) == 1 else reader
        for conn, ts, raw in source.messages(connections=conns):
            topic = conn.topic
            parse = parsers[topic] if topic != state_topic else None
            row = parse(raw) if parse is not None else None
            if row is not None:
                for name in names_of[topic]:
                    rows[name].append(row)
                    receive[name].append(ts)
                continue
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.msgtype == TF_TYPE:
                transforms.update((topic, tr.header.frame_id, tr.child_frame_id) for tr in msg.transforms)
            for name in names_of[topic]:
                got = pose_rows(msg, conn.msgtype, poses[name].child_frame)
                rows[name] += got
                receive[name] += [ts] * len(got)
            if topic == state_topic:
                state_rows.append([read(msg) for read in readers])
                header = getattr(msg, "header", None) if state_header else None
                state_stamps.append(
                    ts
                    if header is None
                    else int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)
                )
    trajectories: dict[str, Trajectory] = {}
    repeated: dict[str, int] = {}
    for name, req in poses.items():
        a = np.asarray(rows[name], dtype=np.float64).reshape(-1, 9)
        if not a.shape[0]:
            what = ""
            if by_topic[req.topic].msgtype == TF_TYPE:
                what = f" with child frame {req.child_frame!r}" + _frames_on(transforms, req.topic)
            raise DataError(f"{path}: topic {req.topic} has no pose{what}; check the topic and frame names")
        sec = np.asarray([r[0] for r in rows[name]], dtype=np.int64)
        nsec = np.asarray([r[1] for r in rows[name]], dtype=np.int64)
        if stamp == "header":
            if not (sec.any() or nsec.any()):
                raise DataError(
                    f"{path}: topic {req.topic}: every header stamp is zero (the publisher does not stamp "
                    f"its messages); use {option('stamp', 'receive')} to time them by the recorder's clock"
                )
            t = _seconds(sec, nsec)
        else:
            ns = np.asarray(receive[name], dtype=np.int64)
            t = _seconds(ns // 1_000_000_000, ns % 1_000_000_000)
        tr, repeated[name] = Trajectory.from_unsorted(t, a[:, 2:5], a[:, 5:9], f"{path}:{req.topic}")
        trajectories[name] = tr
    state = None
    if state_topic:
        ns = np.asarray(state_stamps, dtype=np.int64)
        order = np.argsort(ns, kind="stable")
        ns = ns[order]
        values = np.asarray(state_rows, dtype=np.float64).reshape(-1, len(readers))[order]
        state = StateSeries(
            _seconds(ns // 1_000_000_000, ns % 1_000_000_000), values, tuple(state_fields), state_topic
        )
    return BagContents(trajectories, repeated, state)
