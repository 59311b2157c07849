"""A log file split into train, calibration and test files, with a record of the split.

:func:`split_file` is what ``ipcverify split`` runs: it reads a log, splits it with
:meth:`~ipcverify.data.PerceptionDataset.split` (of rows, or of whole groups such as flights or
runs), writes one file per part and ``split.json`` beside them. The record names the source
and every part by SHA-256, of the file and of its numbers, so a reviewer can check that a model
was trained on the train part (its file's ``train_data_hash``), calibrated on the calibration
part (``calibration.data_hash``) and certified on the test part (``certificate.json``'s test
``content_sha256``).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ipcverify._wording._spelling import option
from ipcverify.data._checks import TIME_NAMES, time_column
from ipcverify.data._dataset import PerceptionDataset, load_dataset, save_dataset
from ipcverify.data._files import file_sha256, refuse_overwriting_input, write_json
from ipcverify.data._split import group_codes, refuse_empty_parts, split_fractions, split_parts, time_blocks
from ipcverify.data._tables import SUFFIXES
from ipcverify.errors import DataError, InvalidInputError

#: The parts of a split, in order (their files are ``<name><suffix>``).
PART_NAMES: tuple[str, str, str] = ("train", "calibration", "test")
#: The record written beside the parts.
RECORD_NAME = "split.json"


@dataclass(frozen=True)
class SplitPart:
    """One part of a split written to disk.

    Attributes
    ----------
    name : str
        ``"train"``, ``"calibration"`` or ``"test"``.
    path : Path or None
        The file written (None for a part whose share is 0).
    rows : int
        Samples in the part.
    groups : int or None
        Distinct values of the group column in the part (None for a split of rows).
    sha256 : str or None
        SHA-256 of the file written.
    content_sha256 : str or None
        :meth:`~ipcverify.data.PerceptionDataset.content_hash` of the part: what a model file
        records of its training data (``train_data_hash``) and its calibration data
        (``calibration.data_hash``), and ``certificate.json`` of its test data.
    """

    name: str
    path: Path | None
    rows: int
    groups: int | None
    sha256: str | None
    content_sha256: str | None = None

    def __post_init__(self) -> None:
        if self.name not in PART_NAMES:
            raise InvalidInputError(f"a split part is one of {', '.join(PART_NAMES)}; got {self.name!r}")
        if self.rows < 0 or (self.groups is not None and self.groups < 0):
            raise InvalidInputError(f"part {self.name}: rows and groups must be >= 0")
        if (self.path is None) != (self.rows == 0):
            raise InvalidInputError(f"part {self.name}: a file is written exactly when the part has rows")


@dataclass(frozen=True)
class SplitFiles:
    """What :func:`split_file` wrote: the parts, how they were drawn, and the record's path.

    Attributes
    ----------
    source : Path
        The log that was split.
    source_sha256 : str
        Its SHA-256.
    parts : tuple of SplitPart
        Train, calibration and test, in that order.
    fractions : tuple of float
        The shares of the parts (of rows, or of groups with ``group_column``).
    seed : int
        The seed of the draw (the same seed splits the same file the same way).
    group_columns : tuple of str
        The column(s) whose groups were kept whole (empty: rows were split at random).
    group_name : str or None
        The column added to the parts that names each row's group (None: none added).
    dropped_columns : tuple of str
        Columns of the source not written to the parts (an NPZ part holds only x, y and yhat).
    other_columns : tuple of str
        The source's columns other than x, y and yhat (candidates for ``group_column``).
    record : Path
        ``split.json``, this object as JSON.
    block_seconds : float or None
        The length of the contiguous time blocks kept whole (None: no blocks).
    time_column : str or None
        The column the blocks were cut from.
    """

    source: Path
    source_sha256: str
    parts: tuple[SplitPart, ...]
    fractions: tuple[float, ...]
    seed: int
    group_columns: tuple[str, ...]
    group_name: str | None
    dropped_columns: tuple[str, ...]
    other_columns: tuple[str, ...]
    record: Path
    block_seconds: float | None = None
    time_column: str | None = None

    def __post_init__(self) -> None:
        if (self.block_seconds is None) != (self.time_column is None):
            raise InvalidInputError("time blocks have a length and a time column, or neither")
        if tuple(p.name for p in self.parts) != PART_NAMES:
            raise InvalidInputError(f"a split has the parts {', '.join(PART_NAMES)}, in that order")
        if len(self.fractions) != len(PART_NAMES):
            raise InvalidInputError("a split has one share per part")

    def to_dict(self) -> dict[str, Any]:
        """Plain data for ``split.json`` (paths as given, relative to the working folder)."""
        return {
            "source": str(self.source),
            "source_sha256": self.source_sha256,
            "fractions": list(self.fractions),
            "seed": self.seed,
            "group_columns": list(self.group_columns),
            "block_seconds": self.block_seconds,
            "time_column": self.time_column,
            "group_name": self.group_name,
            "parts": {
                p.name: {
                    "path": None if p.path is None else str(p.path),
                    "rows": p.rows,
                    "groups": p.groups,
                    "sha256": p.sha256,
                    "content_sha256": p.content_sha256,
                }
                for p in self.parts
            },
            "dropped_columns": list(self.dropped_columns),
        }


def _part_suffix(source: Path, suffix: str | None) -> str:
    """The parts' extension: ``suffix`` or the source's (``.pq`` written as ``.parquet``)."""
    ext = (suffix or source.suffix).lower()
    ext = ".parquet" if ext == ".pq" else ext
    if ext not in SUFFIXES:
        raise DataError(f"unknown data format {ext!r} for the parts; use one of .csv, .parquet, .npz")
    return ext


def _part_paths(out_dir: Path, suffix: str) -> dict[str, Path]:
    return {name: out_dir / f"{name}{suffix}" for name in PART_NAMES}


def split_outputs(
    path: str | os.PathLike[str], out_dir: str | os.PathLike[str], suffix: str | None = None
) -> tuple[Path, ...]:
    """The files :func:`split_file` may write: one per part and the record (a part whose share is 0 is not).

    Parameters
    ----------
    path : path-like
        The log to split.
    out_dir : path-like
        The folder of the parts.
    suffix : str, optional
        The parts' format, as for :func:`split_file`.

    Examples
    --------
    >>> [p.name for p in split_outputs("log.pq", "parts")]
    ['train.parquet', 'calibration.parquet', 'test.parquet', 'split.json']
    """
    out = Path(out_dir)
    return (*_part_paths(out, _part_suffix(Path(path), suffix)).values(), out / RECORD_NAME)


def _check_targets(source: Path, paths: dict[str, Path], empty: Sequence[str]) -> None:
    """Refuse to overwrite the source, and to leave a stale file where this split has no part."""
    for name, p in paths.items():
        refuse_overwriting_input(p, {"DATA": source}, option=f"{option('out_dir')}'s {name} part")
    for name in empty:
        if paths[name].exists():
            raise InvalidInputError(
                f"{paths[name]} exists, but this split has no {name} part (its share is 0); "
                f"remove the file or choose another {option('out_dir')} folder"
            )


def _group_labels(
    data: PerceptionDataset, columns: tuple[str, ...], blocks: NDArray[np.intp] | None = None
) -> NDArray[Any] | None:
    """One label per row: the column's values, or a number per combination of several columns and
    the time block (None: no groups)."""
    if not columns and blocks is None:
        return None
    if len(columns) == 1 and blocks is None:
        return data.column(columns[0])
    codes = [group_codes(data.column(c), f"{data.source}: group column {c!r}")[0] for c in columns]
    codes += [] if blocks is None else [blocks]
    return np.unique(np.stack(codes, axis=1), axis=0, return_inverse=True)[1].reshape(-1)


def _time_column(data: PerceptionDataset, name: str | None) -> str:
    """The column time blocks are cut from: ``name``, or the first extra column named like a time."""
    if name is not None:
        data.column(name)  # a missing column is refused, naming the available ones
        return name
    found = time_column(data)
    if found is not None:
        return found
    raise DataError(
        f"{data.source}: time blocks need a column of times in seconds ({', '.join(TIME_NAMES)}); "
        f"name yours with {option('time_column', 'COL')}"
    )


def _with_group_column(
    data: PerceptionDataset,
    columns: tuple[str, ...],
    labels: NDArray[Any] | None,
    name: str,
    blocks: NDArray[np.intp] | None = None,
) -> PerceptionDataset:
    """``data`` with a column ``name``: each row's group, its ``columns``' values (and its time
    block's number) joined by ``":"``."""
    if labels is None:
        raise InvalidInputError(
            f"a group column ({name!r}) needs the columns that name a group ({option('split_by')}) or time "
            f"blocks ({option('block')})"
        )
    taken = {*data.x_columns, *data.y_columns, *data.yhat_columns, *data.extra}
    if name in taken:
        raise InvalidInputError(
            f"{data.source} already has a column {name!r}; name the group column otherwise"
        )
    values = [np.asarray(data.column(c)).astype(str) for c in columns]
    values += [] if blocks is None else [blocks.astype(str)]
    text = values[0]
    for v in values[1:]:
        text = np.char.add(np.char.add(text, ":"), v)
    if len(np.unique(text)) != len(np.unique(labels)):
        raise InvalidInputError(
            f"joined by ':', the values of {', '.join(columns)} name fewer groups than they are (a value "
            "holds ':'); add a group column to the log yourself"
        )
    return PerceptionDataset(
        data.x, data.y, data.yhat, source=data.source, x_columns=data.x_columns, y_columns=data.y_columns,
        yhat_columns=data.yhat_columns, extra={**data.extra, name: text},
    )  # fmt: skip


def split_file(
    path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    fractions: Sequence[float] = (0.6, 0.2, 0.2),
    seed: int = 0,
    group_column: str | Sequence[str] | None = None,
    suffix: str | None = None,
    group_name: str | None = None,
    block: float | None = None,
    time_column: str | None = None,
) -> SplitFiles:
    """Split a log file into train, calibration and test files, and record the split.

    Parameters
    ----------
    path : path-like
        The log: CSV, Parquet or NPZ with columns ``x_i``, ``y_i``, ``yhat_i`` and any others.
    out_dir : path-like
        The folder for ``train``, ``calibration`` and ``test`` files and ``split.json``
        (created if missing; files of the same names are replaced, atomically).
    fractions : three floats summing to 1
        Shares of the parts: of rows, or of groups with ``group_column``. A share may be 0
        (that part is not written).
    seed : int
        The seed of the random draw.
    group_column : str or sequence of str, optional
        A column naming the unit whose rows are correlated (a flight, run or sequence): whole
        groups go to one part each, as the guarantees for correlated rows need. Several
        columns name a group together (``["method", "run"]``: one group per pair).
    suffix : str, optional
        The parts' format: ``".csv"``, ``".parquet"`` or ``".npz"`` (default: the input's).
    group_name : str, optional
        A new column, written to every part, holding each row's group: the values of the
        ``group_column`` columns joined by ``":"`` (``"vislam_rp:3"``). ``calibrate`` and
        ``certify`` take one group column; this gives them the groups the split kept whole.
        With ``block``, the block's number comes last (``"KITTI_00_ORB:3"``).
    block : float, optional
        Keep contiguous stretches of time whole: blocks of ``block`` seconds of the time column,
        counted from each group's first time (from the log's first time without
        ``group_column``), are the groups (within the ``group_column`` groups, if given). For a
        log of one or a few long runs; rows next to a block's edge are still neighbours of rows
        in another part.
    time_column : str, optional
        The column of times in seconds that ``block`` cuts (default: the first of ``t``,
        ``time``, ``timestamp``, ``stamp``).

    Returns
    -------
    SplitFiles
        The parts written, their sizes and SHA-256, and the record's path.

    Raises
    ------
    DataError
        If the log cannot be read, the group column is missing, or there are too few rows or groups
        to give every part with a positive share one.
    InvalidInputError
        If a part would overwrite the input, or a stale part file would be left beside the split.

    Examples
    --------
    >>> import tempfile, numpy as np
    >>> from ipcverify.data import PerceptionDataset, save_dataset
    >>> d = Path(tempfile.mkdtemp())
    >>> z = np.zeros((8, 1))
    >>> save_dataset(PerceptionDataset(z, z, z, extra={"run": np.arange(8) // 2}), d / "log.csv")
    >>> s = split_file(d / "log.csv", d / "parts", (0.5, 0.25, 0.25), group_column="run")
    >>> [(p.name, p.rows, p.groups) for p in s.parts]
    [('train', 4, 2), ('calibration', 2, 1), ('test', 2, 1)]
    """
    source = Path(path)
    data = load_dataset(source)
    fr = tuple(float(f) for f in split_fractions(fractions))
    ext = _part_suffix(source, suffix)
    columns = (group_column,) if isinstance(group_column, str) else tuple(group_column or ())
    blocks, t_col = None, None
    if block is not None:
        t_col = _time_column(data, time_column)
        runs = _group_labels(data, columns)
        blocks = time_blocks(
            data.column(t_col),
            block,
            runs,
            f"{source}: time column {t_col!r}",
            f"{source}: {option('split_by')} groups",
        )
    elif time_column is not None:
        raise InvalidInputError(
            f"a time column ({option('time_column')}) is used only to cut time blocks ({option('block')})"
        )
    labels = _group_labels(data, columns, blocks)
    if group_name is not None:
        data = _with_group_column(data, columns, labels, group_name, blocks)
    units = [f"group column(s) {', '.join(columns)}"] if columns else []
    if blocks is not None:
        units.append(f"{block:g} s blocks of {t_col!r}")
    what = f"{source}: {' and '.join(units)}"
    try:
        index = split_parts(len(data), fr, seed, labels, what)
    except DataError as e:
        if blocks is None:
            raise
        raise DataError(f"{e}; a shorter {option('block')} gives more blocks") from None
    if labels is None:  # of rows: a part with a share must get one (groups are checked by split_parts)
        refuse_empty_parts(fr, [len(i) for i in index], f"{source} has", "row", fractions)
    parts_data: list[PerceptionDataset | None] = [
        data.subset(np.sort(i), name) if len(i) else None for i, name in zip(index, PART_NAMES, strict=True)
    ]
    out = Path(out_dir)
    paths = _part_paths(out, ext)
    empty = [name for name, d in zip(PART_NAMES, parts_data, strict=True) if d is None]
    _check_targets(source, paths, empty)
    out.mkdir(parents=True, exist_ok=True)
    parts = []
    for name, rows, part in zip(PART_NAMES, index, parts_data, strict=True):
        groups = None if labels is None else len(np.unique(labels[rows]))
        if part is None:
            parts.append(SplitPart(name, None, 0, groups, None))
            continue
        save_dataset(part, paths[name])
        parts.append(
            SplitPart(name, paths[name], len(part), groups, file_sha256(paths[name]), part.content_hash())
        )
    other = tuple(data.extra)
    result = SplitFiles(
        source=source,
        source_sha256=file_sha256(source),
        parts=tuple(parts),
        fractions=fr,
        seed=int(seed),
        group_columns=columns,
        group_name=group_name,
        dropped_columns=other if ext == ".npz" else (),
        other_columns=other,
        record=out / RECORD_NAME,
        block_seconds=None if block is None else float(block),
        time_column=t_col,
    )
    write_json(result.record, result.to_dict())
    return result
