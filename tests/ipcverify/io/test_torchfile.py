"""The torch-free reader of torch.save archives: the same values as torch.load, and nothing runs."""

from __future__ import annotations

import collections
import io
import pickle
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch

from ipcverify.io._torchfile import DamagedArchiveError, NeedsTorchError, UnsafeContentError, read_torch_file


def _same(ours, theirs, where="payload"):
    """Equal structure; tensors equal to their arrays in dtype, shape and every byte."""
    if isinstance(theirs, torch.Tensor):
        ref = theirs.detach().contiguous().numpy()
        assert isinstance(ours, np.ndarray), where
        assert (ours.dtype, ours.shape) == (ref.dtype, ref.shape), where
        assert ours.flags.c_contiguous and ours.tobytes() == ref.tobytes(), where
        return
    assert type(ours) is type(theirs), (where, type(ours), type(theirs))
    if isinstance(theirs, dict):
        assert list(ours) == list(theirs), where
        for k in theirs:
            _same(ours[k], theirs[k], f"{where}.{k}")
    elif isinstance(theirs, (list, tuple)):
        assert len(ours) == len(theirs), where
        for i, (a, b) in enumerate(zip(ours, theirs, strict=True)):
            _same(a, b, f"{where}[{i}]")
    else:
        assert ours == theirs, where


def _saved(obj, path: Path) -> Path:
    torch.save(obj, path)
    return path


def test_reads_what_torch_load_reads(tmp_path):
    gen = torch.Generator().manual_seed(0)
    base = torch.randn(4, 6, generator=gen, dtype=torch.float64)
    payload = {
        "format": "x",
        "nested": [1, 2.5, None, True, "s", (3, "t")],
        "state": collections.OrderedDict(
            w32=torch.randn(3, 5, generator=gen),
            w64=base,
            transposed=base.T,  # non-contiguous: a view with strides
            column=base[:, 2],  # offset and stride into a shared storage
            stacked=torch.randn(2, 1, 7, generator=gen),
            empty=torch.zeros(0, 3),
            half=torch.randn(5, generator=gen).half(),
            ints=torch.arange(-3, 3),
            small=torch.tensor([1, -2], dtype=torch.int8),
            mask=torch.tensor([True, False, True]),
            scalar=torch.tensor(2.5),
        ),
        "bad_values": torch.tensor([float("nan"), float("inf"), -0.0]),
    }
    p = _saved(payload, tmp_path / "p.pt")
    ours, theirs = read_torch_file(p), torch.load(p, weights_only=True)
    _same(ours, theirs)
    assert isinstance(ours["state"], collections.OrderedDict)
    # views are copied out of their storage: writing one does not change another
    ours["state"]["column"][0] = 123.0
    assert ours["state"]["w64"][0, 2] == theirs["state"]["w64"][0, 2].item()


def _rewritten(src: Path, dst: Path, change) -> Path:
    """A copy of archive ``src`` with ``change(name, data) -> data or None`` applied to each record."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_STORED) as zout:
        for name in zin.namelist():
            data = change(name, zin.read(name))
            if data is not None:
                zout.writestr(name, data)
    return dst


def test_big_endian_archives_are_read_in_their_byte_order(tmp_path):
    values = torch.tensor([[1.5, -2.25], [1e300, 3.0]], dtype=torch.float64)
    p = _saved({"v": values}, tmp_path / "little.pt")

    def to_big(name, data):
        if name.endswith("/byteorder"):
            return b"big"
        if "/data/" in name:
            return np.frombuffer(data, "<f8").astype(">f8").tobytes()
        return data

    big = _rewritten(p, tmp_path / "big.pt", to_big)
    np.testing.assert_array_equal(read_torch_file(big)["v"], values.numpy())
    # without a byteorder record the data are little-endian (as torch reads them)
    plain = _rewritten(p, tmp_path / "plain.pt", lambda n, d: None if n.endswith("/byteorder") else d)
    np.testing.assert_array_equal(read_torch_file(plain)["v"], values.numpy())


def test_a_pickle_that_would_run_code_is_refused_and_never_runs(tmp_path, runs_code):
    marker = tmp_path / "RAN"
    p = _saved({"x": torch.zeros(2), "evil": runs_code(str(marker))}, tmp_path / "evil.pt")
    with pytest.raises(UnsafeContentError, match=r"io\.open"):  # what pickle names builtins.open
        read_torch_file(p)
    assert not marker.exists()


def test_a_torch_object_it_does_not_know_is_left_to_torch(tmp_path):
    p = _saved({"layer": torch.nn.Linear(2, 2)}, tmp_path / "module.pt")
    with pytest.raises(NeedsTorchError, match="torch.nn"):
        read_torch_file(p)


def test_damaged_archives(tmp_path):
    p = _saved({"w": torch.arange(12, dtype=torch.float32)}, tmp_path / "ok.pt")
    raw = p.read_bytes()
    (tmp_path / "cut.pt").write_bytes(raw[: len(raw) // 2])
    (tmp_path / "text.pt").write_bytes(b"not an archive")
    short = _rewritten(p, tmp_path / "short.pt", lambda n, d: d[:-4] if "/data/" in n else d)
    for bad in (tmp_path / "cut.pt", tmp_path / "text.pt", short):
        with pytest.raises(DamagedArchiveError):
            read_torch_file(bad)


def _crafted(tmp_path: Path, offset: int, size: tuple, stride: tuple, numel: int = 4) -> Path:
    """An archive whose one tensor has the given geometry over a float32 storage of ``numel``."""

    class Storage:
        pass

    class Tensor:
        def __reduce__(self):
            hooks = collections.OrderedDict()
            return (torch._utils._rebuild_tensor_v2, (Storage(), offset, size, stride, False, hooks))

    class Pickler(pickle.Pickler):
        def persistent_id(self, obj):
            return ("storage", torch.FloatStorage, "0", "cpu", numel) if isinstance(obj, Storage) else None

    buf = io.BytesIO()
    Pickler(buf, protocol=2).dump({"t": Tensor()})
    path = tmp_path / "crafted.pt"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as z:
        z.writestr("archive/data.pkl", buf.getvalue())
        z.writestr("archive/byteorder", b"little")
        z.writestr("archive/data/0", np.arange(numel, dtype="<f4").tobytes())
    return path


def test_tensor_geometry_is_checked_against_its_storage(tmp_path):
    # the crafted archive itself is sound: a strided view reads the right elements
    np.testing.assert_array_equal(read_torch_file(_crafted(tmp_path, 1, (2,), (2,)))["t"], [1.0, 3.0])
    for offset, size, stride in (
        (3, (2,), (1,)),  # runs past the end
        (0, (2, 2), (3, 1)),  # last element at index 4 of 4
        (-1, (1,), (1,)),  # negative offset
        (0, (2,), (-1,)),  # negative stride
        (0, (2,), (1, 1)),  # size and stride disagree
    ):
        with pytest.raises(DamagedArchiveError):
            read_torch_file(_crafted(tmp_path, offset, size, stride))
    with pytest.raises(NeedsTorchError, match="more elements"):  # an expanded view: left to torch
        read_torch_file(_crafted(tmp_path, 0, (8,), (0,)))
