"""Trajectory files: TUM, EuRoC ground-truth CSV and KITTI poses, read into :class:`Trajectory`.

=========  =====================================================================================
format     layout
=========  =====================================================================================
``tum``    one pose a line, ``t x y z qx qy qz qw`` (seconds; spaces or commas; ``#`` comments)
``euroc``  CSV ``timestamp [ns], x, y, z, qw, qx, qy, qz`` and maybe more columns (velocities,
           biases), as EuRoC's ``state_groundtruth_estimate0/data.csv``; stamps read as
           integer nanoseconds
``kitti``  one pose a line, the 12 entries of ``[R | t]`` row by row; no stamps: the times come
           from a separate file with one time (seconds) a line, as KITTI's ``times.txt``
=========  =====================================================================================

A file ending in ``.gz`` is read through gzip. Poses are sorted by stamp and the first of a
repeated stamp is kept; :class:`FileTrajectory` says how many were dropped.
"""

from __future__ import annotations

import gzip
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Literal

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ipcverify._wording._spelling import option
from ipcverify.errors import DataError
from ipcverify.io.ingest._trajectory import Trajectory

FORMATS = ("tum", "euroc", "kitti")
Format = Literal["tum", "euroc", "kitti"]

_SPLIT = re.compile(r"[\s,]+")
_LAYOUT = {
    "tum": "t x y z qx qy qz qw (8 numbers)",
    "euroc": "timestamp_ns, x, y, z, qw, qx, qy, qz (at least 8 columns)",
    "kitti": "the 12 entries of a 3x4 pose [R | t], row by row",
}


@dataclass(frozen=True, eq=False)
class FileTrajectory:
    """A trajectory read from a file, and how many repeated stamps were dropped.

    Attributes
    ----------
    trajectory : Trajectory
        The file's poses sorted by time, one per stamp (the first of a repeated stamp kept).
    repeated_stamps : int
        How many poses were dropped because their stamp repeated an earlier one (0 for a clean file).
    """

    trajectory: Trajectory
    repeated_stamps: int


def _open_text(path: Path) -> IO[str]:
    if path.suffix.lower() == ".gz":
        return gzip.open(path, "rt", encoding="utf-8")
    return open(path, encoding="utf-8")


def _rows(
    path: Path, fmt: str, width: int, at_least: bool, first_as_int: bool
) -> tuple[NDArray[np.float64], list[int]]:
    """The numeric rows of a text file (comments, blank lines and one header line skipped)."""
    rows: list[list[float]] = []
    stamps: list[int] = []
    try:
        with _open_text(path) as f:
            for lineno, line in enumerate(f, start=1):
                text = line.split("#", 1)[0].strip()
                if not text:
                    continue
                parts = [s for s in _SPLIT.split(text) if s]
                if len(parts) < width or (len(parts) > width and not at_least):
                    raise DataError(
                        f"{path}, line {lineno}: {len(parts)} values; "
                        f"a {fmt.upper()} line holds {_LAYOUT[fmt]}"
                        + (
                            f"; pick the right {option('format')}"
                            if fmt != "kitti" or len(parts) != 8
                            else ""
                        )
                    )
                try:
                    stamp = int(parts[0]) if first_as_int else 0
                    values = [float(s) for s in parts[int(first_as_int) : width]]
                except ValueError:
                    if not rows and lineno == 1:  # a header line without '#'
                        continue
                    raise DataError(
                        f"{path}, line {lineno}: not a number in {text[:60]!r}; a {fmt.upper()} line "
                        f"holds {_LAYOUT[fmt]}"
                    ) from None
                stamps.append(stamp)
                rows.append(values)
    except (UnicodeDecodeError, OSError, EOFError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise DataError(f"{path}: cannot read as a {fmt.upper()} text file: {exc}") from None
    if not rows:
        raise DataError(f"{path}: no poses; a {fmt.upper()} file holds one pose a line: {_LAYOUT[fmt]}")
    return np.asarray(rows, dtype=np.float64), stamps


def read_times(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Times (seconds) from a file with one number a line, as KITTI's ``times.txt``.

    Parameters
    ----------
    path : path-like
        A text file of times, one a line (a `#` starts a comment).

    Examples
    --------
    >>> import os, tempfile
    >>> p = os.path.join(tempfile.mkdtemp(), "times.txt")
    >>> _ = open(p, "w").write("0.0\\n1.0e-01\\n")
    >>> read_times(p).tolist()
    [0.0, 0.1]
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(2, "No such file", str(p))
    try:
        with _open_text(p) as f:
            values = [s for line in f for s in _SPLIT.split(line.split("#", 1)[0].strip()) if s]
        return np.asarray([float(v) for v in values], dtype=np.float64)
    except ValueError as exc:
        raise DataError(f"{p}: a times file holds one number (seconds) a line: {exc}") from None


def read_trajectory(
    path: str | os.PathLike[str], fmt: Format, times: str | os.PathLike[str] | None = None
) -> FileTrajectory:
    """Read a TUM, EuRoC or KITTI trajectory file (see the module docstring for the layouts).

    Parameters
    ----------
    path : path-like
        The file (``.gz`` is decompressed).
    fmt : {"tum", "euroc", "kitti"}
        Its layout.
    times : path-like, optional
        KITTI only: the times file, one time a line, one line per pose.

    Raises
    ------
    DataError
        Naming the file and line: a line of the wrong width, a value that is not a number,
        no poses, a KITTI file without times or with a different number of them.

    Examples
    --------
    >>> import os, tempfile
    >>> p = os.path.join(tempfile.mkdtemp(), "traj.txt")
    >>> _ = open(p, "w").write("# t x y z qx qy qz qw\\n1.0 0 0 0 0 0 0 1\\n2.0 1 0 0 0 0 0 1\\n")
    >>> read_trajectory(p, "tum").trajectory.p[:, 0].tolist()
    [0.0, 1.0]
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(2, "No such file", str(p))
    if fmt not in FORMATS:
        raise DataError(f"unknown trajectory format {fmt!r}; use one of {', '.join(FORMATS)}")
    if fmt != "kitti" and times is not None:
        raise DataError(f"{p}: a times file applies to KITTI poses only, not to {fmt.upper()}")
    if fmt == "tum":
        a, _ = _rows(p, fmt, 8, at_least=False, first_as_int=False)
        t, pos, quat = a[:, 0], a[:, 1:4], a[:, 4:8]
    elif fmt == "euroc":
        a, ns = _rows(p, fmt, 8, at_least=True, first_as_int=True)
        stamps = np.asarray(ns, dtype=np.int64)
        t = (stamps // 1_000_000_000).astype(np.float64) + (stamps % 1_000_000_000) * 1e-9
        pos, quat = a[:, 0:3], a[:, [4, 5, 6, 3]]
    else:
        if times is None:
            raise DataError(
                f"{p}: KITTI poses carry no stamps; give the times file ({option('times')}, one time a line)"
            )
        a, _ = _rows(p, fmt, 12, at_least=False, first_as_int=False)
        t = read_times(times)
        if t.shape[0] != a.shape[0]:
            raise DataError(
                f"{p}: {a.shape[0]} poses but {t.shape[0]} times in {times}; the times file needs one "
                "line per pose"
            )
        m = a.reshape(-1, 3, 4)
        pos = m[:, :, 3]
        try:
            quat = Rotation.from_matrix(m[:, :, :3]).as_quat()
        except ValueError as exc:
            raise DataError(f"{p}: a pose's 3x3 block is not a rotation: {exc}") from None
    tr, repeated = Trajectory.from_unsorted(t, pos, quat, str(p))
    return FileTrajectory(tr, repeated)
