"""Read the archives ``torch.save`` writes, without torch: tensors as NumPy arrays, and plain data.

A ``torch.save`` file is a zip archive: ``PREFIX/data.pkl``, a pickle of the saved object in
which every tensor is a call ``torch._utils._rebuild_tensor_v2(storage, offset, size, stride,
...)`` and every storage a persistent id ``("storage", torch.FloatStorage, key, location,
numel)`` naming the record ``PREFIX/data/KEY`` that holds its raw bytes (in the byte order of
``PREFIX/byteorder``, little-endian when absent). That is the format of every torch since 1.6.

:func:`read_torch_file` reads it with a restricted unpickler (the "restricting globals"
recipe of Python's :mod:`pickle` documentation): the only globals it resolves are
``_rebuild_tensor_v2`` and ``_rebuild_parameter`` -- both mapped to this module's own array
builders, never to torch's functions --, the storage classes of the NumPy dtypes (mapped to
those dtypes) and ``collections.OrderedDict``. Nothing a file names is ever imported or
called, so no file can run code while it is read. A global of any other module is refused
(:class:`UnsafeContentError`); a global of torch's that this reader does not know -- a layout a
later torch may write -- raises :class:`NeedsTorchError`, and the caller hands the file to
``torch.load(weights_only=True)`` (:func:`ipcverify.io.load_model` does). Every offset,
size and stride is checked against its storage before a byte is read.

Examples
--------
>>> import io, torch
>>> buf = io.BytesIO()
>>> torch.save({"w": torch.arange(6, dtype=torch.float32).reshape(2, 3).T, "n": 3}, buf)
>>> out = read_torch_file(io.BytesIO(buf.getvalue()))
>>> out["w"].tolist(), out["w"].dtype.name, out["n"]
([[0.0, 3.0], [1.0, 4.0], [2.0, 5.0]], 'float32', 3)
"""

from __future__ import annotations

import collections
import io
import math
import os
import pickle
import zipfile
import zlib
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

#: Storage classes (``torch.FloatStorage`` ...) and the NumPy dtype of their elements.
STORAGE_DTYPES = {
    "DoubleStorage": "f8",
    "FloatStorage": "f4",
    "HalfStorage": "f2",
    "LongStorage": "i8",
    "IntStorage": "i4",
    "ShortStorage": "i2",
    "CharStorage": "i1",
    "ByteStorage": "u1",
    "BoolStorage": "b1",
}


class NeedsTorchError(Exception):
    """The archive uses a part of torch's format this reader does not know: load it with torch."""


class UnsafeContentError(Exception):
    """The archive names a global outside torch's tensor format (unpickling it could run code)."""


class DamagedArchiveError(Exception):
    """The archive is not a readable ``torch.save`` file (not a zip, truncated, inconsistent)."""


class _StorageType:
    """What a storage class stands for: the dtype of its elements (a pickle cannot alter it)."""

    __slots__ = ("name", "dtype")

    def __init__(self, name: str, dtype: np.dtype[Any]) -> None:
        self.name = name
        self.dtype = dtype

    def __setstate__(self, state: Any) -> None:
        raise DamagedArchiveError("a storage class given a state")


def _array(
    storage: Any,
    offset: Any,
    size: Any,
    stride: Any,
    requires_grad: Any,
    hooks: Any,
    metadata: Any = None,
) -> NDArray[Any]:
    """``_rebuild_tensor_v2``: the strided view of ``storage`` as a new C-contiguous array."""
    if not isinstance(storage, np.ndarray) or storage.ndim != 1:
        raise DamagedArchiveError("a tensor without a storage")
    if not (isinstance(size, tuple) and isinstance(stride, tuple) and len(size) == len(stride)):
        raise DamagedArchiveError("a tensor's size and stride disagree")
    if not all(type(v) is int and v >= 0 for v in (offset, *size, *stride)):
        raise DamagedArchiveError("a tensor with a negative or non-integer size, stride or offset")
    if hooks or metadata or not isinstance(requires_grad, bool):
        raise NeedsTorchError("a tensor with hooks or metadata")
    if 0 in size:
        return np.empty(size, dtype=storage.dtype)
    if math.prod(size) > len(storage):  # an expanded view (stride 0): never in an ipcverify file
        raise NeedsTorchError("a tensor with more elements than its storage")
    last = offset + sum((n - 1) * s for n, s in zip(size, stride, strict=True))
    if last >= len(storage):
        raise DamagedArchiveError("a tensor reaches past the end of its storage")
    step = storage.dtype.itemsize
    view = np.lib.stride_tricks.as_strided(
        storage[offset:], shape=size, strides=tuple(s * step for s in stride), writeable=False
    )
    return np.array(view, order="C")


def _parameter(data: Any, requires_grad: Any, hooks: Any) -> NDArray[Any]:
    """``_rebuild_parameter``: a parameter's data (the gradient flag is of no use here)."""
    if not isinstance(data, np.ndarray) or hooks:
        raise NeedsTorchError("a parameter with hooks")
    return data


class _Unpickler(pickle.Unpickler):
    def __init__(self, file: IO[bytes], records: dict[str, bytes], byteorder: str) -> None:
        super().__init__(file)
        self._records = records
        self._order = "<" if byteorder == "little" else ">"
        self._storages: dict[str, NDArray[Any]] = {}

    def find_class(self, module: str, name: str) -> Any:
        if module == "torch._utils" and name == "_rebuild_tensor_v2":
            return _array
        if module == "torch._utils" and name == "_rebuild_parameter":
            return _parameter
        if module == "torch" and name in STORAGE_DTYPES:
            return _StorageType(name, np.dtype(self._order + STORAGE_DTYPES[name]))
        if module == "collections" and name == "OrderedDict":
            return collections.OrderedDict
        if module == "torch" or module.startswith("torch."):
            raise NeedsTorchError(f"{module}.{name}")
        raise UnsafeContentError(f"{module}.{name}")

    def persistent_load(self, pid: Any) -> NDArray[Any]:
        if not (isinstance(pid, tuple) and len(pid) == 5 and pid[0] == "storage"):
            raise NeedsTorchError(f"persistent id {str(pid)[:80]}")
        kind, key, numel = pid[1], pid[2], pid[4]
        if not (isinstance(kind, _StorageType) and isinstance(key, str) and type(numel) is int):
            raise DamagedArchiveError("a malformed storage reference")
        if key not in self._storages:
            raw = self._records.get(key)
            if raw is None or len(raw) != numel * kind.dtype.itemsize:
                raise DamagedArchiveError(f"storage {key!r} is missing or has the wrong size")
            arr = np.frombuffer(raw, dtype=kind.dtype)
            self._storages[key] = arr.astype(kind.dtype.newbyteorder("="), copy=False)
        stored = self._storages[key]
        if stored.dtype.kind != kind.dtype.kind or stored.dtype.itemsize != kind.dtype.itemsize:
            raise DamagedArchiveError(f"storage {key!r} is read as two dtypes")
        return stored


def read_torch_file(file: str | os.PathLike[str] | IO[bytes]) -> Any:
    """The object a ``torch.save`` archive holds, with NumPy arrays in place of tensors.

    Parameters
    ----------
    file : path-like or binary file object
        The archive.

    Raises
    ------
    DamagedArchiveError
        If the file is not a zip archive of torch's layout, or its records are inconsistent.
    UnsafeContentError
        If the pickle names a global outside torch's tensor format (nothing of it has run).
    NeedsTorchError
        If it uses a part of torch's format this reader does not know (nothing has run).
    """
    try:
        with zipfile.ZipFile(file) as archive:
            names = archive.namelist()
            if any(info.compress_type != zipfile.ZIP_STORED for info in archive.infolist()):
                raise NeedsTorchError("compressed records (torch.save stores them uncompressed)")
            pickles = [n for n in names if n.count("/") == 1 and n.endswith("/data.pkl")]
            if len(pickles) != 1:
                raise DamagedArchiveError("no single data.pkl record")
            prefix = pickles[0][: -len("data.pkl")]
            if not all(n.startswith(prefix) for n in names):
                raise DamagedArchiveError("records outside the archive's folder")
            data = prefix + "data/"
            records = {n[len(data) :]: archive.read(n) for n in names if n.startswith(data)}
            order = archive.read(prefix + "byteorder") if prefix + "byteorder" in names else b"little"
            pickled = archive.read(pickles[0])
    except (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, EOFError, ValueError, RuntimeError) as exc:
        raise DamagedArchiveError(f"{type(exc).__name__}: {exc}") from None
    if order not in (b"little", b"big"):
        raise DamagedArchiveError("unknown byte order")
    unpickler = _Unpickler(io.BytesIO(pickled), records, order.decode())
    try:
        obj = unpickler.load()
        _check_plain(obj)
    except (NeedsTorchError, UnsafeContentError, DamagedArchiveError):
        raise
    except Exception as exc:  # noqa: BLE001 -- any failure of a hostile or damaged pickle is "damaged"
        raise DamagedArchiveError(f"{type(exc).__name__}: {exc}") from None
    return obj


_LEAVES = (str, int, float, bool, bytes, type(None))


def _check_plain(obj: Any) -> None:
    """Refuse anything but containers, plain values and numeric arrays (what torch.save wrote)."""
    if isinstance(obj, _LEAVES):
        return
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind not in "biuf":
            raise UnsafeContentError(f"an array of dtype {obj.dtype}")
        return
    if isinstance(obj, dict):
        for k, v in obj.items():
            _check_plain(k)
            _check_plain(v)
        return
    if isinstance(obj, (list, tuple)):
        for v in obj:
            _check_plain(v)
        return
    raise UnsafeContentError(f"an object of type {type(obj).__name__}")
