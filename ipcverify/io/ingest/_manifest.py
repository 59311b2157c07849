"""The ingested table on disk, and the manifest beside it.

The manifest (``NAME.manifest.json`` beside ``NAME.csv`` or ``NAME.parquet``) records what the
rows came from and how: every input's SHA-256, the topics or file formats, the options, the
rows kept and dropped per run and why, the alignment if one was fitted, the ipcverify
version, and the table's own SHA-256.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pandas as pd

from ipcverify._package import VERSION
from ipcverify.data._files import atomic_write, file_sha256, write_json
from ipcverify.errors import DataError
from ipcverify.io.ingest._samples import MANIFEST_KEY

TABLE_SUFFIXES = (".csv", ".parquet", ".pq")


def input_record(path: str | os.PathLike[str], role: str) -> dict[str, Any]:
    """Path, role, size and SHA-256 of an input file, or of every file in an input directory.

    Parameters
    ----------
    path : path-like
        The input file or directory.
    role : str
        What it is (``"truth"``, ``"estimate"``, ``"bag"``, ...).

    Examples
    --------
    >>> import os, tempfile
    >>> p = os.path.join(tempfile.mkdtemp(), "gt.txt")
    >>> _ = open(p, "w").write("")
    >>> r = input_record(p, "truth")
    >>> r["role"], r["bytes"], r["sha256"][:8]
    ('truth', 0, 'e3b0c442')
    """
    p = Path(path)
    if p.is_dir():
        files = sorted(f for f in p.rglob("*") if f.is_file())
        return {
            "path": str(p),
            "role": role,
            "files": [
                {"path": str(f.relative_to(p)), "bytes": f.stat().st_size, "sha256": file_sha256(f)}
                for f in files
            ],
        }
    return {"path": str(p), "role": role, "bytes": p.stat().st_size, "sha256": file_sha256(p)}


def manifest_path(out: str | os.PathLike[str]) -> Path:
    """Where the manifest of the table ``out`` goes: ``log.csv`` -> ``log.manifest.json``.

    Parameters
    ----------
    out : path-like
        The table written.

    Examples
    --------
    >>> str(manifest_path("runs/log.parquet"))
    'runs/log.manifest.json'
    """
    p = Path(out)
    return p.with_name(p.stem + ".manifest.json")


def write_ingested(frame: pd.DataFrame, out: str | os.PathLike[str]) -> Path:
    """Write an ingested table (CSV or Parquet by the suffix) and its manifest, both atomically.

    Parameters
    ----------
    frame : pandas.DataFrame
        What :func:`ipcverify.io.ingest.ingest_bags` or
        :func:`~ipcverify.io.ingest.ingest_trajectories` returned (its ``attrs`` carry the
        manifest).
    out : path-like
        ``.csv``, ``.parquet`` or ``.pq``.

    Returns
    -------
    Path
        The manifest's path.

    Raises
    ------
    DataError
        For another suffix, or a frame that carries no ingest manifest.
    """
    p = Path(out)
    suffix = p.suffix.lower()
    if suffix not in TABLE_SUFFIXES:
        raise DataError(f"{p}: write the samples as .csv or .parquet; got {suffix or 'no suffix'!r}")
    account = frame.attrs.get(MANIFEST_KEY)
    if account is None:
        raise DataError(
            "this frame carries no ingest manifest (frame.attrs); build it with ipcverify.io.ingest"
        )
    plain = frame.copy()
    plain.attrs = {}
    if suffix == ".csv":
        atomic_write(p, lambda f: plain.to_csv(f, index=False, float_format="%.17g"))
    else:
        atomic_write(p, lambda f: plain.to_parquet(f, index=False))
    manifest = {
        "ipcverify_version": VERSION,
        **account,
        "output": {
            "path": str(p),
            "rows": len(frame),
            "columns": list(frame.columns),
            "sha256": file_sha256(p),
        },
    }
    m = manifest_path(p)
    write_json(m, manifest)
    return m
