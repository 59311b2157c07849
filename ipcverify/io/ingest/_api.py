"""The entry points: bags and trajectory files to a DataFrame of perception triples.

Both return a pandas DataFrame with columns ``x_0..``, ``y_0..``, ``yhat_0..``, ``run`` and
``t`` (seconds since the run's first estimate), one row per sample, plus any ``tags``. The
account of the rows (inputs and their SHA-256, options, rows dropped and why, the alignment)
is in ``frame.attrs["ipcverify.io.ingest"]``; :func:`ipcverify.io.ingest.write_ingested`
writes the table and that manifest. ``PerceptionDataset.from_frame(frame)`` makes a dataset of
it directly.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ipcverify._wording._spelling import option
from ipcverify.errors import DataError
from ipcverify.io.ingest._bagio import PoseRequest, Stamp, read_bag
from ipcverify.io.ingest._formats import Format, read_trajectory
from ipcverify.io.ingest._manifest import input_record
from ipcverify.io.ingest._samples import (
    MANIFEST_KEY,
    IngestOptions,
    RunData,
    build_samples,
    warn_camera_frame,
    with_up,
)

PathLike = str | os.PathLike[str]


def run_names(paths: Sequence[PathLike], names: Sequence[str] | None) -> list[str]:
    """The run names: ``names`` if given (one per path), else each file's stem (a directory's name).

    Parameters
    ----------
    paths : sequence of path-like
        The input files or directories.
    names : sequence of str or None
        The names given.

    Examples
    --------
    >>> run_names(["a/run1.bag", "b/run2.txt.gz", "c/bag3.mcap"], None)
    ['run1', 'run2', 'bag3']
    """
    if names:
        if len(names) != len(paths):
            raise DataError(
                f"{len(names)} run name(s) for {len(paths)} input(s); give one name per input "
                f"({option('runs')})"
            )
        return [str(n) for n in names]
    out = []
    for p in map(Path, paths):
        base = Path(p.stem) if p.suffix.lower() == ".gz" else p
        out.append(p.name if p.is_dir() else base.stem)
    return out


def _refuse_the_truth_as_estimate(frame: pd.DataFrame, truth: str, estimate: str) -> None:
    """Refuse a table whose every estimate equals its truth: the two inputs are the same poses.

    Parameters
    ----------
    frame : DataFrame
        The samples.
    truth, estimate : str
        The inputs, in words (topics and frames, or files), for the message.

    Examples
    --------
    >>> same = pd.DataFrame({"y_0": [0.1, 0.2], "yhat_0": [0.1, 0.2]})
    >>> _refuse_the_truth_as_estimate(same, "gt.txt", "gt.txt")
    Traceback (most recent call last):
    ...
    ipcverify.errors.DataError: every one of the 2 samples has its estimate equal to its truth ...
    """
    y = frame.filter(regex=r"^y_\d+$").to_numpy()
    yhat = frame.filter(regex=r"^yhat_\d+$").to_numpy()
    if len(frame) and y.shape == yhat.shape and np.array_equal(y, yhat):
        raise DataError(
            f"every one of the {len(frame)} samples has its estimate equal to its truth (truth: {truth}; "
            f"estimate: {estimate}): they are the same poses, and the log would hold no error to learn; "
            f"give the ground truth (motion capture, GPS/INS) as {option('truth')} and the estimator's "
            "output "
            f"as {option('estimates')}"
        )


def _finish(frame: pd.DataFrame, tags: Mapping[str, str], extra: Mapping[str, Any]) -> pd.DataFrame:
    for k, v in tags.items():
        if k in frame.columns:
            raise DataError(f"tag {k!r} would replace the column of that name; choose another tag name")
        frame[k] = v
    account = frame.attrs[MANIFEST_KEY]
    frame.attrs[MANIFEST_KEY] = {**extra, **account, "tags": dict(tags)}
    return frame


def ingest_trajectories(
    truth: PathLike | Sequence[PathLike],
    estimates: Sequence[PathLike],
    *,
    truth_format: Format = "tum",
    estimate_format: Format = "tum",
    times: PathLike | None = None,
    runs: Sequence[str] | None = None,
    options: IngestOptions | None = None,
    tags: Mapping[str, str] | None = None,
) -> pd.DataFrame:
    """Perception triples from trajectory files, one run per estimate file.

    Parameters
    ----------
    truth : path-like or sequence of them
        One ground-truth file for every run, or one per estimate file.
    estimates : sequence of path-like
        The estimated trajectories; each is a run.
    truth_format, estimate_format : {"tum", "euroc", "kitti"}
        The files' layouts (:mod:`ipcverify.io.ingest._formats`).
    times : path-like, optional
        The times file of KITTI poses.
    runs : sequence of str, optional
        Run names, one per estimate (default: the files' stems).
    options : IngestOptions, optional
        Quantity, horizon, stride, max gap, clock offset, alignment.
    tags : mapping of str to str, optional
        Constant columns to add (e.g. ``{"method": "vislam_rp"}``).

    Examples
    --------
    >>> import os, tempfile, numpy as np
    >>> d = tempfile.mkdtemp()
    >>> t = np.arange(0.0, 2.0, 0.05)
    >>> rows = np.column_stack([t, t, 0 * t, 0 * t, 0 * t, 0 * t, 0 * t, 1 + 0 * t])
    >>> np.savetxt(os.path.join(d, "gt.txt"), rows)
    >>> est = rows[::2] * [1, 1.1, 1, 1, 1, 1, 1, 1]  # an estimate 10 % fast along x
    >>> np.savetxt(os.path.join(d, "est.txt"), est)
    >>> df = ingest_trajectories(os.path.join(d, "gt.txt"), [os.path.join(d, "est.txt")])
    >>> len(df), df["run"].iloc[0], float(df["y_0"].round(12).iloc[0]), float(df["yhat_0"].round(12).iloc[0])
    (6, 'est', 0.5, 0.55)
    """
    options = options or IngestOptions()
    told_up = options.up is not None
    # x is read from the estimate, in the truth's world frame once aligned
    frame_format = truth_format if options.align != "none" else estimate_format
    options = with_up(options, "-y" if frame_format == "kitti" else "+z")
    truths = [truth] if isinstance(truth, (str, os.PathLike)) else list(truth)
    if not estimates:
        raise DataError(f"no estimate file; give at least one in {option('estimates')}")
    if len(truths) not in (1, len(estimates)):
        raise DataError(
            f"{len(truths)} truth files for {len(estimates)} estimates; "
            "give one truth file, or one per estimate"
        )
    names = run_names(estimates, runs)
    kitti_times = {"kitti"} & {truth_format, estimate_format}
    if times is not None and not kitti_times:
        raise DataError(
            f"{option('times')} applies to KITTI poses only; give {option('format', 'kitti')} or drop "
            f"{option('times')}"
        )
    read_truth = {
        str(p): read_trajectory(p, truth_format, times if truth_format == "kitti" else None) for p in truths
    }
    run_list = []
    repeated: dict[str, int] = {k: v.repeated_stamps for k, v in read_truth.items()}
    for i, (name, est) in enumerate(zip(names, estimates, strict=True)):
        got = read_trajectory(est, estimate_format, times if estimate_format == "kitti" else None)
        repeated[str(est)] = got.repeated_stamps
        gt = read_truth[str(truths[0] if len(truths) == 1 else truths[i])].trajectory
        run_list.append(RunData(name, gt, got.trajectory))
    if not told_up and options.up == "+z" and options.align == "none":
        warn_camera_frame(run_list)
    frame = build_samples(run_list, options)
    _refuse_the_truth_as_estimate(frame, ", ".join(map(str, truths)), ", ".join(map(str, estimates)))
    inputs = [input_record(p, "truth") for p in truths] + [input_record(p, "estimate") for p in estimates]
    if times is not None:
        inputs.append(input_record(times, "times"))
    extra = {
        "source": "trajectories",
        "inputs": inputs,
        "formats": {"truth": truth_format, "estimate": estimate_format},
        "repeated_stamps_dropped": repeated,
    }
    return _finish(frame, tags or {}, extra)


def ingest_bags(
    paths: Sequence[PathLike],
    *,
    truth_topic: str,
    estimate_topic: str,
    child_frame: str | None = None,
    truth_child_frame: str | None = None,
    estimate_child_frame: str | None = None,
    stamp: Stamp = "header",
    state_topic: str | None = None,
    state_fields: Sequence[str] = (),
    typestore: str | None = None,
    runs: Sequence[str] | None = None,
    options: IngestOptions | None = None,
    tags: Mapping[str, str] | None = None,
) -> pd.DataFrame:
    """Perception triples from ROS 1 bags, ROS 2 bags and raw MCAP files, one run per bag.

    Parameters
    ----------
    paths : sequence of path-like
        Bags (:mod:`ipcverify.io.ingest._bagio` says what a path may be).
    truth_topic, estimate_topic : str
        The pose topics (PoseStamped, PoseWithCovarianceStamped, TransformStamped, Odometry,
        or ``/tf`` with a child frame).
    child_frame, truth_child_frame, estimate_child_frame : str, optional
        The body's frame on a ``/tf`` topic; ``truth_child_frame`` and
        ``estimate_child_frame`` override it for one side.
    stamp : {"header", "receive"}
        Time messages by their header stamps (default) or by the recorder's receive times.
    state_topic, state_fields : optional
        A topic whose numeric fields are appended to ``x``, the last value at or before each
        sample's start.
    typestore : str, optional
        Message definitions for bags that carry none (``ros2_humble``, ``ros1_noetic``, ...).
    runs, options, tags
        As for :func:`ingest_trajectories`.
    """
    options = with_up(options or IngestOptions(), "+z")  # REP 103: ROS world frames are z-up
    if not paths:
        raise DataError("no bag given")
    names = run_names(paths, runs)
    requests = {
        "truth": PoseRequest(topic=truth_topic, child_frame=truth_child_frame or child_frame),
        "estimate": PoseRequest(topic=estimate_topic, child_frame=estimate_child_frame or child_frame),
    }
    run_list, repeated = [], {}
    for name, path in zip(names, paths, strict=True):
        got = read_bag(
            path,
            requests,
            stamp=stamp,
            state_topic=state_topic,
            state_fields=state_fields,
            typestore=typestore,
        )
        repeated[name] = dict(got.repeated_stamps)
        run_list.append(RunData(name, got.poses["truth"], got.poses["estimate"], got.state))
    hint = (
        f"; or time both by the recorder's clock with {option('stamp', 'receive')}"
        if stamp == "header"
        else ""
    )
    frame = build_samples(run_list, options, hint)
    _refuse_the_truth_as_estimate(
        frame,
        f"topic {truth_topic}"
        + (f" (child frame {requests['truth'].child_frame!r})" if requests["truth"].child_frame else ""),
        f"topic {estimate_topic}"
        + (
            f" (child frame {requests['estimate'].child_frame!r})" if requests["estimate"].child_frame else ""
        ),
    )
    extra = {
        "source": "bags",
        "inputs": [input_record(p, "bag") for p in paths],
        "topics": {
            "truth": truth_topic,
            "estimate": estimate_topic,
            "truth_child_frame": requests["truth"].child_frame,
            "estimate_child_frame": requests["estimate"].child_frame,
            "state": state_topic,
            "state_fields": list(state_fields),
        },
        "stamp": stamp,
        "typestore": typestore,
        "repeated_stamps_dropped": repeated,
    }
    return _finish(frame, tags or {}, extra)
