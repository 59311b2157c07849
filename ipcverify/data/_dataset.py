"""Perception logs: triples (state x, truth y, estimate yhat) loaded, validated and split.

File formats
------------
CSV and Parquet files hold one sample per row with columns ``x_0..x_{d-1}``,
``y_0..y_{n-1}`` and ``yhat_0..yhat_{n-1}`` (names overridable). NPZ files hold the
arrays ``x`` (N, d), ``y`` (N, n) and ``yhat`` (N, n). Any other columns of a table
are kept as :attr:`PerceptionDataset.extra` (for example a group label for Mondrian
calibration).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from ipcverify.data._files import atomic_write
from ipcverify.data._split import split_fractions, split_parts
from ipcverify.data._tables import SUFFIXES, data_file, frame_blocks, read_blocks
from ipcverify.errors import DataError

FloatArray = NDArray[np.float64]
#: Largest magnitude accepted in x, y and yhat: the network trains in float32 (largest float ~3.4e38),
#: and squared distances of such values must not overflow.
MAX_ABS_VALUE = 1e30


def _checked_blocks(
    source: str, blocks: Mapping[str, Any], names: Mapping[str, Sequence[str]]
) -> tuple[dict[str, FloatArray], dict[str, tuple[str, ...]]]:
    """Validate 2-D, non-empty, equally long, finite blocks; default their column names ``kind_i``."""
    arrays: dict[str, FloatArray] = {}
    for kind, value in blocks.items():
        a = np.array(value, dtype=np.float64, copy=True)
        if a.ndim == 1:
            a = a[:, None]
        if a.ndim != 2:
            raise DataError(f"{source}: {kind} must be 2-D (N, dim); got shape {a.shape}")
        arrays[kind] = a
    rows = {a.shape[0] for a in arrays.values()}
    if 0 in rows:
        raise DataError(f"{source}: the dataset is empty (0 samples); log some data first")
    if len(rows) > 1:
        sizes = ", ".join(str(a.shape[0]) for a in arrays.values())
        raise DataError(f"{source}: {', '.join(arrays)} have different numbers of rows ({sizes})")
    cols: dict[str, tuple[str, ...]] = {}
    for kind, a in arrays.items():
        cols[kind] = tuple(names.get(kind) or ()) or tuple(f"{kind}_{i}" for i in range(a.shape[1]))
        if len(cols[kind]) != a.shape[1]:
            raise DataError(f"{source}: {len(cols[kind])} names given for {kind} columns")
        bad = ~np.isfinite(a)
        if bad.any():
            r, c = np.argwhere(bad)[0]
            value = float(a[r, c])
            read_as = (
                " (an empty cell, or text such as NA or n/a in a table, reads as nan)"
                if value != value
                else ""
            )
            raise DataError(
                f"{source}: row {int(r)} (0-based), column {cols[kind][int(c)]!r}: non-finite value "
                f"{value}{read_as}; drop or repair that row"
            )
        big = np.abs(a) > MAX_ABS_VALUE
        if big.any():
            r, c = np.argwhere(big)[0]
            raise DataError(
                f"{source}: row {int(r)} (0-based), column {cols[kind][int(c)]!r}: value "
                f"{float(a[r, c]):g} is too large (|value| > {MAX_ABS_VALUE:g}; the network computes in "
                "float32) -- express the column in other units"
            )
        a.setflags(write=False)
    return arrays, cols


def _checked_extra(source: str, extra: Mapping[str, Any], n: int) -> dict[str, NDArray[Any]]:
    out = {}
    for k, v in dict(extra).items():
        a = np.array(v, copy=True)
        if a.shape[:1] != (n,):
            raise DataError(f"{source}: extra column {k!r} has length {a.shape[:1]}")
        a.setflags(write=False)
        out[k] = a
    return out


@dataclass(frozen=True, eq=False)
class PerceptionDataset:
    """An immutable, validated set of perception samples.

    Parameters
    ----------
    x : array_like, shape (N, d)
        System states.
    y : array_like, shape (N, n)
        Ground-truth values of the perceived quantity.
    yhat : array_like, shape (N, n)
        Perceived values.
    source : str
        Where the data came from (used in error messages).
    x_columns, y_columns, yhat_columns : tuple of str
        Column names (default ``x_i``, ``y_i``, ``yhat_i``).
    extra : mapping of str to array, optional
        Other per-sample columns (length N each), e.g. a group label.

    Examples
    --------
    >>> import numpy as np
    >>> ds = PerceptionDataset(np.zeros((4, 2)), np.ones((4, 3)), np.ones((4, 3)))
    >>> len(ds), ds.x_dim, ds.y_dim
    (4, 2, 3)
    """

    x: FloatArray
    y: FloatArray
    yhat: FloatArray
    source: str = "<memory>"
    x_columns: tuple[str, ...] = ()
    y_columns: tuple[str, ...] = ()
    yhat_columns: tuple[str, ...] = ()
    extra: Mapping[str, NDArray[Any]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        arrays, cols = _checked_blocks(
            self.source,
            {"x": self.x, "y": self.y, "yhat": self.yhat},
            {"x": self.x_columns, "y": self.y_columns, "yhat": self.yhat_columns},
        )
        x, y, yhat = arrays["x"], arrays["y"], arrays["yhat"]
        if y.shape[1] != yhat.shape[1]:
            raise DataError(
                f"{self.source}: y has dimension {y.shape[1]} but yhat has {yhat.shape[1]}; "
                "the estimate and the truth must describe the same quantity"
            )
        extra = _checked_extra(self.source, self.extra, x.shape[0])
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "yhat", yhat)
        object.__setattr__(self, "x_columns", cols["x"])
        object.__setattr__(self, "y_columns", cols["y"])
        object.__setattr__(self, "yhat_columns", cols["yhat"])
        object.__setattr__(self, "extra", extra)

    @classmethod
    def from_frame(
        cls,
        frame: pd.DataFrame,
        x_columns: Sequence[str] | None = None,
        y_columns: Sequence[str] | None = None,
        yhat_columns: Sequence[str] | None = None,
        source: str = "<frame>",
    ) -> PerceptionDataset:
        """A dataset from a DataFrame in memory, validated as :func:`load_dataset` validates a file.

        The columns are found as in a file (``x_0..``, ``y_0..``, ``yhat_0..`` unless named);
        every other column (``run``, ``t`` ...) is kept in :attr:`extra`. What
        :func:`ipcverify.io.ingest.ingest_bags` returns goes in directly, with no temporary file.

        Raises
        ------
        DataError
            As :func:`load_dataset`: missing columns, a non-number, y and yhat of different
            dimension, a non-finite value, no rows.

        Examples
        --------
        >>> import pandas as pd
        >>> df = pd.DataFrame({"x_0": [0.1, 0.2], "y_0": [1.0, 2.0], "yhat_0": [1.1, 1.9], "run": ["a", "b"]})
        >>> ds = PerceptionDataset.from_frame(df)
        >>> len(ds), ds.x_dim, ds.column("run").tolist()
        (2, 1, ['a', 'b'])
        """
        names = {"x": x_columns, "y": y_columns, "yhat": yhat_columns}
        arrays, cols, extra = frame_blocks(frame, names, source)
        return cls(
            arrays["x"],
            arrays["y"],
            arrays["yhat"],
            source=source,
            x_columns=cols["x"],
            y_columns=cols["y"],
            yhat_columns=cols["yhat"],
            extra=extra,
        )

    def __len__(self) -> int:
        return int(self.x.shape[0])

    def __repr__(self) -> str:
        return (
            f"PerceptionDataset(n={len(self)}, x_dim={self.x_dim}, y_dim={self.y_dim}, "
            f"source={self.source!r})"
        )

    @property
    def x_dim(self) -> int:
        """State dimension ``d``."""
        return int(self.x.shape[1])

    @property
    def y_dim(self) -> int:
        """Dimension ``n`` of the perceived quantity."""
        return int(self.y.shape[1])

    def column(self, name: str) -> NDArray[Any]:
        """One column by name, from x, y, yhat or the extra columns.

        Raises
        ------
        DataError
            If no column has that name; the message lists the available ones.
        """
        for names, arr in (
            (self.x_columns, self.x),
            (self.y_columns, self.y),
            (self.yhat_columns, self.yhat),
        ):
            if name in names:
                return arr[:, names.index(name)]
        if name in self.extra:
            return self.extra[name]
        avail = [*self.x_columns, *self.y_columns, *self.yhat_columns, *self.extra]
        raise DataError(f"{self.source}: no column {name!r}; available: {', '.join(avail)}")

    def subset(self, index: NDArray[Any] | Sequence[int], label: str = "subset") -> PerceptionDataset:
        """The samples at ``index`` (integer indices or a boolean mask)."""
        idx = np.asarray(index)
        return PerceptionDataset(
            self.x[idx],
            self.y[idx],
            self.yhat[idx],
            source=f"{self.source}[{label}]",
            x_columns=self.x_columns,
            y_columns=self.y_columns,
            yhat_columns=self.yhat_columns,
            extra={k: v[idx] for k, v in self.extra.items()},
        )

    def content_hash(self) -> str:
        """SHA-256 of the numeric content (x, y, yhat as little-endian float64)."""
        h = hashlib.sha256()
        for a in (self.x, self.y, self.yhat):
            h.update(np.asarray(a.shape, dtype="<i8").tobytes())
            h.update(np.ascontiguousarray(a, dtype="<f8").tobytes())
        return h.hexdigest()

    def split(
        self,
        fractions: Sequence[float] = (0.6, 0.2, 0.2),
        seed: int = 0,
        group_column: str | None = None,
    ) -> DatasetSplits:
        """Deterministic random train / calibration / test split, of samples or of whole groups.

        Parameters
        ----------
        fractions : three floats summing to 1
            Shares of train, calibration and test samples (of groups, with ``group_column``).
            A share may be 0.
        seed : int
            The same seed always gives the same split of the same data.
        group_column : str, optional
            A column naming the exchangeable unit (a flight, run or sequence: samples of one
            group are correlated). Whole groups are assigned to the parts, so no group is
            split between training, calibration and test; the shares count groups, not rows.

        Raises
        ------
        DataError
            If the fractions are bad, the group column is unknown or has missing labels, or
            there are too few groups to give every part with a positive share one group.

        Examples
        --------
        >>> import numpy as np
        >>> ds = PerceptionDataset(np.zeros((6, 1)), np.ones((6, 1)), np.ones((6, 1)),
        ...                        extra={"run": np.array([1, 1, 2, 2, 3, 3])})
        >>> parts = ds.split((1 / 3, 1 / 3, 1 / 3), seed=0, group_column="run")
        >>> sorted(len(np.unique(p.column("run"))) for p in (parts.train, parts.calibration, parts.test))
        [1, 1, 1]
        """
        split_fractions(fractions)  # first, as before: bad fractions are reported before a bad column
        column = None if group_column is None else self.column(group_column)
        what = f"{self.source}: group column {group_column!r}"
        parts = split_parts(len(self), fractions, seed, column, what)
        return DatasetSplits(
            *(
                self.subset(np.sort(p), label) if len(p) else None
                for p, label in zip(parts, ("train", "calibration", "test"), strict=True)
            )
        )

    def to_frame(self) -> pd.DataFrame:
        """All columns as a pandas DataFrame."""
        data: dict[str, Any] = {}
        for names, arr in (
            (self.x_columns, self.x),
            (self.y_columns, self.y),
            (self.yhat_columns, self.yhat),
        ):
            for i, c in enumerate(names):
                data[c] = arr[:, i]
        data.update(self.extra)
        return pd.DataFrame(data)


@dataclass(frozen=True)
class DatasetSplits:
    """Train, calibration and test parts of a dataset (a part may be ``None`` if empty).

    Attributes
    ----------
    train, calibration, test : PerceptionDataset or None
        The three parts.
    """

    train: PerceptionDataset | None
    calibration: PerceptionDataset | None
    test: PerceptionDataset | None


def load_dataset(
    path: str | os.PathLike[str],
    x_columns: Sequence[str] | None = None,
    y_columns: Sequence[str] | None = None,
    yhat_columns: Sequence[str] | None = None,
) -> PerceptionDataset:
    """Load and validate a perception log from CSV, Parquet or NPZ.

    Parameters
    ----------
    path : path-like
        A ``.csv``, ``.parquet``/``.pq`` or ``.npz`` file.
    x_columns, y_columns, yhat_columns : sequence of str, optional
        Column names to use instead of the defaults ``x_i``, ``y_i``, ``yhat_i``
        (tables only).

    Raises
    ------
    DataError
        With the file, row and column at fault: unknown format, missing columns,
        y and yhat of different dimension, a non-finite or non-numeric value, an
        empty file.
    FileNotFoundError
        If ``path`` does not exist.

    Examples
    --------
    >>> import tempfile, os, numpy as np
    >>> d = tempfile.mkdtemp()
    >>> p = os.path.join(d, "log.npz")
    >>> np.savez(p, x=np.zeros((3, 2)), y=np.ones((3, 1)), yhat=np.ones((3, 1)))
    >>> load_dataset(p).y_dim
    1
    """
    p = data_file(path)
    names = {"x": x_columns, "y": y_columns, "yhat": yhat_columns}
    arrays, cols, extra = read_blocks(p, names)
    return PerceptionDataset(
        arrays["x"],
        arrays["y"],
        arrays["yhat"],
        source=str(p),
        x_columns=cols["x"],
        y_columns=cols["y"],
        yhat_columns=cols["yhat"],
        extra=extra,
    )


def save_dataset(dataset: PerceptionDataset, path: str | os.PathLike[str]) -> None:
    """Write a dataset atomically as CSV, Parquet or NPZ (chosen by the suffix).

    Parameters
    ----------
    dataset : PerceptionDataset
        The log to write. A table (CSV, Parquet) gets every column of
        :meth:`PerceptionDataset.to_frame` (its column names, its extra columns; CSV floats with
        17 significant digits, so they read back exactly); an NPZ file only ``x``, ``y`` and ``yhat``.
    path : path-like
        A ``.csv``, ``.parquet``/``.pq`` or ``.npz`` path.
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in SUFFIXES:
        raise DataError(f"{p}: unknown data format {suffix!r}; use one of {', '.join(SUFFIXES)}")
    if suffix == ".npz":
        atomic_write(p, lambda f: np.savez(f, x=dataset.x, y=dataset.y, yhat=dataset.yhat))
    elif suffix == ".csv":
        atomic_write(p, lambda f: dataset.to_frame().to_csv(f, index=False, float_format="%.17g"))
    else:
        atomic_write(p, lambda f: dataset.to_frame().to_parquet(f, index=False))


@dataclass(frozen=True, eq=False)
class PerceptionInputs:
    """Deployment queries: states ``x`` and estimates ``yhat``, without ground truth.

    What ``predict`` and ``monitor`` read: a deployment log has no ``y``. Validated like
    :class:`PerceptionDataset` (finite, 2-D, equal numbers of rows).

    Attributes
    ----------
    x : ndarray, shape (N, d)
        States.
    yhat : ndarray, shape (N, n)
        Estimates.
    source : str
        Where the queries came from (for error messages).
    x_columns, yhat_columns : tuple of str
        Column names (default ``x_i``, ``yhat_i``).
    extra : mapping of str to ndarray
        Any other columns, one value per row.

    Examples
    --------
    >>> import numpy as np
    >>> q = PerceptionInputs(np.zeros((4, 2)), np.ones((4, 3)))
    >>> len(q), q.x_columns, q.yhat_columns[0]
    (4, ('x_0', 'x_1'), 'yhat_0')
    """

    x: FloatArray
    yhat: FloatArray
    source: str = "<memory>"
    x_columns: tuple[str, ...] = ()
    yhat_columns: tuple[str, ...] = ()
    extra: Mapping[str, NDArray[Any]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        arrays, cols = _checked_blocks(
            self.source, {"x": self.x, "yhat": self.yhat}, {"x": self.x_columns, "yhat": self.yhat_columns}
        )
        object.__setattr__(self, "x", arrays["x"])
        object.__setattr__(self, "yhat", arrays["yhat"])
        object.__setattr__(self, "x_columns", cols["x"])
        object.__setattr__(self, "yhat_columns", cols["yhat"])
        object.__setattr__(self, "extra", _checked_extra(self.source, self.extra, arrays["x"].shape[0]))

    def __len__(self) -> int:
        return int(self.x.shape[0])


def query_rows(a: ArrayLike) -> FloatArray:
    """Queries as float64 rows: a single query (a 1-D array) becomes one row.

    The caller checks the shapes and values, with its own message.

    Parameters
    ----------
    a : array_like
        One query (1-D) or rows of queries (2-D).

    Examples
    --------
    >>> query_rows([1, 2]).shape, query_rows([[1, 2], [3, 4]]).dtype
    ((1, 2), dtype('float64'))
    """
    arr = np.asarray(a, dtype=np.float64)
    return arr[None] if arr.ndim == 1 else arr


def load_inputs(
    path: str | os.PathLike[str],
    x_columns: Sequence[str] | None = None,
    yhat_columns: Sequence[str] | None = None,
) -> PerceptionInputs:
    """Load deployment queries (``x`` and ``yhat``; truth columns, if any, are kept as extras).

    Parameters
    ----------
    path : path-like
        A ``.csv``, ``.parquet``/``.pq`` or ``.npz`` file.
    x_columns, yhat_columns : sequence of str, optional
        Column names to use instead of ``x_i`` and ``yhat_i`` (tables only).

    Examples
    --------
    >>> import tempfile, os, numpy as np
    >>> p = os.path.join(tempfile.mkdtemp(), "q.npz")
    >>> np.savez(p, x=np.zeros((3, 2)), yhat=np.ones((3, 1)))
    >>> load_inputs(p).yhat.shape
    (3, 1)
    """
    p = data_file(path)
    arrays, cols, extra = read_blocks(p, {"x": x_columns, "yhat": yhat_columns})
    return PerceptionInputs(
        arrays["x"], arrays["yhat"], str(p), x_columns=cols["x"], yhat_columns=cols["yhat"], extra=extra
    )
