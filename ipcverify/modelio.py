"""Safe model files.

A model file is a ``torch.save`` of a dict holding only tensors and plain data::

    {"format": "ipcverify-model", "format_version": 1,
     "config": {...}, "state_dict": {name: tensor}, "metadata": {...},
     "calibration": {...} or None}

It is read with ``torch.load(..., weights_only=True)``, which unpickles only
tensors and plain containers: a file that holds any other object (which could run
code when unpickled) is refused before anything in it executes.
"""

from __future__ import annotations

import os
import pickle
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import torch

from ipcverify.architecture import ModelConfig
from ipcverify.calibration.kinds import calibration_from_dict
from ipcverify.data import PerceptionDataset, load_dataset
from ipcverify.errors import InvalidInputError, ModelFileError
from ipcverify.files import atomic_write
from ipcverify.model import IPCModel, IPCNetwork

__all__ = ["FORMAT", "FORMAT_VERSION", "save_model", "load_model", "load_data_for_model"]

FORMAT = "ipcverify-model"
FORMAT_VERSION = 1
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

    Examples
    --------
    >>> import tempfile, os, numpy as np
    >>> m = IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=3, hidden=(8,))))
    >>> p = os.path.join(tempfile.mkdtemp(), "model.pt")
    >>> save_model(m, p)
    >>> load_model(p).config.hidden
    (8,)
    """
    metadata = _plain(dict(model.metadata))
    calibration = None if model.calibration is None else _plain(model.calibration.to_dict())
    _check_plain(metadata, "metadata")
    _check_plain(calibration, "calibration")
    payload = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "config": model.config.to_dict(),
        "state_dict": {k: v.detach().clone() for k, v in model.network.state_dict().items()},
        "metadata": metadata,
        "calibration": calibration,
    }
    atomic_write(path, lambda f: torch.save(payload, f))


def load_model(path: str | os.PathLike[str]) -> IPCModel:
    """Load a model file safely (``weights_only=True``) and rebuild the model.

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
    try:
        payload = torch.load(p, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        if "Unsupported global" in str(exc):
            raise ModelFileError(
                f"{p}: refused to load: the file holds objects other than tensors and plain "
                "data, which could run code; only load model files written by ipcverify"
            ) from None
        raise ModelFileError(f"{p}: not a readable model file ({first or 'unpickling failed'})") from None
    except (RuntimeError, EOFError, OSError, ValueError, AttributeError, IndexError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ModelFileError(f"{p}: not a readable model file ({first[:200]})") from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise ModelFileError(f"{p}: not an ipcverify model file (no 'format': '{FORMAT}' entry)")
    version = payload.get("format_version")
    if version != FORMAT_VERSION:
        raise ModelFileError(
            f"{p}: model format version {version!r} is not supported (this ipcverify reads "
            f"version {FORMAT_VERSION}); retrain or upgrade ipcverify"
        )
    try:
        config = ModelConfig.from_dict(payload["config"])
        net = IPCNetwork(config)
        net.load_state_dict(payload["state_dict"], strict=True)
    except (KeyError, TypeError, RuntimeError, InvalidInputError) as exc:
        first = str(exc).strip().splitlines()[0]
        raise ModelFileError(f"{p}: damaged model file ({first[:200]})") from None
    for name, t in net.state_dict().items():
        if t.is_floating_point() and not torch.isfinite(t).all():
            raise ModelFileError(f"{p}: parameter {name!r} holds non-finite values")
    calibration = None
    if payload.get("calibration") is not None:
        try:
            calibration = calibration_from_dict(payload["calibration"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelFileError(f"{p}: damaged calibration record ({exc})") from None
    return IPCModel(net, calibration, payload.get("metadata") or {})


def load_data_for_model(path: str | os.PathLike[str], model: IPCModel) -> PerceptionDataset:
    """Load a data file with the column names the model was trained on (tables; NPZ has no names).

    Examples
    --------
    >>> import tempfile, os
    >>> from ipcverify.synthetic import make_lagged_perception
    >>> from ipcverify.data import save_dataset
    >>> from ipcverify.architecture import ModelConfig
    >>> p = os.path.join(tempfile.mkdtemp(), "d.csv")
    >>> save_dataset(make_lagged_perception(5, seed=0), p)
    >>> len(load_data_for_model(p, IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3)))))
    5
    """
    if Path(path).suffix.lower() == ".npz":
        return load_dataset(path)
    meta = model.metadata
    return load_dataset(
        path, meta.get("x_columns") or None, meta.get("y_columns") or None, meta.get("yhat_columns") or None
    )
