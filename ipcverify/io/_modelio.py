"""Safe model files.

A model file is a ``torch.save`` of a dict holding only tensors and plain data::

    {"format": "ipcverify-model", "format_version": 1 or 2,
     "config": {...}, "state_dict": {name: tensor}, "metadata": {...},
     "calibration": {...} or None, "domain": {...} or None,
     "row_fingerprints": {"scheme": str, "training": tensor, "calibration": tensor} or None}

Version 2 holds a low-rank network (:class:`~ipcverify.network.LowRankEnsemble`: every
member's weights are in the state dict, stacked, and the config has ``param="lowrank"``,
``linear_center`` and ``members``). A network with the paper's heads is still written as
version 1, exactly as before, so older ipcverify versions read it; both versions are read.

It is read without torch by :func:`ipcverify.io.read_torch_file`, whose restricted
unpickler resolves only torch's tensor-rebuilding names (to its own NumPy builders) and refuses
every other global: a file that holds any other object (which could run code when unpickled)
is refused before anything in it executes. A file in a part of torch's format that reader does
not know is read with ``torch.load(..., weights_only=True)``, which refuses the same. The
weights become a :class:`~ipcverify.network.NetworkWeights` (names, shapes and dtypes checked
against the architecture, values finite), so that ``predict`` and ``monitor`` run without torch.

The fingerprints of the training and calibration rows (:mod:`ipcverify.data._fingerprints`; the
model's metadata holds them under ``row_fingerprints`` as sorted uint64 arrays) are stored as
int64 tensors of the same bits, 8 bytes a row, beside the metadata; a reader that does not know
them ignores the entry, and a file without them reads with none (their overlap is then unchecked).
"""

from __future__ import annotations

import os
import pickle
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ipcverify.calibration._kinds import calibration_from_dict
from ipcverify.contract._model import IPCModel
from ipcverify.data._dataset import (
    PerceptionDataset,
    PerceptionInputs,
    load_dataset,
    load_inputs,
)
from ipcverify.data._files import atomic_write
from ipcverify.data._fingerprints import ROWS_KEY, SCHEME
from ipcverify.data._tables import refuse_unknown_columns
from ipcverify.errors import InvalidInputError, ModelFileError
from ipcverify.guard._domain import DomainModel
from ipcverify.io._torchfile import DamagedArchiveError, NeedsTorchError, UnsafeContentError, read_torch_file
from ipcverify.network._architecture import ModelConfig
from ipcverify.network._weights import NetworkWeights

FORMAT = "ipcverify-model"
#: Every torch.save archive starts with a zip local-file header.
_ZIP_MAGIC = b"PK\x03\x04"
#: The newest format written (low-rank networks); others are written as version 1.
FORMAT_VERSION = 2
#: Format versions this ipcverify reads.
READ_VERSIONS = (1, 2)
_PLAIN = (str, int, float, bool, type(None))


def _check_plain(obj: Any, where: str) -> None:
    if isinstance(obj, _PLAIN):
        return
    if isinstance(obj, Mapping):
        for k, v in obj.items():
            if not isinstance(k, str):
                raise InvalidInputError(f"{where}: keys must be strings; got {k!r}")
            _check_plain(v, f"{where}.{k}")
        return
    if isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            _check_plain(v, f"{where}[{i}]")
        return
    raise InvalidInputError(
        f"{where}: only plain data can be stored in a model file; got {type(obj).__name__}"
    )


def _plain(obj: Any) -> Any:
    if isinstance(obj, Mapping):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, tuple):
        return [_plain(v) for v in obj]
    if isinstance(obj, list):
        return [_plain(v) for v in obj]
    return obj


def save_model(model: IPCModel, path: str | os.PathLike[str]) -> None:
    """Write ``model`` atomically to ``path`` in the safe model-file format.

    Parameters
    ----------
    model : IPCModel
        The model (with its calibration and domain test, if any).
    path : path-like
        The file to write (replaced atomically if it exists).

    Examples
    --------
    >>> import tempfile, os, numpy as np
    >>> from ipcverify import example
    >>> m = example(config=ModelConfig(x_dim=2, y_dim=3, hidden=(8,))).model
    >>> p = os.path.join(tempfile.mkdtemp(), "model.pt")
    >>> save_model(m, p)
    >>> load_model(p).config.hidden
    (8,)
    """
    import torch

    rows = {k: v for k, v in (model.metadata.get(ROWS_KEY) or {}).items() if v is not None}
    metadata = _plain({k: v for k, v in model.metadata.items() if k != ROWS_KEY})
    calibration = None if model.calibration is None else _plain(model.calibration.to_dict())
    _check_plain(metadata, "metadata")
    _check_plain(calibration, "calibration")
    domain = None
    if model.domain is not None:
        record = model.domain.to_dict()
        reference = torch.from_numpy(np.array(record.pop("reference"), dtype=np.float64))
        _check_plain(record, "domain")
        domain = {**record, "reference": reference}
    payload = {
        "format": FORMAT,
        "format_version": model.config.file_version,  # the oldest that holds it (older readers read it)
        "config": model.config.to_dict(),
        "state_dict": {k: torch.from_numpy(np.array(v)) for k, v in model.weights.state.items()},
        "metadata": metadata,
        "calibration": calibration,
        "domain": domain,
        "row_fingerprints": None if not rows else _rows_payload(rows, torch.from_numpy),
    }
    atomic_write(path, lambda f: torch.save(payload, f))


def load_model(path: str | os.PathLike[str]) -> IPCModel:
    """Load a model file safely (tensors and plain data only; nothing in it runs) and rebuild the model.

    torch is not imported (unless the file uses a part of torch's format the torch-free reader
    does not know): the model predicts, calibrates and is monitored with NumPy alone.

    Parameters
    ----------
    path : path-like
        The model file (written by :func:`save_model`).

    Raises
    ------
    ModelFileError
        If the file is not a model file, is corrupt, is from an unknown format
        version, or holds anything but tensors and plain data (such a file is
        refused without running any of it).
    FileNotFoundError
        If ``path`` does not exist.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(2, "No such file", str(p))
    with open(p, "rb") as fh:
        head = fh.read(len(_ZIP_MAGIC))
    if head != _ZIP_MAGIC:
        raise ModelFileError(
            f"{p}: not a readable model file: it is not the archive `ipcverify train` or "
            "`ipcverify calibrate` writes (a text, CSV or other file was given as the model?)"
        )
    payload = _read(p)
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise ModelFileError(f"{p}: not an ipcverify model file (no 'format': '{FORMAT}' entry)")
    version = payload.get("format_version")
    if version not in READ_VERSIONS:
        raise ModelFileError(
            f"{p}: model format version {version!r} is not supported (this ipcverify reads "
            f"versions {', '.join(map(str, READ_VERSIONS))}); retrain or upgrade ipcverify"
        )
    try:
        config = ModelConfig.from_dict(payload["config"])
        if version < config.file_version:
            raise InvalidInputError(
                f"a {config.param} network in a version-{version} file "
                f"(it needs version {config.file_version})"
            )
        weights = NetworkWeights.from_state_dict(config, payload["state_dict"])
    except (KeyError, TypeError, AttributeError, ValueError) as exc:  # InvalidInputError is a ValueError
        first = str(exc).strip().splitlines()[0]
        raise ModelFileError(f"{p}: damaged model file ({first[:200]})") from None
    for name, value in weights.state.items():
        if not np.isfinite(value).all():
            raise ModelFileError(f"{p}: parameter {name!r} holds non-finite values")
    calibration = None
    if payload.get("calibration") is not None:
        try:
            calibration = calibration_from_dict(payload["calibration"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelFileError(f"{p}: damaged calibration record ({exc})") from None
    domain = None
    if payload.get("domain") is not None:
        try:
            domain = DomainModel.from_dict(dict(payload["domain"]))
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise ModelFileError(f"{p}: damaged domain-of-validity record ({exc})") from None
    metadata = dict(payload.get("metadata") or {})
    if payload.get("row_fingerprints") is not None:
        try:
            metadata[ROWS_KEY] = _rows_record(payload["row_fingerprints"])
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise ModelFileError(f"{p}: damaged row-fingerprint record ({exc})") from None
    try:
        return IPCModel(weights, calibration, metadata, domain)
    except InvalidInputError as exc:
        raise ModelFileError(f"{p}: inconsistent model file ({exc})") from None


def _rows_payload(rows: Mapping[str, Any], to_tensor: Any) -> dict[str, Any]:
    """The row fingerprints as the model file holds them: each array's uint64 bits as an int64 tensor."""
    out: dict[str, Any] = {"scheme": str(rows.get("scheme", SCHEME))}
    for role, value in rows.items():
        if role != "scheme":
            out[role] = to_tensor(np.array(value, dtype=np.uint64).view(np.int64))  # a writable copy
    return out


def _rows_record(stored: Mapping[str, Any]) -> dict[str, Any]:
    """The metadata record of the fingerprints a file holds (sorted distinct uint64 arrays, read-only)."""
    record: dict[str, Any] = {"scheme": str(stored["scheme"])}
    for role, value in stored.items():
        if role == "scheme":
            continue
        arr = np.asarray(value)
        if arr.dtype != np.int64 or arr.ndim != 1:
            raise ValueError(f"{role}: expected a 1-D int64 array, got {arr.dtype} of shape {arr.shape}")
        bits = np.ascontiguousarray(arr).view(np.uint64)
        if len(bits) > 1 and not (bits[1:] > bits[:-1]).all():
            raise ValueError(f"{role}: the fingerprints are not sorted and distinct")
        bits.setflags(write=False)
        record[str(role)] = bits
    return record


_REFUSED = (
    "refused to load: the file holds objects other than tensors and plain data, which could run code; "
    "only load model files written by ipcverify"
)


def _read(p: Path) -> Any:
    """The archive's payload with NumPy arrays for tensors: without torch, or by torch for a layout
    the torch-free reader does not know (both refuse anything but tensors and plain data)."""
    try:
        return read_torch_file(p)
    except UnsafeContentError:
        raise ModelFileError(f"{p}: {_REFUSED}") from None
    except DamagedArchiveError:
        raise ModelFileError(f"{p}: not a readable model file: its archive is damaged or truncated") from None
    except NeedsTorchError:
        pass
    import torch

    try:
        payload = torch.load(p, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:
        if "Unsupported global" in str(exc):
            raise ModelFileError(f"{p}: {_REFUSED}") from None
        raise ModelFileError(f"{p}: not a readable model file: its archive is damaged") from None
    except Exception:  # noqa: BLE001 - torch raises many kinds; none of their internals helps the user
        raise ModelFileError(f"{p}: not a readable model file: its archive is damaged or truncated") from None
    return _numpy(payload, torch.Tensor)


def _numpy(obj: Any, tensor: type) -> Any:
    """``obj`` with every tensor replaced by a NumPy copy of it."""
    if isinstance(obj, tensor):
        return obj.detach().cpu().numpy().copy()  # type: ignore[attr-defined]
    if isinstance(obj, Mapping):
        return {k: _numpy(v, tensor) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return type(obj)(_numpy(v, tensor) for v in obj)
    return obj


def _columns(model: IPCModel, kind: str) -> list[str]:
    names = model.metadata.get(f"{kind}_columns") or []
    if names:
        return [str(c) for c in names]
    dim = model.config.x_dim if kind == "x" else model.config.y_dim
    return [f"{kind}_{i}" for i in range(dim)]


def load_data_for_model(path: str | os.PathLike[str], model: IPCModel) -> PerceptionDataset:
    """Load labelled data with the model's column names; refuse columns the model does not know.

    Tables are read with the ``x`` / ``y`` / ``yhat`` column names recorded at training
    (NPZ files have none); a table with extra ``x_i``-like columns is refused rather than
    read without them (:func:`~ipcverify.data._dataset.refuse_unknown_columns`).

    Parameters
    ----------
    path : path-like
        A CSV, Parquet or NPZ file of ``x``, ``y`` and ``yhat``.
    model : IPCModel
        The model whose column names are used.

    Examples
    --------
    >>> import tempfile, os
    >>> from ipcverify import example
    >>> from ipcverify.data import save_dataset
    >>> from ipcverify.network import ModelConfig
    >>> p = os.path.join(tempfile.mkdtemp(), "d.csv")
    >>> save_dataset(example(5, seed=0).data, p)
    >>> len(load_data_for_model(p, example(config=ModelConfig(x_dim=6, y_dim=3)).model))
    5
    """
    if Path(path).suffix.lower() == ".npz":
        return load_dataset(path)
    known = {k: _columns(model, k) for k in ("x", "y", "yhat")}
    data = load_dataset(path, known["x"], known["y"], known["yhat"])
    refuse_unknown_columns(data.source, data.extra, known)
    return data


def load_inputs_for_model(path: str | os.PathLike[str], model: IPCModel) -> PerceptionInputs:
    """Load deployment queries (``x``, ``yhat``; no truth needed) with the model's column names.

    Parameters
    ----------
    path : path-like
        A CSV, Parquet or NPZ file of ``x`` and ``yhat``.
    model : IPCModel
        The model whose column names are used.

    Examples
    --------
    >>> import tempfile, os
    >>> import numpy as np, pandas as pd
    >>> from ipcverify.network import ModelConfig
    >>> p = os.path.join(tempfile.mkdtemp(), "q.csv")
    >>> pd.DataFrame({"x_0": [0.0, 1.0], "yhat_0": [0.5, 0.5]}).to_csv(p, index=False)
    >>> from ipcverify import example
    >>> load_inputs_for_model(p, example(config=ModelConfig(x_dim=1, y_dim=1)).model).x.shape
    (2, 1)
    """
    if Path(path).suffix.lower() == ".npz":
        return load_inputs(path)
    known = {k: _columns(model, k) for k in ("x", "yhat")}
    inputs = load_inputs(path, known["x"], known["yhat"])
    refuse_unknown_columns(inputs.source, inputs.extra, known)
    return inputs
