"""Reading perception logs: CSV, Parquet and NPZ files to named numeric blocks.

:func:`read_blocks` is the one reader behind :func:`ipcverify.data.load_dataset` (x, y and
yhat) and :func:`ipcverify.data.load_inputs` (x and yhat only, for deployment queries). It
finds the ``kind_0, kind_1, ...`` columns (or takes the names given), checks that they are
numeric, and keeps every other column of a table as an extra. Errors name the file, row and
column at fault.
"""

from __future__ import annotations

import csv
import os
import re
import warnings
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from ipcverify._wording._spelling import options
from ipcverify.errors import DataError

SUFFIXES = (".csv", ".parquet", ".pq", ".npz")


def numbered_columns(prefix: str, columns: Sequence[str]) -> list[str]:
    """The columns ``prefix_0, prefix_1, ...`` in order; refuses a gap in the numbering.

    Parameters
    ----------
    prefix : str
        The prefix (``"x"``, ``"y"``, ``"yhat"``).
    columns : sequence of str
        The table's columns.

    Examples
    --------
    >>> numbered_columns("x", ["y_0", "x_1", "x_0", "t"])
    ['x_0', 'x_1']
    """
    pat = re.compile(rf"^{re.escape(prefix)}_(\d+)$")
    found = sorted((int(m.group(1)), c) for c in columns if (m := pat.match(c)))
    names = [c for _, c in found]
    idx = [i for i, _ in found]
    if idx != list(range(len(idx))):
        missing = sorted(set(range(max(idx) + 1)) - set(idx)) if idx else []
        raise DataError(
            f"columns {prefix}_0..{prefix}_{max(idx)} are not contiguous: missing "
            + ", ".join(f"{prefix}_{i}" for i in missing)
            + f" -- number them from {prefix}_0 without gaps, or name them (CLI: --{prefix}-columns)"
        )
    return names


def _csv_header(path: Path) -> list[str]:
    with open(path, newline="", encoding="utf-8", errors="replace") as f:
        return next(csv.reader(f), [])


def _read_table(path: Path) -> pd.DataFrame:
    suffix = path.suffix.lower()
    try:
        with warnings.catch_warnings():  # a row longer than the header is an error, not a shifted index
            warnings.simplefilter("error", pd.errors.ParserWarning)
            df = pd.read_csv(path, index_col=False) if suffix == ".csv" else pd.read_parquet(path)
    except pd.errors.EmptyDataError:
        raise DataError(f"{path}: the file is empty; expected a header row and samples") from None
    except pd.errors.ParserWarning:
        raise DataError(
            f"{path}: cannot read as CSV: a row has more fields than the header; every row needs one value "
            "per column"
        ) from None
    except (pd.errors.ParserError, UnicodeDecodeError, OSError, ValueError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise DataError(f"{path}: cannot read as {suffix[1:].upper()}: {msg}") from None
    names = _csv_header(path) if suffix == ".csv" else [str(c) for c in df.columns]
    repeated = {c: names.count(c) for c in names if names.count(c) > 1}
    if repeated:
        listed = ", ".join(f"{c} appears {k} times" for c, k in repeated.items())
        raise DataError(f"{path}: {listed}; every column name must be unique (which one is meant?)")
    return df


def data_file(path: str | os.PathLike[str]) -> Path:
    """``path`` as a Path, if it exists and has a known data-file suffix.

    Parameters
    ----------
    path : path-like
        The data file.
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(2, "No such file", str(p))
    if p.suffix.lower() not in SUFFIXES:
        raise DataError(f"{p}: unknown data format {p.suffix.lower()!r}; use one of {', '.join(SUFFIXES)}")
    return p


def _read_npz(p: Path, kinds: Sequence[str]) -> dict[str, NDArray[Any]]:
    try:
        with np.load(p, allow_pickle=False) as z:
            missing = [k for k in kinds if k not in z.files]
            if missing:
                raise DataError(f"{p}: NPZ lacks array(s) {', '.join(missing)}; it needs {', '.join(kinds)}")
            arrs = {k: z[k] for k in kinds}
    except DataError:
        raise
    except (ValueError, OSError, zipfile.BadZipFile, EOFError) as exc:
        raise DataError(f"{p}: cannot read as NPZ: {exc}") from None
    for k, a in arrs.items():
        if not np.issubdtype(a.dtype, np.number):
            raise DataError(f"{p}: array {k!r} is not numeric (dtype {a.dtype})")
        if np.issubdtype(a.dtype, np.complexfloating):
            raise DataError(
                f"{p}: array {k!r} is complex (dtype {a.dtype}); store real numbers (its real part, if "
                "that is what was meant)"
            )
    return arrs


def read_blocks(
    p: Path, names: Mapping[str, Sequence[str] | None]
) -> tuple[dict[str, NDArray[Any]], dict[str, tuple[str, ...]], dict[str, NDArray[Any]]]:
    """The numeric blocks of the kinds in ``names`` (x, y, yhat ...), their columns, and the rest.

    Parameters
    ----------
    p : Path
        The data file.
    names : mapping of str to sequence of str or None
        For each kind, its column names (None: the numbered defaults).
    """
    kinds = list(names)
    if p.suffix.lower() == ".npz":
        if any(names.values()):
            raise DataError(f"{p}: column names apply to CSV/Parquet, not NPZ (arrays {', '.join(kinds)})")
        return _read_npz(p, kinds), {k: () for k in kinds}, {}
    df = _read_table(p)
    if len(df) == 0:
        raise DataError(f"{p}: the file has a header but no samples")
    return frame_blocks(df, names, str(p))


def frame_blocks(
    df: pd.DataFrame, names: Mapping[str, Sequence[str] | None], source: str = "<frame>"
) -> tuple[dict[str, NDArray[Any]], dict[str, tuple[str, ...]], dict[str, NDArray[Any]]]:
    """The numeric blocks of a table already in memory, their columns, and the other columns.

    Parameters
    ----------
    df : pandas.DataFrame
        The table.
    names : mapping of str to sequence of str or None
        For each kind (``"x"``, ``"y"``, ``"yhat"``), its column names (None: the numbered defaults).
    source : str
        The table's name in error messages.

    Examples
    --------
    >>> import pandas as pd
    >>> arrays, cols, extra = frame_blocks(pd.DataFrame({"x_0": [1.0], "y_0": [2.0], "run": ["a"]}),
    ...                                    {"x": None, "y": None})
    >>> arrays["y"].tolist(), cols["x"], list(extra)
    ([[2.0]], ('x_0',), ['run'])
    """
    p = source
    if len(df) == 0:
        raise DataError(f"{p}: the table has no rows")
    df = df.rename(columns=str)
    cols = list(df.columns)
    try:
        chosen = {k: list(v) if v else numbered_columns(k, cols) for k, v in names.items()}
    except DataError as exc:  # the numbering's message, with the table it is about
        raise DataError(f"{p}: {exc}") from None
    for kind, ks in chosen.items():
        if not ks:
            raise DataError(
                f"{p}: no {kind} columns (expected {kind}_0, {kind}_1, ...; "
                f"found: {', '.join(cols[:12])}{' ...' if len(cols) > 12 else ''}){_spaced_hint(cols)}"
            )
        missing = [c for c in ks if c not in cols]
        if missing:
            raise DataError(f"{p}: missing column(s) {', '.join(missing)}{_spaced_hint(cols)}")
    _refuse_shared_columns(chosen, p)
    if "y" in chosen and "yhat" in chosen and len(chosen["y"]) != len(chosen["yhat"]):
        raise DataError(
            f"{p}: y has {len(chosen['y'])} columns but yhat has {len(chosen['yhat'])}; they must describe "
            "the same quantity"
        )
    arrays = {}
    for kind, ks in chosen.items():
        block = df[ks]
        for c in ks:
            if not pd.api.types.is_numeric_dtype(block[c]):
                conv = pd.to_numeric(block[c], errors="coerce")
                bad = conv.isna() & block[c].notna()
                if not bad.any():
                    raise DataError(
                        f"{p}: column {c!r} holds numbers stored as text (dtype {block[c].dtype}); store it "
                        "as a numeric (float) column"
                    )
                r = int(np.flatnonzero(bad.to_numpy())[0])
                raise DataError(f"{p}: row {r} (0-based), column {c!r}: not a number ({block[c].iloc[r]!r})")
        arrays[kind] = block.to_numpy(dtype=np.float64)
    used = {c for ks in chosen.values() for c in ks}
    extra = {c: df[c].to_numpy() for c in cols if c not in used}
    return arrays, {k: tuple(v) for k, v in chosen.items()}, extra


def _spaced_hint(cols: Sequence[str]) -> str:
    """A hint naming column names with spaces around them (`` y_0`` is not ``y_0``), or ''."""
    spaced = [c for c in cols if c != c.strip()]
    if not spaced:
        return ""
    shown = ", ".join(repr(c) for c in spaced[:4]) + (" ..." if len(spaced) > 4 else "")
    return f"; the column names {shown} have spaces around them: remove the spaces from the header"


def _a(kind: str) -> str:
    return f"an {kind}" if kind == "x" else f"a {kind}"


def _refuse_shared_columns(chosen: Mapping[str, Sequence[str]], source: str) -> None:
    """Refuse a column named twice, in one role or in two (x and y: the truth as an input)."""
    role: dict[str, str] = {}
    for kind, ks in chosen.items():
        for c in ks:
            if c in role:
                where = (
                    f"twice among the {kind} columns"
                    if role[c] == kind
                    else f"both {_a(role[c])} and {_a(kind)} column"
                )
                raise DataError(
                    f"{source}: column {c!r} is {where}; every column plays one role once -- fix the "
                    f"column lists ({options('x_columns', 'y_columns', 'yhat_columns')})"
                )
            role[c] = kind


def refuse_unknown_columns(source: str, extra: Mapping[str, Any], known: Mapping[str, Sequence[str]]) -> None:
    """Refuse a table whose extra columns look like ``x_i`` / ``y_i`` / ``yhat_i`` columns the model lacks.

    A file with more state columns than the model was trained on would otherwise be read
    silently without them.

    Parameters
    ----------
    source : str
        The table's name in error messages.
    extra : mapping
        The table's extra columns.
    known : mapping of str to sequence of str
        The model's column names per kind.

    Raises
    ------
    DataError
        Naming the columns and the ones the model knows.

    Examples
    --------
    >>> refuse_unknown_columns("log.csv", {"x_6": None}, {"x": ["x_0", "x_1"]})  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ipcverify.errors.DataError: log.csv: column x_6 looks like an x column but the model knows only x_0, ...
    """
    for kind, names in known.items():
        pat = re.compile(rf"^{re.escape(kind)}_(\d+)$")
        unknown = sorted((str(c) for c in extra if pat.match(str(c))), key=lambda c: (len(c), c))
        if unknown:
            raise DataError(
                f"{source}: column{'s' if len(unknown) > 1 else ''} {', '.join(unknown)} look"
                f"{'' if len(unknown) > 1 else 's'} like {_a(kind)} column but the model knows only "
                f"{', '.join(names)} -- drop {'them' if len(unknown) > 1 else 'it'}, or retrain and "
                "recalibrate with them"
            )
